//! Render farms: one render split into parts that separate processes (a Slurm job array's
//! tasks, a Kubernetes Indexed Job's pods) render on their own, and the merge that puts the parts
//! back together into exactly the image one process would have rendered.
//!
//! A part is an OpenEXR file of the full image size with 32-bit float RGB channels: the tiles the
//! part holds carry the film's values bit for bit, every other pixel is black, so any EXR viewer
//! shows what a part holds. Its header carries one text attribute, `HEADER_ATTRIBUTE`, holding a
//! [`PartHeader`] as JSON: the scene's content hash, the settings, the part's index and count, the
//! tiles it holds and rayscope's version. The merge checks those before it reads any pixel.
//!
//! Tiles are dealt so that parts take about the same time even where a few tiles hold most of the
//! cost (see `owners`).

use std::io::{self, Read};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::film::Film;
use crate::output::{write_atomic, OutputError};
use crate::render::{tile_grid, tile_rect, TILE};
use crate::settings::{Limits, RenderSettings};

/// The EXR header attribute that holds a part's [`PartHeader`] as JSON.
pub(crate) const HEADER_ATTRIBUTE: &str = "rayscope.part";

/// The format name and version in every part's header.
pub(crate) const FORMAT: &str = "rayscope-part/1";

/// rayscope's version, recorded in each part: parts of different versions never merge, since a
/// change of version may change pixels.
pub(crate) const VERSION: &str = env!("CARGO_PKG_VERSION");

/// Part `index` of `count` (`--part K/N`, K = 0 … N−1 as Slurm array and Kubernetes completion
/// indices count).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PartSpec {
    /// K.
    pub index: u32,
    /// N.
    pub count: u32,
}

impl PartSpec {
    /// Parses `K/N`.
    ///
    /// # Errors
    /// A message saying what was expected.
    pub fn parse(s: &str) -> Result<PartSpec, String> {
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| format!("expected K/N such as 3/8 (part K of N, K from 0 to N-1), found '{s}'"))?;
        let num = |v: &str, what: &str| {
            v.trim()
                .parse::<u32>()
                .map_err(|_| format!("expected a whole number for {what} in K/N, found '{v}' in '{s}'"))
        };
        let (index, count) = (num(k, "K")?, num(n, "N")?);
        if count == 0 {
            return Err(format!("N in K/N must be at least 1, found '{s}'"));
        }
        if index >= count {
            return Err(format!(
                "part {index} of {count} does not exist: K counts from 0 to N-1 ({}), as Slurm array and Kubernetes completion indices do",
                count - 1
            ));
        }
        Ok(PartSpec { index, count })
    }
}

