//! Reading a student tracer's ray log: JSON Lines (one object per ray) or RayTracer.Debug's binary
//! `.rays` files, streamed in batches so a log of any size is read in bounded memory.
//!
//! Every record is validated against the scene and the render flags while it is read (entity and
//! light names, pixel and sample ranges), so the judge only sees records it can use. A malformed
//! record is a [`Diagnostic`] naming the file, line and column and what was expected.

use std::borrow::Cow;
use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};

use glam::DVec3;
use rayon::prelude::*;
use rayscope_scene::Diagnostic;
use rustc_hash::FxHashMap;
use serde::Deserialize;

mod fast;

/// Why a ray was cast, as the log names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Kind {
    /// From the camera through the image plane (`camera`, `primary`, `eye`).
    Camera,
    /// Towards a point light (`shadow`).
    Shadow,
    /// A mirror reflection (`reflection`, `reflect`, `reflected`, `mirror`).
    Reflection,
    /// Transmission through glass (`refraction`, `refract`, `refracted`, `transmission`).
    Refraction,
    /// Any other word: the ray is judged on what it hit only.
    Other(Box<str>),
}

impl Kind {
    /// The kind a log's word names (case-insensitive, with common synonyms).
    #[must_use]
    pub fn from_word(w: &str) -> Kind {
        match w.to_ascii_lowercase().as_str() {
            "camera" | "primary" | "eye" => Kind::Camera,
            "shadow" => Kind::Shadow,
            "reflection" | "reflect" | "reflected" | "mirror" => Kind::Reflection,
            "refraction" | "refract" | "refracted" | "transmission" | "transmitted" => Kind::Refraction,
            _ => Kind::Other(w.into()),
        }
    }

    /// The canonical word for the kind.
    #[must_use]
    pub fn name(&self) -> &str {
        match self {
            Kind::Camera => "camera",
            Kind::Shadow => "shadow",
            Kind::Reflection => "reflection",
            Kind::Refraction => "refraction",
            Kind::Other(w) => w,
        }
    }
}

/// A logged answer that may be missing, explicitly nothing (`null`), or a value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Answer<T> {
    /// The field was not in the record: the tracer did not say.
    NotLogged,
    /// The field was `null`: a miss, or a light that was reached.
    Nothing,
    /// The value.
    Found(T),
}

/// What a tracer says its ray hit. Every part is optional.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HitClaim {
    /// Distance along the ray, in units of the logged direction's length.
    pub t: Option<f64>,
    /// Hit point.
    pub point: Option<DVec3>,
    /// Normal at the hit.
    pub normal: Option<DVec3>,
    /// Entity index in the scene.
    pub entity: Option<u32>,
}

/// One ray of a student's log, validated against the scene.
#[derive(Debug, Clone, PartialEq)]
pub struct LoggedRay {
    /// 1-based line in a JSON Lines log, or the 1-based ray number in a `.rays` file.
    pub line: u64,
    /// Pixel (x, y), 0-based from the top-left.
    pub pixel: Option<[u32; 2]>,
    /// Sample index within the pixel (`None`: unknown, as in `.rays` files).
    pub sample: Option<u32>,
    /// The ray's id, for `parent` links.
    pub id: Option<i64>,
    /// The id of the ray whose hit cast this one.
    pub parent: Option<i64>,
    /// Why it was cast, when the log says.
    pub kind: Option<Kind>,
    /// Origin.
    pub origin: DVec3,
    /// Unit direction.
    pub direction: DVec3,
    /// Length of the direction as logged; `t` values are scaled by it.
    pub dir_len: f64,
    /// The end point of a `from`/`to` segment.
    pub end: Option<DVec3>,
    /// What the tracer found.
    pub hit: Answer<HitClaim>,
    /// Shadow rays: the light aimed at (index into the scene's lights).
    pub light: Option<u32>,
    /// Shadow rays: the entity in the way, or `Nothing` when the light is reached.
    pub blocked_by: Answer<u32>,
}

#[cfg(test)]
impl LoggedRay {
    /// A camera ray of `pixel` and `sample` on log line `line`, with nothing else logged.
    pub(crate) fn for_tests(pixel: [u32; 2], sample: u32, line: u64) -> Self {
        Self {
            line,
            pixel: Some(pixel),
            sample: Some(sample),
            id: None,
            parent: None,
            kind: None,
            origin: DVec3::ZERO,
            direction: DVec3::Z,
            dir_len: 1.0,
            end: None,
            hit: Answer::NotLogged,
            light: None,
            blocked_by: Answer::NotLogged,
        }
    }
}

