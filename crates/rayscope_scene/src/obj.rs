//! A small, strict Wavefront OBJ reader for triangle meshes.
//!
//! Supported: `v x y z [w]`, `vn x y z`, `vt …` (counted, otherwise ignored) and `f` with the
//! `v`, `v/vt`, `v//vn` and `v/vt/vn` forms, including negative (relative) indices; polygons are
//! fan-triangulated. Every other statement (`o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, …) is
//! ignored. Vertex indices must refer to vertices defined on earlier lines, as the OBJ format
//! says, and so must normal indices once the file has normals.
//!
//! Students' readers take only what they draw from a line, so files take liberties with the rest;
//! those that change nothing drawn load, with one warning a kind naming the first line (and
//! counting the others): texture coordinate indices the file lacks (texture coordinates are never
//! used), normal indices in a file without `vn` lines before the face (the face is shaded flat),
//! and `vn` lines that cannot be read (faces using them are shaded flat).
//!
//! OBJ files are right-handed and the scene is left-handed, so positions become
//! (s·x + ox, s·y + oy, −s·z + oz) and normals normalize(nx, ny, −nz). Negating z mirrors the
//! mesh, which reverses the winding of every face; indices are nevertheless kept in file order,
//! because the renderer intersects triangles from both sides and shades with normals that it
//! orients towards the ray (interpolated `vn` normals, or the flat normal when a face has none).

use std::path::Path;

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::diagnostic::{decode_utf8, Diagnostic, Severity};
use crate::lexer::{lines, parse_number, NumberError};
use crate::{Mesh, MeshTriangle, SceneError};

/// How an OBJ model is placed in the scene: `p_scene = scale · p_obj + offset` after flipping z.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObjOptions {
    /// Uniform scale applied before the offset.
    pub scale: f64,
    /// Translation applied after scaling.
    pub offset: DVec3,
}

impl Default for ObjOptions {
    fn default() -> Self {
        Self {
            scale: 1.0,
            offset: DVec3::ZERO,
        }
    }
}

/// Parses OBJ text as if read from `path` (used in messages), converting it to scene space.
pub fn parse_obj(src: &str, path: &Path, opts: &ObjOptions) -> Result<Mesh, SceneError> {
    parse_obj_with_warnings(src, path, opts)
        .map(|(mesh, _)| mesh)
        .map_err(SceneError::Invalid)
}

/// Reads and parses an OBJ file, converting it to scene space.
pub fn load_obj(path: &Path, opts: &ObjOptions) -> Result<Mesh, SceneError> {
    let bytes = crate::input::read_bounded(path, crate::input::MAX_OBJ_BYTES).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = decode_utf8(&bytes, path).map_err(SceneError::Invalid)?;
    parse_obj(text, path, opts)
}

/// Whitespace-separated tokens of an OBJ line with their byte offsets, comment removed, into
/// `out` (cleared first; one buffer serves every line of a file).
fn obj_tokens<'a>(line: &'a str, out: &mut Vec<(usize, &'a str)>) {
    out.clear();
    // Byte by byte while the line is ASCII, as OBJ files are, in one pass that also finds the
    // comment: decoding chars, and separate passes for the comment and for whether the line is
    // ASCII, were most of the time spent reading a large file.
    let bytes = line.as_bytes();
    let mut start = None;
    for (i, &b) in bytes.iter().enumerate() {
        if b >= 0x80 {
            // Not ASCII: the whole line is split again, by chars.
            out.clear();
            let code = line.find('#').map_or(line, |i| &line[..i]);
            split_tokens(code, code.char_indices(), out);
            return;
        }
        let space = ascii_space(b);
        if space || b == b'#' {
            if let Some(s) = start.take() {
                out.push((s, &line[s..i]));
            }
            if b == b'#' {
                return;
            }
        } else if start.is_none() {
            start = Some(i);
        }
    }
    if let Some(s) = start {
        out.push((s, &line[s..]));
    }
}

/// `char::is_whitespace` for an ASCII byte: space, and tab to carriage return (which includes
/// the vertical tab that `u8::is_ascii_whitespace` leaves out).
fn ascii_space(b: u8) -> bool {
    b == b' ' || (b'\t'..=b'\r').contains(&b)
}

/// Appends to `out` the whitespace-separated tokens of `code`, whose chars `chars` yields with
/// their byte offsets.
fn split_tokens<'a>(code: &'a str, chars: impl Iterator<Item = (usize, char)>, out: &mut Vec<(usize, &'a str)>) {
    let mut start = None;
    for (i, c) in chars {
        if c.is_whitespace() {
            if let Some(s) = start.take() {
                out.push((s, &code[s..i]));
            }
        } else if start.is_none() {
            start = Some(i);
        }
    }
    if let Some(s) = start {
        out.push((s, &code[s..]));
    }
}

/// What one stretch of lines of an OBJ file defines: counted first, so that the stretches can
/// then be parsed at the same time, each knowing what the lines before it defined and writing
/// its elements straight to their place in the mesh.
#[derive(Debug, Clone, Copy, Default)]
struct Counts {
    lines: usize,
    positions: usize,
    normals: usize,
    texcoords: usize,
    triangles: usize,
}

