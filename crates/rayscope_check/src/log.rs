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
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use rayscope_scene::Diagnostic;
use rustc_hash::FxHashMap;

mod fast;
mod raw;

use raw::{BlockerRef, LightRef, RawRay};

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
    /// The kind a log's word names (case-insensitive, with common synonyms). Any other word is
    /// kept in [`printable`] form, at most [`MAX_KIND_CHARS`] characters of it.
    #[must_use]
    pub fn from_word(w: &str) -> Kind {
        // The words tracers write, spelled as rayscope's own log spells them, decided at once.
        match w {
            "camera" => return Kind::Camera,
            "shadow" => return Kind::Shadow,
            "reflection" => return Kind::Reflection,
            "refraction" => return Kind::Refraction,
            _ => {}
        }
        let is = |words: &[&str]| words.iter().any(|x| w.eq_ignore_ascii_case(x));
        if is(&["camera", "primary", "eye"]) {
            Kind::Camera
        } else if is(&["shadow"]) {
            Kind::Shadow
        } else if is(&["reflection", "reflect", "reflected", "mirror"]) {
            Kind::Reflection
        } else if is(&["refraction", "refract", "refracted", "transmission", "transmitted"]) {
            Kind::Refraction
        } else {
            let mut word: String = w.chars().take(MAX_KIND_CHARS).collect();
            if word.len() < w.len() {
                word.push('…');
            }
            Kind::Other(printable(&word).into())
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

/// Characters of a kind word the log names that are kept: a kind is one word.
pub const MAX_KIND_CHARS: usize = 64;

/// `text` safe to print on a terminal: control characters (and the invisible characters that
/// reorder text) escaped as `\u{1b}`, so that a log cannot send escape sequences to the terminal.
#[must_use]
pub fn printable(text: &str) -> Cow<'_, str> {
    let unsafe_char = |c: char| {
        c.is_control() || matches!(c, '\u{200E}'..='\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}')
    };
    if !text.chars().any(unsafe_char) {
        return Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if unsafe_char(c) {
            out.extend(c.escape_unicode());
        } else {
            out.push(c);
        }
    }
    Cow::Owned(out)
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
    /// Shadow rays: what is in the way (`Found(None)`: something the log does not name), or
    /// `Nothing` when the light is reached.
    pub blocked_by: Answer<Option<u32>>,
    /// The linear colour the ray brought back to whoever cast it, before clamping, when logged.
    pub color: Option<DVec3>,
}

impl LoggedRay {
    /// A ray of line `line` with nothing logged: a placeholder for a line that is not a ray.
    fn blank(line: u64) -> Self {
        Self {
            line,
            pixel: None,
            sample: None,
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
            color: None,
        }
    }
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
            color: None,
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
    light_positions: Vec<DVec3>,
    // The same names as the reader of rayscope's own shape finds them.
    entity_names: fast::Names,
    light_names: fast::Names,
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
            entity_names: fast::Names::new(&entity_list),
            light_names: fast::Names::new(&scene.light_names),
            entities: index(&entity_list),
            entity_list,
            lights: index(&scene.light_names),
            light_list: scene.light_names.clone(),
            light_positions: scene.lights.iter().map(|l| l.position.as_dvec3()).collect(),
            width,
            height,
            spp,
            aa,
        }
    }
}

/// The light at `p`: the nearest one within single-precision rounding of the scene's position, so
/// that a tracer storing positions as floats is matched too.
fn light_at(ctx: &LogContext, p: DVec3) -> Option<u32> {
    let (i, d) = ctx
        .light_positions
        .iter()
        .enumerate()
        .map(|(i, l)| (i, (*l - p).length()))
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let scale = p.abs().max_element().max(1.0);
    (d <= 1e-5 * scale).then_some(i as u32)
}

