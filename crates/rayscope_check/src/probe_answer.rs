//! `rayscope probe`'s reader of one answer line from a student's intersector (the protocol is in
//! docs/probe.md): a miss, a hit with its `t`, point and normal, or the error the intersector
//! raised. Any line at all gives an answer or a message saying what was expected, never a panic,
//! and what is kept of a line is bounded.

use glam::DVec3;
use serde_json::Value;

/// Longest error message kept from an `"error"` answer, in bytes; the rest is cut with " …".
pub const MAX_ERROR_MESSAGE: usize = 300;

/// Longest piece of the answer quoted in a message saying why it cannot be read, in characters.
const MAX_QUOTED: usize = 120;

/// What the program answered to one request.
#[derive(Debug, Clone, PartialEq)]
pub enum Answer {
    /// `"hit": null`.
    Miss,
    /// `"hit": {...}` with at least `t` or `point`.
    Hit {
        /// Ray parameter.
        t: Option<f64>,
        /// Hit point.
        point: Option<DVec3>,
        /// Normal.
        normal: Option<DVec3>,
    },
    /// `"error": "..."`: the intersector threw (the message cut to [`MAX_ERROR_MESSAGE`] bytes).
    Error(String),
}

/// Puts quotes around bare NaN and infinity tokens (Python's `json.dumps` and C's `printf`
/// write them), so that such an answer is judged rather than rejected as garbage.
fn quote_non_finite(line: &str) -> String {
    let mut out = String::with_capacity(line.len() + 8);
    let mut chars = line.char_indices().peekable();
    let mut in_string = false;
    while let Some((i, c)) = chars.next() {
        if in_string {
            out.push(c);
            if c == '\\' {
                if let Some((_, n)) = chars.next() {
                    out.push(n);
                }
            } else if c == '"' {
                in_string = false;
            }
            continue;
        }
        if c == '"' {
            in_string = true;
            out.push(c);
            continue;
        }
        let starts_word = c.is_ascii_alphabetic()
            || ((c == '-' || c == '+') && matches!(line[i + 1..].chars().next(), Some(n) if n.is_ascii_alphabetic()));
        if starts_word {
            let end = line[i + 1..]
                .find(|ch: char| !ch.is_ascii_alphabetic())
                .map_or(line.len(), |k| i + 1 + k);
            let word = &line[i..end];
            let lower = word.to_ascii_lowercase();
            let replaced = match lower.trim_start_matches('+') {
                "nan" | "-nan" => Some("\"NaN\""),
                "inf" | "infinity" => Some("\"Infinity\""),
                "-inf" | "-infinity" => Some("\"-Infinity\""),
                _ => None,
            };
            out.push_str(replaced.unwrap_or(word));
            while chars.peek().is_some_and(|(k, _)| *k < end) {
                chars.next();
            }
            continue;
        }
        out.push(c);
    }
    out
}

/// `s` cut to at most `max` bytes at a character boundary, with " …" when cut.
fn cut(s: &str, max: usize) -> String {
    if s.len() <= max {
        return s.to_string();
    }
    let end = (0..=max).rev().find(|i| s.is_char_boundary(*i)).unwrap_or(0);
    format!("{} …", &s[..end])
}

/// A JSON value as it reads in a message, shortened.
fn brief(v: &Value) -> String {
    let s = v.to_string();
    let short: String = s.chars().take(MAX_QUOTED).collect();
    if short.len() < s.len() {
        format!("{short} …")
    } else {
        short
    }
}

fn number(v: &Value, what: &str) -> Result<f64, String> {
    match v {
        Value::Number(n) => n.as_f64().ok_or_else(|| format!("{what} is not a number")),
        Value::String(s) => match s.to_ascii_lowercase().as_str() {
            "nan" | "-nan" => Ok(f64::NAN),
            "inf" | "infinity" | "+infinity" | "∞" => Ok(f64::INFINITY),
            "-inf" | "-infinity" | "-∞" => Ok(f64::NEG_INFINITY),
            _ => s
                .trim()
                .parse()
                .map_err(|_| format!("{what} should be a number, found the string \"{}\"", cut(s, MAX_QUOTED))),
        },
        other => Err(format!("{what} should be a number, found {}", brief(other))),
    }
}

fn vector(v: &Value, what: &str) -> Result<DVec3, String> {
    let items = v.as_array().filter(|a| a.len() == 3).ok_or_else(|| {
        format!(
            "{what} should be an array of three numbers [x, y, z], found {}",
            brief(v)
        )
    })?;
    Ok(DVec3::new(
        number(&items[0], what)?,
        number(&items[1], what)?,
        number(&items[2], what)?,
    ))
}

