//! The scene-file parser: one command per line, validated as it is read.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

use glam::DVec3;

use crate::diagnostic::{decode_utf8, suggest, Diagnostic, Severity};
use crate::lexer::{char_len, column, lex_line, lines, parse_number, Line, NumberError, Token};
use crate::obj::{parse_obj_with_warnings, ObjOptions};
use crate::{
    EntityDef, MaterialDef, MaterialKind, PointLightDef, SceneError, SceneFile, Shape, VariantArray, PHONG_MAX_EXPONENT,
};

/// The commands of the format, in the order they are listed in messages.
const COMMANDS: [&str; 6] = ["Material", "PointLight", "Plane", "Sphere", "Triangle", "ObjModel"];

/// Parses scene text as if it had been read from `path`.
///
/// `path` is used in messages and to resolve the paths of OBJ models, which are loaded now.
/// Errors stop parsing at the first problem; warnings are collected in [`SceneFile::warnings`].
pub fn parse_str(src: &str, path: &Path) -> Result<SceneFile, SceneError> {
    Parser::new(src, path).run().map_err(SceneError::Invalid)
}

/// Reads and parses a scene file; an empty file is a valid, empty scene.
pub fn load(path: &Path) -> Result<SceneFile, SceneError> {
    let bytes = crate::input::read_bounded(path, crate::input::MAX_SCENE_BYTES).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = decode_utf8(&bytes, path).map_err(SceneError::Invalid)?;
    parse_str(text, path)
}

type Res<T> = Result<T, Box<Diagnostic>>;

/// Names of the three components of a vector, for messages.
#[derive(Clone, Copy)]
enum Axes {
    /// x, y, z coordinates.
    Xyz,
    /// red, green, blue components.
    Rgb,
}

impl Axes {
    fn names(self) -> (&'static str, [&'static str; 3]) {
        match self {
            Axes::Xyz => ("(x, y, z)", ["x coordinate", "y coordinate", "z coordinate"]),
            Axes::Rgb => ("(r, g, b)", ["red component", "green component", "blue component"]),
        }
    }
}

/// The state of the line being parsed.
struct Cursor<'a> {
    path: &'a Path,
    line_no: usize,
    text: &'a str,
    lexed: Line<'a>,
    pos: usize,
    command: &'static str,
    usage: &'static str,
    /// Description of the last item read, for the extra-tokens warning.
    last_what: String,
}

impl<'a> Cursor<'a> {
    /// A diagnostic spanning bytes `start..end` of the line.
    fn diag(&self, severity: Severity, start: usize, end: usize, message: String) -> Diagnostic {
        let col = column(self.text, start);
        let len = if end > start {
            char_len(self.text, start, end)
        } else {
            1
        };
        let mut d = Diagnostic::error(self.path, self.line_no, self.text, col, len, message);
        d.severity = severity;
        d
    }

    fn token_diag(&self, tok: &Token<'_>, message: String) -> Diagnostic {
        self.diag(Severity::Error, tok.start, tok.end, message)
    }

    fn usage_note(&self) -> String {
        format!("a {} line is: {}", self.command, self.usage)
    }

    /// Error for a line that ends where `what` was expected.
    fn missing(&self, what: &str) -> Box<Diagnostic> {
        let end = self.lexed.content_end;
        Box::new(
            self.diag(
                Severity::Error,
                end,
                end,
                format!("expected {what} but found the end of the line"),
            )
            .with_label(format!("expected {what}"))
            .with_note(self.usage_note()),
        )
    }

