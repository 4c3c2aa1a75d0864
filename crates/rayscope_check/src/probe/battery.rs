//! The battery of rays `probe` sends for each primitive, and what a correct intersector answers.
//!
//! Every number sent is rounded to 7 significant digits first, so a reproduction printed in the
//! report is short and pastes into a test unchanged. The expected answer is the checker's oracle's
//! on exactly those numbers, in f64; where the ray passes within rounding of an edge or a rim (the
//! log checker's tie rule, [`crate::tie`]) the case is a genuine tie and either answer is accepted.

use std::rc::Rc;

use glam::DVec3;
use rayscope_core::rng::Rng;
use rayscope_scene::{SceneFile, Shape as SceneShape};

use crate::oracle::{hit_plane, hit_sphere, rim_margin, OracleRay};
use crate::tie::{is_tie, magnitude};
use crate::Tolerances;

/// Single-precision epsilon: the rounding a tracer in f32 lives with.
const EPS32: f64 = f32::EPSILON as f64;

/// The three kinds of primitive the protocol knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum PrimKind {
    /// A sphere.
    Sphere,
    /// An infinite plane.
    Plane,
    /// A triangle (single or from a mesh).
    Triangle,
}

impl PrimKind {
    /// The protocol's name.
    pub fn name(self) -> &'static str {
        match self {
            PrimKind::Sphere => "sphere",
            PrimKind::Plane => "plane",
            PrimKind::Triangle => "triangle",
        }
    }
}

/// A primitive's geometry, exactly as sent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Centre and radius.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius.
        radius: f64,
    },
    /// A point on the plane and its unit normal.
    Plane {
        /// A point on the plane.
        point: DVec3,
        /// Unit normal.
        normal: DVec3,
    },
    /// Corners v0, v1, v2; the normal is (v1 − v0) × (v2 − v0).
    Triangle {
        /// Corners.
        v: [DVec3; 3],
    },
}

impl Shape {
    /// Which kind of primitive this is.
    pub fn kind(&self) -> PrimKind {
        match self {
            Shape::Sphere { .. } => PrimKind::Sphere,
            Shape::Plane { .. } => PrimKind::Plane,
            Shape::Triangle { .. } => PrimKind::Triangle,
        }
    }
}

/// The situations the battery tests; each primitive kind uses a subset.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CaseKind {
    /// Sphere: from outside, aimed at it.
    OutsideHit,
    /// Front face (the normal's side), aimed at it.
    FrontHit,
    /// Back face, aimed at it.
    BackHit,
    /// From outside, passing beside.
    OutsideMiss,
    /// The primitive lies behind the origin.
    Behind,
    /// Moving away from a plane.
    Away,
    /// Starting inside a sphere.
    Inside,
    /// Starting at a sphere's centre.
    Centre,
    /// Within 0.1 % inside or outside a sphere's rim, or at a grazing angle.
    Grazing,
    /// Touching a sphere's rim exactly.
    Tangent,
    /// 0.1 % inside a triangle's edge.
    NearEdgeIn,
    /// 0.1 % outside a triangle's edge.
    NearEdgeOut,
    /// Exactly through a triangle's edge.
    Edge,
    /// Exactly through a triangle's corner.
    Vertex,
    /// Parallel to a plane or a triangle's plane.
    Parallel,
    /// Lying in a plane.
    InPlane,
    /// Starting on the surface, leaving it.
    SurfaceOut,
    /// Starting on a sphere's surface, going through the sphere.
    SurfaceIn,
    /// Starting very near the surface.
    Near,
    /// Starting very far away.
    Far,
    /// A hit from the front or outside, primitive and ray scaled by 0.0001 about the world
    /// origin: rounding is as before, so only an absolute epsilon can fail it.
    Tiny,
    /// The same scaled by 1000: only an absolute maximum distance can fail it.
    Huge,
}

/// The cases each kind of primitive gets, in report order.
pub fn cases_for(kind: PrimKind) -> &'static [CaseKind] {
    use CaseKind::*;
    match kind {
        PrimKind::Sphere => &[
            OutsideHit,
            OutsideMiss,
            Behind,
            Inside,
            Centre,
            Grazing,
            Tangent,
            SurfaceOut,
            SurfaceIn,
            Near,
            Far,
            Tiny,
            Huge,
        ],
        PrimKind::Plane => &[
            FrontHit, BackHit, Away, Parallel, InPlane, Grazing, SurfaceOut, Near, Far, Tiny, Huge,
        ],
        PrimKind::Triangle => &[
            FrontHit,
            BackHit,
            OutsideMiss,
            NearEdgeIn,
            NearEdgeOut,
            Edge,
            Vertex,
            Parallel,
            Behind,
            Grazing,
            SurfaceOut,
            Near,
            Far,
            Tiny,
            Huge,
        ],
    }
}