/// Spreads the bits of `v` to the even bit positions (for a Morton code).
fn spread(v: u32) -> u64 {
    let mut x = u64::from(v);
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// The part (of `parts`) that renders each tile of a `tiles_x` × `tiles_y` grid, by tile index
/// (raster order).
///
/// The tiles are put in Morton (Z-curve) order, which keeps runs of consecutive tiles close
/// together in 2D, and cut into groups of `parts` consecutive tiles, each a small patch of the
/// image; each group gives one tile to every part, the assignment turned by one from each group
/// to the next, so that over `parts` neighbouring patches every part takes every position once.
/// Every part holds the same number of tiles (±1), spread evenly over the image: where a few
/// tiles hold most of the cost (a glass object, a caustic), the patches over them share it out
/// among all the parts, rather than one part getting it all, as it would with contiguous blocks,
/// or whole columns, as a plain stride gives when the row length is a multiple of the part count.
/// Measured on a Whitted scene whose mirror and glass spheres hold most of the rays
/// (`tests/farm.rs`): the longest of 8 parts does 1.06× the mean work, contiguous bands 1.77×.
#[must_use]
pub(crate) fn owners(tiles_x: u32, tiles_y: u32, parts: u32) -> Vec<u32> {
    let mut order: Vec<u32> = (0..tiles_x * tiles_y).collect();
    order.sort_by_key(|&t| spread(t % tiles_x) | (spread(t / tiles_x) << 1));
    let n = u64::from(parts);
    let mut owner = vec![0; order.len()];
    for (i, &t) in order.iter().enumerate() {
        let (group, slot) = (i as u64 / n, i as u64 % n);
        owner[t as usize] = ((slot + group) % n) as u32;
    }
    owner
}

/// The tiles part `spec` renders in a `tiles_x` × `tiles_y` grid, in raster order.
#[must_use]
pub fn deal(tiles_x: u32, tiles_y: u32, spec: PartSpec) -> Vec<u32> {
    let owner = owners(tiles_x, tiles_y, spec.count);
    (0..tiles_x * tiles_y)
        .filter(|&t| owner[t as usize] == spec.index)
        .collect()
}

/// The SHA-256 of a scene's content: the scene file and every OBJ file it loads, in the order
/// it names them. Paths do not count, so the same scene copied to a cluster hashes the same.
///
/// # Errors
/// When a file cannot be read again.
pub fn scene_hash(file: &rayscope_scene::SceneFile) -> Result<String, String> {
    let mut h = Sha256::new();
    let mut add = |path: &Path| -> Result<(), String> {
        let bytes = std::fs::read(path).map_err(|e| format!("cannot read {} to hash it: {e}", path.display()))?;
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
        Ok(())
    };
    add(&file.path)?;
    for e in &file.entities {
        if let rayscope_scene::Shape::Mesh { source, .. } = &e.shape {
            add(source)?;
        }
    }
    Ok(hex(&h.finalize()))
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What a part file says about itself (the `HEADER_ATTRIBUTE` of its EXR header).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PartHeader {
    /// `FORMAT`.
    pub format: String,
    /// The rayscope version that rendered it ([`VERSION`]).
    pub(crate) rayscope_version: String,
    /// The scene file as it was given (for messages only; the hash decides).
    pub scene: String,
    /// [`scene_hash`] of the scene.
    pub(crate) scene_sha256: String,
    /// Every setting that changes pixels, as [`RenderSettings`] serialises them.
    pub settings: serde_json::Value,
    /// The render flags that give the same pixels (for messages and re-running a part).
    pub flags: String,
    /// The animation frame, for a frame of `--frames`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<u32>,
    /// K.
    pub part: u32,
    /// N.
    pub parts: u32,
    /// Tile edge in pixels ([`TILE`]).
    pub(crate) tile_size: u32,
    /// How many tiles the part holds.
    pub(crate) tile_count: u32,
    /// The tiles it holds: a bitmap over the image's tiles in raster order (tile `t` is bit
    /// `t % 8` of byte `t / 8`), in hexadecimal.
    pub tiles: String,
    /// Samples that were NaN or infinite and were written as black.
    pub nonfinite: u64,
    /// Seconds the part's render loop took.
    pub render_seconds: f64,
}

impl PartHeader {
    /// The header of part `spec` of a render of `scene` (content hash `scene_sha256`) with
    /// `settings`, holding `tiles`.
    #[must_use]
    pub fn new(
        scene: &Path,
        scene_sha256: String,
        settings: &RenderSettings,
        flags: String,
        frame: Option<u32>,
        spec: PartSpec,
        tiles: &[u32],
    ) -> PartHeader {
        let (tx, ty) = tile_grid(settings.width, settings.height);
        let mut bitmap = vec![0u8; (tx * ty).div_ceil(8) as usize];
        for &t in tiles {
            bitmap[(t / 8) as usize] |= 1 << (t % 8);
        }
        PartHeader {
            format: FORMAT.into(),
            rayscope_version: VERSION.into(),
            scene: scene.display().to_string(),
            scene_sha256,
            settings: serde_json::to_value(settings).unwrap_or(serde_json::Value::Null),
            flags,
            frame,
            part: spec.index,
            parts: spec.count,
            tile_size: TILE,
            tile_count: tiles.len() as u32,
            tiles: hex(&bitmap),
            nonfinite: 0,
            render_seconds: 0.0,
        }
    }

    /// Parses a part header's JSON and checks its format name.
    ///
    /// # Errors
    /// A message saying what is wrong with it (no file name: the caller adds it).
    pub fn from_json(text: &str) -> Result<PartHeader, String> {
        let h: PartHeader =
            serde_json::from_str(text).map_err(|e| format!("its '{HEADER_ATTRIBUTE}' header is damaged: {e}"))?;
        if h.format != FORMAT {
            return Err(format!(
                "it is a part in format '{}'; this rayscope reads '{FORMAT}'",
                h.format
            ));
        }
        Ok(h)
    }

    /// The image size the settings give, unchecked.
    fn size(&self) -> Result<(u32, u32), String> {
        let w = self.settings.get("width").and_then(serde_json::Value::as_u64);
        let h = self.settings.get("height").and_then(serde_json::Value::as_u64);
        match (w, h) {
            (Some(w @ 1..=0xffff_ffff), Some(h @ 1..=0xffff_ffff)) => Ok((w as u32, h as u32)),
            _ => Err("its header's settings name no image size (width, height)".into()),
        }
    }

    /// Checks every size the header states, against `limits` and against each other, without
    /// allocating anything for them: the image (a render's limits: pixels, memory), the tile
    /// size, the part's index and count (at most one part a tile) and the tile bitmap (its
    /// length, its digits, `tile_count`). Returns the image size.
    ///
    /// # Errors
    /// A message naming the field at fault and the limit it breaks.
    pub fn check(&self, limits: &Limits) -> Result<(u32, u32), String> {
        let settings: RenderSettings = serde_json::from_value(self.settings.clone())
            .map_err(|e| format!("its header's settings are not a render's ({e})"))?;
        let (w, h) = (settings.width, settings.height);
        settings
            .check(limits)
            .map_err(|e| format!("its header's settings (width {w}, height {h}) are refused: {e}"))?;
        if self.tile_size != TILE {
            return Err(format!(
                "its header's tile_size is {}; rayscope's tiles are {TILE} pixels",
                self.tile_size
            ));
        }
        let (tx, ty) = tile_grid(w, h);
        let tiles = tx * ty;
        if self.parts == 0 || self.parts > tiles {
            return Err(format!(
                "its header's parts is {}: a {w}×{h} image has {tiles} tiles of {TILE}×{TILE} pixels, so from 1 to {tiles} parts",
                self.parts
            ));
        }
        if self.part >= self.parts {
            return Err(format!(
                "its header's part is {} of {}: parts count from 0 to {}",
                self.part,
                self.parts,
                self.parts - 1
            ));
        }
        let digits = 2 * tiles.div_ceil(8) as usize;
        if self.tiles.len() != digits {
            return Err(format!(
                "its header's tile bitmap has {} hex digits; a {w}×{h} image of {tiles} tiles needs {digits}",
                self.tiles.len()
            ));
        }
        if !self.tiles.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err("its header's tile bitmap is not hexadecimal".into());
        }
        let mut held = 0u32;
        for t in self.held_tiles() {
            if t >= tiles {
                return Err(format!(
                    "its header's tile bitmap names tile {t}, past the image's {tiles} tiles"
                ));
            }
            held += 1;
        }
        if held != self.tile_count {
            return Err(format!(
                "its header's tile_count is {} but its tile bitmap holds {held} tiles",
                self.tile_count
            ));
        }
        Ok((w, h))
    }

    /// The tiles of the bitmap, in raster order (a digit that is not hexadecimal counts as 0:
    /// [`PartHeader::check`] refuses those).
    fn held_tiles(&self) -> impl Iterator<Item = u32> + '_ {
        let digit = |c: u8| (c as char).to_digit(16).unwrap_or(0) as u8;
        self.tiles
            .as_bytes()
            .chunks_exact(2)
            .enumerate()
            .flat_map(move |(i, pair)| {
                let byte = (digit(pair[0]) << 4) | digit(pair[1]);
                (0..8u32)
                    .filter(move |bit| byte & (1 << bit) != 0)
                    .map(move |bit| i as u32 * 8 + bit)
            })
    }
}

