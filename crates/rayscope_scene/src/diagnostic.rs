//! Source-annotated diagnostics: `file:line:col`, the offending line and a caret underline.
//!
//! Rendering is hand-written, plain text and deterministic (no colours, no terminal probing), so
//! messages can be snapshot-tested and printed anywhere.

use std::fmt;
use std::path::{Path, PathBuf};

/// How serious a [`Diagnostic`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Severity {
    /// The file cannot be used.
    Error,
    /// The file is usable but probably not what was meant.
    Warning,
}

impl Severity {
    /// `"error"` or `"warning"`.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Severity::Error => "error",
            Severity::Warning => "warning",
        }
    }
}

/// A message about a place in a file: severity, location, the source line and an underline.
///
/// Displays as plain text in the style of rustc:
///
/// ```text
/// error: unknown material type 'Difuse' (expected one of Diffuse, Reflective, Refractive, Emissive, Glossy, Phong)
///   --> scenes/x.txt:3:17
///    |
///  3 | Material "Red" Difuse (1, .5, .5) 1
///    |                ^^^^^^ did you mean 'Diffuse'?
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// The file the message is about (as given, or the resolved path for OBJ files).
    pub file: PathBuf,
    /// 1-based line number.
    pub line: usize,
    /// 1-based column, counted in characters (a tab counts as one).
    pub column: usize,
    /// The one-line message: what was expected and what was found.
    pub message: String,
    /// The text of the offending line, without its line ending.
    pub source_line: String,
    /// Length of the underlined span in characters (at least one caret is drawn).
    pub span_len: usize,
    /// A short text printed after the carets (e.g. "did you mean 'Diffuse'?").
    pub label: Option<String>,
    /// Extra explanation printed below the snippet. Each line of the note gets its own
    /// `= note:` prefix, except lines that start with a space, which continue the previous one.
    pub note: Option<String>,
}

impl Diagnostic {
    /// An error at `line:column` (1-based) spanning `span_len` characters of `source_line`.
    #[must_use]
    pub fn error(
        file: &Path,
        line: usize,
        source_line: &str,
        column: usize,
        span_len: usize,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Error,
            file: file.to_path_buf(),
            line,
            column,
            message: message.into(),
            source_line: source_line.to_string(),
            span_len,
            label: None,
            note: None,
        }
    }

    /// A warning at `line:column` (1-based) spanning `span_len` characters of `source_line`.
    #[must_use]
    pub fn warning(
        file: &Path,
        line: usize,
        source_line: &str,
        column: usize,
        span_len: usize,
        message: impl Into<String>,
    ) -> Self {
        Self {
            severity: Severity::Warning,
            ..Self::error(file, line, source_line, column, span_len, message)
        }
    }

    /// Sets the text shown after the carets.
    #[must_use]
    pub fn with_label(mut self, label: impl Into<String>) -> Self {
        self.label = Some(label.into());
        self
    }

    /// Appends a note (a new `= note:` line when a note is already present).
    #[must_use]
    pub fn with_note(mut self, note: impl Into<String>) -> Self {
        self.add_note(note);
        self
    }

    /// Appends a note in place (a new `= note:` line when a note is already present).
    pub fn add_note(&mut self, note: impl Into<String>) {
        let note = note.into();
        self.note = Some(match self.note.take() {
            Some(old) => format!("{old}\n{note}"),
            None => note,
        });
    }
}

/// Tab stops used when showing a source line.
const TAB_WIDTH: usize = 4;

/// The displayed form of a source line: tabs expanded to the next tab stop, control characters
/// replaced. Returns the text and, for each character of the input, its display column (0-based)
/// followed by the total display width.
fn expand(line: &str) -> (String, Vec<usize>) {
    let mut out = String::with_capacity(line.len());
    let mut cols = Vec::with_capacity(line.len() + 1);
    let mut width = 0;
    for c in line.chars() {
        cols.push(width);
        if c == '\t' {
            let n = TAB_WIDTH - width % TAB_WIDTH;
            out.push_str(&" ".repeat(n));
            width += n;
        } else if c.is_control() {
            out.push('\u{FFFD}');
            width += 1;
        } else {
            out.push(c);
            width += 1;
        }
    }
    cols.push(width);
    (out, cols)
}

/// Source lines wider than this many columns are shown as a window around the underlined span.
const MAX_SHOWN_WIDTH: usize = 120;

/// Message, label and note lines longer than this many characters lose their middle.
const MAX_TEXT_CHARS: usize = 300;