impl CaseKind {
    /// A stable identifier for scripts.
    pub fn id(self) -> &'static str {
        use CaseKind::*;
        match self {
            OutsideHit => "outside-hit",
            FrontHit => "front-hit",
            BackHit => "back-hit",
            OutsideMiss => "outside-miss",
            Behind => "behind",
            Away => "away",
            Inside => "inside",
            Centre => "centre",
            Grazing => "grazing",
            Tangent => "tangent",
            NearEdgeIn => "near-edge-inside",
            NearEdgeOut => "near-edge-outside",
            Edge => "edge",
            Vertex => "vertex",
            Parallel => "parallel",
            InPlane => "in-plane",
            SurfaceOut => "surface-leaving",
            SurfaceIn => "surface-entering",
            Near => "near",
            Far => "far",
            Tiny => "tiny",
            Huge => "huge",
        }
    }

    /// What the rays of this case do, in words.
    pub fn describe(self, kind: PrimKind) -> &'static str {
        use CaseKind::*;
        match (kind, self) {
            (PrimKind::Sphere, OutsideHit) => "ray from outside, aimed at the sphere",
            (PrimKind::Sphere, OutsideMiss) => "ray from outside, passing beside the sphere",
            (PrimKind::Sphere, Behind) => "sphere behind the ray's origin",
            (PrimKind::Sphere, Inside) => "ray starting inside the sphere",
            (PrimKind::Sphere, Centre) => "ray starting at the centre",
            (PrimKind::Sphere, Grazing) => "ray passing 0.1 % of the radius inside or outside the rim",
            (PrimKind::Sphere, Tangent) => "ray touching the rim (hit or miss are both right)",
            (PrimKind::Sphere, SurfaceOut) => "ray starting on the surface, leaving the sphere",
            (PrimKind::Sphere, SurfaceIn) => "ray starting on the surface, going through the sphere",
            (PrimKind::Sphere, Near) => "ray starting just outside (1 % of the radius away)",
            (PrimKind::Sphere, Far) => "ray from far away (200 radii)",
            (PrimKind::Sphere, Tiny) => "sphere and ray scaled by 0.0001 (about the world origin)",
            (PrimKind::Sphere, Huge) => "sphere and ray scaled by 1000 (about the world origin)",
            (PrimKind::Plane, FrontHit) => "ray from the front (the normal's side) toward the plane",
            (PrimKind::Plane, BackHit) => "ray from behind the plane toward it",
            (PrimKind::Plane, Away) => "ray moving away from the plane",
            (PrimKind::Plane, Parallel) => "ray parallel to the plane",
            (PrimKind::Plane, InPlane) => "ray lying in the plane (a miss or any hit on it is right)",
            (PrimKind::Plane, Grazing) => "ray meeting the plane at a grazing angle (0.06 degrees)",
            (PrimKind::Plane, SurfaceOut) => "ray starting on the plane, leaving it",
            (PrimKind::Plane, Near) => "ray starting 0.01 from the plane",
            (PrimKind::Plane, Far) => "ray starting 200 from the plane",
            (PrimKind::Plane, Tiny) => "plane and ray scaled by 0.0001 (about the world origin)",
            (PrimKind::Plane, Huge) => "plane and ray scaled by 1000 (about the world origin)",
            (PrimKind::Triangle, FrontHit) => "ray toward the front face (the side (v1 - v0) x (v2 - v0) points to)",
            (PrimKind::Triangle, BackHit) => "ray toward the back face",
            (PrimKind::Triangle, OutsideMiss) => "ray passing beside the triangle, through its plane",
            (PrimKind::Triangle, NearEdgeIn) => "ray 0.1 % inside an edge",
            (PrimKind::Triangle, NearEdgeOut) => "ray 0.1 % outside an edge",
            (PrimKind::Triangle, Edge) => "ray exactly through an edge",
            (PrimKind::Triangle, Vertex) => "ray exactly through a corner",
            (PrimKind::Triangle, Parallel) => "ray parallel to the triangle's plane",
            (PrimKind::Triangle, Behind) => "triangle behind the ray's origin",
            (PrimKind::Triangle, Grazing) => "ray meeting the triangle at a grazing angle (0.06 degrees)",
            (PrimKind::Triangle, SurfaceOut) => "ray starting on the triangle, leaving it",
            (PrimKind::Triangle, Near) => "ray starting just in front (1 % of the triangle's size away)",
            (PrimKind::Triangle, Far) => "ray from far away (200 x the triangle's size)",
            (PrimKind::Triangle, Tiny) => "triangle and ray scaled by 0.0001 (about the world origin)",
            (PrimKind::Triangle, Huge) => "triangle and ray scaled by 1000 (about the world origin)",
            _ => "other rays",
        }
    }
}

/// The hit a correct intersector reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Truth {
    /// Ray parameter, in units of the direction as sent.
    pub t: f64,
    /// origin + t · direction.
    pub point: DVec3,
    /// Unit geometric normal: outward for spheres, as given for planes, (v1 − v0) × (v2 − v0)
    /// for triangles.
    pub normal: DVec3,
}

/// Which answers are right for one ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Expect {
    /// The nearest hit in front of the origin, if the ray has one.
    pub hit: Option<Truth>,
    /// A miss is accepted (no hit, a tie, or only a hit at the origin itself).
    pub miss_ok: bool,
    /// A hit at t ≈ 0 is accepted: the ray starts on the surface.
    pub at_origin_ok: bool,
    /// Any finite hit with t ≥ 0 is accepted (a ray lying in a plane or nearly parallel to it).
    pub any_hit_ok: bool,
    /// A genuine tie: the ray passes within rounding of an edge or a rim.
    pub tie: bool,
    /// The sphere's other root, to recognise the wrong one being chosen.
    pub other_t: Option<f64>,
    /// Tolerance on t and on the point.
    pub tol: f64,
    /// |t| below this is the origin itself.
    pub zero: f64,
    /// Tolerance on a normal's length and on the cosine to the true normal: a normal worked out
    /// from a hit point is off by the point's error over the primitive's size.
    pub normal_tol: f64,
}

impl Expect {
    /// True when only a hit is right.
    pub fn hit_required(&self) -> bool {
        self.hit.is_some() && !self.miss_ok
    }
}