/// The scene's lights with their positions, for a message about a light logged by position.
fn list_lights(ctx: &LogContext) -> String {
    let named: Vec<String> = ctx
        .light_list
        .iter()
        .zip(&ctx.light_positions)
        .take(8)
        // The scene's own numbers: its positions are single precision.
        .map(|(n, p)| format!("'{n}' at [{}, {}, {}]", p.x as f32, p.y as f32, p.z as f32))
        .collect();
    match ctx.light_list.len() {
        0 => "none".into(),
        n if n > 8 => format!("{} and {} more", named.join(", "), n - 8),
        _ => named.join(", "),
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
    /// The log interleaves the rays of more pixel samples than the check holds at once.
    Interleaved {
        /// Where the check stopped (see [`RaySource::place`]).
        place: String,
        /// Rays of unfinished pixel samples that were waiting.
        rays: u64,
        /// The unfinished pixel samples.
        samples: u64,
        /// The most rays the check holds, which was exceeded.
        limit: u64,
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
            LogError::Interleaved {
                place,
                rays,
                samples,
                limit,
            } => write!(
                f,
                "error: the log interleaves the rays of too many pixel samples: {rays} rays of {samples} unfinished pixel samples were waiting for the rest of their samples, more than the {limit} rays check holds at once\n  --> {place}\n  = note: write each pixel sample's rays together, one sample after another (a tracer that renders in parallel can collect a sample's rays and write them at once when the sample is done), or log fewer pixels at a time"
            ),
        }
    }
}

impl std::error::Error for LogError {}

/// The pixel sample a ray belongs to: its pixel and its sample, each as logged.
pub type SampleKey = (Option<[u32; 2]>, Option<u32>);

impl LoggedRay {
    /// The pixel sample the ray belongs to.
    #[must_use]
    pub fn sample_key(&self) -> SampleKey {
        (self.pixel, self.sample)
    }
}

/// A stream of validated rays, read batch by batch.
pub trait RaySource {
    /// Appends the next rays to `out` (at most about [`BATCH`]); false once the log is exhausted.
    fn next_batch(&mut self, out: &mut Vec<LoggedRay>) -> Result<bool, LogError>;
    /// [`Self::next_batch`], also appending each ray's [`SampleKey`] to `keys`.
    fn next_batch_keyed(&mut self, out: &mut Vec<LoggedRay>, keys: &mut Vec<SampleKey>) -> Result<bool, LogError> {
        let before = out.len();
        let more = self.next_batch(out)?;
        keys.par_extend(out[before..].par_iter().with_min_len(1024).map(LoggedRay::sample_key));
        Ok(more)
    }
    /// Bytes consumed so far and the log's size, for a progress bar.
    fn progress(&self) -> (u64, u64);
    /// Records skipped as malformed under `--lenient`, and the first one's diagnostic.
    fn skipped(&self) -> (u64, Option<&Diagnostic>);
    /// Where record `record` (a line, or a `.rays` file's ray number) is, for messages.
    fn place(&self, record: u64) -> String;
}

/// Rays handed out per batch, at most (for JSON Lines, lines read per batch). The check reads
/// one batch while it judges the one before, and waits for both at the end of each batch: a
/// batch of 16,384 rays (about 5 MB, 3.8 MB of log) makes those waits few.
pub const BATCH: usize = 1 << 14;

/// Bytes of a JSON Lines log held at once, at most (with [`MAX_LINE`] more): room for a whole
/// batch of records of up to 256 bytes, and little more, as the bytes after a batch are moved to
/// the front of the buffer before the next is read.
const CHUNK: usize = 4 << 20;

/// The longest line of a JSON Lines log, in bytes: a ray record is a few hundred bytes, so a
/// longer line is not one, and the reader never holds more than this of a line it refuses.
pub const MAX_LINE: usize = 64 << 10;

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