/// Reads an answer line to request `id`; the error says what was expected.
pub fn parse_answer(line: &str, id: usize) -> Result<Answer, String> {
    let fixed = quote_non_finite(line);
    let value: Value = serde_json::from_str(fixed.trim()).map_err(|e| format!("not JSON ({e})"))?;
    let obj = value.as_object().ok_or_else(|| "not a JSON object".to_string())?;
    match obj.get("id") {
        Some(v) if v.as_u64() == Some(id as u64) => {}
        Some(v) => return Err(format!("its \"id\" is {}, but rayscope asked request {id}", brief(v))),
        None => return Err(format!("it has no \"id\" (it should be {id}, the request's)")),
    }
    if let Some(e) = obj.get("error") {
        let msg = match e {
            Value::String(s) => cut(s, MAX_ERROR_MESSAGE),
            other => cut(&other.to_string(), MAX_ERROR_MESSAGE),
        };
        return Ok(Answer::Error(msg));
    }
    let hit = obj
        .get("hit")
        .ok_or_else(|| "it has neither \"hit\" (null for a miss) nor \"error\"".to_string())?;
    if hit.is_null() {
        return Ok(Answer::Miss);
    }
    let h = hit.as_object().ok_or_else(|| {
        format!(
            "\"hit\" should be null or an object {{\"t\":…,\"point\":[…],\"normal\":[…]}}, found {}",
            brief(hit)
        )
    })?;
    let t = h
        .get("t")
        .filter(|v| !v.is_null())
        .map(|v| number(v, "\"t\""))
        .transpose()?;
    let point = h
        .get("point")
        .filter(|v| !v.is_null())
        .map(|v| vector(v, "\"point\""))
        .transpose()?;
    let normal = h
        .get("normal")
        .filter(|v| !v.is_null())
        .map(|v| vector(v, "\"normal\""))
        .transpose()?;
    if t.is_none() && point.is_none() {
        return Err("its \"hit\" has neither \"t\" nor \"point\": give at least one".into());
    }
    Ok(Answer::Hit { t, point, normal })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_parse_with_non_finite_tokens() {
        assert_eq!(parse_answer(r#"{"id":3,"hit":null}"#, 3), Ok(Answer::Miss));
        let a = parse_answer(r#"{"id":3,"hit":{"t":Infinity,"point":[NaN,-inf,1]}}"#, 3).unwrap();
        let Answer::Hit { t, point, .. } = a else {
            panic!("{a:?}")
        };
        assert_eq!(t, Some(f64::INFINITY));
        assert!(point.unwrap().x.is_nan() && point.unwrap().y == f64::NEG_INFINITY);
        assert_eq!(
            parse_answer(r#"{"id":3,"error":"ZeroDivisionError: Infinity"}"#, 3),
            Ok(Answer::Error("ZeroDivisionError: Infinity".into())),
            "strings are left alone"
        );
        assert!(parse_answer(r#"{"id":4,"hit":null}"#, 3)
            .unwrap_err()
            .contains("request 3"));
        assert!(parse_answer("hello", 3).unwrap_err().contains("not JSON"));
        assert!(parse_answer(r#"{"id":3,"hit":{"normal":[0,0,1]}}"#, 3)
            .unwrap_err()
            .contains("neither \"t\" nor \"point\""));
        assert!(parse_answer(r#"{"id":3,"hit":{"t":1,"point":[1,2]}}"#, 3)
            .unwrap_err()
            .contains("three numbers"));
    }

    #[test]
    fn what_is_kept_of_a_long_answer_is_bounded() {
        let long = "é".repeat(20_000);
        let Ok(Answer::Error(m)) = parse_answer(&format!(r#"{{"id":0,"error":"{long}"}}"#), 0) else {
            panic!("an error answer")
        };
        assert!(
            m.len() <= MAX_ERROR_MESSAGE + " …".len() && m.ends_with(" …"),
            "{}",
            m.len()
        );
        let why = parse_answer(&format!(r#"{{"id":0,"hit":["{long}"]}}"#), 0).unwrap_err();
        assert!(why.len() < 600 && why.contains("found [\"é"), "{why}");
        let why = parse_answer(&format!(r#"{{"id":"{long}","hit":null}}"#), 0).unwrap_err();
        assert!(why.len() < 600 && why.contains("request 0"), "{why}");
    }

    #[test]
    fn the_fuzz_seeds_and_regressions_read_within_bounds() {
        // The fuzz target's checks (fuzz/fuzz_targets/probe_answer.rs), on its seeds and on any
        // input it found that was fixed since.
        let fuzz = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz");
        let mut read = 0;
        for (dir, seeds_only) in [("corpus/probe_answer", true), ("regressions/probe_answer", false)] {
            let Ok(entries) = std::fs::read_dir(fuzz.join(dir)) else {
                continue;
            };
            for entry in entries {
                let path = entry.unwrap().path();
                if seeds_only && !path.file_name().unwrap().to_string_lossy().starts_with("seed-") {
                    continue;
                }
                let data = std::fs::read(&path).unwrap();
                let line = String::from_utf8_lossy(&data);
                for id in 0..4 {
                    match parse_answer(&line, id) {
                        Ok(Answer::Error(m)) => assert!(m.len() <= MAX_ERROR_MESSAGE + " …".len()),
                        Ok(Answer::Hit { t, point, .. }) => assert!(t.is_some() || point.is_some()),
                        Ok(Answer::Miss) => {}
                        Err(why) => assert!(!why.is_empty() && why.len() < 1024, "{}: {why}", path.display()),
                    }
                }
                read += 1;
            }
        }
        assert!(read >= 7, "the seeds are in fuzz/corpus/probe_answer");
    }

    #[test]
    fn odd_lines_give_a_reason_not_a_panic() {
        for line in [
            "",
            "{",
            "[]",
            "null",
            "-",
            "+inf",
            "\"",
            r#"{"id":-1}"#,
            r#"{"id":0,"hit":{"t":"x"}}"#,
            r#"{"id":0,"hit":{"t":1e999}}"#,
            r#"{"id":0,"hit":{"t":[1]}}"#,
            "{\"id\":0,\"hit\":{\"t\":-nan\u{e9}}}",
        ] {
            let _ = parse_answer(line, 0);
        }
        assert_eq!(
            parse_answer(r#"{"id":0,"hit":{"t":"-Infinity"}}"#, 0),
            Ok(Answer::Hit {
                t: Some(f64::NEG_INFINITY),
                point: None,
                normal: None
            })
        );
    }
}