/// Names and ranges a record is validated against.
#[derive(Debug, Clone)]
pub struct LogContext {
    // Looked up for every hit and shadow ray read, so with a cheap hash.
    entities: FxHashMap<String, u32>,
    entity_list: Vec<String>,
    lights: FxHashMap<String, u32>,
    light_list: Vec<String>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// The flag that sets the samples per pixel, for messages (e.g. "-x 4").
    pub aa: u32,
}

impl LogContext {
    /// A context for `scene` rendered at `width`×`height` with `spp` samples (`-x aa`).
    #[must_use]
    pub fn new(scene: &rayscope_core::Scene, width: u32, height: u32, spp: u32, aa: u32) -> Self {
        let index = |names: &[String]| names.iter().enumerate().map(|(i, n)| (n.clone(), i as u32)).collect();
        let entity_list: Vec<String> = scene.entities.iter().map(|e| e.name.clone()).collect();
        Self {
            entities: index(&entity_list),
            entity_list,
            lights: index(&scene.light_names),
            light_list: scene.light_names.clone(),
            width,
            height,
            spp,
            aa,
        }
    }
}

/// Names listed in a message: the first few, then how many more.
fn list_names(names: &[String]) -> String {
    let shown: Vec<String> = names.iter().take(8).map(|n| format!("'{n}'")).collect();
    let mut s = shown.join(", ");
    if names.len() > 8 {
        s.push_str(&format!(" and {} more", names.len() - 8));
    }
    if s.is_empty() {
        s = "none".into();
    }
    s
}

/// Why a log could not be read.
#[derive(Debug)]
pub enum LogError {
    /// The file could not be opened or read.
    Io {
        /// The log.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A JSON Lines record is malformed; the diagnostic names file, line and column.
    Malformed(Box<Diagnostic>),
    /// A `.rays` record is malformed.
    Binary {
        /// The log.
        path: PathBuf,
        /// 1-based ray number.
        ray: u64,
        /// Byte offset of the problem.
        offset: u64,
        /// What was expected and found.
        message: String,
    },
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LogError::Io { path, source } => write!(f, "error: cannot read ray log {}: {source}", path.display()),
            LogError::Malformed(d) => write!(f, "{d}"),
            LogError::Binary {
                path,
                ray,
                offset,
                message,
            } => write!(
                f,
                "error: {message}\n  --> {}: ray {ray}, byte {offset}",
                path.display()
            ),
        }
    }
}

impl std::error::Error for LogError {}

/// A stream of validated rays, read batch by batch.
pub trait RaySource {
    /// Appends the next rays to `out` (at most about [`BATCH`]); false once the log is exhausted.
    fn next_batch(&mut self, out: &mut Vec<LoggedRay>) -> Result<bool, LogError>;
    /// Bytes consumed so far and the log's size, for a progress bar.
    fn progress(&self) -> (u64, u64);
    /// Records skipped as malformed under `--lenient`, and the first one's diagnostic.
    fn skipped(&self) -> (u64, Option<&Diagnostic>);
}

/// Rays handed out per batch.
pub const BATCH: usize = 1 << 16;

/// Bytes of a JSON Lines log read per step.
const CHUNK: usize = 8 << 20;

/// How a `.rays` file's int32 ids map onto the record's fields.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IdRole {
    /// Pixel column.
    X,
    /// Pixel row.
    Y,
    /// Sample index within the pixel.
    Sample,
    /// The ray's id.
    Id,
    /// The parent ray's id.
    Parent,
    /// Not used.
    Ignore,
}

impl IdRole {
    /// Parses a comma-separated list such as `x,y` or `x,y,sample,id,parent` (`_` ignores an id).
    pub fn parse_list(s: &str) -> Result<Vec<IdRole>, String> {
        if s.trim() == "none" {
            return Ok(Vec::new());
        }
        s.split(',')
            .map(|w| match w.trim() {
                "x" => Ok(IdRole::X),
                "y" => Ok(IdRole::Y),
                "sample" => Ok(IdRole::Sample),
                "id" => Ok(IdRole::Id),
                "parent" => Ok(IdRole::Parent),
                "_" => Ok(IdRole::Ignore),
                other => Err(format!(
                    "unknown id role '{other}' (expected x, y, sample, id, parent or _, or 'none')"
                )),
            })
            .collect()
    }
}