/// One request of the battery.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// The situation tested.
    pub case: CaseKind,
    /// The primitive as sent (scaled for the tiny and huge cases).
    pub shape: Shape,
    /// The scene entity the primitive comes from (shared by the source's cases).
    pub source: Rc<str>,
    /// Ray origin as sent.
    pub origin: DVec3,
    /// Ray direction as sent (unit length to 7 digits).
    pub dir: DVec3,
    /// The right answers.
    pub expect: Expect,
}

/// A scene primitive the battery is built from.
#[derive(Debug, Clone, PartialEq)]
pub struct Source {
    /// Its geometry.
    pub shape: Shape,
    /// Where it comes from, for the report.
    pub name: Rc<str>,
}

/// The scene's primitives: every plane, sphere and triangle, and `mesh_triangles` triangles of
/// each mesh, spread evenly over it. Degenerate triangles are skipped.
pub fn sources(file: &SceneFile, mesh_triangles: usize) -> Vec<Source> {
    let mut out = Vec::new();
    for e in &file.entities {
        let name = format!("\"{}\" (line {})", e.name, e.line);
        match &e.shape {
            SceneShape::Plane { point, normal } => out.push(Source {
                shape: Shape::Plane {
                    point: nice_v(*point),
                    normal: nice_dir(*normal),
                },
                name: name.as_str().into(),
            }),
            SceneShape::Sphere { center, radius } => out.push(Source {
                shape: Shape::Sphere {
                    center: nice_v(*center),
                    radius: nice(*radius),
                },
                name: name.as_str().into(),
            }),
            SceneShape::Triangle { vertices } => {
                let v = vertices.map(nice_v);
                if !degenerate(&v) {
                    out.push(Source {
                        shape: Shape::Triangle { v },
                        name: name.as_str().into(),
                    });
                }
            }
            SceneShape::Mesh { mesh, .. } => {
                let n = mesh.triangles.len();
                let take = mesh_triangles.min(n);
                for k in 0..take {
                    let i = k * n / take;
                    let tri = &mesh.triangles[i];
                    let v = tri.positions.map(|p| nice_v(mesh.positions[p as usize].as_dvec3()));
                    if !degenerate(&v) {
                        out.push(Source {
                            shape: Shape::Triangle { v },
                            name: format!("triangle {} of {name}", i + 1).into(),
                        });
                    }
                }
            }
        }
    }
    out
}

/// How many requests [`sources`] and [`battery`] make at most for `file` (degenerate triangles,
/// which are skipped, are counted), and of how many primitives: counted without building them.
pub fn request_bound(file: &SceneFile, mesh_triangles: usize, per_case: usize) -> (u64, u64) {
    let mut primitives = 0u64;
    let mut requests = 0u64;
    for e in &file.entities {
        let (kind, n) = match &e.shape {
            SceneShape::Plane { .. } => (PrimKind::Plane, 1),
            SceneShape::Sphere { .. } => (PrimKind::Sphere, 1),
            SceneShape::Triangle { .. } => (PrimKind::Triangle, 1),
            SceneShape::Mesh { mesh, .. } => (PrimKind::Triangle, mesh_triangles.min(mesh.triangles.len())),
        };
        let n = n as u64;
        primitives = primitives.saturating_add(n);
        let each = (cases_for(kind).len() as u64).saturating_mul(per_case as u64);
        requests = requests.saturating_add(n.saturating_mul(each));
    }
    (requests, primitives)
}

fn degenerate(v: &[DVec3; 3]) -> bool {
    let n = (v[1] - v[0]).cross(v[2] - v[0]);
    n.length_squared() <= 0.0 || !n.is_finite()
}

/// `x` rounded to 7 significant digits (short to print, within f32 rounding of `x`).
pub fn nice(x: f64) -> f64 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    format!("{x:.6e}").parse().unwrap_or(x)
}

fn nice_v(v: DVec3) -> DVec3 {
    DVec3::new(nice(v.x), nice(v.y), nice(v.z))
}

fn nice_dir(d: DVec3) -> DVec3 {
    nice_v(d.normalize())
}

/// Uniform random numbers for one primitive and case.
struct Dice(Rng);

impl Dice {
    fn u(&mut self) -> f64 {
        f64::from(self.0.next_f32())
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.u()
    }
    fn unit(&mut self) -> DVec3 {
        let z = 2.0 * self.u() - 1.0;
        let phi = std::f64::consts::TAU * self.u();
        let s = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(s * phi.cos(), s * phi.sin(), z)
    }
    /// A point in the ball of radius `r`.
    fn ball(&mut self, r: f64) -> DVec3 {
        self.unit() * r * self.u().cbrt()
    }
    /// A unit vector perpendicular to the unit vector `n`.
    fn perpendicular(&mut self, n: DVec3) -> DVec3 {
        loop {
            let p = n.cross(self.unit());
            if p.length_squared() > 1e-4 {
                return p.normalize();
            }
        }
    }
    /// A unit vector perpendicular to `n`, exactly so when `n` lies along an axis.
    fn parallel_to_plane(&mut self, n: DVec3) -> DVec3 {
        let a = n.abs();
        let zeros = [a.x, a.y, a.z].iter().filter(|c| **c == 0.0).count();
        if zeros == 2 {
            loop {
                let mut d = self.unit();
                if a.x > 0.0 {
                    d.x = 0.0;
                } else if a.y > 0.0 {
                    d.y = 0.0;
                } else {
                    d.z = 0.0;
                }
                if d.length_squared() > 1e-2 {
                    return nice_dir(d);
                }
            }
        }
        nice_dir(self.perpendicular(n))
    }
    /// A direction in the hemisphere around the unit vector `n`, at least 6° from its rim.
    fn hemisphere(&mut self, n: DVec3) -> DVec3 {
        loop {
            let d = self.unit();
            let c = d.dot(n);
            if c.abs() > 0.1 {
                return if c > 0.0 { d } else { -d };
            }
        }
    }
    /// Barycentric weights of a random point well inside a triangle (each at least `min`).
    fn interior(&mut self, min: f64) -> [f64; 3] {
        let (a, b) = (self.u(), self.u());
        let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
        let w = [1.0 - a - b, a, b];
        let k = 1.0 - 3.0 * min;
        w.map(|x| min + k * x)
    }
    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[((self.u() * items.len() as f64) as usize).min(items.len() - 1)]
    }
}