    fn next(&mut self, what: &str) -> Res<Token<'a>> {
        let tok = self
            .lexed
            .tokens
            .get(self.pos)
            .copied()
            .ok_or_else(|| self.missing(what))?;
        self.pos += 1;
        self.last_what = what.to_string();
        Ok(tok)
    }

    /// Reads a number that the renderer stores in single precision: finite and at most
    /// `f32::MAX` in magnitude.
    fn number(&mut self, what: &str, missing_what: &str) -> Res<(f64, Token<'a>)> {
        let (value, tok) = self.any_number(what, missing_what)?;
        if value.abs() > f64::from(f32::MAX) {
            return Err(Box::new(
                self.token_diag(
                    &tok,
                    format!(
                        "expected a number between -3.4e38 and 3.4e38 for {what} but found '{}'",
                        tok.text
                    ),
                )
                .with_label("too large: the renderer uses single precision")
                .with_note(self.usage_note()),
            ));
        }
        Ok((value, tok))
    }

    /// Reads any finite double.
    fn any_number(&mut self, what: &str, missing_what: &str) -> Res<(f64, Token<'a>)> {
        let tok = self.next(missing_what)?;
        let text = tok.text;
        let value = parse_number(text).map_err(|e| {
            let (message, label) = match e {
                NumberError::Malformed => (
                    format!("expected a number for {what} but found '{text}'"),
                    "not a number".to_string(),
                ),
                NumberError::NotFinite => (
                    format!("expected a finite number for {what} but found '{text}'"),
                    "non-finite number".to_string(),
                ),
                NumberError::Overflow => (
                    format!("expected a finite number for {what} but found '{text}'"),
                    "non-finite number: too large for a double".to_string(),
                ),
            };
            Box::new(
                self.token_diag(&tok, message)
                    .with_label(label)
                    .with_note(self.usage_note()),
            )
        })?;
        self.last_what = what.to_string();
        Ok((value, tok))
    }

    /// Reads three numbers; returns the vector and its byte span (parentheses included).
    fn vector(&mut self, what: &str, axes: Axes) -> Res<(DVec3, (usize, usize))> {
        self.vector_in(what, axes, true)
    }

    /// [`Cursor::vector`]; `bounded`: each component must fit single precision (not needed for
    /// a direction, which is normalised in double precision).
    fn vector_in(&mut self, what: &str, axes: Axes, bounded: bool) -> Res<(DVec3, (usize, usize))> {
        let (shape, names) = axes.names();
        // A balanced ( … ) group must hold exactly three numbers.
        if let Some(first) = self.lexed.tokens.get(self.pos) {
            if let Some(g) = first.group {
                let group = self.lexed.groups[g];
                if group.count != 3 {
                    let close = group.close.unwrap_or(group.open) + 1;
                    let shown = self.text.get(group.open..close).unwrap_or_default();
                    let numbers = if group.count == 1 { "number" } else { "numbers" };
                    return Err(Box::new(
                        self.diag(
                            Severity::Error,
                            group.open,
                            close,
                            format!(
                                "expected 3 numbers {shape} for {what} but found {} {numbers} in '{shown}'",
                                group.count
                            ),
                        )
                        .with_label("needs exactly 3 numbers")
                        .with_note(self.usage_note()),
                    ));
                }
            }
        }
        let mut v = [0.0; 3];
        let mut span = (0, 0);
        for (k, slot) in v.iter_mut().enumerate() {
            let component = format!("the {} of {what}", names[k]);
            let missing = if k == 0 {
                format!("{what} {shape}")
            } else {
                component.clone()
            };
            let (x, tok) = if bounded {
                self.number(&component, &missing)?
            } else {
                self.any_number(&component, &missing)?
            };
            *slot = x;
            if k == 0 {
                span.0 = tok.group.map_or(tok.start, |g| self.lexed.groups[g].open);
            }
            span.1 = tok
                .group
                .and_then(|g| self.lexed.groups[g].close)
                .map_or(tok.end, |c| c + 1);
        }
        self.last_what = what.to_string();
        Ok((DVec3::from_array(v), span))
    }

    /// Warns about tokens left on the line.
    /// A warning for a quote or parenthesis without its partner. The course's reader treats them
    /// as plain separators and so accepts the line, and so does rayscope, but such a line is
    /// usually a typo whose meaning the author should check.
    fn unbalanced(&self) -> Option<Diagnostic> {
        let (at, c) = self.lexed.unbalanced?;
        let (message, label) = match c {
            '"' => (
                "unbalanced quote: the line has an odd number of '\"', and this one has no partner",
                "no partner",
            ),
            '(' => (
                "unbalanced parenthesis: this '(' is never closed on its line",
                "no closing ')'",
            ),
            _ => ("unbalanced parenthesis: this ')' closes nothing", "no opening '('"),
        };
        Some(
            self.diag(Severity::Warning, at, at + 1, message.to_string())
                .with_label(label)
                .with_note(
                    "quotes and parentheses only separate words, so the line is still read (as the course's reader does); check that it says what you meant",
                ),
        )
    }

    fn finish(&self) -> Option<Diagnostic> {
        let rest = self.lexed.tokens.get(self.pos..).unwrap_or_default();
        let first = rest.first()?;
        let end = self.lexed.content_end.max(first.end);
        let n = rest.len() + self.lexed.dropped;
        let found = self.text.get(first.start..end).unwrap_or_default();
        let found = if found.chars().count() > 40 {
            format!("{}…", found.chars().take(40).collect::<String>())
        } else {
            found.to_string()
        };
        let tokens = if n == 1 { "token" } else { "tokens" };
        Some(
            self.diag(
                Severity::Warning,
                first.start,
                end,
                format!(
                    "extra {tokens} ignored: expected the line to end after {} but found '{found}'",
                    self.last_what
                ),
            )
            .with_label(format!("{n} extra {tokens} ignored"))
            .with_note(self.usage_note()),
        )
    }
}