impl Counts {
    /// The statements of `text`, as [`ObjParser::statement`] will take them (a face whose
    /// corners are too few to make a triangle is an error there).
    fn of(text: &str) -> Counts {
        let mut c = Counts::default();
        let mut toks = Vec::new();
        for line in lines(text) {
            c.lines += 1;
            if !line.is_ascii() {
                // Split as the parser splits it.
                obj_tokens(line, &mut toks);
                if let Some(&(_, word)) = toks.first() {
                    c.add(word.as_bytes(), toks.len() - 1);
                }
                continue;
            }
            // The tokens `obj_tokens` finds in an ASCII line, but only as far as needed: the
            // keyword, and on a face line the number of corners.
            let code = line.as_bytes();
            let code = memchr::memchr(b'#', code).map_or(code, |i| &code[..i]);
            let from = code.iter().position(|&b| !ascii_space(b)).unwrap_or(code.len());
            let rest = &code[from..];
            let end = rest.iter().position(|&b| ascii_space(b)).unwrap_or(rest.len());
            let word = &rest[..end];
            let args = if word == b"f" {
                let mut gap = true;
                rest[end..].iter().fold(0, |n, &b| {
                    let space = ascii_space(b);
                    let starts = gap && !space;
                    gap = space;
                    n + usize::from(starts)
                })
            } else {
                0
            };
            c.add(word, args);
        }
        c
    }

    /// Counts a statement with keyword `word` and `args` arguments.
    fn add(&mut self, word: &[u8], args: usize) {
        match word {
            b"v" => self.positions += 1,
            b"vn" => self.normals += 1,
            b"vt" => self.texcoords += 1,
            // A fan over n corners; fewer than three is an error when the face is parsed.
            b"f" => self.triangles += args.saturating_sub(2),
            _ => {}
        }
    }

    fn plus(self, o: Counts) -> Counts {
        Counts {
            lines: self.lines + o.lines,
            positions: self.positions + o.positions,
            normals: self.normals + o.normals,
            texcoords: self.texcoords + o.texcoords,
            triangles: self.triangles + o.triangles,
        }
    }
}

/// Where a stretch's elements go: its part of the mesh's array, filled from the front, or (when
/// the whole file is one stretch, which is not counted first) an array of its own.
enum Slots<'o, T> {
    Part(&'o mut [T], usize),
    Own(Vec<T>),
}

impl<T> Slots<'_, T> {
    /// Writes the next element. [`Counts`] sized a part for every element its text defines.
    fn push(&mut self, v: T) {
        match self {
            Slots::Part(buf, len) => {
                buf[*len] = v;
                *len += 1;
            }
            Slots::Own(buf) => buf.push(v),
        }
    }

    /// How many elements have been written.
    fn len(&self) -> usize {
        match self {
            Slots::Part(_, len) => *len,
            Slots::Own(buf) => buf.len(),
        }
    }

    /// The array of its own (empty for a part).
    fn into_own(self) -> Vec<T> {
        match self {
            Slots::Part(..) => Vec::new(),
            Slots::Own(buf) => buf,
        }
    }
}

/// A stretch's outputs: positions, one normal per `vn` line, triangles.
type Outputs<'o> = (Slots<'o, Vec3>, Slots<'o, Vec3>, Slots<'o, MeshTriangle>);
/// A whole file's positions, normals per `vn` line and triangles (see [`mesh_from`]).
type Parsed = (Vec<Vec3>, Vec<Vec3>, Vec<MeshTriangle>);

/// Parsing state for one stretch of lines of an OBJ file.
struct ObjParser<'a, 'o> {
    path: &'a Path,
    opts: ObjOptions,
    /// What the lines before this stretch defined.
    before: Counts,
    positions: Slots<'o, Vec3>,
    /// One per `vn` line: the unit normal, or zero where the line's normal has no length (it is
    /// dropped once every stretch is parsed, see [`mesh_from`]).
    normals: Slots<'o, Vec3>,
    /// Triangles; their normals are `vn` lines (0-based) until every stretch is parsed.
    triangles: Slots<'o, MeshTriangle>,
    texcoords: usize,
    line_no: usize,
    line: &'a str,
    /// Scratch for a face's corners: position indices.
    corner_positions: Vec<u32>,
    /// Scratch for a face's corners: normal indices (`None` where a corner has none).
    corner_normals: Vec<Option<u32>>,
    /// The lines of this stretch that loaded with something ignored, by [`Ignore`] kind.
    ignored: [Ignored; IGNORE_KINDS],
}

/// What a resolved index is wrong about.
#[derive(Debug, Clone, Copy)]
enum IndexProblem {
    /// Not a whole number.
    NotANumber,
    /// 0, which OBJ indices never are.
    Zero,
    /// A number that names no element defined so far.
    Missing(i64),
}