/// Opens the ray log at `path` for reading, with its size: only a regular file is read (a
/// folder, a named pipe or a device is named as such instead of blocking or growing without end).
///
/// # Errors
/// [`LogError::Io`] with the OS error, or saying what the path is instead of a file.
pub fn open_file(path: &Path) -> Result<(File, u64), LogError> {
    rayscope_scene::input::open_regular(path).map_err(|source| LogError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Opens `path` as a ray log: `.rays` files as RayTracer.Debug's binary format, everything else
/// as JSON Lines. Only a regular file is read ([`open_file`]).
///
/// # Errors
/// See [`open_file`].
pub fn open(
    path: &Path,
    ctx: LogContext,
    lenient: bool,
    id_roles: &[IdRole],
) -> Result<Box<dyn RaySource + Send>, LogError> {
    let (file, total) = open_file(path)?;
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
    /// Bytes read and not yet dropped; those before `pos` are consumed. At most [`CHUNK`] plus
    /// [`MAX_LINE`] bytes.
    buf: Vec<u8>,
    pos: usize,
    /// Bytes dropped from the front of `buf`.
    dropped: u64,
    /// Line number of the line at `pos`.
    next_line: u64,
    /// Under `--lenient`, inside a line longer than [`MAX_LINE`]: the rest of it is skipped.
    skipping: bool,
    eof: bool,
    total: u64,
    skipped: u64,
    first_skipped: Option<Diagnostic>,
    /// The batch's lines and what each parsed to, kept between batches so that their memory
    /// (megabytes) is not handed back to the system and faulted in again for every batch.
    lines: Vec<LineSpan>,
    parsed: Vec<Result<Option<LoggedRay>, ()>>,
}

/// A line of the batch being parsed: its number and where it lies in the buffer.
type LineSpan = (u64, usize, usize);

impl<R: Read> JsonlReader<R> {
    /// A reader over `src` (named `path` in messages, `total` bytes long).
    pub fn new(src: R, path: &Path, total: u64, ctx: LogContext, lenient: bool) -> Self {
        Self {
            src,
            path: path.to_path_buf(),
            ctx,
            lenient,
            buf: Vec::new(),
            pos: 0,
            dropped: 0,
            next_line: 1,
            skipping: false,
            eof: false,
            total,
            skipped: 0,
            first_skipped: None,
            lines: Vec::new(),
            parsed: Vec::new(),
        }
    }

    /// Drops the consumed bytes and reads more, up to [`CHUNK`] plus [`MAX_LINE`] bytes held.
    fn read_more(&mut self) -> Result<(), LogError> {
        self.buf.drain(..self.pos);
        self.dropped += self.pos as u64;
        self.pos = 0;
        // At least a chunk when what is held is part of a line (at most `MAX_LINE` bytes).
        let room = (CHUNK + MAX_LINE).saturating_sub(self.buf.len());
        // `read_to_end` reads into the spare capacity without zeroing it first.
        self.buf.reserve(room);
        let n = (&mut self.src)
            .take(room as u64)
            .read_to_end(&mut self.buf)
            .map_err(|source| LogError::Io {
                path: self.path.clone(),
                source,
            })?;
        if n < room {
            self.eof = true;
        }
        Ok(())
    }

    /// Reads until the unconsumed bytes hold a whole line, or more than [`MAX_LINE`] bytes of
    /// one, or the log ends.
    fn fill(&mut self) -> Result<(), LogError> {
        let mut searched = self.pos;
        loop {
            if memchr::memchr(b'\n', &self.buf[searched..]).is_some()
                || self.eof
                || self.buf.len() - self.pos > MAX_LINE
            {
                return Ok(());
            }
            searched = self.buf.len() - self.pos;
            self.read_more()?;
        }
    }

    /// Consumes the rest of a line longer than [`MAX_LINE`], holding at most [`CHUNK`] of it.
    fn skip_long_line(&mut self) -> Result<(), LogError> {
        loop {
            if let Some(i) = memchr::memchr(b'\n', &self.buf[self.pos..]) {
                self.pos += i + 1;
                self.skipping = false;
                return Ok(());
            }
            self.pos = self.buf.len();
            if self.eof {
                self.skipping = false;
                return Ok(());
            }
            self.read_more()?;
        }
    }

    /// The diagnostic of line `no`, which is longer than [`MAX_LINE`] and starts at `start`.
    fn long_line(&self, no: u64, start: usize) -> Diagnostic {
        let head = &self.buf[start..(start + 120).min(self.buf.len())];
        Diagnostic::error(
            &self.path,
            no as usize,
            &String::from_utf8_lossy(head),
            1,
            1,
            format!(
                "this line is longer than {MAX_LINE} bytes, the most a ray record may be (a record is a few hundred bytes)"
            ),
        )
        .with_note("a ray log has one JSON object per line, one ray per object; is this a ray log?")
    }

    /// Notes a malformed line: the error, or under `--lenient` a line skipped (the first's
    /// diagnostic kept, the others counted).
    fn malformed(&mut self, diagnostic: impl FnOnce(&Self) -> Diagnostic) -> Result<(), LogError> {
        if !self.lenient {
            return Err(LogError::Malformed(Box::new(diagnostic(self))));
        }
        self.skipped += 1;
        if self.first_skipped.is_none() {
            self.first_skipped = Some(diagnostic(self));
        }
        Ok(())
    }

    /// The next lines after those already in `lines`, up to [`BATCH`] in all, each at most
    /// [`MAX_LINE`] bytes; with the line after them when that one is longer. Reads only what
    /// `fill` has made whole.
    fn split(&self, lines: &mut Vec<LineSpan>) -> Option<(u64, usize)> {
        let text = &self.buf[self.pos..];
        let (mut start, mut no) = lines
            .last()
            .map_or((0, self.next_line), |&(n, _, b)| (b + 1 - self.pos, n + 1));
        let from = start;
        for nl in memchr::memchr_iter(b'\n', &text[from..]).map(|i| from + i) {
            if nl - start > MAX_LINE {
                return Some((no, self.pos + start));
            }
            lines.push((no, self.pos + start, self.pos + nl));
            start = nl + 1;
            no += 1;
            if lines.len() == BATCH {
                return None;
            }
        }
        let tail = text.len() - start;
        if tail > MAX_LINE {
            return Some((no, self.pos + start));
        }
        if self.eof && tail > 0 {
            lines.push((no, self.pos + start, self.pos + text.len()));
        }
        None
    }

    /// Moves past the batch's lines (`self.lines`), and notes the line after them when `long`
    /// says it is too long.
    fn finish_batch(&mut self, long: Option<(u64, usize)>) -> Result<bool, LogError> {
        if let Some(&(n, _, b)) = self.lines.last() {
            self.next_line = n + 1;
            self.pos = (b + 1).min(self.buf.len());
        }
        if let Some((n, start)) = long {
            self.malformed(|me| me.long_line(n, start))?;
            self.next_line = n + 1;
            self.pos = start;
            self.skipping = true;
        }
        Ok(true)
    }
}

impl<R: Read> RaySource for JsonlReader<R> {
    fn next_batch(&mut self, out: &mut Vec<LoggedRay>) -> Result<bool, LogError> {
        self.batch(out, None)
    }

    fn next_batch_keyed(&mut self, out: &mut Vec<LoggedRay>, keys: &mut Vec<SampleKey>) -> Result<bool, LogError> {
        self.batch(out, Some(keys))
    }

    fn progress(&self) -> (u64, u64) {
        (self.dropped + self.pos as u64, self.total)
    }

    fn skipped(&self) -> (u64, Option<&Diagnostic>) {
        (self.skipped, self.first_skipped.as_ref())
    }

    fn place(&self, record: u64) -> String {
        format!("{}:{record}", self.path.display())
    }
}

impl<R: Read> JsonlReader<R> {
    /// The next batch into `out`, and with `keys` each ray's sample key into it.
    fn batch(&mut self, out: &mut Vec<LoggedRay>, mut keys: Option<&mut Vec<SampleKey>>) -> Result<bool, LogError> {
        if self.skipping {
            self.skip_long_line()?;
        }
        self.fill()?;
        if self.pos == self.buf.len() {
            return Ok(false);
        }
        let mut lines = std::mem::take(&mut self.lines);
        let mut parsed = std::mem::take(&mut self.parsed);
        lines.clear();
        let mut long = self.split(&mut lines);
        if lines.len() < BATCH && long.is_none() && !self.eof && self.pos > 0 {
            // The bytes held end inside the batch: dropping those consumed makes room for more
            // of the log, so that every batch but the log's last is whole.
            let dropped = self.pos;
            self.read_more()?;
            for (_, a, b) in &mut lines {
                *a -= dropped;
                *b -= dropped;
            }
            long = self.split(&mut lines);
        }
        let (ctx, path, buf) = (&self.ctx, self.path.as_path(), &self.buf);
        // Most batches are all rays: they are parsed straight into `out`, each ray written once.
        // A batch with a blank or malformed line is parsed again below, line by line.
        let before = out.len();
        let keys_before = keys.as_ref().map_or(0, |k| k.len());
        let odd = AtomicBool::new(false);
        let parse = |&(n, a, b): &LineSpan| match parse_line(&buf[a..b], n, path, ctx) {
            Ok(Some(r)) => r,
            _ => {
                odd.store(true, Ordering::Relaxed);
                LoggedRay::blank(n)
            }
        };
        match keys.as_deref_mut() {
            // Each ray's key is written as the ray is, in one pass over the batch's lines.
            Some(keys) if out.is_empty() && keys.is_empty() => lines
                .par_iter()
                .with_min_len(256)
                .map(|line| {
                    let r = parse(line);
                    let k = r.sample_key();
                    (r, k)
                })
                .unzip_into_vecs(out, keys),
            _ => out.par_extend(lines.par_iter().with_min_len(256).map(parse)),
        }
        if !odd.load(Ordering::Relaxed) {
            if let Some(keys) = keys.filter(|k| k.len() == keys_before) {
                keys.extend(out[before..].iter().map(LoggedRay::sample_key));
            }
            self.lines = lines;
            self.parsed = parsed;
            return self.finish_batch(long);
        }
        out.truncate(before);
        if let Some(keys) = keys.as_deref_mut() {
            keys.truncate(keys_before);
        }
        // A malformed line's diagnostic is dropped at once and made again for the one reported,
        // so a log of bad lines costs no memory per line.
        parsed.clear();
        parsed.par_extend(
            lines
                .par_iter()
                .with_min_len(256)
                .map(|&(n, a, b)| parse_line(&buf[a..b], n, path, ctx).map_err(drop)),
        );
        out.reserve(parsed.len());
        let mut result = Ok(());
        for (p, &(n, a, b)) in parsed.drain(..).zip(&lines) {
            match p {
                Ok(Some(r)) => out.push(r),
                Ok(None) => {}
                Err(()) => {
                    result = self.malformed(|me| {
                        parse_line(&me.buf[a..b], n, &me.path, &me.ctx).map_or_else(
                            |d| *d,
                            |_| {
                                // Parsing is deterministic: the line fails again.
                                Diagnostic::error(&me.path, n as usize, "", 1, 1, "expected a JSON ray record")
                            },
                        )
                    });
                    if result.is_err() {
                        break;
                    }
                }
            }
        }
        self.parsed = parsed;
        self.lines = lines;
        if let Some(keys) = keys {
            keys.extend(out[before..].iter().map(LoggedRay::sample_key));
        }
        result?;
        self.finish_batch(long)
    }
}

/// The fields a ray record may have, for notes.
const FORMAT_NOTE: &str = "a record is one JSON object per line: {\"pixel\": [x, y], \"sample\": 0, \"id\": 1, \"parent\": null, \"kind\": \"camera\", \"origin\": [x, y, z], \"direction\": [x, y, z], \"hit\": {\"t\": 1.0, \"point\": [x, y, z], \"normal\": [x, y, z], \"entity\": \"Name\"} or null}; shadow rays add \"light\" (a name or [x, y, z]) and \"blocked_by\" (a name, true or null); any ray may add \"color\": [r, g, b]";

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

/// Refuses a record whose pixel or sample lies outside the image being checked.
fn in_range<'a>(
    raw: &RawRay,
    ctx: &LogContext,
    shown: &dyn Fn() -> Cow<'a, str>,
    err: &dyn Fn(usize, usize, String) -> Box<Diagnostic>,
) -> Result<(), Box<Diagnostic>> {
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
    Ok(())
}

/// The scene's index of the light a shadow ray names (by name or by position).
fn light_index<'a>(
    light: Option<LightRef>,
    ctx: &LogContext,
    shown: &dyn Fn() -> Cow<'a, str>,
    err: &dyn Fn(usize, usize, String) -> Box<Diagnostic>,
) -> Result<Option<u32>, Box<Diagnostic>> {
    let light = match light {
        None => None,
        Some(LightRef::Position(p)) => Some(light_at(ctx, DVec3::from_array(p)).ok_or_else(|| {
            let (c, s) = key_column(&shown(), "light");
            err(
                c,
                s,
                format!("no light at {p:?} in the scene (its lights: {})", list_lights(ctx)),
            )
        })?),
        Some(LightRef::Name(name)) => Some(ctx.lights.get(name.as_ref()).copied().ok_or_else(|| {
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
    Ok(light)
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
    // Records of rayscope's own shape are read straight into their ray.
    if let Some(r) = fast::ray(bytes, line_no, ctx) {
        return Ok(Some(r));
    }
    parse_general(bytes, line_no, path, ctx)
}

/// Parses one line that is not blank, whatever its shape.
fn parse_general(
    bytes: &[u8],
    line_no: u64,
    path: &Path,
    ctx: &LogContext,
) -> Result<Option<LoggedRay>, Box<Diagnostic>> {
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
    in_range(&raw, ctx, &shown, &err)?;
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
        Some(None | Some(BlockerRef::Blocked(false))) => Answer::Nothing,
        Some(Some(BlockerRef::Blocked(true))) => Answer::Found(None),
        Some(Some(BlockerRef::Name(name))) => Answer::Found(Some(entity(&name, "blocked_by")?)),
    };
    let light = light_index(raw.light, ctx, &shown, &err)?;
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
        color: raw.color.map(vec),
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
        self.fail_at(self.offset, message)
    }

    /// An error about the current ray at byte `offset` of the file.
    fn fail_at(&self, offset: u64, message: String) -> LogError {
        LogError::Binary {
            path: self.path.clone(),
            ray: self.next_ray,
            offset,
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
        let start = self.offset;
        let mut n = [0u8; 1];
        self.read_exact(&mut n, "the number of ids")?;
        let mut id_bytes = [0u8; 255 * 4];
        let id_bytes = &mut id_bytes[..n[0] as usize * 4];
        self.read_exact(id_bytes, "the ids")?;
        let mut pts = [0u8; 48];
        self.read_exact(&mut pts, "from and to as six doubles")?;
        let f = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&pts[i * 8..i * 8 + 8]);
            f64::from_le_bytes(b)
        };
        let from = DVec3::new(f(0), f(1), f(2));
        let to = DVec3::new(f(3), f(4), f(5));
        let ids = id_bytes
            .chunks_exact(4)
            .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]));
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
            color: None,
        };
        let (mut x, mut y) = (None, None);
        for (k, (role, v)) in self.roles.iter().zip(ids).enumerate() {
            match role {
                IdRole::X => x = Some(v),
                IdRole::Y => y = Some(v),
                IdRole::Sample => {
                    let Ok(s) = u32::try_from(v) else {
                        return Err(self.fail_at(
                            start + 1 + 4 * k as u64,
                            format!(
                                "ray {} is sample {v}: expected a sample index of 0 or more (is --ray-ids right about which id is the sample?)",
                                self.next_ray
                            ),
                        ));
                    };
                    r.sample = Some(s);
                }
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

    fn place(&self, record: u64) -> String {
        format!("{}: ray {record}", self.path.display())
    }
}