/// The battery for one primitive: `per_case` rays of every case its kind gets.
pub fn battery(src: &Source, index: usize, per_case: usize, seed: u64) -> Vec<Case> {
    let mut out = Vec::new();
    for (ci, &case) in cases_for(src.shape.kind()).iter().enumerate() {
        let mut dice = Dice(Rng::for_sample(seed, index as u64, ci as u64));
        let scale = match case {
            CaseKind::Tiny => Some(1e-4),
            CaseKind::Huge => Some(1e3),
            _ => None,
        };
        let base = match (scale, src.shape.kind()) {
            (None, _) => case,
            (Some(_), PrimKind::Sphere) => CaseKind::OutsideHit,
            (Some(_), _) => CaseKind::FrontHit,
        };
        for _ in 0..per_case {
            let (shape, origin, dir) = match src.shape {
                Shape::Sphere { center, radius } => sphere_ray(&mut dice, base, center, radius),
                Shape::Plane { point, normal } => plane_ray(&mut dice, base, point, normal),
                Shape::Triangle { v } => triangle_ray(&mut dice, base, v),
            };
            let (shape, origin) = match scale {
                None => (shape, origin),
                Some(k) => (
                    match shape {
                        Shape::Sphere { center, radius } => Shape::Sphere {
                            center: nice_v(center * k),
                            radius: nice(radius * k),
                        },
                        Shape::Plane { point, normal } => Shape::Plane {
                            point: nice_v(point * k),
                            normal,
                        },
                        Shape::Triangle { v } => Shape::Triangle {
                            v: v.map(|p| nice_v(p * k)),
                        },
                    },
                    origin * k,
                ),
            };
            let (origin, dir) = (nice_v(origin), nice_dir(dir));
            out.push(Case {
                case,
                shape,
                source: src.name.clone(),
                origin,
                dir,
                expect: expect(&shape, origin, dir),
            });
        }
    }
    out
}

fn sphere_ray(dice: &mut Dice, case: CaseKind, c: DVec3, r: f64) -> (Shape, DVec3, DVec3) {
    use CaseKind::*;
    let shape = |r: f64| Shape::Sphere { center: c, radius: r };
    let aimed = |dice: &mut Dice, r: f64, dist: f64| {
        let o = c + dice.unit() * dist * r;
        let target = c + dice.ball(0.8 * r);
        (o, target - o)
    };
    // A line whose nearest point to the centre is k·r away, ahead of the origin.
    let beside = |dice: &mut Dice, k: f64| {
        let w = dice.unit();
        let d = dice.perpendicular(w);
        let q = c + w * k * r;
        (q - d * dice.range(2.0, 6.0) * r, d)
    };
    match case {
        OutsideHit => {
            let d = dice.range(2.0, 6.0);
            let (o, d) = aimed(dice, r, d);
            (shape(r), o, d)
        }
        OutsideMiss => {
            let k = dice.range(1.2, 2.0);
            let (o, d) = beside(dice, k);
            (shape(r), o, d)
        }
        Behind => {
            let d = dice.range(2.0, 6.0);
            let (o, d) = aimed(dice, r, d);
            (shape(r), o, -d)
        }
        Inside => (shape(r), c + dice.ball(0.7 * r), dice.unit()),
        Centre => (shape(r), c, dice.unit()),
        Grazing => {
            let k = if dice.u() < 0.5 { 1.0 - 1e-3 } else { 1.0 + 1e-3 };
            let (o, d) = beside(dice, k);
            (shape(r), o, d)
        }
        Tangent => {
            let (o, d) = beside(dice, 1.0);
            (shape(r), o, d)
        }
        SurfaceOut | SurfaceIn => {
            let n = dice.unit();
            let h = dice.hemisphere(n);
            (shape(r), c + n * r, if case == SurfaceOut { h } else { -h })
        }
        Near => {
            let n = dice.unit();
            let o = c + n * r * 1.01;
            (shape(r), o, -n + dice.perpendicular(n) * dice.range(0.0, 0.3))
        }
        Far => {
            let (o, d) = aimed(dice, r, 200.0);
            (shape(r), o, d)
        }
        _ => unreachable!("not a sphere case"),
    }
}