/// Resolves a 1-based or negative OBJ index `text` against `count` elements defined so far.
fn resolve(text: &str, count: usize) -> Result<usize, IndexProblem> {
    let n: i64 = text.parse().map_err(|_| IndexProblem::NotANumber)?;
    if n == 0 {
        return Err(IndexProblem::Zero);
    }
    let resolved = if n > 0 {
        usize::try_from(n - 1).ok().filter(|&i| i < count)
    } else {
        usize::try_from(n.unsigned_abs())
            .ok()
            .and_then(|back| count.checked_sub(back))
    };
    resolved.ok_or(IndexProblem::Missing(n))
}

/// The kinds of liberty a line may take that loads with a warning, the thing concerned ignored.
#[derive(Debug, Clone, Copy)]
enum Ignore {
    /// A face's texture coordinate index names none that is defined.
    Texcoord,
    /// A face gives normal indices in a file with no normals before it.
    FaceNormal,
    /// A `vn` line whose coordinates cannot be read.
    NormalLine,
}

/// How many [`Ignore`] kinds there are.
const IGNORE_KINDS: usize = 3;

/// How many later line numbers a warning about ignored things lists.
const SHOWN_LINES: usize = 5;

/// The lines of one kind that loaded with something ignored: the first one's warning, and how
/// many more there were, the first few by number.
#[derive(Debug, Default)]
struct Ignored {
    /// The warning for the first such line.
    first: Option<Diagnostic>,
    /// Numbers of the next lines, at most [`SHOWN_LINES`].
    shown: Vec<usize>,
    /// How many lines there were after the first.
    more: usize,
}

impl Ignored {
    /// Counts one more line, `line`, after the first.
    fn later(&mut self, line: usize) {
        if self.shown.len() < SHOWN_LINES {
            self.shown.push(line);
        }
        self.more += 1;
    }

    /// These lines followed by those of `after`, a later stretch.
    fn then(mut self, after: Ignored) -> Ignored {
        let Some(first) = after.first else {
            return self;
        };
        if self.first.is_none() {
            return Ignored {
                first: Some(first),
                ..after
            };
        }
        self.later(first.line);
        let unshown = after.more - after.shown.len();
        for line in after.shown {
            self.later(line);
        }
        self.more += unshown;
        self
    }

    /// The warning, naming the other lines like it.
    fn into_warning(self) -> Option<Diagnostic> {
        let mut d = self.first?;
        if self.more > 0 {
            let lines: Vec<String> = self.shown.iter().map(ToString::to_string).collect();
            let rest = self.more - self.shown.len();
            let also = if rest > 0 {
                format!("{} and {rest} more", lines.join(", "))
            } else {
                lines.join(", ")
            };
            let s = if self.more == 1 { "" } else { "s" };
            d.add_note(format!("the same holds on {} more line{s}: {also}", self.more));
        }
        Some(d)
    }
}