/// Opens `path` as a ray log: `.rays` files (or files that do not start with `{`) as
/// RayTracer.Debug's binary format, everything else as JSON Lines.
pub fn open(
    path: &Path,
    ctx: LogContext,
    lenient: bool,
    id_roles: &[IdRole],
) -> Result<Box<dyn RaySource + Send>, LogError> {
    let io = |source| LogError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = File::open(path).map_err(io)?;
    let total = file.metadata().map(|m| m.len()).unwrap_or(0);
    let binary = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rays"));
    if binary {
        Ok(Box::new(BinaryReader::new(file, path, total, ctx, id_roles)))
    } else {
        Ok(Box::new(JsonlReader::new(file, path, total, ctx, lenient)))
    }
}

/// A JSON Lines log.
pub struct JsonlReader<R: Read> {
    src: R,
    path: PathBuf,
    ctx: LogContext,
    lenient: bool,
    buf: Vec<u8>,
    /// Line number of the first line in `buf`.
    next_line: u64,
    eof: bool,
    consumed: u64,
    total: u64,
    skipped: u64,
    first_skipped: Option<Diagnostic>,
}

impl<R: Read> JsonlReader<R> {
    /// A reader over `src` (named `path` in messages, `total` bytes long).
    pub fn new(src: R, path: &Path, total: u64, ctx: LogContext, lenient: bool) -> Self {
        Self {
            src,
            path: path.to_path_buf(),
            ctx,
            lenient,
            buf: Vec::new(),
            next_line: 1,
            eof: false,
            consumed: 0,
            total,
            skipped: 0,
            first_skipped: None,
        }
    }

    /// Reads until the buffer holds at least one whole line (or the log ends).
    fn fill(&mut self) -> Result<(), LogError> {
        let mut want = CHUNK;
        loop {
            if self.buf.len() < want && !self.eof {
                // `read_to_end` reads into the spare capacity without zeroing it first.
                let need = want - self.buf.len();
                self.buf.reserve(need);
                let n = (&mut self.src)
                    .take(need as u64)
                    .read_to_end(&mut self.buf)
                    .map_err(|source| LogError::Io {
                        path: self.path.clone(),
                        source,
                    })?;
                if n < need {
                    self.eof = true;
                }
            }
            if self.eof || memchr::memrchr(b'\n', &self.buf).is_some() {
                return Ok(());
            }
            // A line longer than the buffer: read on until it ends.
            want = self.buf.len() * 2;
        }
    }
}

impl<R: Read> RaySource for JsonlReader<R> {
    fn next_batch(&mut self, out: &mut Vec<LoggedRay>) -> Result<bool, LogError> {
        self.fill()?;
        if self.buf.is_empty() {
            return Ok(false);
        }
        let end = match memchr::memrchr(b'\n', &self.buf) {
            Some(i) if !self.eof => i + 1,
            _ => self.buf.len(),
        };
        let text = &self.buf[..end];
        let mut lines: Vec<(u64, &[u8])> = Vec::with_capacity(text.len() / 128);
        let mut start = 0;
        let mut no = self.next_line;
        for nl in memchr::memchr_iter(b'\n', text) {
            lines.push((no, &text[start..nl]));
            start = nl + 1;
            no += 1;
        }
        if start < text.len() {
            lines.push((no, &text[start..]));
            no += 1;
        }
        let (ctx, path) = (&self.ctx, self.path.as_path());
        let parsed: Vec<Result<Option<LoggedRay>, Box<Diagnostic>>> = lines
            .par_iter()
            .with_min_len(256)
            .map(|&(n, l)| parse_line(l, n, path, ctx))
            .collect();
        for p in parsed {
            match p {
                Ok(Some(r)) => out.push(r),
                Ok(None) => {}
                Err(d) if self.lenient => {
                    self.skipped += 1;
                    if self.first_skipped.is_none() {
                        self.first_skipped = Some(*d);
                    }
                }
                Err(d) => return Err(LogError::Malformed(d)),
            }
        }
        self.next_line = no;
        self.consumed += end as u64;
        self.buf.drain(..end);
        Ok(true)
    }

    fn progress(&self) -> (u64, u64) {
        (self.consumed, self.total)
    }

    fn skipped(&self) -> (u64, Option<&Diagnostic>) {
        (self.skipped, self.first_skipped.as_ref())
    }
}

/// Deserialises a field that may be absent (outer `None`), `null` or a value.
fn present<'de, D, T>(d: D) -> Result<Option<Option<T>>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    Option::<T>::deserialize(d).map(Some)
}