fn plane_ray(dice: &mut Dice, case: CaseKind, p: DVec3, n: DVec3) -> (Shape, DVec3, DVec3) {
    use CaseKind::*;
    let shape = Shape::Plane { point: p, normal: n };
    let t1 = dice.perpendicular(n);
    let t2 = n.cross(t1);
    let on_plane = |dice: &mut Dice, s: f64| p + (t1 * dice.range(-2.0, 2.0) + t2 * dice.range(-2.0, 2.0)) * s;
    let q = on_plane(dice, 1.0);
    // From `side` (+1 the front, −1 the back) at a height from `lo` to `hi`, aimed at a point
    // of the plane up to 2·`s` away.
    let toward = |dice: &mut Dice, lo: f64, hi: f64, side: f64, s: f64| {
        let o = q + n * side * dice.range(lo, hi);
        let target = q + (t1 * dice.range(-2.0, 2.0) + t2 * dice.range(-2.0, 2.0)) * s;
        (o, target - o)
    };
    let (o, d) = match case {
        FrontHit => toward(dice, 0.5, 3.0, 1.0, 1.0),
        BackHit => toward(dice, 0.5, 3.0, -1.0, 1.0),
        Away => {
            let side = if dice.u() < 0.5 { 1.0 } else { -1.0 };
            let (o, d) = toward(dice, 0.5, 3.0, side, 1.0);
            (o, -d)
        }
        Parallel => {
            let side = if dice.u() < 0.5 { 1.0 } else { -1.0 };
            (q + n * side * dice.range(0.5, 3.0), dice.parallel_to_plane(n))
        }
        InPlane => (q, dice.parallel_to_plane(n)),
        Grazing => {
            let o = q + n * dice.range(0.05, 0.2);
            (o, dice.perpendicular(n) - n * 1e-3)
        }
        SurfaceOut => (
            on_plane(dice, 1.0),
            dice.hemisphere(n) * if dice.u() < 0.5 { 1.0 } else { -1.0 },
        ),
        Near => toward(dice, 0.01, 0.02, 1.0, 0.01),
        Far => toward(dice, 200.0, 400.0, 1.0, 100.0),
        _ => unreachable!("not a plane case"),
    };
    (shape, o, d)
}

fn triangle_ray(dice: &mut Dice, case: CaseKind, v: [DVec3; 3]) -> (Shape, DVec3, DVec3) {
    use CaseKind::*;
    let shape = Shape::Triangle { v };
    let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
    let size = (v[1] - v[0])
        .length()
        .max((v[2] - v[1]).length())
        .max((v[0] - v[2]).length());
    let at = |v: &[DVec3; 3], w: [f64; 3]| v[0] * w[0] + v[1] * w[1] + v[2] * w[2];
    // A ray from `side` (+1 the front, −1 the back) at distance `h`, aimed at `target`.
    let from_side = |dice: &mut Dice, target: DVec3, side: f64, h: f64| {
        let o = target + (n + dice.perpendicular(n) * dice.range(0.0, 0.5)).normalize() * side * h;
        (o, target - o)
    };
    // Weights of a point on the triangle's plane whose weight `i` is `wi`.
    let with_weight = |dice: &mut Dice, wi: f64| {
        let i = dice.pick(&[0usize, 1, 2]);
        let s = dice.range(0.1, 0.9);
        let mut w = [0.0; 3];
        w[i] = wi;
        w[(i + 1) % 3] = (1.0 - wi) * s;
        w[(i + 2) % 3] = (1.0 - wi) * (1.0 - s);
        w
    };
    // Straight at `b` against the normal, from the front. When the triangle lies in an axis
    // plane the normal is an axis and every operation on the numbers is exact, so the ray meets
    // the edge or corner exactly.
    let straight_at = |dice: &mut Dice, b: DVec3| {
        // A power of two near the triangle's size keeps the origin's coordinate exact.
        let h = 2f64.powi(size.log2().round() as i32) * dice.pick(&[0.5, 1.0, 1.5]);
        (b + n * h, -n)
    };
    match case {
        FrontHit | BackHit => {
            let target = at(&v, dice.interior(0.1));
            let side = if case == FrontHit { 1.0 } else { -1.0 };
            let h = dice.range(0.5, 2.0) * size;
            let (o, d) = from_side(dice, target, side, h);
            (shape, o, d)
        }
        OutsideMiss => {
            let w = dice.range(-0.5, -0.05);
            let target = at(&v, with_weight(dice, w));
            let side = if dice.u() < 0.5 { 1.0 } else { -1.0 };
            let h = dice.range(0.5, 2.0) * size;
            let (o, d) = from_side(dice, target, side, h);
            (shape, o, d)
        }
        NearEdgeIn | NearEdgeOut => {
            let w = if case == NearEdgeIn { 1e-3 } else { -1e-3 };
            let target = at(&v, with_weight(dice, w));
            let h = dice.range(0.5, 2.0) * size;
            let (o, d) = from_side(dice, target, 1.0, h);
            (shape, o, d)
        }
        Edge => {
            let i = dice.pick(&[0usize, 1, 2]);
            let s = dice.pick(&[0.25, 0.5, 0.75]);
            let (a, b) = (v[(i + 1) % 3], v[(i + 2) % 3]);
            let (o, d) = straight_at(dice, a + (b - a) * s);
            (shape, o, d)
        }
        Vertex => {
            let corner = v[dice.pick(&[0usize, 1, 2])];
            let (o, d) = straight_at(dice, corner);
            (shape, o, d)
        }
        Parallel => {
            let side = if dice.u() < 0.5 { 1.0 } else { -1.0 };
            let o = at(&v, dice.interior(0.1)) + n * side * dice.range(0.1, 1.0) * size;
            let o = o - dice.parallel_to_plane(n) * size;
            (shape, o, dice.parallel_to_plane(n))
        }
        Behind => {
            let target = at(&v, dice.interior(0.1));
            let h = dice.range(0.5, 2.0) * size;
            let (o, d) = from_side(dice, target, 1.0, h);
            (shape, o, -d)
        }
        Grazing => {
            let target = at(&v, dice.interior(0.2));
            let d = dice.perpendicular(n) - n * 1e-3;
            (shape, target - d * 0.5 * size, d)
        }
        SurfaceOut => {
            let o = at(&v, dice.interior(0.1));
            let side = if dice.u() < 0.5 { 1.0 } else { -1.0 };
            (shape, o, dice.hemisphere(n) * side)
        }
        Near => {
            let target = at(&v, dice.interior(0.1));
            let h = dice.range(0.01, 0.02) * size;
            let (o, d) = from_side(dice, target, 1.0, h);
            (shape, o, d)
        }
        Far => {
            let target = at(&v, dice.interior(0.1));
            let (o, d) = from_side(dice, target, 1.0, 200.0 * size);
            (shape, o, d)
        }
        _ => unreachable!("not a triangle case"),
    }
}