impl<'a> ObjParser<'a, '_> {
    fn error(&self, start: usize, text: &str, message: String) -> Diagnostic {
        let column = crate::lexer::column(self.line, start);
        Diagnostic::error(
            self.path,
            self.line_no,
            self.line,
            column,
            text.chars().count().max(1),
            message,
        )
    }

    /// Reads three coordinates after the keyword, pointing past the end when some are missing.
    fn coords(&self, toks: &[(usize, &str)], what: &str) -> Result<DVec3, Box<Diagnostic>> {
        let mut v = [0.0; 3];
        for (k, slot) in v.iter_mut().enumerate() {
            let axis = ["x", "y", "z"][k];
            let Some(&(start, text)) = toks.get(k + 1) else {
                let end = toks.last().map_or(0, |&(s, t)| s + t.len());
                let found = toks.len() - 1;
                return Err(self
                    .error(
                        end,
                        " ",
                        format!("expected 3 coordinates (x y z) after '{}' but found {found}", toks[0].1),
                    )
                    .with_label(format!("expected the {axis} coordinate of the {what}"))
                    .into());
            };
            *slot = parse_number(text).map_err(|e| {
                let (message, label) = match e {
                    NumberError::Malformed => (
                        format!("expected a number for the {axis} coordinate of the {what} but found '{text}'"),
                        "not a number",
                    ),
                    NumberError::NotFinite => (
                        format!("expected a finite number for the {axis} coordinate of the {what} but found '{text}'"),
                        "non-finite number",
                    ),
                    NumberError::Overflow => (
                        format!("expected a finite number for the {axis} coordinate of the {what} but found '{text}'"),
                        "non-finite number: too large for a double",
                    ),
                };
                Box::new(self.error(start, text, message).with_label(label))
            })?;
        }
        Ok(DVec3::from_array(v))
    }

    /// Resolves a 1-based or negative OBJ index against `count` elements defined so far.
    fn index(&self, start: usize, text: &str, kind: &str, count: usize) -> Result<usize, Box<Diagnostic>> {
        resolve(text, count).map_err(|problem| Box::new(self.index_error(start, text, kind, count, problem)))
    }

    /// The error for an index `text` of a `kind` that [`resolve`] rejected.
    fn index_error(&self, start: usize, text: &str, kind: &str, count: usize, problem: IndexProblem) -> Diagnostic {
        match problem {
            IndexProblem::NotANumber => {
                let d = self
                    .error(
                        start,
                        text,
                        format!("expected a {kind} index (a whole number) but found '{text}'"),
                    )
                    .with_label("not an index");
                if text == "\\" {
                    // Some writers continue a long line this way; students' readers, and this
                    // one, read a statement from one line.
                    d.with_note("a '\\' at the end of a line does not continue it on the next here: join the lines")
                } else {
                    d
                }
            }
            IndexProblem::Zero => self
                .error(start, text, format!("expected a {kind} index but found 0"))
                .with_label("OBJ indices start at 1")
                .with_note("negative indices count back from the most recent element: -1 is the last one"),
            IndexProblem::Missing(n) => {
                let kinds = match kind {
                    "vertex" if count != 1 => "vertices".to_string(),
                    _ if count != 1 => format!("{kind}s"),
                    _ => kind.to_string(),
                };
                let so_far = match count {
                    0 => format!("no {kinds} are defined so far"),
                    1 => format!("only 1 {kinds} is defined so far"),
                    _ => format!("only {count} {kinds} are defined so far"),
                };
                let label = if n > 0 {
                    so_far.clone()
                } else {
                    format!("counts back past the first {kind}")
                };
                self.error(start, text, format!("face refers to {kind} {n} but {so_far}"))
                    .with_label(label)
                    .with_note("OBJ indices refer to elements defined on earlier lines, counting from 1")
            }
        }
    }

    /// Records that the current line loaded with something of kind `kind` ignored; `warning`
    /// makes the warning when this is the first such line of the stretch (later ones are only
    /// counted, so that a file of a million such faces costs no more memory than one).
    fn ignore(&mut self, kind: Ignore, warning: impl FnOnce(&Self) -> Diagnostic) {
        let line = self.line_no;
        if self.ignored[kind as usize].first.is_none() {
            let mut d = warning(self);
            d.severity = Severity::Warning;
            self.ignored[kind as usize].first = Some(d);
        } else {
            self.ignored[kind as usize].later(line);
        }
    }

    fn face(&mut self, toks: &[(usize, &str)]) -> Result<(), Box<Diagnostic>> {
        let corners = &toks[1..];
        if corners.len() < 3 {
            let end = toks.last().map_or(0, |&(s, t)| s + t.len());
            return Err(self
                .error(
                    end,
                    " ",
                    format!("expected a face with at least 3 vertices but found {}", corners.len()),
                )
                .with_label("expected another vertex")
                .into());
        }
        // The parser's buffers, taken for this face and put back, so faces allocate nothing.
        let mut positions = std::mem::take(&mut self.corner_positions);
        let mut normals = std::mem::take(&mut self.corner_normals);
        positions.clear();
        normals.clear();
        // One warning of each kind a line at most, however many of its corners it concerns.
        let (mut texcoord_warned, mut normal_warned) = (false, false);
        for &(start, text) in corners {
            let mut parts = text.split('/');
            let v = parts.next().unwrap_or_default();
            let vt = parts.next();
            let vn = parts.next();
            if parts.next().is_some() {
                return Err(self
                    .error(
                        start,
                        text,
                        format!("expected a face vertex (v, v/vt, v//vn or v/vt/vn) but found '{text}'"),
                    )
                    .with_label("too many '/'")
                    .into());
            }
            let vi = self.index(start, v, "vertex", self.before.positions + self.positions.len())?;
            positions.push(u32::try_from(vi).unwrap_or(u32::MAX));
            let mut offset = start + v.len() + 1;
            if let Some(vt) = vt.filter(|t| !t.is_empty()) {
                // Texture coordinates are never used, so one the file lacks changes nothing drawn:
                // the course's readers skip them, and so does this one, with a warning.
                let count = self.before.texcoords + self.texcoords;
                if let Err(problem) = resolve(vt, count) {
                    if !texcoord_warned {
                        texcoord_warned = true;
                        self.ignore(Ignore::Texcoord, |p| {
                            p.index_error(offset, vt, "texture coordinate", count, problem)
                                .with_label("ignored: texture coordinates are not used")
                        });
                    }
                }
            }
            offset += vt.map_or(0, |t| t.len() + 1);
            match vn {
                Some(vn) if !vn.is_empty() => {
                    let count = self.before.normals + self.normals.len();
                    if count == 0 {
                        // A file without normals: the indices cannot mean any, and a reader that
                        // ignores them draws the face flat, as this one then does.
                        if !normal_warned {
                            normal_warned = true;
                            self.ignore(Ignore::FaceNormal, |p| {
                                p.error(
                                    offset,
                                    vn,
                                    format!(
                                        "face refers to normal '{vn}' but no normals ('vn' lines) are defined so far"
                                    ),
                                )
                                .with_label("ignored: the face is shaded flat")
                            });
                        }
                        normals.push(None);
                    } else {
                        // Normals that exist but are indexed wrongly would shade wrongly: an error.
                        let ni = self.index(offset, vn, "normal", count)?;
                        normals.push(u32::try_from(ni).ok());
                    }
                }
                _ => normals.push(None),
            }
        }
        // Vertex normals only when every corner has one (and, once known, each has a length).
        let normals_used = normals.iter().all(Option::is_some);
        for i in 1..positions.len() - 1 {
            self.triangles.push(MeshTriangle {
                positions: [positions[0], positions[i], positions[i + 1]],
                normals: normals_used.then(|| [0, i, i + 1].map(|k| normals[k].unwrap_or_default())),
            });
        }
        self.corner_positions = positions;
        self.corner_normals = normals;
        Ok(())
    }

    fn statement(&mut self, toks: &[(usize, &str)]) -> Result<(), Box<Diagnostic>> {
        match toks[0].1 {
            "v" => {
                let p = self.coords(toks, "vertex")?;
                let s = self.opts.scale;
                let o = self.opts.offset;
                let q = DVec3::new(s * p.x + o.x, s * p.y + o.y, -s * p.z + o.z).as_vec3();
                if !q.is_finite() {
                    return Err(self
                        .error(
                            toks[1].0,
                            toks[1].1,
                            "expected a vertex within single-precision range but this one is too large once scaled"
                                .into(),
                        )
                        .with_label("overflows")
                        .into());
                }
                if self.before.positions + self.positions.len() >= u32::MAX as usize {
                    return Err(self
                        .error(toks[0].0, "v", "too many vertices (more than 4294967295)".into())
                        .into());
                }
                self.positions.push(q);
            }
            "vn" => {
                let n = match self.coords(toks, "normal") {
                    Ok(n) => n,
                    Err(d) => {
                        // Kept as a normal without length, which faces then ignore (shading flat):
                        // the geometry does not depend on it, and readers that skip `vn` load it.
                        self.ignore(Ignore::NormalLine, move |_| {
                            (*d).with_label("ignored: faces using this normal are shaded flat")
                        });
                        DVec3::ZERO
                    }
                };
                let n = DVec3::new(n.x, n.y, -n.z);
                let m = n.abs().max_element();
                let unit = if m > 0.0 { (n / m).normalize() } else { DVec3::ZERO };
                self.normals.push(if unit.length_squared() > 0.5 {
                    unit.as_vec3()
                } else {
                    Vec3::ZERO
                });
            }
            "vt" => self.texcoords += 1,
            "f" => self.face(toks)?,
            _ => {}
        }
        Ok(())
    }
}

