//! The protocol's lines, and the verdict on each answer.

use glam::DVec3;
use serde_json::Value;

use super::battery::{Case, CaseKind, PrimKind, Shape};

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
    /// `"error": "..."`: the intersector threw.
    Error(String),
}

/// What is wrong with one answer. The order is the report's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Verdict {
    /// The intersector threw an error.
    Raised,
    /// t, point or normal is NaN or infinite.
    NotFinite,
    /// A hit with t < 0.
    BehindOrigin,
    /// A miss where the ray hits.
    Missed,
    /// A hit where the ray misses.
    Phantom,
    /// The sphere's other root.
    WrongRoot,
    /// A hit at the wrong distance.
    WrongT,
    /// `point` is not origin + t · direction.
    WrongPoint,
    /// The normal is not unit length.
    NormalNotUnit,
    /// The normal is not perpendicular to the surface.
    NormalWrong,
    /// The normal points the other way from the convention of the other answers.
    NormalFlipped,
}

impl Verdict {
    /// A stable code for scripts.
    pub fn code(self) -> &'static str {
        match self {
            Verdict::Raised => "raised-error",
            Verdict::NotFinite => "not-finite",
            Verdict::BehindOrigin => "behind-origin",
            Verdict::Missed => "missed",
            Verdict::Phantom => "phantom-hit",
            Verdict::WrongRoot => "wrong-root",
            Verdict::WrongT => "wrong-t",
            Verdict::WrongPoint => "wrong-point",
            Verdict::NormalNotUnit => "normal-not-unit",
            Verdict::NormalWrong => "normal-wrong",
            Verdict::NormalFlipped => "normal-flipped",
        }
    }
}

/// How an accepted hit's normal is oriented, for the consistency check across answers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orientation {
    /// Along the outward (geometric) normal.
    pub outward: bool,
    /// Against the ray direction.
    pub facing: bool,
}

/// The verdicts on one answer, and the normal's orientation when the hit was right and had
/// a normal along the surface's.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Judgement {
    /// What is wrong (empty: right).
    pub verdicts: Vec<Verdict>,
    /// For the normal-consistency pass.
    pub orientation: Option<Orientation>,
}

/// The hello rayscope sends first.
pub const HELLO: &str = r#"{"hello":"rayscope-probe","version":1}"#;

/// A number as JSON (shortest text that reads back as the same f64).
fn num(x: f64) -> String {
    if x == 0.0 {
        // -0 is valid JSON but reads oddly in a reproduction.
        return "0".into();
    }
    format!("{x}")
}

/// A vector as a JSON array.
pub fn arr(v: DVec3) -> String {
    format!("[{},{},{}]", num(v.x), num(v.y), num(v.z))
}

/// The primitive as JSON.
pub fn primitive_json(shape: &Shape) -> String {
    match *shape {
        Shape::Sphere { center, radius } => {
            format!(
                r#"{{"kind":"sphere","center":{},"radius":{}}}"#,
                arr(center),
                num(radius)
            )
        }
        Shape::Plane { point, normal } => {
            format!(r#"{{"kind":"plane","point":{},"normal":{}}}"#, arr(point), arr(normal))
        }
        Shape::Triangle { v } => format!(
            r#"{{"kind":"triangle","vertices":[{},{},{}]}}"#,
            arr(v[0]),
            arr(v[1]),
            arr(v[2])
        ),
    }
}

/// The request line for a case. Fields always come in this order and every number is a plain
/// JSON number, so an adapter may read the numbers in order instead of parsing JSON.
pub fn request_json(id: usize, case: &Case) -> String {
    format!(
        r#"{{"id":{id},"ray":{{"origin":{},"direction":{}}},"primitive":{}}}"#,
        arr(case.origin),
        arr(case.dir),
        primitive_json(&case.shape)
    )
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
                .map_err(|_| format!("{what} should be a number, found the string \"{s}\"")),
        },
        other => Err(format!("{what} should be a number, found {other}")),
    }
}