/// How the true normal at a hit is found.
enum NormalRule {
    /// The same everywhere (planes, triangles).
    Fixed(DVec3),
    /// From the sphere's centre to the point.
    FromCentre(DVec3),
}

/// How a ray meets a primitive, on the numbers as sent.
struct Crossing {
    /// The ray's roots against the surface, sorted, in units of `d`.
    roots: Vec<f64>,
    /// Whether the ray's line meets the primitive at all.
    inside: bool,
    /// Whether it passes within rounding of the primitive's rim or an edge.
    near_boundary: bool,
    normal_rule: NormalRule,
    /// How much the division by the cosine of the angle of incidence magnifies rounding in t.
    cond: f64,
    /// Whether any hit (or none) is right: a ray in the surface's own plane.
    any_hit_ok: bool,
}

/// Where `o + t d` meets `shape` (see [`Crossing`]), by the oracle's tests.
fn crossing(shape: &Shape, o: DVec3, d: DVec3, tie_tol: f64) -> Crossing {
    // The oracle works along a unit direction; t as sent is in units of `d`.
    let len = d.length();
    let u = d / len;
    let mut cond = 1.0;
    let mut any_hit_ok = false;
    let (roots, inside, near_boundary, normal_rule) = match *shape {
        Shape::Sphere { center, radius } => {
            let margin = rim_margin(center, radius, o, u);
            let along = (center - o).dot(u);
            let near = hit_sphere(center, radius, o, u, f64::NEG_INFINITY, f64::INFINITY);
            let far = near.and_then(|t0| hit_sphere(center, radius, o, u, t0.max(along), f64::INFINITY));
            let roots: Vec<f64> = match (near, far) {
                (Some(t0), Some(t1)) => vec![t0 / len, t1 / len],
                (Some(t0), None) => vec![t0 / len],
                // The tangent point, for a tie that a student reports as a hit.
                _ => vec![along / len],
            };
            let closest = o + u * along;
            let tie = is_tie(margin, tie_tol, magnitude(&[o, closest]));
            (roots, margin >= 0.0, tie, NormalRule::FromCentre(center))
        }
        Shape::Plane { point, normal } => {
            let den = u.dot(normal);
            let n = normal.normalize();
            match hit_plane(point, normal, o, u, f64::NEG_INFINITY, f64::INFINITY) {
                None => {
                    if (point - o).dot(normal) == 0.0 {
                        any_hit_ok = true;
                    }
                    (vec![], false, false, NormalRule::Fixed(n))
                }
                Some(t) if den.abs() < 1e-6 => {
                    any_hit_ok = true;
                    (vec![t / len], true, true, NormalRule::Fixed(n))
                }
                Some(t) => {
                    cond = 1.0 / den.abs();
                    (vec![t / len], true, false, NormalRule::Fixed(n))
                }
            }
        }
        Shape::Triangle { v } => {
            let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
            let n = e1.cross(e2).normalize();
            // Möller and Trumbore's determinant over its largest value: how well the ray's
            // crossing is conditioned in a tracer that uses it.
            let rel_det = e1.cross(e2).dot(u).abs() / (e1.length() * e2.length());
            cond = 1.0 / rel_det;
            match OracleRay::new(o, u).triangle_weights(&v) {
                Some((w, t)) if rel_det >= 1e-7 => {
                    let margin = w[0].min(w[1]).min(w[2]);
                    // Each weight is the point's distance from the opposite edge over the
                    // altitude onto it: the distance to the nearest edge's line, in scene units.
                    let area2 = e1.cross(e2).length();
                    let dist = (0..3)
                        .map(|k| (w[k] * area2 / (v[(k + 2) % 3] - v[(k + 1) % 3]).length()).abs())
                        .fold(f64::INFINITY, f64::min);
                    let p = o + u * t;
                    // Exactly on the boundary, in real arithmetic on the numbers sent, is no
                    // tie: a miss there is the inside test's, not rounding's.
                    let exact = (0..3).any(|k| w[k] == 0.0 && meets_edge_exactly(o, d, v[(k + 1) % 3], v[(k + 2) % 3]));
                    let tie = !exact && is_tie(dist, tie_tol, magnitude(&[o, p]));
                    (vec![t / len], margin >= 0.0, tie, NormalRule::Fixed(n))
                }
                _ => {
                    if rel_det != 0.0 || (o - v[0]).dot(n) == 0.0 {
                        any_hit_ok = true;
                    }
                    (vec![], false, false, NormalRule::Fixed(n))
                }
            }
        }
    };
    Crossing {
        roots,
        inside,
        near_boundary,
        normal_rule,
        cond,
        any_hit_ok,
    }
}