/// Parser state across lines.
struct Parser<'a> {
    src: &'a str,
    path: &'a Path,
    scene: SceneFile,
    materials: HashMap<String, usize>,
    lights: HashMap<String, usize>,
    entities: HashMap<String, usize>,
}

impl<'a> Parser<'a> {
    fn new(src: &'a str, path: &'a Path) -> Self {
        Self {
            src,
            path,
            scene: SceneFile {
                path: path.to_path_buf(),
                ..SceneFile::default()
            },
            materials: HashMap::new(),
            lights: HashMap::new(),
            entities: HashMap::new(),
        }
    }

    fn run(mut self) -> Res<SceneFile> {
        for (i, text) in lines(self.src).enumerate() {
            let lexed = lex_line(text);
            let Some(&cmd) = lexed.tokens.first() else {
                continue;
            };
            let split_quote = lexed.split_quote;
            let mut cur = Cursor {
                path: self.path,
                line_no: i + 1,
                text,
                lexed,
                pos: 1,
                command: "",
                usage: "",
                last_what: String::new(),
            };
            let result = self.line(&mut cur, cmd);
            let add_quote_note = |d: &mut Diagnostic| {
                if let Some((a, b)) = split_quote {
                    let quoted = text.get(a..b).unwrap_or_default();
                    d.add_note(format!(
                        "names cannot contain spaces, commas or parentheses, even in quotes: {quoted} is read as several tokens"
                    ));
                }
            };
            match result {
                Ok(()) => {
                    if let Some(w) = cur.unbalanced() {
                        self.scene.warnings.push(w);
                    }
                    if let Some(mut w) = cur.finish() {
                        add_quote_note(&mut w);
                        self.scene.warnings.push(w);
                    }
                }
                Err(mut e) => {
                    if e.file == self.path && e.line == i + 1 {
                        add_quote_note(&mut e);
                    }
                    return Err(e);
                }
            }
        }
        Ok(self.scene)
    }

    fn line(&mut self, cur: &mut Cursor<'a>, cmd: Token<'a>) -> Res<()> {
        let (command, usage) = match cmd.text {
            "Material" => ("Material", "Material \"Name\" Type (r, g, b) number"),
            "PointLight" => ("PointLight", "PointLight \"Name\" (x, y, z) (r, g, b)"),
            "Plane" => ("Plane", "Plane \"Name\" (x, y, z) (nx, ny, nz) \"Material\""),
            "Sphere" => ("Sphere", "Sphere \"Name\" (x, y, z) radius \"Material\""),
            "Triangle" => (
                "Triangle",
                "Triangle \"Name\" (x0, y0, z0) (x1, y1, z1) (x2, y2, z2) \"Material\"",
            ),
            "ObjModel" => (
                "ObjModel",
                "ObjModel \"Name\" \"path.obj\" (x, y, z) scale \"Material\"",
            ),
            other => return Err(Box::new(unknown_command(cur, &cmd, other))),
        };
        cur.command = command;
        cur.usage = usage;
        match command {
            "Material" => self.material(cur),
            "PointLight" => self.light(cur),
            _ => self.entity(cur),
        }
    }

