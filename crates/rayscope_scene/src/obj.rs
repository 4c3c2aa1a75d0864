//! A small, strict Wavefront OBJ reader for triangle meshes.
//!
//! Supported: `v x y z [w]`, `vn x y z`, `vt …` (counted, otherwise ignored) and `f` with the
//! `v`, `v/vt`, `v//vn` and `v/vt/vn` forms, including negative (relative) indices; polygons are
//! fan-triangulated. Every other statement (`o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, …) is
//! ignored. Indices must refer to elements defined on earlier lines, as the OBJ format says.
//!
//! OBJ files are right-handed and the scene is left-handed, so positions become
//! (s·x + ox, s·y + oy, −s·z + oz) and normals normalize(nx, ny, −nz). Negating z mirrors the
//! mesh, which reverses the winding of every face; indices are nevertheless kept in file order,
//! because the renderer intersects triangles from both sides and shades with normals that it
//! orients towards the ray (interpolated `vn` normals, or the flat normal when a face has none).

use std::path::Path;

use glam::DVec3;

use crate::diagnostic::{decode_utf8, Diagnostic};
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
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
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
    let code = line.bytes().position(|b| b == b'#').map_or(line, |i| &line[..i]);
    // Byte by byte where the line is ASCII, as OBJ files are: decoding chars was a large part of
    // reading one.
    if code.is_ascii() {
        split_tokens(code, code.bytes().map(char::from).enumerate(), out);
    } else {
        split_tokens(code, code.char_indices(), out);
    }
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

/// Parsing state for one OBJ file.
struct ObjParser<'a> {
    path: &'a Path,
    opts: ObjOptions,
    mesh: Mesh,
    /// For each `vn` line, its index in `mesh.normals`, or `None` for a zero-length normal.
    normal_map: Vec<Option<u32>>,
    texcoords: usize,
    line_no: usize,
    line: &'a str,
    /// Scratch for a face's corners: position indices.
    corner_positions: Vec<u32>,
    /// Scratch for a face's corners: normal indices (`None` where a corner has none).
    corner_normals: Vec<Option<u32>>,
}

impl<'a> ObjParser<'a> {
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
        // Made only for a message: built for every index, it was an allocation per corner.
        let kinds = || match kind {
            "vertex" if count != 1 => "vertices".to_string(),
            _ if count != 1 => format!("{kind}s"),
            _ => kind.to_string(),
        };
        let defined = if count == 1 { "is" } else { "are" };
        let n: i64 = text.parse().map_err(|_| {
            Box::new(
                self.error(
                    start,
                    text,
                    format!("expected a {kind} index (a whole number) but found '{text}'"),
                )
                .with_label("not an index"),
            )
        })?;
        if n == 0 {
            return Err(Box::new(
                self.error(start, text, format!("expected a {kind} index but found 0"))
                    .with_label("OBJ indices start at 1")
                    .with_note("negative indices count back from the most recent element: -1 is the last one"),
            ));
        }
        let resolved = if n > 0 {
            usize::try_from(n - 1).ok().filter(|&i| i < count)
        } else {
            usize::try_from(n.unsigned_abs())
                .ok()
                .and_then(|back| count.checked_sub(back))
        };
        resolved.ok_or_else(|| {
            let label = if n > 0 {
                format!("only {count} {} {defined} defined so far", kinds())
            } else {
                format!("counts back past the first {kind}")
            };
            Box::new(
                self.error(
                    start,
                    text,
                    format!(
                        "face refers to {kind} {n} but only {count} {} {defined} defined so far",
                        kinds()
                    ),
                )
                .with_label(label)
                .with_note("OBJ indices refer to elements defined on earlier lines, counting from 1"),
            )
        })
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
            let vi = self.index(start, v, "vertex", self.mesh.positions.len())?;
            positions.push(u32::try_from(vi).unwrap_or(u32::MAX));
            let mut offset = start + v.len() + 1;
            if let Some(vt) = vt.filter(|t| !t.is_empty()) {
                self.index(offset, vt, "texture coordinate", self.texcoords)?;
            }
            offset += vt.map_or(0, |t| t.len() + 1);
            match vn {
                Some(vn) if !vn.is_empty() => {
                    let ni = self.index(offset, vn, "normal", self.normal_map.len())?;
                    normals.push(self.normal_map[ni]);
                }
                _ => normals.push(None),
            }
        }
        // Vertex normals only when every corner has one.
        let normals_used = normals.iter().all(Option::is_some);
        for i in 1..positions.len() - 1 {
            self.mesh.triangles.push(MeshTriangle {
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
                if self.mesh.positions.len() >= u32::MAX as usize {
                    return Err(self
                        .error(toks[0].0, "v", "too many vertices (more than 4294967295)".into())
                        .into());
                }
                self.mesh.positions.push(q);
            }
            "vn" => {
                let n = self.coords(toks, "normal")?;
                let n = DVec3::new(n.x, n.y, -n.z);
                let m = n.abs().max_element();
                let unit = if m > 0.0 { (n / m).normalize() } else { DVec3::ZERO };
                if unit.length_squared() > 0.5 {
                    self.normal_map.push(u32::try_from(self.mesh.normals.len()).ok());
                    self.mesh.normals.push(unit.as_vec3());
                } else {
                    self.normal_map.push(None);
                }
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
    let mut p = ObjParser {
        path,
        opts: *opts,
        mesh: Mesh::default(),
        normal_map: Vec::new(),
        texcoords: 0,
        line_no: 0,
        line: "",
        corner_positions: Vec::new(),
        corner_normals: Vec::new(),
    };
    let mut last_line = (0, "");
    let mut toks = Vec::new();
    for (i, line) in lines(src).enumerate() {
        p.line_no = i + 1;
        p.line = line;
        last_line = (i + 1, line);
        obj_tokens(line, &mut toks);
        if !toks.is_empty() {
            p.statement(&toks)?;
        }
    }
    let mut warnings = Vec::new();
    if p.mesh.triangles.is_empty() {
        let (n, text) = last_line;
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
    Ok((p.mesh, warnings))
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
        let e = parse("v 0 0 0\nv 0 0 0\nv 0 0 0\nf 1/1 2 3\n").unwrap_err();
        assert_eq!((e.line, e.column), (4, 5));
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

    #[test]
    fn empty_is_valid_with_warning() {
        let (m, w) = parse_obj_with_warnings("", Path::new("m.obj"), &ObjOptions::default()).unwrap();
        assert_eq!(m, Mesh::default());
        assert_eq!(w.len(), 1);
    }
}