/// The right answers for a ray, on the numbers as sent: where it meets the primitive is the
/// oracle's (`hit_sphere`, `hit_plane`, the watertight triangle test), and whether it passes
/// within rounding of a rim or an edge, so that a miss and a hit are both right, is the log
/// checker's rule ([`crate::tie`]). The tolerances on t, the point and the normal admit a
/// tracer computing in f32.
pub fn expect(shape: &Shape, o: DVec3, d: DVec3) -> Expect {
    let size = match *shape {
        Shape::Sphere { radius, .. } => radius,
        Shape::Plane { .. } => 1.0,
        Shape::Triangle { v } => (v[1] - v[0])
            .length()
            .max((v[2] - v[1]).length())
            .max((v[0] - v[2]).length()),
    };
    let feature = match *shape {
        Shape::Sphere { center, .. } => center,
        Shape::Plane { point, .. } => point,
        Shape::Triangle { v } => v[0],
    };
    // What rounding to f32 can move a coordinate by, and what that does to t.
    let rounding = 8.0 * EPS32 * (o.length() + feature.length());
    let mut e = Expect {
        hit: None,
        miss_ok: false,
        at_origin_ok: false,
        any_hit_ok: false,
        tie: false,
        other_t: None,
        tol: 0.0,
        zero: 0.0,
        normal_tol: 0.0,
    };
    let tie_tol = Tolerances::default().tie;
    let Crossing {
        roots,
        inside,
        near_boundary,
        normal_rule,
        cond,
        any_hit_ok,
    } = crossing(shape, o, d, tie_tol);
    e.any_hit_ok = any_hit_ok;
    // A ray leaving a surface at a shallow angle meets it again within rounding over the sine.
    let zero = 1e-5 * size + rounding * cond.min(1e3);
    e.zero = zero;
    let near_t = roots.iter().copied().find(|t| *t > zero);
    let at_origin = roots.iter().any(|t| t.abs() <= zero);
    e.at_origin_ok = at_origin && inside;
    let hit64 = if inside { near_t } else { None };
    let tie = near_boundary;
    e.tie = tie;
    let truth_t = hit64.or(if tie { near_t } else { None });
    e.hit = truth_t.map(|t| {
        let point = o + d * t;
        Truth {
            t,
            point,
            normal: match normal_rule {
                NormalRule::Fixed(n) => n,
                NormalRule::FromCentre(c) => (point - c).normalize(),
            },
        }
    });
    e.miss_ok = hit64.is_none() || tie || e.any_hit_ok;
    if roots.len() == 2 {
        e.other_t = truth_t.and_then(|t| roots.iter().copied().find(|r| *r != t));
    }
    let t_mag = truth_t.map_or(0.0, f64::abs);
    // A tracer in f32 rounds the coordinates by `rounding`, which moves the crossing along the
    // ray by that over the sine of the angle of incidence, and t by its own relative rounding.
    let mut tol = 1e-4 * (size + t_mag) + (rounding + 8.0 * EPS32 * t_mag) * cond.min(1e6);
    if tie {
        // Near a rim t moves with the square root of the distance from it.
        tol += 4.0 * size * (2.0 * tie_tol * magnitude(&[o, feature]).max(size) / size).sqrt();
    }
    e.tol = tol;
    e.normal_tol = 1e-3 + 2.0 * tol / size;
    e
}