    fn material(&mut self, cur: &mut Cursor<'a>) -> Res<()> {
        let name = cur.next("the material's name")?;
        if let Some(&first) = self.materials.get(name.text) {
            let first_line = self.scene.materials[first].line;
            return Err(Box::new(
                cur.token_diag(
                    &name,
                    format!(
                        "duplicate material name '{}' (expected a name not used by another material)",
                        name.text
                    ),
                )
                .with_label("already defined")
                .with_note(format!(
                    "the first material named '{}' is on line {first_line}",
                    name.text
                )),
            ));
        }
        let kind_tok = cur.next("the material's type")?;
        let kind = (MaterialKind::VARIANTS.iter().copied())
            .find(|k| k.name() == kind_tok.text)
            .ok_or_else(|| {
                let names: Vec<_> = MaterialKind::VARIANTS.iter().map(|k| k.name()).collect();
                let label = suggest(kind_tok.text, names.iter().copied()).map_or_else(
                    || "unknown material type".to_string(),
                    |s| format!("did you mean '{s}'?"),
                );
                Box::new(
                    cur.token_diag(
                        &kind_tok,
                        format!(
                            "unknown material type '{}' (expected one of {})",
                            kind_tok.text,
                            names.join(", ")
                        ),
                    )
                    .with_label(label),
                )
            })?;
        let (color, span) = cur.vector("the material's colour", Axes::Rgb)?;
        if kind == MaterialKind::Refractive && color.min_element() < 0.0 {
            // Beer's law attenuates by exp(−σ·d): a negative σ amplifies without bound.
            let shown = cur.text.get(span.0..span.1).unwrap_or_default();
            return Err(Box::new(
                cur.diag(
                    Severity::Error,
                    span.0,
                    span.1,
                    format!("expected a non-negative absorbance for the refractive material but found '{shown}'"),
                )
                .with_label("absorbance cannot be negative")
                .with_note("a Refractive material's colour is its absorbance per channel (Beer's law); (0, 0, 0) is clear glass"),
            ));
        }
        let what = format!("the material's {}", kind.number_meaning().unwrap_or("number"));
        let (value, tok) = cur.number(&what, &what).map_err(|mut e| {
            if kind.number_meaning().is_none() {
                e.add_note(format!(
                    "a {} material ignores the number, but the format requires one (1 is customary)",
                    kind.name()
                ));
            }
            e
        })?;
        if kind == MaterialKind::Refractive && value <= 0.0 {
            return Err(Box::new(
                cur.token_diag(
                    &tok,
                    format!("expected a positive refractive index but found '{}'", tok.text),
                )
                .with_label("must be positive")
                .with_note("glass is about 1.5, water 1.33, air 1"),
            ));
        }
        if kind == MaterialKind::Phong && !(0.0..=PHONG_MAX_EXPONENT).contains(&value) {
            return Err(Box::new(
                cur.token_diag(
                    &tok,
                    format!(
                        "expected a Phong exponent from 0 to {PHONG_MAX_EXPONENT} but found '{}'",
                        tok.text
                    ),
                )
                .with_label(if value < 0.0 {
                    "must not be negative"
                } else {
                    "too large"
                })
                .with_note("1 is a dull sheen, 20 to 100 a plastic highlight, 1000 nearly a mirror"),
            ));
        }
        cur.last_what = "the material's number".to_string();
        self.materials.insert(name.text.to_string(), self.scene.materials.len());
        self.scene.materials.push(MaterialDef {
            name: name.text.to_string(),
            kind,
            color,
            value,
            line: cur.line_no,
        });
        Ok(())
    }