/// Parses OBJ text, returning the mesh and any warnings, or the first error.
pub(crate) fn parse_obj_with_warnings(
    src: &str,
    path: &Path,
    opts: &ObjOptions,
) -> Result<(Mesh, Vec<Diagnostic>), Box<Diagnostic>> {
    // A large file is parsed in stretches on every thread, a few per thread so that they even
    // out; a small one in one go.
    let threads = rayon::current_num_threads();
    let stretches = if src.len() < PARALLEL_BYTES || threads == 1 {
        1
    } else {
        (threads * 4).min(src.len() / (PARALLEL_BYTES / 4))
    };
    parse_in_stretches(src, path, opts, stretches)
}

/// Files from this size on are parsed on several threads.
const PARALLEL_BYTES: usize = 1 << 20;

/// `src` cut into about `n` stretches of whole lines (each but the last ending in `\n`).
fn stretches(src: &str, n: usize) -> Vec<&str> {
    let mut out = Vec::with_capacity(n);
    let mut start = 0;
    for k in 1..n {
        let aim = (src.len() * k / n).max(start);
        let Some(end) = src.as_bytes()[aim..]
            .iter()
            .position(|&b| b == b'\n')
            .map(|i| aim + i + 1)
        else {
            break;
        };
        if end > start {
            out.push(&src[start..end]);
            start = end;
        }
    }
    out.push(&src[start..]);
    out
}

impl<'a, 'o> ObjParser<'a, 'o> {
    /// A parser for the stretch after the lines `before`, writing to `positions`, `normals` and
    /// `triangles`.
    fn new(path: &'a Path, opts: &ObjOptions, before: Counts, (positions, normals, triangles): Outputs<'o>) -> Self {
        ObjParser {
            path,
            opts: *opts,
            before,
            positions,
            normals,
            triangles,
            texcoords: 0,
            line_no: 0,
            line: "",
            corner_positions: Vec::new(),
            corner_normals: Vec::new(),
            ignored: Default::default(),
        }
    }

    /// Parses the stretch `text`, stopping at its first error.
    fn run(&mut self, text: &'a str) -> Result<(), Box<Diagnostic>> {
        let mut toks = Vec::new();
        for (i, line) in lines(text).enumerate() {
            self.line_no = self.before.lines + i + 1;
            self.line = line;
            obj_tokens(line, &mut toks);
            if !toks.is_empty() {
                self.statement(&toks)?;
            }
        }
        Ok(())
    }
}