/// `text` with its middle replaced by `…` when it is longer than [`MAX_TEXT_CHARS`], so that a
/// huge token quoted in a message cannot flood the terminal, and control characters escaped.
fn shorten(text: &str) -> std::borrow::Cow<'_, str> {
    if text.chars().any(char::is_control) {
        let escaped: String = text
            .chars()
            .map(|c| {
                if c.is_control() {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect();
        return shorten(&escaped).into_owned().into();
    }
    let n = text.chars().count();
    if n <= MAX_TEXT_CHARS {
        return text.into();
    }
    let head: String = text.chars().take(MAX_TEXT_CHARS * 2 / 3).collect();
    let tail: String = text.chars().skip(n - MAX_TEXT_CHARS / 3).collect();
    format!("{head}…{tail}").into()
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let number = self.line.to_string();
        let pad = " ".repeat(number.len() + 1);
        writeln!(f, "{}: {}", self.severity.as_str(), shorten(&self.message))?;
        writeln!(
            f,
            "{pad}--> {}:{}:{}",
            shorten(&self.file.display().to_string()),
            self.line,
            self.column
        )?;
        writeln!(f, "{pad} |")?;
        let (shown, cols) = expand(&self.source_line);
        let shown = shown.trim_end();

        // Display columns of the span; positions past the end of the line continue one per char.
        let total = cols.len() - 1; // characters in the line
        let end_width = cols[total];
        let display_col = |char_index: usize| -> usize {
            if char_index <= total {
                cols[char_index]
            } else {
                end_width + (char_index - total)
            }
        };
        let start = self.column.saturating_sub(1);
        let mut begin = display_col(start);
        let mut finish = display_col(start.saturating_add(self.span_len)).max(begin + 1);

        // A long line is shown as a window that starts a little before the span (every character
        // of `shown` is one column wide: tabs are expanded and control characters replaced).
        let width = shown.chars().count();
        if width.max(finish) > MAX_SHOWN_WIDTH {
            let from = begin.saturating_sub(MAX_SHOWN_WIDTH / 4).min(width);
            let to = (from + MAX_SHOWN_WIDTH).min(width);
            let mut window: String = shown.chars().skip(from).take(to - from).collect();
            let mut shift = from;
            if from > 0 {
                window.insert(0, '…');
                shift -= 1;
            }
            if to < width {
                window.push('…');
            }
            writeln!(f, " {number} | {window}")?;
            begin -= shift;
            let window_width = window.chars().count();
            finish = (finish - shift).min(window_width.max(begin + 1)).max(begin + 1);
        } else {
            writeln!(f, " {number} | {shown}")?;
        }
        let mut underline = format!("{}{}", " ".repeat(begin), "^".repeat(finish - begin));
        if let Some(label) = &self.label {
            underline.push(' ');
            underline.push_str(&shorten(label));
        }
        write!(f, "{pad} | {underline}")?;
        if let Some(note) = &self.note {
            for line in note.lines() {
                if line.starts_with(' ') {
                    write!(f, "\n{pad}         {}", shorten(line.trim_start()))?;
                } else {
                    write!(f, "\n{pad} = note: {}", shorten(line))?;
                }
            }
        }
        Ok(())
    }
}

impl std::error::Error for Diagnostic {}

/// Decodes `bytes` as UTF-8 (skipping a UTF-8 byte-order mark), or explains where it is not.
pub(crate) fn decode_utf8<'a>(bytes: &'a [u8], path: &Path) -> Result<&'a str, Box<Diagnostic>> {
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(text),
        Err(err) => {
            let bad = err.valid_up_to();
            let line_start = bytes[..bad]
                .iter()
                .rposition(|&b| b == b'\n' || b == b'\r')
                .map_or(0, |i| i + 1);
            let line_no = 1 + bytes[..line_start]
                .iter()
                .enumerate()
                .filter(|&(i, &b)| b == b'\n' || (b == b'\r' && bytes.get(i + 1).copied() != Some(b'\n')))
                .count();
            let line_end = bytes[line_start..]
                .iter()
                .position(|&b| b == b'\n' || b == b'\r')
                .map_or(bytes.len(), |i| line_start + i);
            // The prefix up to the bad byte is valid UTF-8 by construction.
            let prefix = String::from_utf8_lossy(&bytes[line_start..bad]);
            let column = prefix.chars().count() + 1;
            let shown = String::from_utf8_lossy(&bytes[line_start..line_end]);
            let byte = bytes.get(bad).copied().unwrap_or_default();
            let mut diag = Diagnostic::error(
                path,
                line_no,
                &shown,
                column,
                1,
                format!("expected UTF-8 text but found the byte 0x{byte:02X}, which is not valid UTF-8"),
            )
            .with_label("not UTF-8");
            let utf16 = bytes.starts_with(b"\xFF\xFE") || bytes.starts_with(b"\xFE\xFF");
            if utf16 {
                diag.add_note("the file looks like UTF-16; save it as UTF-8 (plain ASCII is fine)");
            } else {
                diag.add_note("save the file as UTF-8 (plain ASCII is fine)");
            }
            Err(Box::new(diag))
        }
    }
}