    fn light(&mut self, cur: &mut Cursor<'a>) -> Res<()> {
        let name = cur.next("the light's name")?;
        if let Some(&first) = self.lights.get(name.text) {
            let first_line = self.scene.lights[first].line;
            return Err(Box::new(
                cur.token_diag(
                    &name,
                    format!(
                        "duplicate light name '{}' (expected a name not used by another light)",
                        name.text
                    ),
                )
                .with_label("already defined")
                .with_note(format!("the first light named '{}' is on line {first_line}", name.text)),
            ));
        }
        let (position, _) = cur.vector("the light's position", Axes::Xyz)?;
        let (color, _) = cur.vector("the light's colour", Axes::Rgb)?;
        self.lights.insert(name.text.to_string(), self.scene.lights.len());
        self.scene.lights.push(PointLightDef {
            name: name.text.to_string(),
            position,
            color,
            line: cur.line_no,
        });
        Ok(())
    }

    fn entity(&mut self, cur: &mut Cursor<'a>) -> Res<()> {
        let noun = match cur.command {
            "Plane" => "plane",
            "Sphere" => "sphere",
            "Triangle" => "triangle",
            _ => "model",
        };
        let name = cur.next(&format!("the {noun}'s name"))?;
        if let Some(&first) = self.entities.get(name.text) {
            let other = &self.scene.entities[first];
            return Err(Box::new(
                cur.token_diag(
                    &name,
                    format!(
                        "duplicate entity name '{}' (expected a name not used by another Plane, Sphere, Triangle or ObjModel)",
                        name.text
                    ),
                )
                .with_label("already defined")
                .with_note(format!(
                    "'{}' is already the name of the {} on line {}",
                    name.text,
                    other.shape.command(),
                    other.line
                )),
            ));
        }
        let shape = match cur.command {
            "Plane" => {
                let (point, _) = cur.vector("the plane's point", Axes::Xyz)?;
                let (normal, span) = cur.vector_in("the plane's normal", Axes::Xyz, false)?;
                let m = normal.abs().max_element();
                if m <= 0.0 {
                    return Err(Box::new(
                        cur.diag(
                            Severity::Error,
                            span.0,
                            span.1,
                            "expected a non-zero normal for the plane but found (0, 0, 0)".to_string(),
                        )
                        .with_label("zero-length normal")
                        .with_note("the normal gives the plane's orientation; e.g. (0, 1, 0) is a floor"),
                    ));
                }
                Shape::Plane {
                    point,
                    normal: (normal / m).normalize(),
                }
            }
            "Sphere" => {
                let (center, _) = cur.vector("the sphere's centre", Axes::Xyz)?;
                let what = "the sphere's radius";
                let (radius, tok) = cur.number(what, what)?;
                if radius <= 0.0 {
                    return Err(Box::new(
                        cur.token_diag(
                            &tok,
                            format!(
                                "expected a positive number for the sphere's radius but found '{}'",
                                tok.text
                            ),
                        )
                        .with_label("the radius must be greater than zero"),
                    ));
                }
                Shape::Sphere { center, radius }
            }
            "Triangle" => {
                let (v0, s0) = cur.vector("the triangle's first corner", Axes::Xyz)?;
                let (v1, _) = cur.vector("the triangle's second corner", Axes::Xyz)?;
                let (v2, s2) = cur.vector("the triangle's third corner", Axes::Xyz)?;
                let vertices = [v0, v1, v2];
                if let Some(why) = degenerate(&vertices) {
                    self.scene.warnings.push(
                        cur.diag(
                            Severity::Warning,
                            s0.0,
                            s2.1,
                            format!(
                                "degenerate triangle '{}': expected corners enclosing a non-zero area but {why}",
                                name.text
                            ),
                        )
                        .with_label("zero area")
                        .with_note("the triangle is kept but will not be rendered"),
                    );
                }
                Shape::Triangle { vertices }
            }
            _ => return self.obj_model(cur, name),
        };
        let material = self.material_ref(cur, &format!("the {noun}'s material"))?;
        self.push_entity(cur, name, shape, material);
        Ok(())
    }

    fn push_entity(&mut self, cur: &Cursor<'a>, name: Token<'a>, shape: Shape, material: usize) {
        self.entities.insert(name.text.to_string(), self.scene.entities.len());
        self.scene.entities.push(EntityDef {
            name: name.text.to_string(),
            shape,
            material,
            line: cur.line_no,
        });
    }

