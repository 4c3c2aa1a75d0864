//! The protocol's lines, and the verdict on each answer (the answer's parser is
//! [`crate::probe_answer`], where it can be fuzzed).

pub use crate::probe_answer::{parse_answer, Answer};
use glam::DVec3;

use super::battery::{Case, CaseKind, PrimKind, Shape};

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
    /// Every verdict, in the report's order.
    pub const ALL: [Verdict; 11] = [
        Verdict::Raised,
        Verdict::NotFinite,
        Verdict::BehindOrigin,
        Verdict::Missed,
        Verdict::Phantom,
        Verdict::WrongRoot,
        Verdict::WrongT,
        Verdict::WrongPoint,
        Verdict::NormalNotUnit,
        Verdict::NormalWrong,
        Verdict::NormalFlipped,
    ];

    /// The verdict whose [`Self::code`] is `code`.
    #[must_use]
    pub fn parse(code: &str) -> Option<Verdict> {
        Verdict::ALL.into_iter().find(|v| v.code() == code)
    }

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
    fn conventions() {
        let o = |outward, facing| Orientation { outward, facing };
        let c = convention(&[o(true, true), o(true, false), o(false, true)]);
        assert!(c.outward);
        assert_eq!(c.breaking, vec![2]);
        let c = convention(&[o(false, true), o(true, true), o(false, true)]);
        assert!(!c.outward && c.breaking.is_empty());
    }
}