/// True when the line `o + t d`, with `d` along a coordinate axis, meets the line through `a`
/// and `b` exactly, in real arithmetic on these numbers. The battery's edge and corner rays are
/// built so on triangles in an axis plane; where the scene's numbers are not exact in binary
/// the ray passes within rounding of the edge instead, and that is a tie.
fn meets_edge_exactly(o: DVec3, d: DVec3, a: DVec3, b: DVec3) -> bool {
    let axes: Vec<usize> = (0..3).filter(|&k| d[k] != 0.0).collect();
    let &[axis] = axes.as_slice() else {
        return false;
    };
    let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
    // x − y, where it is exact (Knuth's two-sum leaves no error).
    let diff = |x: f64, y: f64| {
        let s = x - y;
        let back = s - x;
        ((x - (s - back)) + (-y - back) == 0.0).then_some(s)
    };
    let (Some(ax), Some(ay), Some(bx), Some(by)) =
        (diff(a[i], o[i]), diff(a[j], o[j]), diff(b[i], o[i]), diff(b[j], o[j]))
    else {
        return false;
    };
    // The cross product of the two differences in the plane across the ray: zero with both
    // products exact.
    let (p, q) = (ax * by, ay * bx);
    ax.mul_add(by, -p) == 0.0 && ay.mul_add(bx, -q) == 0.0 && p == q
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere() -> Shape {
        Shape::Sphere {
            center: DVec3::new(0.0, 0.0, 5.0),
            radius: 1.0,
        }
    }

    #[test]
    fn sphere_expectations() {
        let e = expect(&sphere(), DVec3::ZERO, DVec3::Z);
        assert!(!e.miss_ok && (e.hit.unwrap().t - 4.0).abs() < 1e-12);
        assert_eq!(e.other_t, Some(6.0));
        let inside = expect(&sphere(), DVec3::new(0.0, 0.0, 5.0), DVec3::Y);
        assert!((inside.hit.unwrap().t - 1.0).abs() < 1e-12 && !inside.miss_ok);
        let behind = expect(&sphere(), DVec3::ZERO, -DVec3::Z);
        assert!(behind.hit.is_none() && behind.miss_ok);
        let tangent = expect(&sphere(), DVec3::new(1.0, 0.0, 0.0), DVec3::Z);
        assert!(tangent.tie && tangent.miss_ok && tangent.hit.is_some(), "{tangent:?}");
    }

    #[test]
    fn triangle_edge_through_axis_aligned_wall_is_strict() {
        // The course's left wall; a ray along +x through the middle of its first edge.
        let t = Shape::Triangle {
            v: [
                DVec3::new(-1.0, -1.0, 0.0),
                DVec3::new(-1.0, 1.0, 0.0),
                DVec3::new(-1.0, 1.0, 3.0),
            ],
        };
        let e = expect(&t, DVec3::new(0.0, 0.0, 0.0), DVec3::new(-1.0, 0.0, 0.0));
        assert!(!e.tie && !e.miss_ok, "{e:?}");
        let beside = expect(&t, DVec3::new(0.0, 0.0, -0.5), DVec3::new(-1.0, 0.0, 0.0));
        assert!(beside.hit.is_none() && beside.miss_ok);
    }

    #[test]
    fn an_edge_ray_is_strict_only_where_it_meets_the_edge_exactly() {
        // Our room's right wall: 0.65, 2.4 and 1.1 are not exact in binary, so the ray through
        // the middle of the diagonal decimal edge passes within rounding of it, and a correct
        // double-precision intersector may miss it.
        let wall = Shape::Triangle {
            v: [
                DVec3::new(1.1, -1.0, -0.6),
                DVec3::new(1.1, 1.2, 3.4),
                DVec3::new(1.1, 1.2, -0.6),
            ],
        };
        let e = expect(&wall, DVec3::new(-0.9, 0.65, 2.4), DVec3::X);
        assert!(e.tie && e.miss_ok && e.hit.is_some(), "{e:?}");
        // The same on a wall whose numbers are exact: a hit is required.
        let exact = Shape::Triangle {
            v: [
                DVec3::new(1.0, -1.0, -0.5),
                DVec3::new(1.0, 1.0, 3.5),
                DVec3::new(1.0, 1.0, -0.5),
            ],
        };
        let e = expect(&exact, DVec3::new(-1.0, 0.5, 2.5), DVec3::X);
        assert!(!e.tie && e.hit_required(), "{e:?}");
    }

    #[test]
    fn ties_are_the_log_checkers_and_relative_to_the_coordinates() {
        // 1e-5 inside the rim of a unit sphere five units away: within 1e-4 of the coordinates.
        let e = expect(&sphere(), DVec3::new(1.0 - 1e-5, 0.0, 0.0), DVec3::Z);
        assert!(e.tie && e.miss_ok, "{e:?}");
        // A ray through the middle of a sphere shrunk by 1e-4 about the origin is no tie: the
        // tolerance shrinks with the coordinates (no floor of 1 as in a course log).
        let tiny = Shape::Sphere {
            center: DVec3::new(0.0, 0.0, 5e-4),
            radius: 1e-4,
        };
        let e = expect(&tiny, DVec3::ZERO, DVec3::Z);
        assert!(!e.tie && e.hit_required(), "{e:?}");
        assert!((e.hit.unwrap().t - 4e-4).abs() < 1e-12);
        // A tie never excuses a hit clearly behind the origin.
        let tangent = expect(&sphere(), DVec3::new(1.0, 0.0, 0.0), DVec3::Z);
        let case = Case {
            case: CaseKind::Tangent,
            shape: sphere(),
            source: "test".into(),
            origin: DVec3::new(1.0, 0.0, 0.0),
            dir: DVec3::Z,
            expect: tangent,
        };
        let behind = crate::probe::judge::Answer::Hit {
            t: Some(-5.0),
            point: None,
            normal: None,
        };
        assert!(tangent.tie);
        assert_eq!(
            crate::probe::judge::judge(&case, &behind).verdicts,
            vec![crate::probe::judge::Verdict::BehindOrigin]
        );
    }

    #[test]
    fn plane_parallel_is_a_strict_miss_and_in_plane_anything() {
        let p = Shape::Plane {
            point: DVec3::new(0.0, -1.0, 0.0),
            normal: DVec3::Y,
        };
        let e = expect(&p, DVec3::ZERO, DVec3::X);
        assert!(e.hit.is_none() && e.miss_ok && !e.any_hit_ok);
        let e = expect(&p, DVec3::new(0.0, -1.0, 0.0), DVec3::X);
        assert!(e.any_hit_ok);
    }

    #[test]
    fn every_case_of_the_course_scenes_is_labelled_truthfully() {
        // The generator's intent and the oracle agree: hit cases expect hits, miss cases misses.
        use CaseKind::*;
        let mut scenes = vec![
            rayscope_testkit::scene("basic.txt"),
            rayscope_testkit::scene("room.txt"),
        ];
        if let Some(course) = rayscope_testkit::course_part() {
            scenes.extend(["sample_scene_1.txt", "sample_scene_2.txt"].map(|s| course.scene(s)));
        }
        for path in scenes {
            let file = rayscope_scene::load(&path).expect("scene");
            for (i, s) in sources(&file, 4).iter().enumerate() {
                for c in battery(s, i, 20, 1) {
                    let e = &c.expect;
                    match c.case {
                        OutsideHit | FrontHit | BackHit | Inside | Centre | SurfaceIn | Near | Far | Tiny | Huge
                        | NearEdgeIn => {
                            assert!(e.hit_required(), "{c:?}")
                        }
                        OutsideMiss | Behind | Away | NearEdgeOut | Parallel => {
                            assert!(e.hit.is_none() || e.any_hit_ok, "{c:?}")
                        }
                        SurfaceOut => assert!(e.miss_ok, "{c:?}"),
                        Edge | Vertex => assert!(e.hit.is_some(), "{c:?}"),
                        Tangent => assert!(e.tie, "{c:?}"),
                        Grazing | InPlane => {}
                    }
                }
            }
        }
    }
}