    fn obj_model(&mut self, cur: &mut Cursor<'a>, name: Token<'a>) -> Res<()> {
        let path_tok = cur.next("the model's OBJ file path")?;
        let (offset, _) = cur.vector("the model's offset", Axes::Xyz)?;
        let what = "the model's scale";
        let (scale, scale_tok) = cur.number(what, what)?;
        if scale == 0.0 {
            return Err(Box::new(
                cur.token_diag(
                    &scale_tok,
                    "expected a non-zero number for the model's scale but found '0'".to_string(),
                )
                .with_label("scale must be non-zero"),
            ));
        }
        let material = self.material_ref(cur, "the model's material")?;

        let source = resolve_obj_path(path_tok.text, self.path).map_err(|tried| {
            let mut note = String::from("tried these paths, in order:");
            for p in &tried {
                note.push_str(&format!("\n  {}", p.display()));
            }
            Box::new(
                cur.token_diag(
                    &path_tok,
                    if Path::new(path_tok.text).is_absolute() {
                        format!(
                            "cannot find the OBJ file '{}' (expected the path of an existing file)",
                            path_tok.text
                        )
                    } else {
                        format!(
                            "cannot find the OBJ file '{}' (expected a path relative to the current directory, the scene's folder or one of its ancestors)",
                            path_tok.text
                        )
                    },
                )
                .with_label("file not found")
                .with_note(note),
            )
        })?;
        let referenced = format!(
            "the OBJ file is loaded by ObjModel '{}' at {}:{}:{}",
            name.text,
            self.path.display(),
            cur.line_no,
            column(cur.text, path_tok.start)
        );
        let bytes = crate::input::read_bounded(&source, crate::input::MAX_OBJ_BYTES).map_err(|e| {
            Box::new(
                cur.token_diag(
                    &path_tok,
                    format!(
                        "cannot read the OBJ file '{}' ({}): {e}",
                        path_tok.text,
                        source.display()
                    ),
                )
                .with_label("unreadable"),
            )
        })?;
        let with_context = |mut d: Box<Diagnostic>| {
            d.add_note(referenced.clone());
            d
        };
        let text = decode_utf8(&bytes, &source).map_err(with_context)?;
        let (mesh, warnings) =
            parse_obj_with_warnings(text, &source, &ObjOptions { scale, offset }).map_err(with_context)?;
        self.scene
            .warnings
            .extend(warnings.into_iter().map(|d| *with_context(Box::new(d))));
        let shape = Shape::Mesh {
            source,
            offset,
            scale,
            mesh,
        };
        self.push_entity(cur, name, shape, material);
        Ok(())
    }

    /// Reads a material name and looks it up.
    fn material_ref(&self, cur: &mut Cursor<'a>, what: &str) -> Res<usize> {
        let tok = cur.next(what)?;
        if let Some(&i) = self.materials.get(tok.text) {
            return Ok(i);
        }
        let names = self.scene.materials.iter().map(|m| m.name.as_str());
        let label =
            suggest(tok.text, names).map_or_else(|| "not defined".to_string(), |s| format!("did you mean '{s}'?"));
        let mut d = cur
            .token_diag(
                &tok,
                format!(
                    "undefined material '{}' (expected the name of a material defined on an earlier line)",
                    tok.text
                ),
            )
            .with_label(label);
        if let Some(later) = self.defined_later(tok.text, cur.line_no) {
            d.add_note(format!(
                "'{}' is defined later, on line {later}; a material must be defined before it is used",
                tok.text
            ));
        } else if self.scene.materials.is_empty() {
            d.add_note("no materials are defined before this line");
        } else {
            let mut list: Vec<&str> = self.scene.materials.iter().take(12).map(|m| m.name.as_str()).collect();
            if self.scene.materials.len() > 12 {
                list.push("…");
            }
            d.add_note(format!("the materials defined so far are: {}", list.join(", ")));
        }
        Err(Box::new(d))
    }

    /// The line of a `Material` with this name after `after`, if any.
    fn defined_later(&self, name: &str, after: usize) -> Option<usize> {
        lines(self.src)
            .enumerate()
            .skip(after)
            .find(|(_, text)| {
                let l = lex_line(text);
                matches!(l.tokens.as_slice(), [cmd, n, ..] if cmd.text == "Material" && n.text == name)
            })
            .map(|(i, _)| i + 1)
    }
}