/// Writes a part: the film's pixels (only `header`'s tiles matter; the rest should be black) as
/// 32-bit float RGB, with `header` in the EXR header, atomically.
///
/// # Errors
/// When the file cannot be written; whatever was at `path` is then untouched.
pub fn write_part(path: &Path, header: &PartHeader, film: &Film) -> Result<(), OutputError> {
    use exr::prelude::*;
    let json = serde_json::to_string(header).map_err(|e| OutputError::Io {
        path: path.to_path_buf(),
        source: io::Error::other(e),
    })?;
    let json = ascii_json(&json);
    write_atomic(path, |w| {
        let (fw, px) = (film.width as usize, &film.pixels);
        let channels = SpecificChannels::rgb(|Vec2(x, y): Vec2<usize>| {
            let p = px[y * fw + x];
            (p.x, p.y, p.z)
        });
        let mut attrs = LayerAttributes::named("rayscope part");
        attrs.software_name = Some(Text::from(format!("rayscope {VERSION}").as_str()));
        attrs.other.insert(
            Text::from(HEADER_ATTRIBUTE),
            AttributeValue::Text(Text::from(json.as_str())),
        );
        // ZIP over 16 scan lines: the black tiles of other parts take almost no space.
        let layer = Layer::new(
            (film.width as usize, film.height as usize),
            attrs,
            Encoding::SMALL_LOSSLESS,
            channels,
        );
        Image::from_layer(layer)
            .write()
            .non_parallel()
            .to_buffered(&mut *w)
            .map_err(io::Error::other)
    })
    .map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// `json` with every non-ASCII character written as a `\u` escape: EXR text attributes hold
/// Latin-1 bytes, and a scene path may hold any character. Outside strings serde_json writes
/// ASCII only, so this is the same JSON value.
fn ascii_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{u:04x}"));
            }
        }
    }
    out
}