#[derive(Debug, PartialEq, Deserialize)]
struct RawHit<'a> {
    t: Option<f64>,
    point: Option<[f64; 3]>,
    normal: Option<[f64; 3]>,
    #[serde(borrow)]
    entity: Option<Cow<'a, str>>,
}

#[derive(Debug, PartialEq, Deserialize)]
struct RawRay<'a> {
    pixel: Option<[u32; 2]>,
    sample: Option<u32>,
    id: Option<i64>,
    parent: Option<i64>,
    #[serde(borrow)]
    kind: Option<Cow<'a, str>>,
    origin: Option<[f64; 3]>,
    direction: Option<[f64; 3]>,
    from: Option<[f64; 3]>,
    to: Option<[f64; 3]>,
    #[serde(default, deserialize_with = "present", borrow)]
    hit: Option<Option<RawHit<'a>>>,
    #[serde(borrow)]
    light: Option<Cow<'a, str>>,
    #[serde(default, deserialize_with = "present", borrow)]
    blocked_by: Option<Option<Cow<'a, str>>>,
}

/// The fields a ray record may have, for notes.
const FORMAT_NOTE: &str = "a record is one JSON object per line: {\"pixel\": [x, y], \"sample\": 0, \"id\": 1, \"parent\": null, \"kind\": \"camera\", \"origin\": [x, y, z], \"direction\": [x, y, z], \"hit\": {\"t\": 1.0, \"point\": [x, y, z], \"normal\": [x, y, z], \"entity\": \"Name\"} or null}; shadow rays add \"light\" and \"blocked_by\"";

/// 1-based character column of byte offset `byte` in `line`.
fn char_column(line: &str, byte: usize) -> usize {
    line.get(..byte.min(line.len())).map_or(byte, |s| s.chars().count()) + 1
}

/// The column of `"key"` in the line (1 when it does not occur).
fn key_column(line: &str, key: &str) -> (usize, usize) {
    let quoted = format!("\"{key}\"");
    match line.find(&quoted) {
        Some(i) => (char_column(line, i), quoted.chars().count()),
        None => (1, 1),
    }
}

/// The column of the quoted string value `"value"` after `key` (else of the key).
fn value_column(line: &str, key: &str, value: &str) -> (usize, usize) {
    let quoted_key = format!("\"{key}\"");
    let from = line.find(&quoted_key).unwrap_or(0);
    let quoted = format!("\"{value}\"");
    match line[from..].find(&quoted) {
        Some(i) => (char_column(line, from + i), quoted.chars().count()),
        None => key_column(line, key),
    }
}