/// [`parse_obj_with_warnings`] with the text cut into about `n` stretches.
fn parse_in_stretches(
    src: &str,
    path: &Path,
    opts: &ObjOptions,
    n: usize,
) -> Result<(Mesh, Vec<Diagnostic>), Box<Diagnostic>> {
    let parts = stretches(src, n.max(1));
    let ((positions, normals, triangles), ignored) = if let [text] = parts[..] {
        let own = (Slots::Own(Vec::new()), Slots::Own(Vec::new()), Slots::Own(Vec::new()));
        let mut parser = ObjParser::new(path, opts, Counts::default(), own);
        parser.run(text)?;
        (
            (
                parser.positions.into_own(),
                parser.normals.into_own(),
                parser.triangles.into_own(),
            ),
            parser.ignored,
        )
    } else {
        in_parts(&parts, path, opts)?
    };
    let mesh = mesh_from(positions, &normals, triangles);
    let mut warnings: Vec<Diagnostic> = ignored.into_iter().filter_map(Ignored::into_warning).collect();
    warnings.sort_by_key(|d| (d.line, d.column));
    if mesh.triangles.is_empty() {
        let (n, text) = lines(src).enumerate().last().map_or((0, ""), |(i, l)| (i + 1, l));
        warnings.push(
            Diagnostic::warning(
                path,
                n.max(1),
                text,
                1,
                text.chars().count().max(1),
                "expected at least one face ('f' line) in the OBJ file but found none",
            )
            .with_label("the model is empty")
            .with_note("the model will not be visible"),
        );
    }
    Ok((mesh, warnings))
}

/// The positions, per-line normals and triangles of the stretches `parts`, parsed at once on
/// every thread once counted, and the lines that loaded with something ignored.
fn in_parts(
    parts: &[&str],
    path: &Path,
    opts: &ObjOptions,
) -> Result<(Parsed, [Ignored; IGNORE_KINDS]), Box<Diagnostic>> {
    let counts: Vec<Counts> = parts.par_iter().map(|t| Counts::of(t)).collect();
    let total = counts.iter().fold(Counts::default(), |a, &c| a.plus(c));
    // Every element's place is known, so each stretch writes its own part of these.
    let mut positions = filled(total.positions, Vec3::ZERO);
    let mut normals = filled(total.normals, Vec3::ZERO);
    let mut triangles = filled(
        total.triangles,
        MeshTriangle {
            positions: [0; 3],
            normals: None,
        },
    );
    let mut jobs = Vec::with_capacity(parts.len());
    let (mut p_rest, mut n_rest, mut t_rest) = (&mut positions[..], &mut normals[..], &mut triangles[..]);
    let mut before = Counts::default();
    for (&text, &c) in parts.iter().zip(&counts) {
        let (p, pr) = std::mem::take(&mut p_rest).split_at_mut(c.positions);
        let (nn, nr) = std::mem::take(&mut n_rest).split_at_mut(c.normals);
        let (t, tr) = std::mem::take(&mut t_rest).split_at_mut(c.triangles);
        (p_rest, n_rest, t_rest) = (pr, nr, tr);
        jobs.push((text, before, (Slots::Part(p, 0), Slots::Part(nn, 0), Slots::Part(t, 0))));
        before = before.plus(c);
    }
    // Each stretch stops at its first error; the file's first error is the earliest stretch's.
    let results: Vec<Result<[Ignored; IGNORE_KINDS], Box<Diagnostic>>> = jobs
        .into_par_iter()
        .map(|(text, before, out)| {
            let mut parser = ObjParser::new(path, opts, before, out);
            parser.run(text).map(|()| parser.ignored)
        })
        .collect();
    let mut ignored: [Ignored; IGNORE_KINDS] = Default::default();
    for stretch in results {
        // In file order, so that the warnings are those of the file parsed in one go.
        for (all, part) in ignored.iter_mut().zip(stretch?) {
            *all = std::mem::take(all).then(part);
        }
    }
    Ok(((positions, normals, triangles), ignored))
}

/// `n` copies of `v`, written on every thread (for a large mesh this is fresh memory, whose
/// first writes cost more than the copies).
fn filled<T: Copy + Send + Sync>(n: usize, v: T) -> Vec<T> {
    let mut out = Vec::new();
    (0..n).into_par_iter().map(|_| v).collect_into_vec(&mut out);
    out
}