/// The most bytes of a part file rayscope reads before its pixels: the EXR header, which holds
/// the JSON with its tile bitmap. The largest render, 2^30 pixels, has at most 2^26 tiles (one
/// pixel wide), 16 MiB of hexadecimal; at least 16 pixels wide, 2^22 tiles, 1 MiB.
pub const MAX_HEADER_BYTES: u64 = 20 << 20;

/// The most a part's pixels can be compressed: rayscope writes ZIP (deflate), which never
/// compresses better than 1032:1, and twice that leaves room for any lossless EXR compression a
/// tool may have saved the part with. A header claiming more pixels than its file could hold is
/// refused before anything is allocated for them.
pub const MAX_COMPRESSION_RATIO: u64 = 2048;

/// Bytes of one pixel of a part: three 32-bit floats.
const PART_PIXEL_BYTES: u64 = 12;

/// OpenEXR's magic number, the first four bytes of every EXR file.
const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];

/// Reads a part file's header from `reader` (the file from its first byte, `file_len` bytes in
/// all) and checks it before anything is allocated for its pixels: an OpenEXR image of one
/// layer with 32-bit float R, G and B channels, its `HEADER_ATTRIBUTE` a [`PartHeader`] whose
/// sizes pass [`PartHeader::check`], its pixels the size the settings give, at the origin, and
/// the file large enough to hold them (see [`MAX_COMPRESSION_RATIO`]). At most
/// [`MAX_HEADER_BYTES`] are read.
///
/// # Errors
/// A message saying what is wrong (no file name: the caller adds it).
pub fn read_part_header(reader: impl Read, file_len: u64, limits: &Limits) -> Result<PartHeader, String> {
    let mut reader = reader.take(MAX_HEADER_BYTES);
    let mut magic = [0u8; 4];
    let not_exr = "it is not a rayscope part: not an OpenEXR file (render parts with `rayscope -f SCENE -o part_K.exr --part K/N`)";
    reader.read_exact(&mut magic).map_err(|_| not_exr.to_string())?;
    if magic != EXR_MAGIC {
        return Err(not_exr.into());
    }
    let meta = exr::meta::MetaData::read_from_buffered(io::BufReader::new((&magic[..]).chain(reader)), false).map_err(
        |e| {
            format!(
                "a damaged OpenEXR header, or one longer than the {} MiB a part's header may be ({e})",
                MAX_HEADER_BYTES >> 20
            )
        },
    )?;
    let [header] = meta.headers.as_slice() else {
        return Err(format!(
            "it holds {} images; a part holds one (was it converted?)",
            meta.headers.len()
        ));
    };
    let key = exr::prelude::Text::from(HEADER_ATTRIBUTE);
    let value = header
        .own_attributes
        .other
        .get(&key)
        .or_else(|| header.shared_attributes.other.get(&key))
        .ok_or_else(|| {
            format!(
                "it is an OpenEXR image but not a rayscope part: it has no '{HEADER_ATTRIBUTE}' header (render parts with --part K/N)"
            )
        })?;
    let exr::meta::attribute::AttributeValue::Text(text) = value else {
        return Err(format!("its '{HEADER_ATTRIBUTE}' header is not text"));
    };
    let part = PartHeader::from_json(&text.to_string())?;
    let f32_rgb = ["B", "G", "R"].iter().all(|c| {
        header
            .channels
            .list
            .iter()
            .any(|ch| ch.name == **c && ch.sample_type == exr::prelude::SampleType::F32)
    });
    if header.deep || !f32_rgb {
        return Err(
            "it has lost its 32-bit float R, G and B channels (was it converted?); render the part again".into(),
        );
    }
    // The file's length first: a header that claims more pixels than its file can hold is not
    // a render too large for the limits but a damaged or forged part.
    let (w, h) = part.size()?;
    let least = u64::from(w) * u64::from(h) * PART_PIXEL_BYTES / MAX_COMPRESSION_RATIO;
    if file_len < least {
        return Err(format!(
            "its header says {w}×{h} pixels, which take at least {least} bytes even compressed {MAX_COMPRESSION_RATIO}:1, but the file is {file_len} bytes: it is damaged or not what it says"
        ));
    }
    let (w, h) = part.check(limits)?;
    let (size, at) = (header.layer_size, header.own_attributes.layer_position);
    if (size.width(), size.height()) != (w as usize, h as usize) || (at.x(), at.y()) != (0, 0) {
        return Err(format!(
            "its pixels are {}×{} at ({}, {}); its header's settings say {w}×{h} at (0, 0)",
            size.width(),
            size.height(),
            at.x(),
            at.y()
        ));
    }
    Ok(part)
}