/// Parses one line: `Ok(None)` for a blank line.
fn parse_line(bytes: &[u8], line_no: u64, path: &Path, ctx: &LogContext) -> Result<Option<LoggedRay>, Box<Diagnostic>> {
    let bytes = bytes.strip_suffix(b"\r").unwrap_or(bytes);
    let bytes = if line_no == 1 {
        bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes)
    } else {
        bytes
    };
    if bytes.iter().all(u8::is_ascii_whitespace) {
        return Ok(None);
    }
    // The line as text is needed only for a message, so it is decoded only then.
    let shown = || String::from_utf8_lossy(bytes);
    let err = |col: usize, span: usize, msg: String| {
        Box::new(Diagnostic::error(path, line_no as usize, &shown(), col, span, msg).with_note(FORMAT_NOTE))
    };
    // Records of the common shape take the fast reader; serde_json reads the rest and words errors.
    let raw: RawRay = match fast::parse(bytes).map_or_else(|| serde_json::from_slice(bytes), Ok) {
        Ok(r) => r,
        Err(e) => {
            let text = e.to_string();
            let what = text.split(" at line ").next().unwrap_or(&text).to_string();
            let mut msg = format!("expected a JSON ray record: {what}");
            let line = shown();
            if line.contains("NaN") || line.contains("Infinity") {
                msg.push_str(" (NaN and Infinity are not JSON numbers: your tracer produced a non-finite value)");
            }
            return Err(err(e.column().max(1), 1, msg));
        }
    };
    let vec = |v: [f64; 3]| DVec3::from_array(v);
    let (origin, dir_raw, end) = match (raw.origin, raw.direction, raw.from, raw.to) {
        (Some(o), Some(d), _, _) => (vec(o), vec(d), None),
        (_, _, Some(f), Some(t)) => (vec(f), vec(t) - vec(f), Some(vec(t))),
        _ => {
            return Err(err(
                1,
                1,
                "expected the ray: \"origin\" and \"direction\", or \"from\" and \"to\"".into(),
            ))
        }
    };
    let dir_len = dir_raw.length();
    if !(dir_len > 0.0 && dir_len.is_finite()) {
        let key = if end.is_some() { "to" } else { "direction" };
        let (c, s) = key_column(&shown(), key);
        let msg = if end.is_some() {
            "expected \"to\" to differ from \"from\": a segment needs a length"
        } else {
            "expected a non-zero direction"
        };
        return Err(err(c, s, msg.into()));
    }
    if let Some([x, y]) = raw.pixel {
        if x >= ctx.width || y >= ctx.height {
            let (c, s) = key_column(&shown(), "pixel");
            return Err(err(
                c,
                s,
                format!(
                    "pixel [{x}, {y}] is outside the {}×{} image being checked: pass the -w and -h your tracer rendered with",
                    ctx.width, ctx.height
                ),
            ));
        }
    }
    if let Some(s) = raw.sample {
        if s >= ctx.spp {
            let (c, span) = key_column(&shown(), "sample");
            return Err(err(
                c,
                span,
                format!(
                    "sample {s} does not exist: at -x {} a pixel has {} samples (0 to {}); pass the -x your tracer used",
                    ctx.aa,
                    ctx.spp,
                    ctx.spp - 1
                ),
            ));
        }
    }
    let entity = |name: &str, key: &str| -> Result<u32, Box<Diagnostic>> {
        ctx.entities.get(name).copied().ok_or_else(|| {
            let (c, s) = value_column(&shown(), key, name);
            err(
                c,
                s,
                format!(
                    "no entity named '{name}' in the scene (its entities: {})",
                    list_names(&ctx.entity_list)
                ),
            )
        })
    };
    let hit = match raw.hit {
        None => Answer::NotLogged,
        Some(None) => Answer::Nothing,
        Some(Some(h)) => Answer::Found(HitClaim {
            t: h.t,
            point: h.point.map(vec),
            normal: h.normal.map(vec),
            entity: match h.entity {
                Some(name) => Some(entity(&name, "entity")?),
                None => None,
            },
        }),
    };
    let blocked_by = match raw.blocked_by {
        None => Answer::NotLogged,
        Some(None) => Answer::Nothing,
        Some(Some(name)) => Answer::Found(entity(&name, "blocked_by")?),
    };
    let light = match raw.light {
        None => None,
        Some(name) => Some(ctx.lights.get(name.as_ref()).copied().ok_or_else(|| {
            let (c, s) = value_column(&shown(), "light", &name);
            err(
                c,
                s,
                format!(
                    "no light named '{name}' in the scene (its lights: {})",
                    list_names(&ctx.light_list)
                ),
            )
        })?),
    };
    Ok(Some(LoggedRay {
        line: line_no,
        pixel: raw.pixel,
        sample: Some(raw.sample.unwrap_or(0)),
        id: raw.id,
        parent: raw.parent,
        kind: raw.kind.map(|k| Kind::from_word(&k)),
        origin,
        direction: dir_raw / dir_len,
        dir_len,
        end,
        hit,
        light,
        blocked_by,
    }))
}

/// RayTracer.Debug's binary `.rays` file: an int32 count, then per ray a byte `n`, `n` int32 ids
/// and the segment's from and to as six little-endian doubles.
pub struct BinaryReader<R: Read> {
    src: BufReader<R>,
    path: PathBuf,
    ctx: LogContext,
    roles: Vec<IdRole>,
    /// Rays still to read (`None` before the count is read).
    left: Option<u64>,
    next_ray: u64,
    offset: u64,
    total: u64,
    tail_checked: bool,
}

impl<R: Read> BinaryReader<R> {
    /// A reader over `src` (named `path` in messages) whose ids mean `roles`.
    pub fn new(src: R, path: &Path, total: u64, ctx: LogContext, roles: &[IdRole]) -> Self {
        Self {
            src: BufReader::with_capacity(1 << 20, src),
            path: path.to_path_buf(),
            ctx,
            roles: roles.to_vec(),
            left: None,
            next_ray: 1,
            offset: 0,
            total,
            tail_checked: false,
        }
    }

    fn fail(&self, message: String) -> LogError {
        LogError::Binary {
            path: self.path.clone(),
            ray: self.next_ray,
            offset: self.offset,
            message,
        }
    }