fn unknown_command(cur: &Cursor<'_>, cmd: &Token<'_>, text: &str) -> Diagnostic {
    let label =
        suggest(text, COMMANDS).map_or_else(|| "unknown command".to_string(), |s| format!("did you mean '{s}'?"));
    let mut d = cur
        .token_diag(
            cmd,
            format!("unknown command '{text}' (expected one of {})", COMMANDS.join(", ")),
        )
        .with_label(label);
    if text.starts_with("//") || text.starts_with("--") || text.starts_with(';') {
        d.add_note("comments start with '#'");
    } else if parse_number(text).is_ok() {
        d.add_note("each line must start with a command; is this the rest of the previous line?");
    }
    d
}

/// Why three points span no area, if they do not.
fn degenerate(v: &[DVec3; 3]) -> Option<&'static str> {
    for (i, j, why) in [
        (0, 1, "the first and second corners are the same point"),
        (1, 2, "the second and third corners are the same point"),
        (0, 2, "the first and third corners are the same point"),
    ] {
        if v[i] == v[j] {
            return Some(why);
        }
    }
    let e1 = v[1] - v[0];
    let e2 = v[2] - v[0];
    let area2 = e1.cross(e2).length();
    (area2.is_finite() && area2 <= 1e-12 * e1.length() * e2.length()).then_some("the corners lie on one line")
}

/// Removes `.` and resolves `..` components without touching the file system.
fn normalize(path: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in path.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push("..");
                }
            }
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Finds an OBJ file: as given (relative to the current directory), then relative to the scene
/// file's folder and each of its ancestors. Returns the resolved path or every path tried.
fn resolve_obj_path(raw: &str, scene: &Path) -> Result<PathBuf, Vec<PathBuf>> {
    let raw_path = Path::new(raw);
    let cwd = std::env::current_dir().ok();
    let absolute = |p: &Path| -> PathBuf {
        match &cwd {
            Some(cwd) if p.is_relative() => normalize(&cwd.join(p)),
            _ => normalize(p),
        }
    };
    let mut tried: Vec<PathBuf> = vec![absolute(raw_path)];
    if raw_path.is_relative() {
        let folder = absolute(scene.parent().unwrap_or(Path::new("")));
        for dir in folder.ancestors() {
            let candidate = normalize(&dir.join(raw_path));
            if !tried.contains(&candidate) {
                tried.push(candidate);
            }
        }
    }
    // A file wins; failing that, something that exists under that name (a folder, a pipe) is
    // returned so that reading it says what it is, rather than "not found".
    let found = tried
        .iter()
        .find(|p| p.is_file())
        .or_else(|| tried.iter().find(|p| p.exists()));
    found.cloned().ok_or(tried)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn degenerate_triangles() {
        let a = DVec3::ZERO;
        let b = DVec3::X;
        assert!(degenerate(&[a, b, DVec3::Y]).is_none());
        assert!(degenerate(&[a, b, 2.0 * b]).is_some());
        assert!(degenerate(&[a, a, b]).is_some());
    }

    #[test]
    fn normalizes_paths() {
        assert_eq!(normalize(Path::new("/a/b/../c/./d")), Path::new("/a/c/d"));
        assert_eq!(normalize(Path::new("../x")), Path::new("../x"));
    }

    #[test]
    fn resolution_lists_ancestors() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("a/b/scene.txt");
        let tried = resolve_obj_path("nope/none.obj", &scene).unwrap_err();
        let cwd = std::env::current_dir().unwrap();
        assert_eq!(tried[0], cwd.join("nope/none.obj"));
        assert_eq!(tried[1], dir.path().join("a/b/nope/none.obj"));
        assert_eq!(tried[2], dir.path().join("a/nope/none.obj"));
        assert_eq!(tried.last().unwrap(), Path::new("/nope/none.obj"));
        let abs = resolve_obj_path("/nope/none.obj", &scene).unwrap_err();
        assert_eq!(abs, [PathBuf::from("/nope/none.obj")]);
    }
}