/// Opens a part file, only if it is a regular file (a named pipe would block, a device never
/// end), and reads its checked header; the file is left open for its pixels.
fn open_part(path: &Path, limits: &Limits) -> Result<(std::fs::File, PartHeader), String> {
    let name = path.display();
    let cannot = |e: io::Error| format!("cannot read part '{name}': {e}");
    let (file, len) = rayscope_scene::input::open_regular(path).map_err(cannot)?;
    // "it is …" reads "'part_3.exr' is …"; other messages follow the name.
    let header = read_part_header(&file, len, limits).map_err(|e| match e.strip_prefix("it ") {
        Some(rest) => format!("'{name}' {rest}"),
        None => format!("'{name}': {e}"),
    })?;
    Ok((file, header))
}

/// Reads a part's pixels, exactly as stored, from the file [`open_part`] checked.
fn read_pixels(mut file: std::fs::File, path: &Path, w: u32, h: u32) -> Result<Film, String> {
    use exr::prelude::*;
    use std::io::Seek;
    let cannot = |e: String| format!("cannot read the pixels of part '{}': {e}", path.display());
    file.rewind().map_err(|e| cannot(e.to_string()))?;
    let (ew, eh) = (w as usize, h as usize);
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgb_channels(
            move |size, _| {
                // The header was checked to be w×h; any other size allocates nothing and is
                // refused below.
                let n = if (size.width(), size.height()) == (ew, eh) {
                    size.area()
                } else {
                    0
                };
                (size.width(), vec![glam::Vec3::ZERO; n])
            },
            |(fw, px): &mut (usize, Vec<glam::Vec3>), Vec2(x, y), (r, g, b): (f32, f32, f32)| {
                if let Some(p) = px.get_mut(y * *fw + x) {
                    *p = glam::Vec3::new(r, g, b);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(io::BufReader::new(file))
        .map_err(|e| cannot(e.to_string()))?;
    let layer = image.layer_data;
    let size = layer.size;
    let pixels = layer.channel_data.pixels.1;
    if (size.width(), size.height()) != (ew, eh)
        || layer.attributes.layer_position != Vec2(0, 0)
        || pixels.len() != ew * eh
    {
        return Err(format!(
            "part '{}' is {}×{} pixels; its header says {w}×{h}",
            path.display(),
            size.width(),
            size.height()
        ));
    }
    Ok(Film {
        width: w,
        height: h,
        pixels,
    })
}

/// A merged render.
#[derive(Debug)]
pub struct Merged {
    /// The image: every tile of the parts given, black where parts are missing.
    pub film: Film,
    /// The header every part shares (that of the first file).
    pub header: PartHeader,
    /// Parts that were not given (only with `allow_missing`).
    pub missing_parts: Vec<u32>,
    /// Tiles no part held, in raster order (only with `allow_missing`).
    pub missing_tiles: Vec<u32>,
    /// Non-finite samples the parts wrote as black, in all.
    pub nonfinite: u64,
}

/// Why parts could not be merged. Every message names the files at fault.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// [`merge_within`] under the command line's limits without `--allow-large`.
///
/// # Errors
/// A [`MergeError`] naming the parts at fault.
pub fn merge(paths: &[PathBuf], allow_missing: bool) -> Result<Merged, MergeError> {
    merge_within(paths, allow_missing, &Limits::command_line(false))
}

/// Why `hd` (from `pd`) is not part of the same render as `first` (from `p0`), if it is not.
fn same_render(first: &PartHeader, p0: &str, hd: &PartHeader, pd: &str) -> Result<(), MergeError> {
    let differs = |what: &str, a: &str, b: &str| {
        Err(MergeError(format!(
            "'{pd}' is not part of the same render as '{p0}': {what} differ ({b} against {a})"
        )))
    };
    if hd.rayscope_version != first.rayscope_version {
        return differs("the rayscope versions", &first.rayscope_version, &hd.rayscope_version);
    }
    if hd.scene_sha256 != first.scene_sha256 {
        return differs(
            "the scenes' contents (scene file or OBJ files)",
            &format!("{} {:.12}", first.scene, first.scene_sha256),
            &format!("{} {:.12}", hd.scene, hd.scene_sha256),
        );
    }
    if hd.frame != first.frame {
        let f = |v: Option<u32>| v.map_or("a still".to_string(), |f| format!("frame {f}"));
        return differs("the frames", &f(first.frame), &f(hd.frame));
    }
    if hd.settings != first.settings {
        return differs("the render flags", &first.flags, &hd.flags);
    }
    if hd.parts != first.parts {
        return differs(
            "the part counts",
            &format!("{} parts", first.parts),
            &format!("{} parts", hd.parts),
        );
    }
    Ok(())
}

/// Merges part files: checks that they belong to one render (scene content, settings, version,
/// frame, part count), that each part is given once and holds the tiles its index deals it, and
/// that together they cover every tile (unless `allow_missing`); then copies each part's tiles
/// into one film. Every size a header states is checked against `limits` and its file's length
/// before anything is allocated for it, and parts are read one at a time: memory holds two
/// images of 12 bytes a pixel and a few bytes a tile, whatever the number of parts.
///
/// # Errors
/// A [`MergeError`] naming the parts at fault.
pub fn merge_within(paths: &[PathBuf], allow_missing: bool, limits: &Limits) -> Result<Merged, MergeError> {
    let err = |m: String| MergeError(m);
    let Some(path0) = paths.first() else {
        return Err(err("no parts given".into()));
    };
    let (_, first) = open_part(path0, limits).map_err(err)?;
    let p0 = path0.display().to_string();
    let (w, h) = first.check(limits).map_err(|e| err(format!("'{p0}': {e}")))?;
    let (tx, ty) = tile_grid(w, h);
    let tile_count = tx * ty;
    // `check` bounds the part count by the tile count, so these are a few bytes a tile.
    let owner = owners(tx, ty, first.parts);
    // Part k's tiles, in raster order, are dealt[start[k]..start[k + 1]].
    let mut start = vec![0usize; first.parts as usize + 1];
    for &o in &owner {
        start[o as usize + 1] += 1;
    }
    for k in 0..first.parts as usize {
        start[k + 1] += start[k];
    }
    let mut dealt = vec![0u32; owner.len()];
    let mut next = start.clone();
    for (t, &o) in owner.iter().enumerate() {
        dealt[next[o as usize]] = t as u32;
        next[o as usize] += 1;
    }
    drop(next);
    // For each part, the path that holds it.
    let mut given: Vec<Option<usize>> = vec![None; first.parts as usize];
    let mut part_of = Vec::with_capacity(paths.len());
    for (i, p) in paths.iter().enumerate() {
        let pd = p.display().to_string();
        let hd = if i == 0 {
            None
        } else {
            Some(open_part(p, limits).map_err(err)?.1)
        };
        let hd = hd.as_ref().unwrap_or(&first);
        // `open_part` checked its sizes; being of the same render, it has the first's size.
        same_render(&first, &p0, hd, &pd)?;
        let k = hd.part as usize;
        if let Some(j) = given[k] {
            return Err(err(format!(
                "part {} of {} is given twice: '{}' and '{pd}'; give each part once",
                hd.part,
                hd.parts,
                paths[j].display()
            )));
        }
        given[k] = Some(i);
        if !hd.held_tiles().eq(dealt[start[k]..start[k + 1]].iter().copied()) {
            return Err(err(format!(
                "'{pd}' holds other tiles than part {} of {} is dealt; it was not written by `--part {}/{}`",
                hd.part, hd.parts, hd.part, hd.parts
            )));
        }
        part_of.push(hd.part);
    }
    let missing_parts: Vec<u32> = (0..first.parts).filter(|&k| given[k as usize].is_none()).collect();
    let missing_tiles: Vec<u32> = (0..tile_count)
        .filter(|&t| given[owner[t as usize] as usize].is_none())
        .collect();
    if !missing_parts.is_empty() && !allow_missing {
        return Err(err(format!(
            "{} of {} parts are missing: {}; {} of {tile_count} tiles are not covered. Render them with `--part K/{}` (flags: {}), or pass --allow-missing to write the image without them",
            missing_parts.len(),
            first.parts,
            list(&missing_parts),
            missing_tiles.len(),
            first.parts,
            first.flags
        )));
    }
    drop(owner);
    let mut film = Film::new(w, h);
    let mut nonfinite = 0u64;
    for (p, &k) in paths.iter().zip(&part_of) {
        // Opened and checked again: the file read now is the one whose header was checked.
        let pd = p.display().to_string();
        let (file, hd) = open_part(p, limits).map_err(err)?;
        same_render(&first, &p0, &hd, &pd)?;
        if hd.part != k {
            return Err(err(format!(
                "'{pd}' changed while the parts were merged (it held part {k}, now part {})",
                hd.part
            )));
        }
        let part = read_pixels(file, p, w, h).map_err(err)?;
        for &t in &dealt[start[k as usize]..start[k as usize + 1]] {
            let (x0, y0, x1, y1) = tile_rect(w, h, t);
            for y in y0..y1 {
                let row = (y * w) as usize;
                film.pixels[row + x0 as usize..row + x1 as usize]
                    .copy_from_slice(&part.pixels[row + x0 as usize..row + x1 as usize]);
            }
        }
        nonfinite = nonfinite.saturating_add(hd.nonfinite);
    }
    Ok(Merged {
        film,
        header: first,
        missing_parts,
        missing_tiles,
        nonfinite,
    })
}

/// Numbers as "1, 4, 7" (at most 20, then "… (N in all)").
#[must_use]
pub fn list(v: &[u32]) -> String {
    let mut s: Vec<String> = v.iter().take(20).map(u32::to_string).collect();
    if v.len() > 20 {
        s.push(format!("… ({} in all)", v.len()));
    }
    s.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_parse_as_slurm_counts() {
        assert_eq!(PartSpec::parse("0/1"), Ok(PartSpec { index: 0, count: 1 }));
        assert_eq!(PartSpec::parse("7/8"), Ok(PartSpec { index: 7, count: 8 }));
        assert!(PartSpec::parse("8/8").unwrap_err().contains("0 to N-1 (7)"));
        assert!(PartSpec::parse("1/0").is_err());
        assert!(PartSpec::parse("3").unwrap_err().contains("K/N"));
        assert!(PartSpec::parse("-1/4").is_err());
    }

    #[test]
    fn every_tile_goes_to_exactly_one_part_in_even_shares() {
        for (tx, ty, parts) in [
            (25u32, 25u32, 8u32),
            (10, 10, 1),
            (7, 1, 7),
            (40, 25, 64),
            (25, 25, 5),
            (3, 17, 4),
        ] {
            let tiles = tx * ty;
            let mut seen = vec![0u32; tiles as usize];
            let mut sizes = Vec::new();
            for k in 0..parts {
                let d = deal(tx, ty, PartSpec { index: k, count: parts });
                sizes.push(d.len());
                for t in d {
                    seen[t as usize] += 1;
                }
            }
            assert!(seen.iter().all(|&c| c == 1), "{tx}×{ty} tiles, {parts} parts");
            let (lo, hi) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(hi - lo <= 1, "{sizes:?}");
        }
    }

    #[test]
    fn a_part_does_not_hold_whole_columns() {
        // 25 tiles a row and 5 parts: a plain stride would give part 0 columns 0, 5, 10, ….
        let d = deal(25, 25, PartSpec { index: 0, count: 5 });
        let columns: std::collections::BTreeSet<u32> = d.iter().map(|t| t % 25).collect();
        assert!(columns.len() > 20, "{columns:?}");
    }

    /// The part_header fuzz target's seeds, read as the target reads them: the real part is
    /// accepted, every forged one refused by the field it lies in.
    #[test]
    fn the_fuzz_seeds_are_judged_by_the_field_that_lies() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/corpus/part_header");
        let limits = Limits {
            ranges: crate::settings::Ranges::COMMAND_LINE,
            max_grid_samples: None,
            max_pixels: 8192 * 8192,
            memory_bytes: 2 << 30,
            max_samples: None,
            pixel_hint: "",
            memory_hint: "",
        };
        let judge = |name: &str| -> Result<(u32, u32), String> {
            let data = std::fs::read(dir.join(name)).unwrap();
            if name.ends_with(".exr") {
                read_part_header(&data[..], data.len() as u64, &limits)?.check(&limits)
            } else {
                PartHeader::from_json(std::str::from_utf8(&data).unwrap())?.check(&limits)
            }
        };
        assert_eq!(judge("seed-part-32x32.exr"), Ok((32, 32)));
        assert_eq!(judge("seed-header.json"), Ok((32, 32)));
        for (name, field) in [
            ("seed-part-huge-parts.exr", "parts is 4294967295"),
            ("seed-huge-parts.json", "parts is 4294967295"),
            ("seed-huge-size.json", "width 1048576, height 1048576"),
            ("seed-bad-bitmap.json", "not hexadecimal"),
        ] {
            let e = judge(name).unwrap_err();
            assert!(e.contains(field), "{name}: {e}");
        }
    }

    #[test]
    fn headers_are_ascii_whatever_the_scene_path() {
        let j = ascii_json(r#"{"scene":"szène/日本/🎥.txt"}"#);
        assert!(j.is_ascii(), "{j}");
        let v: serde_json::Value = serde_json::from_str(&j).unwrap();
        assert_eq!(v["scene"], "szène/日本/🎥.txt");
    }

    #[test]
    fn bitmaps_round_trip() {
        let s = RenderSettings {
            width: 100,
            height: 40,
            ..RenderSettings::default()
        };
        let spec = PartSpec { index: 1, count: 3 };
        let tiles = deal(7, 3, spec);
        let h = PartHeader::new(Path::new("s.txt"), "ab".into(), &s, String::new(), None, spec, &tiles);
        let limits = Limits::command_line(false);
        assert_eq!(h.check(&limits), Ok((100, 40)));
        assert!(h.held_tiles().eq(tiles));
        let bigger = PartHeader {
            settings: serde_json::to_value(RenderSettings { width: 200, ..s }).unwrap(),
            ..h.clone()
        };
        assert!(bigger
            .check(&limits)
            .unwrap_err()
            .contains("tile bitmap has 6 hex digits"));
    }
}