/// The mesh, once every stretch is parsed: normals without length dropped, and the triangles'
/// normals turned from `vn` lines into indices of the normals kept (a face with a dropped normal
/// is shaded flat).
fn mesh_from(positions: Vec<Vec3>, per_line: &[Vec3], mut triangles: Vec<MeshTriangle>) -> Mesh {
    let mut normals = Vec::with_capacity(per_line.len());
    let kept: Vec<Option<u32>> = per_line
        .iter()
        .map(|&n| {
            (n != Vec3::ZERO).then(|| {
                normals.push(n);
                u32::try_from(normals.len() - 1).unwrap_or(u32::MAX)
            })
        })
        .collect();
    if !kept.is_empty() {
        triangles.par_iter_mut().with_min_len(1 << 12).for_each(|t| {
            if let Some(lines) = t.normals {
                let ids = lines.map(|l| kept[l as usize]);
                t.normals = ids
                    .iter()
                    .all(Option::is_some)
                    .then(|| ids.map(Option::unwrap_or_default));
            }
        });
    }
    Mesh {
        positions,
        normals,
        triangles,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn parse(src: &str) -> Result<Mesh, Box<Diagnostic>> {
        parse_obj_with_warnings(src, Path::new("m.obj"), &ObjOptions::default()).map(|(m, _)| m)
    }

    #[test]
    fn face_forms_and_fans() {
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0 1\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
             f 1 2 3\nf 1/1 2/1 3/1\nf 1//1 2//1 3//1 4//1\nf -4/1/-1 -3/1/1 -2/-1/-1\n",
        )
        .unwrap();
        assert_eq!(m.positions.len(), 4);
        assert_eq!(m.normals, [Vec3::new(0.0, 0.0, -1.0)]);
        assert_eq!(m.triangles.len(), 5);
        assert_eq!(m.triangles[0].normals, None);
        assert_eq!(m.triangles[2].positions, [0, 1, 2]);
        assert_eq!(m.triangles[3].positions, [0, 2, 3]);
        assert_eq!(m.triangles[3].normals, Some([0, 0, 0]));
        assert_eq!(m.triangles[4].positions, [0, 1, 2]);
    }

    #[test]
    fn transform_flips_z() {
        let opts = ObjOptions {
            scale: 2.0,
            offset: DVec3::new(1.0, 2.0, 3.0),
        };
        let (m, _) = parse_obj_with_warnings("v 1 1 1\nvn 0 3 4\n", Path::new("m.obj"), &opts).unwrap();
        assert_eq!(m.positions, [Vec3::new(3.0, 4.0, 1.0)]);
        assert_eq!(m.normals, [Vec3::new(0.0, 0.6, -0.8)]);
    }

    #[test]
    fn zero_normals_drop_face_normals() {
        let m = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 0\nvn 0 0 1\nf 1//1 2//2 3//2\n").unwrap();
        assert_eq!(m.normals.len(), 1);
        assert_eq!(m.triangles[0].normals, None);
    }

    #[test]
    fn errors() {
        let e = parse("v 0 0 0\nf 1 2 3\n").unwrap_err();
        assert_eq!((e.line, e.column), (2, 5));
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 0 2 3\n").unwrap_err();
        assert_eq!((e.line, e.column), (4, 3));
        let e = parse("v 0 0 0\nv 0 0 0\nf 1 2\n").unwrap_err();
        assert!(e.message.contains("at least 3"), "{e}");
        let e = parse("v 0 x 0\n").unwrap_err();
        assert_eq!((e.line, e.column), (1, 5));
        let e = parse("v 0 0\n").unwrap_err();
        assert_eq!((e.line, e.column), (1, 6));
        // A texture coordinate the file lacks is ignored with a warning where it is named.
        let (_, w) = parse_obj_with_warnings(
            "v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/1 2 3\n",
            Path::new("m.obj"),
            &ObjOptions::default(),
        )
        .unwrap();
        assert_eq!((w[0].severity, w[0].line, w[0].column), (Severity::Warning, 4, 5));
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/1 2 4/1\n").unwrap_err();
        assert_eq!((e.line, e.column), (4, 9));
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf -4 2 3\n").unwrap_err();
        assert_eq!((e.line, e.column), (4, 3));
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/2/3/4 2 3\n").unwrap_err();
        assert!(e.message.contains("face vertex"), "{e}");
    }

    #[test]
    fn fans_take_each_corner_normal() {
        let m = parse(
            "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvn 0 1 0\nvn 1 0 0\nvn 1 1 0\n\
             f 1//1 2//2 3//3 4//4\nf 1//1 2 3//3\n",
        )
        .unwrap();
        assert_eq!(m.triangles[0].normals, Some([0, 1, 2]));
        assert_eq!(m.triangles[1].positions, [0, 2, 3]);
        assert_eq!(m.triangles[1].normals, Some([0, 2, 3]));
        // A corner without a normal drops the face's normals (the face is shaded flat).
        assert_eq!(m.triangles[2].normals, None);
    }

    #[test]
    fn tokens_split_on_any_whitespace_and_stop_at_comments() {
        // Tabs, a carriage return, Unicode spaces and non-ASCII text in a comment.
        let m = parse("v 0\t0 0\r\nv 1\u{2003}0 0 # café\nv\u{a0}0 1 0\nf 1 2 3 # é\n").unwrap();
        assert_eq!(m.positions[1], glam::Vec3::new(1.0, 0.0, 0.0));
        assert_eq!(m.triangles.len(), 1);
        // Columns count chars, so a wide char before an error does not shift it.
        let e = parse("v\u{2003}0 x 0\n").unwrap_err();
        assert_eq!((e.line, e.column), (1, 5));
    }

    #[test]
    fn index_errors_name_how_many_are_defined() {
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1 2 4\n").unwrap_err();
        assert!(e.message.contains("only 3 vertices are defined so far"), "{e}");
        let e = parse("v 0 0 0\nvn 0 0 1\nf 1//1 1//1 1//2\n").unwrap_err();
        assert!(e.message.contains("only 1 normal is defined so far"), "{e}");
    }

    /// An OBJ text with every kind of line: vertices with and without w, normals (one of them
    /// without length), texture coordinates, faces of each form and of up to five corners,
    /// negative indices reaching back over many lines, comments, blank lines, `o`/`g`/`s`
    /// statements, non-ASCII spaces and comments, and all three line endings.
    fn assorted_obj(copies: usize) -> String {
        let mut t = String::from("# model\r\no thing\n\n");
        for k in 0..copies {
            let x = k as f32;
            t += &format!("v {x} 0 0\nv {x} 1 0 1\r\nv\u{a0}{x} 1 1\nv {x}\t0 1 # corner\n");
            t += "vn 0 0 1\nvn 0 0 0\rvn 0 1 0\nvt 0 0\n";
            t += "g part\ns 1\n";
            t += "f -4 -3 -2\nf -4//-3 -3//-1 -2//-3 -1//-1\n";
            t += "f -4/1/-1 -2/1/-1 -1/1/-1\r\n";
            // The zero-length normal: this face is shaded flat.
            t += "f -4//-2 -3//-1 -2//-1 # café\n";
            t += "\u{2003}f -1 -2 -3 -4\n\n";
            if k > 0 {
                // Back into the previous copy's vertices and normals.
                t += "f -8 -7 -1 -2 -3\nf -5//-6 -6//-4 -7//-1\n";
            }
        }
        t
    }

    fn parse_in(src: &str, n: usize) -> Result<(Mesh, Vec<Diagnostic>), Box<Diagnostic>> {
        parse_in_stretches(src, Path::new("m.obj"), &ObjOptions::default(), n)
    }

    #[test]
    fn stretches_parse_as_the_whole_file() {
        let src = assorted_obj(40);
        let (whole, _) = parse_in(&src, 1).unwrap();
        assert_eq!(whole.positions.len(), 160);
        // 2 normals a copy have length; 4 + 5 + ... triangles a copy.
        assert_eq!(whole.normals.len(), 80);
        assert!(whole.triangles.iter().any(|t| t.normals.is_some()));
        assert!(whole.triangles.iter().any(|t| t.normals.is_none()));
        for n in [2, 3, 5, 8, 13, 40, 200, 10_000] {
            let cut = stretches(&src, n);
            assert!(n <= 2 || cut.len() > 2, "{n} stretches: cut into {}", cut.len());
            assert_eq!(cut.concat(), src);
            let (mesh, _) = parse_in(&src, n).unwrap();
            assert_eq!(mesh, whole, "{n} stretches");
        }
        // Lone carriage returns only: no place to cut, one stretch.
        let cr = src.replace("\r\n", "\n").replace('\n', "\r");
        assert_eq!(stretches(&cr, 8).len(), 1);
        assert_eq!(parse_in(&cr, 8).unwrap().0, whole);
    }

    #[test]
    fn stretches_report_the_files_first_error() {
        let mut src = assorted_obj(30);
        let good = lines(&src).count();
        // An index error near the end (a vertex not yet defined), and a later malformed number.
        src += "f 1 2 999\n";
        src += &assorted_obj(5);
        src += "v 0 x 0\n";
        let whole = parse_in(&src, 1).unwrap_err();
        assert_eq!((whole.line, whole.column), (good + 1, 7));
        assert!(
            whole.message.contains("only 120 vertices are defined so far"),
            "{whole}"
        );
        for n in [2, 3, 7, 50] {
            let e = parse_in(&src, n).unwrap_err();
            assert_eq!(
                (e.line, e.column, &e.message),
                (whole.line, whole.column, &whole.message),
                "{n} stretches"
            );
        }
        // An error in the first stretch wins over one in the last.
        let src = format!("v 0 0 0\nf 1 1 2\n{}v 0 0\n", assorted_obj(30));
        for n in [1, 4] {
            assert_eq!(parse_in(&src, n).unwrap_err().line, 2, "{n} stretches");
        }
    }

    #[test]
    fn stretches_warn_as_the_whole_file() {
        // Faces without their texture coordinates and normals throughout, and one unreadable
        // normal line in the middle.
        let mut src = String::from("v 0 0 0\nv 1 0 0\nv 0 1 0\n");
        for k in 0..20_000 {
            src += if k == 10_000 {
                "vn 0 x 1\n"
            } else {
                "f 1/1 2/2 3/3\nf 1//1 2//1 3//1\n"
            };
        }
        let (whole, warnings) = parse_in(&src, 1).unwrap();
        let shown: Vec<String> = warnings.iter().map(ToString::to_string).collect();
        assert_eq!(warnings.len(), 3, "{shown:?}");
        assert_eq!(
            warnings.iter().map(|w| (w.line, w.column)).collect::<Vec<_>>(),
            [(4, 5), (5, 6), (20_004, 6)]
        );
        assert!(
            shown[0].contains("the same holds on 19998 more lines: 6, 8, 10, 12, 14 and 19993 more"),
            "{}",
            shown[0]
        );
        for n in [2, 3, 7, 50] {
            let (mesh, w) = parse_in(&src, n).unwrap();
            assert_eq!(mesh, whole, "{n} stretches");
            assert_eq!(w, warnings, "{n} stretches");
        }
    }

    #[test]
    fn empty_is_valid_with_warning() {
        let (m, w) = parse_obj_with_warnings("", Path::new("m.obj"), &ObjOptions::default()).unwrap();
        assert_eq!(m, Mesh::default());
        assert_eq!(w.len(), 1);
    }
}