    fn read_exact(&mut self, buf: &mut [u8], what: &str) -> Result<(), LogError> {
        match self.src.read_exact(buf) {
            Ok(()) => {
                self.offset += buf.len() as u64;
                Ok(())
            }
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Err(self.fail(format!(
                "the file ends inside ray {}: expected {what} ({} bytes); the count at the start says more rays follow",
                self.next_ray,
                buf.len()
            ))),
            Err(source) => Err(LogError::Io {
                path: self.path.clone(),
                source,
            }),
        }
    }

    fn read_ray(&mut self) -> Result<LoggedRay, LogError> {
        let mut n = [0u8; 1];
        self.read_exact(&mut n, "the number of ids")?;
        let mut ids = vec![0u8; n[0] as usize * 4];
        self.read_exact(&mut ids, "the ids")?;
        let mut pts = [0u8; 48];
        self.read_exact(&mut pts, "from and to as six doubles")?;
        let f: Vec<f64> = pts
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().unwrap_or([0; 8])))
            .collect();
        let from = DVec3::new(f[0], f[1], f[2]);
        let to = DVec3::new(f[3], f[4], f[5]);
        let ids: Vec<i32> = ids
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes(b.try_into().unwrap_or([0; 4])))
            .collect();
        let mut r = LoggedRay {
            line: self.next_ray,
            pixel: None,
            sample: None,
            id: None,
            parent: None,
            kind: None,
            origin: from,
            direction: DVec3::Z,
            dir_len: 1.0,
            end: Some(to),
            hit: Answer::NotLogged,
            light: None,
            blocked_by: Answer::NotLogged,
        };
        let (mut x, mut y) = (None, None);
        for (role, &v) in self.roles.iter().zip(&ids) {
            match role {
                IdRole::X => x = Some(v),
                IdRole::Y => y = Some(v),
                IdRole::Sample => r.sample = Some(v.max(0) as u32),
                IdRole::Id => r.id = Some(i64::from(v)),
                IdRole::Parent => r.parent = (v >= 0).then_some(i64::from(v)),
                IdRole::Ignore => {}
            }
        }
        if let (Some(x), Some(y)) = (x, y) {
            if x < 0 || y < 0 || x as u32 >= self.ctx.width || y as u32 >= self.ctx.height {
                return Err(self.fail(format!(
                    "ray {} is for pixel ({x}, {y}), outside the {}×{} image being checked: pass the -w and -h your tracer rendered with, or --ray-ids to say what the ids mean",
                    self.next_ray, self.ctx.width, self.ctx.height
                )));
            }
            r.pixel = Some([x as u32, y as u32]);
        }
        if let Some(s) = r.sample {
            if s >= self.ctx.spp {
                return Err(self.fail(format!(
                    "ray {} is sample {s}, but at -x {} a pixel has {} samples",
                    self.next_ray, self.ctx.aa, self.ctx.spp
                )));
            }
        }
        let d = to - from;
        let len = d.length();
        if !(len > 0.0 && len.is_finite() && from.is_finite()) {
            return Err(self.fail(format!(
                "ray {} has from = {from} and to = {to}: expected two different finite points",
                self.next_ray
            )));
        }
        r.direction = d / len;
        r.dir_len = len;
        Ok(r)
    }
}

impl<R: Read> RaySource for BinaryReader<R> {
    fn next_batch(&mut self, out: &mut Vec<LoggedRay>) -> Result<bool, LogError> {
        let left = match self.left {
            Some(l) => l,
            None => {
                let mut c = [0u8; 4];
                self.read_exact(&mut c, "the ray count (int32)")?;
                let count = i32::from_le_bytes(c);
                if count < 0 {
                    return Err(self.fail(format!(
                        "the ray count at the start is {count}: expected 0 or more (is this a RayTracer.Debug .rays file?)"
                    )));
                }
                count as u64
            }
        };
        let n = left.min(BATCH as u64);
        for _ in 0..n {
            let r = self.read_ray()?;
            out.push(r);
            self.next_ray += 1;
        }
        self.left = Some(left - n);
        if left == n && !self.tail_checked {
            self.tail_checked = true;
            let mut extra = [0u8; 1];
            if let Ok(1) = self.src.read(&mut extra) {
                return Err(self.fail(format!(
                    "the file goes on after the {} rays its count announces",
                    self.next_ray - 1
                )));
            }
        }
        Ok(n > 0)
    }

    fn progress(&self) -> (u64, u64) {
        (self.offset, self.total)
    }

    fn skipped(&self) -> (u64, Option<&Diagnostic>) {
        (0, None)
    }
}