/// Edit distance between two strings, ignoring ASCII case.
fn distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().map(|c| c.to_ascii_lowercase()).collect();
    let b: Vec<char> = b.chars().map(|c| c.to_ascii_lowercase()).collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.iter().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let sub = prev[j] + usize::from(ca != cb);
            cur[j + 1] = sub.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// The candidate closest to `word` (ignoring case), if it is close enough to be a likely typo.
pub(crate) fn suggest<'a>(word: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    if word.chars().count() > 64 {
        return None;
    }
    let limit = (word.chars().count() / 3).max(1);
    candidates
        .into_iter()
        .filter(|c| *c != word)
        // The edit distance is at least the difference in length: skip hopeless (and huge) names.
        .filter(|c| c.chars().count().abs_diff(word.chars().count()) <= limit)
        .map(|c| (distance(word, c), c))
        .filter(|&(d, c)| d <= limit || c.eq_ignore_ascii_case(word))
        .min_by_key(|&(d, _)| d)
        .map(|(_, c)| c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(distance("Difuse", "Diffuse"), 1);
        assert_eq!(distance("sphere", "Sphere"), 0);
        assert_eq!(distance("", "abc"), 3);
    }

    #[test]
    fn suggestions() {
        let cmds = ["Material", "PointLight", "Plane", "Sphere", "Triangle", "ObjModel"];
        assert_eq!(suggest("sphere", cmds), Some("Sphere"));
        assert_eq!(suggest("Spehre", cmds), Some("Sphere"));
        assert_eq!(suggest("pointlight", cmds), Some("PointLight"));
        assert_eq!(suggest("Camera", cmds), None);
        assert_eq!(suggest("Sphere", cmds), None);
    }

    #[test]
    fn tabs_line_up() {
        let d = Diagnostic::error(Path::new("a.txt"), 1, "\tSphere x", 9, 1, "m");
        let text = d.to_string();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[3], " 1 |     Sphere x");
        assert_eq!(lines[4], "   |            ^");
    }

    #[test]
    fn long_lines_and_messages_are_shortened() {
        let line = format!("Sphere {}x \"M\"", " ".repeat(1 << 20));
        let col = line.find('x').unwrap() + 1;
        let d = Diagnostic::error(
            Path::new("a.txt"),
            1,
            &line,
            col,
            1,
            format!("bad '{}'", "y".repeat(1 << 20)),
        )
        .with_label("here");
        let text = d.to_string();
        assert!(text.len() < 1500, "{} bytes", text.len());
        let lines: Vec<&str> = text.lines().collect();
        assert!(lines[0].starts_with("error: bad 'yyy") && lines[0].ends_with("yyy'"));
        assert!(lines[0].contains('…'));
        assert!(
            lines[3].starts_with(" 1 | …") && lines[3].ends_with("x \"M\""),
            "{}",
            lines[3]
        );
        // The caret still sits under the x.
        let caret = lines[4].find('^').unwrap();
        assert_eq!(
            lines[3][..lines[3].len() - 4].chars().count(),
            lines[4][..caret].chars().count() + 1
        );
        // A span running to the end of a long line is cut at the window's edge.
        let d = Diagnostic::warning(Path::new("a.txt"), 1, &"1 ".repeat(1 << 19), 3, 1 << 20, "extra");
        let text = d.to_string();
        assert!(text.len() < 600, "{text}");
        assert!(text.lines().nth(3).unwrap().ends_with('…'));
    }

    #[test]
    fn utf8_errors_locate_the_byte() {
        let err = decode_utf8(b"ab\ncd\xFFe\n", Path::new("s.txt")).unwrap_err();
        assert_eq!((err.line, err.column), (2, 3));
        assert_eq!(err.source_line, "cd\u{FFFD}e");
        assert_eq!(decode_utf8(b"\xEF\xBB\xBFok", Path::new("s")).unwrap(), "ok");
    }
}