fn vector(v: &Value, what: &str) -> Result<DVec3, String> {
    let items = v
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| format!("{what} should be an array of three numbers [x, y, z], found {v}"))?;
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
        Some(v) => return Err(format!("its \"id\" is {v}, but rayscope asked request {id}")),
        None => return Err(format!("it has no \"id\" (it should be {id}, the request's)")),
    }
    if let Some(e) = obj.get("error") {
        let msg = match e {
            Value::String(s) => s.clone(),
            other => other.to_string(),
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
        format!("\"hit\" should be null or an object {{\"t\":…,\"point\":[…],\"normal\":[…]}}, found {hit}")
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

/// The verdicts on `answer` to `case`.
pub fn judge(case: &Case, answer: &Answer) -> Judgement {
    let e = &case.expect;
    let mut j = Judgement::default();
    let (t, point, normal) = match answer {
        Answer::Error(_) => {
            j.verdicts.push(Verdict::Raised);
            return j;
        }
        Answer::Miss => {
            if e.hit_required() {
                j.verdicts.push(Verdict::Missed);
            }
            return j;
        }
        Answer::Hit { t, point, normal } => (*t, *point, *normal),
    };
    let finite =
        t.is_none_or(f64::is_finite) && point.is_none_or(|p| p.is_finite()) && normal.is_none_or(|n| n.is_finite());
    if !finite {
        j.verdicts.push(Verdict::NotFinite);
        return j;
    }
    let (o, d) = (case.origin, case.dir);
    let t = t.unwrap_or_else(|| (point.unwrap_or(o) - o).dot(d) / d.length_squared());
    if let Some(p) = point {
        if (p - (o + d * t)).length() > e.tol {
            j.verdicts.push(Verdict::WrongPoint);
        }
    }
    if t < -e.zero {
        j.verdicts.insert(0, Verdict::BehindOrigin);
        return j;
    }
    if let Some(n) = normal {
        if (n.length() - 1.0).abs() > e.normal_tol {
            j.verdicts.push(Verdict::NormalNotUnit);
        }
    }
    let at_origin = t.abs() <= e.zero;
    let matched = e.hit.filter(|h| (t - h.t).abs() <= e.tol);
    if matched.is_none() && !(at_origin && e.at_origin_ok) && !e.any_hit_ok {
        match e.hit {
            None => j.verdicts.insert(0, Verdict::Phantom),
            Some(_) if e.other_t.is_some_and(|o| (t - o).abs() <= e.tol) => j.verdicts.insert(0, Verdict::WrongRoot),
            Some(_) => j.verdicts.insert(0, Verdict::WrongT),
        }
        return j;
    }
    // The normal's direction is judged where the hit is a clear one.
    if let (Some(h), Some(n), false) = (matched, normal, e.tie) {
        let len = n.length();
        if len > 0.0 {
            let n = n / len;
            let c = n.dot(h.normal);
            if c.abs() < 1.0 - e.normal_tol {
                j.verdicts.push(Verdict::NormalWrong);
            } else {
                j.orientation = Some(Orientation {
                    outward: c > 0.0,
                    facing: n.dot(d) < 0.0,
                });
            }
        } else {
            j.verdicts.push(Verdict::NormalWrong);
        }
    }
    j
}

/// Which normal convention a set of answers follows, and the answers that break it.
#[derive(Debug, Clone, PartialEq)]
pub struct Convention {
    /// True when the answers mostly return the outward normal, false when they mostly face the ray.
    pub outward: bool,
    /// Indices (into the slice given) of answers against it.
    pub breaking: Vec<usize>,
}

/// The convention most answers follow (outward or facing the ray; either is fine) and the
/// answers that break it.
pub fn convention(orientations: &[Orientation]) -> Convention {
    let outward = orientations.iter().filter(|o| o.outward).count();
    let facing = orientations.iter().filter(|o| o.facing).count();
    let use_outward = outward >= facing;
    let breaking = orientations
        .iter()
        .enumerate()
        .filter(|(_, o)| if use_outward { !o.outward } else { !o.facing })
        .map(|(i, _)| i)
        .collect();
    Convention {
        outward: use_outward,
        breaking,
    }
}

/// What the verdict means, in the words of the report ("you …").
pub fn phrase(v: Verdict) -> &'static str {
    match v {
        Verdict::Raised => "your intersector raises an error",
        Verdict::NotFinite => "you return a hit whose t, point or normal is NaN or infinite",
        Verdict::BehindOrigin => "you return a hit behind the origin (t < 0)",
        Verdict::Missed => "you return a miss where the ray hits",
        Verdict::Phantom => "you return a hit where the ray misses",
        Verdict::WrongRoot => "you return the sphere's other intersection",
        Verdict::WrongT => "you return the hit at the wrong distance",
        Verdict::WrongPoint => "your point is not origin + t * direction",
        Verdict::NormalNotUnit => "your normal is not unit length",
        Verdict::NormalWrong => "your normal is not perpendicular to the surface",
        Verdict::NormalFlipped => "your normal points the other way than in your other answers",
    }
}

const NOT_UNIT: &str = "Normalise the normal: for a sphere (P - C) / r, for a triangle the \
     normalised (v1 - v0) x (v2 - v0). Shading's N . L needs unit length.";

/// The likely mistake behind a verdict in a case, where one is typical.
pub fn hint(kind: PrimKind, case: Option<CaseKind>, v: Verdict, outward: bool) -> Option<String> {
    use CaseKind::*;
    use PrimKind::*;
    use Verdict::*;
    let Some(case) = case else {
        return (v == NormalNotUnit).then(|| NOT_UNIT.to_string());
    };
    let s = match (kind, case, v) {
        (Sphere, Inside | Centre | SurfaceIn, BehindOrigin) => {
            "When the ray starts inside the sphere the smaller root of the quadratic is negative: \
             the hit is the larger root. Use the smaller root only when it is > 0, else the larger."
        }
        (Sphere, Behind, BehindOrigin | Phantom) => {
            "Both roots are negative: the sphere is behind the ray. Accept a root only when t > 0."
        }
        (_, Behind | Away, BehindOrigin | Phantom) => "The surface is behind the ray. Accept a hit only when t > 0.",
        (_, _, BehindOrigin) => "Accept a hit only when t > 0: points with t < 0 lie behind the ray's start.",
        (Sphere, OutsideHit | Far | Near | Tiny | Huge | Grazing, WrongRoot) => {
            "You take the larger root. From outside the nearer hit is the smaller one, (-b - sqrt(disc)) / 2a."
        }
        (Sphere, Inside | Centre | SurfaceIn, WrongRoot) => {
            "From inside the sphere the hit is the larger root: the smaller one lies behind the origin."
        }
        (Triangle, BackHit, Missed) => {
            "Rays meeting the triangle's back face miss: your test is one-sided (it rejects a \
             negative determinant, or d . n > 0). The course's triangles are two-sided: scene 1's \
             triangle casts its shadow from its back. Reject only |det| < epsilon."
        }
        (Plane, BackHit, Missed) => {
            "Rays from behind the plane miss: your test is one-sided. Planes are two-sided; reject \
             only |d . n| < epsilon, not d . n > 0."
        }
        (Triangle, Edge | Vertex, Missed) => {
            "Rays exactly through an edge or a corner miss: your inside test is strict (u > 0, \
             v > 0, u + v < 1) where it must include the boundary (u >= 0, v >= 0, u + v <= 1). \
             Otherwise rays slip through the crack between two triangles sharing that edge. \
             (These rays meet the boundary exactly, even in floating point.)"
        }
        (Triangle, NearEdgeIn, Missed) => {
            "Rays just inside an edge miss: your inside test has a margin (such as u > epsilon) \
             or one of the three conditions is wrong."
        }
        (Triangle, NearEdgeOut | OutsideMiss, Phantom) => {
            "Rays outside the triangle hit it: check all three conditions u >= 0, v >= 0 and \
             u + v <= 1 (with u and v the weights of v1 and v2)."
        }
        (Plane, Parallel | InPlane, Raised | NotFinite | Phantom) => {
            "The ray is parallel to the plane, so d . n = 0: you divide by it. Return a miss when \
             |d . n| < a tiny epsilon, before dividing."
        }
        (Triangle, Parallel, Raised | NotFinite | Phantom) => {
            "The ray is parallel to the triangle, so the determinant is 0: you divide by it. \
             Return a miss when |det| < a tiny epsilon, before dividing."
        }
        (Sphere, Grazing, Missed | Phantom) => {
            "Rays passing 0.1 % of the radius inside the rim must hit and those 0.1 % outside must \
             miss: check the discriminant test (disc >= 0) and that it uses the right formula."
        }
        (_, Tiny, Missed) => {
            "At this scale the hit is at t of about 0.0001 or less: a fixed epsilon (such as \
             t > 0.001) rejects it. Use a far smaller epsilon for t, or one relative to the scene."
        }
        (_, Near, Missed) => {
            "The hit is very near the origin: an epsilon on t larger than that rejects it. Offset \
             secondary rays' origins instead, and keep the t test's epsilon tiny."
        }
        (_, Huge | Far, Missed) => {
            "The hit is far away: a maximum distance (such as t < 1000) or a loss of precision \
             (float instead of double, or b * b - 4ac cancelling) rejects it."
        }
        (_, Grazing, Missed) => "At a grazing angle the hit is far along the ray: a maximum distance rejects it.",
        (_, SurfaceOut, Phantom | WrongT) => {
            "The ray starts on the surface and leaves it: there is nothing to hit (a hit at t = 0 is also accepted)."
        }
        (_, _, NormalNotUnit) => NOT_UNIT,
        (Sphere, _, NormalWrong) => "A sphere's normal at P is (P - C) / r.",
        (Triangle, _, NormalWrong) => "A triangle's normal is the normalised (v1 - v0) x (v2 - v0).",
        (_, _, NormalFlipped) if outward => {
            return Some(format!(
                "Most of your answers return the outward normal{}, but these point the other \
                 way. Either convention is fine (outward, or flipped to face the ray) as long as \
                 it is the same everywhere.",
                if kind == Triangle {
                    " ((v1 - v0) x (v2 - v0))"
                } else {
                    ""
                }
            ))
        }
        (_, _, NormalFlipped) => {
            "Most of your answers flip the normal to face the ray, but these do not. Either \
             convention is fine as long as it is the same everywhere."
        }
        (_, _, Raised) => "Your intersector should return a miss, not fail.",
        (_, _, NotFinite) => "Somewhere a division by zero or a square root of a negative number slips through.",
        _ => return None,
    };
    Some(s.to_string())
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
    fn conventions() {
        let o = |outward, facing| Orientation { outward, facing };
        let c = convention(&[o(true, true), o(true, false), o(false, true)]);
        assert!(c.outward);
        assert_eq!(c.breaking, vec![2]);
        let c = convention(&[o(false, true), o(true, true), o(false, true)]);
        assert!(!c.outward && c.breaking.is_empty());
    }
}
