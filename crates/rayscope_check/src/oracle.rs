//! The checker's own answers, in double precision, written to be read against the course's
//! rules (`shared/reference/README.md`): which surface a ray meets first, where and with which
//! normal, and where the camera ray of a pixel sample goes. Nothing here calls rayscope's
//! renderer (its f32 BVH, intersection or camera), so the renderer and the checker check each
//! other: `tests/oracle.rs` holds them to the same answers.
//!
//! **Geometry.** The scene's numbers as rayscope stores them (f32, rounded once from the file):
//! infinite planes, spheres, and triangles, OBJ meshes included (their z already negated and
//! scaled then offset by the scene loader, as the course does). Every surface counts from both
//! sides. A triangle's own normal is (v1 − v0) × (v2 − v0), normalised; a sphere's points away
//! from its centre; a plane's is the file's.
//!
//! **Visibility.** The closest hit with `t_min < t < t_max`, by a bounding volume hierarchy over
//! spheres and triangles (planes, being infinite, are tested on every ray); a scene of at most
//! 24 spheres and triangles has every one tested on every ray instead, four triangles at a time,
//! and the hierarchy decides only between two met at the same distance. Triangles are met by
//! the watertight test of Woop, Benthin and Wald (2013): a ray through an edge two triangles share
//! meets at least one of them, whatever the rounding. [`Oracle::near_boundary`] says how close a
//! ray comes to a different answer (an edge, a rim, a second surface at the same depth).
//!
//! **Camera.** Left-handed, at `--cam-pos`, looking along +z turned by Rodrigues' rotation about
//! `--cam-axis` by `--cam-angle`; image plane at distance 1 spanning the field of view along the
//! `--fov-axis` side; sample `s` of pixel (x, y) through ((x + (i + 0.5)/N)/W, (y + (j + 0.5)/N)/H)
//! with (i, j) = (s mod N, s div N) of the `-x N` grid (taken modulo N² when `-q` repeats it),
//! row 0 at the top.

use glam::{DMat3, DVec3};
use rayscope_core::geometry::Triangle;
use rayscope_core::scene::PrimRef;
use rayscope_core::{Channel, FovAxis, RenderSettings, Scene, Stage};
use wide::{f64x2, f64x4};

/// The corners of a triangle as the scene file gave them. The scene keeps a corner and two
/// edges in f32; the other corners are put back on the f32 grid the file's coordinates were
/// rounded to, so that a corner two triangles share is the same number in both (which the
/// watertight test needs).
#[must_use]
pub fn corners(t: &Triangle) -> [DVec3; 3] {
    let v0 = t.v0().as_dvec3();
    let snap = |v: DVec3| v.as_vec3().as_dvec3();
    [v0, snap(v0 + t.e1().as_dvec3()), snap(v0 + t.e2().as_dvec3())]
}

/// The nearest `t` with `t_min < t < t_max` at which `o + t d` meets the plane through `point`
/// with normal `normal` (any length); `None` for a ray parallel to it.
#[must_use]
#[inline]
pub fn hit_plane(point: DVec3, normal: DVec3, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
    let den = normal.dot(d);
    if den == 0.0 {
        return None;
    }
    let t = (point - o).dot(normal) / den;
    (t > t_min && t < t_max).then_some(t)
}

/// The nearest `t` with `t_min < t < t_max` at which `o + t d` (unit `d`) meets the sphere,
/// from outside or inside.
#[must_use]
#[inline]
pub fn hit_sphere(center: DVec3, radius: f64, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<f64> {
    let f = o - center;
    let b = -f.dot(d);
    // The discriminant from the ray's closest approach to the centre, not from b² − c: it keeps
    // its precision for rays that pass far from a small sphere (Ray Tracing Gems, ch. 7).
    let l = f + d * b;
    let disc = radius * radius - l.length_squared();
    if disc < 0.0 {
        return None;
    }
    let q = disc.sqrt();
    let (t0, t1) = (b - q, b + q);
    if t0 > t_min && t0 < t_max {
        Some(t0)
    } else {
        (t1 > t_min && t1 < t_max).then_some(t1)
    }
}

/// How far from the rim of the sphere (`center`, `radius`) the line `o + t d` (unit `d`) passes:
/// the radius less the line's distance from the centre, positive where it goes through the
/// sphere.
#[must_use]
pub fn rim_margin(center: DVec3, radius: f64, o: DVec3, d: DVec3) -> f64 {
    let f = center - o;
    radius - (f - d * f.dot(d)).length()
}

/// A ray prepared for the watertight triangle test and the box test.
#[derive(Debug, Clone, Copy)]
pub struct OracleRay {
    /// Origin.
    pub o: DVec3,
    /// Unit direction.
    pub d: DVec3,
    /// The direction as an array, indexed by axis without a match per access.
    da: [f64; 3],
    /// Origin and reciprocal direction in the lanes of the box test; the fourth lane (the
    /// origin's z again, reciprocal 1) meets the fourth lane of every box, which spans everything.
    o4: f64x4,
    inv4: f64x4,
    /// The direction's largest axis, and the two others (in the order that keeps winding).
    k: [usize; 3],
    /// Shear that maps the direction to (0, 0, 1).
    s: DVec3,
}

impl OracleRay {
    /// The children of inner `node`, the one this ray meets first along the node's split axis
    /// first (the lower one for a direction of +0 or NaN there).
    #[inline]
    fn near_far(&self, node: &Node) -> (u32, u32) {
        if self.da[usize::from(node.axis)] >= 0.0 {
            (node.first, node.first + 1)
        } else {
            (node.first + 1, node.first)
        }
    }

    /// Prepares `o + t d`; `d` must be a unit vector.
    #[must_use]
    pub fn new(o: DVec3, d: DVec3) -> Self {
        let a = d.abs();
        let kz = if a.x >= a.y && a.x >= a.z {
            0
        } else if a.y >= a.z {
            1
        } else {
            2
        };
        let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self {
            o,
            d,
            da: d.to_array(),
            o4: f64x4::new([o.x, o.y, o.z, o.z]),
            inv4: f64x4::new([1.0 / d.x, 1.0 / d.y, 1.0 / d.z, 1.0]),
            k: [kx, ky, kz],
            s: DVec3::new(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]),
        }
    }

    /// The distance at which the ray meets the triangle with corners `v`, either side, with
    /// `t_min < t < t_max` (Woop, Benthin and Wald's watertight test).
    #[must_use]
    #[inline]
    pub fn triangle(&self, v: &[DVec3; 3], t_min: f64, t_max: f64) -> Option<f64> {
        let ([u, v, w], z) = self.sheared(v);
        if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + v + w;
        if det == 0.0 {
            return None;
        }
        let tz = u * z[0] + v * z[1] + w * z[2];
        let t = tz * self.s.z / det;
        (t > t_min && t < t_max).then_some(t)
    }

    /// [`Self::triangle`] for the four triangles of `q`, lane by lane the same arithmetic: each
    /// lane's `t`, or infinity where that triangle is not met in `t_min..t_max`.
    #[inline]
    fn triangles4(&self, q: &TriangleQuad, t_min: f64, t_max: f64) -> [f64; 4] {
        let [kx, ky, kz] = self.k;
        let o = self.o.to_array().map(f64x4::splat);
        let (sx, sy) = (f64x4::splat(self.s.x), f64x4::splat(self.s.y));
        let rel = |c: usize, a: usize| q.corner[c][a] - o[a];
        let shear = |c: usize| {
            let z = rel(c, kz);
            (rel(c, kx) - sx * z, rel(c, ky) - sy * z, z)
        };
        let ((ax, ay, az), (bx, by, bz), (cx, cy, cz)) = (shear(0), shear(1), shear(2));
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = f64x4::ZERO;
        let mixed = (u.simd_lt(zero) | v.simd_lt(zero) | w.simd_lt(zero))
            & (u.simd_gt(zero) | v.simd_gt(zero) | w.simd_gt(zero));
        let det = u + v + w;
        let tz = u * az + v * bz + w * cz;
        let t = tz * f64x4::splat(self.s.z) / det;
        let met = t.simd_gt(f64x4::splat(t_min)) & t.simd_lt(f64x4::splat(t_max)) & det.simd_ne(zero);
        // `mixed` is all ones in the lanes to drop, so it picks infinity there.
        let keep = met & !mixed;
        keep.select(t, f64x4::splat(f64::INFINITY)).to_array()
    }

    /// Where the ray's line crosses the plane of the triangle with corners `v`, by the same
    /// computation as [`Self::triangle`]: the barycentric weights of v0, v1 and v2 (summing to
    /// 1; all at least 0 exactly where [`Self::triangle`] hits, one exactly 0 on an edge) and
    /// `t`, whatever its sign. `None` for a ray parallel to the plane.
    #[must_use]
    pub fn triangle_weights(&self, v: &[DVec3; 3]) -> Option<([f64; 3], f64)> {
        let ([u, v, w], z) = self.sheared(v);
        let det = u + v + w;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let tz = u * z[0] + v * z[1] + w * z[2];
        Some(([u / det, v / det, w / det], tz * self.s.z / det))
    }

    /// The watertight test's scaled barycentric coordinates of the triangle `v`, and its corners'
    /// coordinates along the ray's main axis (relative to the origin).
    #[inline]
    fn sheared(&self, v: &[DVec3; 3]) -> ([f64; 3], [f64; 3]) {
        let [kx, ky, kz] = self.k;
        let (a, b, c) = (
            (v[0] - self.o).to_array(),
            (v[1] - self.o).to_array(),
            (v[2] - self.o).to_array(),
        );
        let (ax, ay) = (a[kx] - self.s.x * a[kz], a[ky] - self.s.y * a[kz]);
        let (bx, by) = (b[kx] - self.s.x * b[kz], b[ky] - self.s.y * b[kz]);
        let (cx, cy) = (c[kx] - self.s.x * c[kz], c[ky] - self.s.y * c[kz]);
        // Scaled barycentric coordinates: the signed areas the ray's point makes with each edge.
        // Each edge's value depends only on its two corners, so two triangles sharing an edge
        // compute it alike and cannot both miss a ray through it.
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        ([u, v, w], [a[kz], b[kz], c[kz]])
    }

    /// True when the ray meets the box `lo`..`hi` grown by `pad` somewhere in `t_min..=t_max`.
    #[inline]
    fn meets_box(&self, lo: f64x4, hi: f64x4, pad: f64, t_min: f64, t_max: f64) -> bool {
        let pad = f64x4::splat(pad);
        let t0 = (lo - pad - self.o4) * self.inv4;
        let t1 = (hi + pad - self.o4) * self.inv4;
        // A slab gives NaN (0 × ∞) only for a ray that runs in the plane of one of its faces;
        // the boxes are padded past their primitives, so such a ray meets none of them, and
        // whether that slab culls does not change the answer.
        let [n0, n1, n2, n3] = t0.min(t1).to_array();
        let [f0, f1, f2, f3] = t0.max(t1).to_array();
        let near = t_min.max(n0.max(n1)).max(n2.max(n3));
        let far = t_max.min(f0.min(f1)).min(f2.min(f3));
        near <= far
    }

    /// [`Self::meets_box`] without padding, for `t_min` and `t_max` that are not NaN: the same
    /// answer. No lane's bound is NaN (a slab's two bounds are NaN together only where its
    /// faces coincide, and every box is padded), so the lanes are reduced by plain comparisons.
    #[inline(always)]
    fn meets_box_exact(&self, lo: f64x4, hi: f64x4, t_min: f64, t_max: f64) -> bool {
        // `lo - 0` and `hi + 0` as in `meets_box`: the same numbers, signed zeros included.
        let zero = f64x4::ZERO;
        let t0 = (lo - zero - self.o4) * self.inv4;
        let t1 = (hi + zero - self.o4) * self.inv4;
        let [n0, n1, n2, n3] = t0.min(t1).to_array();
        let [f0, f1, f2, f3] = t0.max(t1).to_array();
        let [n0, n1] = f64x2::new([n0, n1]).fast_max(f64x2::new([n2, n3])).to_array();
        let [f0, f1] = f64x2::new([f0, f1]).fast_min(f64x2::new([f2, f3])).to_array();
        let max = |a: f64, b: f64| if a > b { a } else { b };
        let min = |a: f64, b: f64| if a < b { a } else { b };
        max(max(n0, n1), t_min) <= min(min(f0, f1), t_max)
    }
}

/// The oracle's closest hit of a ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OracleHit {
    /// The primitive hit (the scene's own indices).
    pub prim: PrimRef,
    /// Entity index (the scene's order).
    pub entity: u32,
    /// Material index.
    pub material: u32,
    /// Distance along the unit direction.
    pub t: f64,
    /// The hit point, origin + t · direction.
    pub point: DVec3,
    /// The surface's own unit normal there (outward for spheres).
    pub normal: DVec3,
    /// True when the ray arrives at the side the own normal points to.
    pub front: bool,
}

/// How close a ray comes to a different answer: the primitive and the distance, in scene units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Near {
    /// The primitive whose edge, rim or depth is that close.
    pub prim: PrimRef,
    /// Its entity.
    pub entity: u32,
    /// What is that close.
    pub kind: NearKind,
    /// The distance.
    pub margin: f64,
}

/// What lies within rounding of a ray's answer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum NearKind {
    /// A triangle's edge or corner.
    Edge,
    /// A sphere's rim (its silhouette seen along the ray).
    Rim,
    /// A plane or triangle the ray runs along, in or next to its plane.
    Along,
    /// A surface of another entity at the closest hit's depth (coinciding surfaces, or a
    /// surface meeting the hit one there).
    Depth,
    /// A surface at one of the ray's ends, `t_min` or `t_max` (a light on a surface).
    End,
}

/// A node of the oracle's hierarchy: a leaf's primitives are `refs[first..first + count]`; an
/// inner node's children are nodes `first` and `first + 1`.
#[derive(Debug, Clone, Copy)]
struct Node {
    lo: f64x4,
    hi: f64x4,
    first: u32,
    count: u32,
    axis: u8,
}

/// Spheres are tagged in [`Oracle`]'s primitive references with this bit.
const SPHERE: u32 = 1 << 31;

/// Most primitives in a leaf.
const LEAF: usize = 4;

/// The scene in double precision with its own hierarchy: the checker's visibility.
#[derive(Debug, Clone, Default)]
pub struct Oracle {
    planes: Vec<(DVec3, DVec3)>,
    spheres: Vec<(DVec3, f64)>,
    triangles: Vec<[DVec3; 3]>,
    plane_info: Vec<(u32, u32)>,
    sphere_info: Vec<(u32, u32)>,
    triangle_info: Vec<(u32, u32)>,
    nodes: Vec<Node>,
    refs: Vec<u32>,
    /// The triangles four to a group, when the scene is small enough for [`Self::closest`] to
    /// test every primitive rather than walk the hierarchy; empty otherwise.
    quads: Vec<TriangleQuad>,
    /// True when [`Self::closest`] tests every primitive.
    brute: bool,
}

/// Most spheres and triangles (together) in a scene whose rays test every one of them: for so
/// few, four triangles a vector beat the hierarchy's box tests and its branches.
const BRUTE_MOST: usize = 24;

/// Four triangles' corners in the lanes of vectors, by corner then axis; lanes past the last
/// triangle hold NaN corners, which no ray meets.
#[derive(Debug, Clone, Copy)]
struct TriangleQuad {
    corner: [[f64x4; 3]; 3],
    index: [u32; 4],
}

/// A primitive's bounds and centre while the hierarchy is built.
struct Item {
    r: u32,
    lo: DVec3,
    hi: DVec3,
    c: DVec3,
}

impl Oracle {
    /// The scene's geometry in f64, with a hierarchy built over it.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let mut o = Oracle {
            planes: scene
                .planes
                .iter()
                .map(|p| (p.point.as_dvec3(), p.normal.as_dvec3()))
                .collect(),
            spheres: scene
                .spheres
                .iter()
                .map(|s| (s.center.as_dvec3(), f64::from(s.radius)))
                .collect(),
            triangles: scene.triangles.iter().map(corners).collect(),
            plane_info: scene.plane_info.clone(),
            sphere_info: scene.sphere_info.clone(),
            triangle_info: scene.triangle_info.iter().map(|t| (t.entity, t.material)).collect(),
            ..Oracle::default()
        };
        let mut items: Vec<Item> = Vec::with_capacity(o.triangles.len() + o.spheres.len());
        for (i, v) in o.triangles.iter().enumerate() {
            let (lo, hi) = (v[0].min(v[1]).min(v[2]), v[0].max(v[1]).max(v[2]));
            items.push(Item {
                r: i as u32,
                lo,
                hi,
                c: (lo + hi) * 0.5,
            });
        }
        for (i, &(c, r)) in o.spheres.iter().enumerate() {
            items.push(Item {
                r: i as u32 | SPHERE,
                lo: c - DVec3::splat(r),
                hi: c + DVec3::splat(r),
                c,
            });
        }
        o.brute = items.len() <= BRUTE_MOST;
        if o.brute {
            for (q, chunk) in o.triangles.chunks(4).enumerate() {
                let lane = |k: usize, c: usize, a: usize| chunk.get(k).map_or(f64::NAN, |v| v[c][a]);
                let corner = [0, 1, 2].map(|c| [0, 1, 2].map(|a| f64x4::new([0, 1, 2, 3].map(|k| lane(k, c, a)))));
                let index = [0, 1, 2, 3].map(|k| (4 * q + k) as u32);
                o.quads.push(TriangleQuad { corner, index });
            }
        }
        if !items.is_empty() {
            o.nodes.push(Node {
                lo: f64x4::ZERO,
                hi: f64x4::ZERO,
                first: 0,
                count: 0,
                axis: 0,
            });
            o.refs.reserve(items.len());
            o.build(0, &mut items);
        }
        o
    }

    /// Fills node `n` for `items` (which it reorders), split where the surface area heuristic
    /// says ([`sah_split`]).
    fn build(&mut self, n: usize, items: &mut [Item]) {
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let (mut clo, mut chi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        for it in items.iter() {
            (lo, hi) = (lo.min(it.lo), hi.max(it.hi));
            (clo, chi) = (clo.min(it.c), chi.max(it.c));
        }
        // Padded past the rounding of the box test, so a primitive never lies on a face.
        let pad = 1e-9 * lo.abs().max(hi.abs()).max_element().max(1.0);
        let (lo, hi) = (lo - DVec3::splat(pad), hi + DVec3::splat(pad));
        self.nodes[n].lo = f64x4::new([lo.x, lo.y, lo.z, f64::NEG_INFINITY]);
        self.nodes[n].hi = f64x4::new([hi.x, hi.y, hi.z, f64::INFINITY]);
        if items.len() <= LEAF {
            // Leaves are made left to right over the items, so the references placed before
            // this leaf are its offset.
            self.nodes[n].first = self.refs.len() as u32;
            self.nodes[n].count = items.len() as u32;
            self.refs.extend(items.iter().map(|it| it.r));
            return;
        }
        let (axis, mid) = sah_split(items, clo, chi);
        let child = self.nodes.len();
        let blank = self.nodes[n];
        self.nodes.push(blank);
        self.nodes.push(blank);
        self.nodes[n].first = child as u32;
        self.nodes[n].count = 0;
        self.nodes[n].axis = axis as u8;
        let (left, right) = items.split_at_mut(mid);
        self.build(child, left);
        self.build(child + 1, right);
    }

    /// Visits the references of the leaves whose boxes, grown by `pad`, the ray meets between
    /// `t_min` and `*t_max`; `f` may lower `*t_max`, which prunes the rest.
    #[inline]
    fn visit(&self, ray: &OracleRay, t_min: f64, t_max: &mut f64, pad: f64, mut f: impl FnMut(u32, &mut f64)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if !ray.meets_box(node.lo, node.hi, pad, t_min, *t_max) {
                continue;
            }
            if node.count > 0 {
                let (a, b) = (node.first as usize, (node.first + node.count) as usize);
                for &r in &self.refs[a..b] {
                    f(r, t_max);
                }
            } else {
                // The nearer child is visited first, so its hits prune the farther one.
                let (near, far) = ray.near_far(node);
                if top + 2 > stack.len() {
                    // Deeper than a median split of 2^62 primitives ever goes.
                    unreachable!("oracle hierarchy deeper than its stack");
                }
                stack[top] = far;
                stack[top + 1] = near;
                top += 2;
            }
        }
    }

    /// The primitive a hierarchy reference stands for.
    #[inline]
    fn prim(r: u32) -> PrimRef {
        if r & SPHERE != 0 {
            PrimRef::Sphere(r & !SPHERE)
        } else {
            PrimRef::Triangle(r)
        }
    }

    /// (entity, material) of a primitive.
    #[must_use]
    pub fn info(&self, prim: PrimRef) -> (u32, u32) {
        match prim {
            PrimRef::Plane(i) => self.plane_info[i as usize],
            PrimRef::Sphere(i) => self.sphere_info[i as usize],
            PrimRef::Triangle(i) => self.triangle_info[i as usize],
        }
    }

    /// The corners of triangle `i`.
    #[must_use]
    pub fn triangle(&self, i: u32) -> [DVec3; 3] {
        self.triangles[i as usize]
    }

    /// The primitive's own unit normal at `p` on it: outward for spheres, (v1 − v0) × (v2 − v0)
    /// for triangles, the file's for planes.
    #[must_use]
    pub fn own_normal(&self, prim: PrimRef, p: DVec3) -> DVec3 {
        match prim {
            PrimRef::Plane(i) => self.planes[i as usize].1.normalize(),
            PrimRef::Sphere(i) => (p - self.spheres[i as usize].0).normalize(),
            PrimRef::Triangle(i) => {
                let [a, b, c] = self.triangles[i as usize];
                (b - a).cross(c - a).normalize()
            }
        }
    }

    /// The closest hit of `o + t d` (unit `d`) with `t_min < t < t_max`, either side of every
    /// surface counting. Of surfaces met at the same distance, the first one tested wins: the
    /// planes in the scene's order, then the hierarchy's leaves, nearer child first.
    #[must_use]
    pub fn closest(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<OracleHit> {
        if t_min.is_nan() || t_max.is_nan() {
            return self.closest_by_visit(o, d, t_min, t_max);
        }
        let ray = OracleRay::new(o, d);
        let (mut best, mut t_far) = self.closest_plane(o, d, t_min, t_max);
        if self.brute {
            if let Some((prim, t)) = self.closest_of_all(&ray, t_min, t_far) {
                return self.hit_at(prim.or(best)?, o, d, t);
            }
        }
        self.walk(&ray, t_min, &mut t_far, |r, t_far| {
            self.test_leaf(&ray, r, t_min, t_far, &mut best);
        });
        self.hit_at(best?, o, d, t_far)
    }

    /// The nearest sphere or triangle with `t_min < t < t_far`, every one tested, and its `t`
    /// (`t_far` and `None` where none is met); `None` when two are met at that same nearest
    /// `t`, where the answer is the first of them the hierarchy's walk tests. Each primitive's
    /// `t` is the walk's number, by the same arithmetic, so a single nearest one is the walk's
    /// answer too.
    #[inline]
    fn closest_of_all(&self, ray: &OracleRay, t_min: f64, t_far: f64) -> Option<(Option<PrimRef>, f64)> {
        let (mut best, mut t_best, mut twice) = (None, t_far, false);
        let mut take = |t: f64, prim: PrimRef| {
            if t < t_best {
                (best, t_best, twice) = (Some(prim), t, false);
            } else if t == t_best && t < t_far {
                twice = true;
            }
        };
        for (i, &(c, r)) in self.spheres.iter().enumerate() {
            if let Some(t) = hit_sphere(c, r, ray.o, ray.d, t_min, t_far) {
                take(t, PrimRef::Sphere(i as u32));
            }
        }
        for q in &self.quads {
            let ts = ray.triangles4(q, t_min, t_far);
            for (t, &i) in ts.iter().zip(&q.index) {
                take(*t, PrimRef::Triangle(i));
            }
        }
        (!twice).then_some((best, t_best))
    }

    /// [`Self::closest`] by [`Self::visit`], which also takes NaN for `t_min` or `t_max`.
    #[cold]
    fn closest_by_visit(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> Option<OracleHit> {
        let ray = OracleRay::new(o, d);
        let (mut best, mut t_far) = self.closest_plane(o, d, t_min, t_max);
        self.visit(&ray, t_min, &mut t_far, 0.0, |r, t_far| {
            self.test_leaf(&ray, r, t_min, t_far, &mut best);
        });
        self.hit_at(best?, o, d, t_far)
    }

    /// The nearest plane `o + t d` meets with `t_min < t < t_max`, in the scene's order on a tie,
    /// and its `t` (`t_max` where none is met).
    #[inline]
    fn closest_plane(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64) -> (Option<PrimRef>, f64) {
        let mut best = None;
        let mut t_far = t_max;
        for (i, &(p, n)) in self.planes.iter().enumerate() {
            if let Some(t) = hit_plane(p, n, o, d, t_min, t_far) {
                t_far = t;
                best = Some(PrimRef::Plane(i as u32));
            }
        }
        (best, t_far)
    }

    /// Tests leaf primitive `r` (a sphere where [`SPHERE`] is set, else a triangle) against
    /// `ray` with `t_min < t < *t_far`; a hit becomes `best` and narrows `t_far`.
    #[inline(always)]
    fn test_leaf(&self, ray: &OracleRay, r: u32, t_min: f64, t_far: &mut f64, best: &mut Option<PrimRef>) {
        let t = if r & SPHERE != 0 {
            let (c, rad) = self.spheres[(r & !SPHERE) as usize];
            hit_sphere(c, rad, ray.o, ray.d, t_min, *t_far)
        } else {
            ray.triangle(&self.triangles[r as usize], t_min, *t_far)
        };
        if let Some(t) = t {
            *t_far = t;
            *best = Some(Self::prim(r));
        }
    }

    /// The hit of `o + t d` on `prim` at `t`.
    #[inline]
    fn hit_at(&self, prim: PrimRef, o: DVec3, d: DVec3, t: f64) -> Option<OracleHit> {
        let (entity, material) = self.info(prim);
        let point = o + d * t;
        let normal = self.own_normal(prim, point);
        Some(OracleHit {
            prim,
            entity,
            material,
            t,
            point,
            normal,
            front: normal.dot(d) < 0.0,
        })
    }

    /// [`Self::visit`] without padding, for `t_min` and `*t_max` that are not NaN: the same
    /// leaves in the same order, each box tested by [`OracleRay::meets_box_exact`], the nearer
    /// child gone to at once and only the farther one stacked.
    #[inline(always)]
    fn walk(&self, ray: &OracleRay, t_min: f64, t_max: &mut f64, mut f: impl FnMut(u32, &mut f64)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = [0u32; 64];
        let mut top = 0;
        let mut at = 0;
        loop {
            let node = &self.nodes[at];
            if ray.meets_box_exact(node.lo, node.hi, t_min, *t_max) {
                if node.count > 0 {
                    let (a, b) = (node.first as usize, (node.first + node.count) as usize);
                    for &r in &self.refs[a..b] {
                        f(r, t_max);
                    }
                } else {
                    let (near, far) = ray.near_far(node);
                    let Some(slot) = stack.get_mut(top) else {
                        // Deeper than a median split of 2^62 primitives ever goes.
                        unreachable!("oracle hierarchy deeper than its stack");
                    };
                    *slot = far;
                    top += 1;
                    at = near as usize;
                    continue;
                }
            }
            if top == 0 {
                return;
            }
            top -= 1;
            at = stack[top] as usize;
        }
    }

    /// How close the answer of [`Self::closest`] for `o + t d` (unit `d`, `t_min < t < t_max`)
    /// comes to being different, when closer than `eps` (scene units): the smallest of
    ///  * how far the ray passes from a triangle's edge, a sphere's rim or a plane it runs along,
    ///    where it meets (or nearly meets) that surface no farther than the closest hit;
    ///  * how far from the closest hit's point another entity's surface lies, measured across
    ///    that surface, where the ray meets it at about the same depth;
    ///  * how far a surface the ray meets lies from the ray's ends at `t_min` and `t_max`.
    ///
    /// `None` when nothing is that close: the answer does not depend on rounding.
    #[must_use]
    pub fn near_boundary(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64, eps: f64) -> Option<Near> {
        let hit = self.closest(o, d, t_min, t_max);
        let t_end = hit.map_or(t_max, |h| h.t);
        let hit_entity = hit.map(|h| h.entity);
        let ray = OracleRay::new(o, d);
        let mut best: Option<Near> = None;
        let mut offer = |prim: PrimRef, kind: NearKind, margin: f64| {
            if margin <= eps && best.is_none_or(|b| margin < b.margin) {
                best = Some(Near {
                    prim,
                    entity: self.info(prim).0,
                    kind,
                    margin,
                });
            }
        };
        // A surface the ray meets at depth `t` where it crosses at `cos` to its normal.
        let depths = |prim: PrimRef, t: f64, cos: f64, offer: &mut dyn FnMut(PrimRef, NearKind, f64)| {
            if t < t_min - eps || t > t_end + eps {
                return;
            }
            if hit_entity.is_some_and(|e| e != self.info(prim).0) {
                offer(prim, NearKind::Depth, (t - t_end).abs() * cos);
            }
            offer(prim, NearKind::End, (t - t_min).abs() * cos);
            if t_max.is_finite() {
                offer(prim, NearKind::End, (t - t_max).abs() * cos);
            }
        };
        for (i, &(p, n)) in self.planes.iter().enumerate() {
            let prim = PrimRef::Plane(i as u32);
            let n = n.normalize();
            let (cos, dist) = (n.dot(d), (o - p).dot(n));
            if cos.abs() * (t_end.min(1e300) - t_min).abs() <= eps || cos == 0.0 {
                // Running along the plane: how far from it the ray stays.
                offer(
                    prim,
                    NearKind::Along,
                    dist.abs().min((o + d * t_end.min(1e300) - p).dot(n).abs()),
                );
            }
            if cos != 0.0 {
                depths(prim, -dist / cos, cos.abs(), &mut offer);
            }
        }
        let mut t_hi = t_end + eps;
        self.visit(&ray, t_min - eps, &mut t_hi, eps, |r, _| {
            let prim = Self::prim(r);
            if r & SPHERE != 0 {
                let (c, rad) = self.spheres[(r & !SPHERE) as usize];
                let f = c - o;
                let along = f.dot(d);
                let perp = (f - d * along).length();
                if along >= t_min - eps - rad && along <= t_end + eps + rad {
                    // Grazing the rim.
                    offer(prim, NearKind::Rim, (rad - perp).abs());
                }
                for t in [
                    hit_sphere(c, rad, o, d, f64::MIN, f64::MAX),
                    hit_sphere(c, rad, o, d, along, f64::MAX),
                ]
                .into_iter()
                .flatten()
                {
                    let cos = ((o + d * t - c) / rad).dot(d).abs();
                    depths(prim, t, cos, &mut offer);
                }
            } else {
                let v = self.triangles[r as usize];
                let n = (v[1] - v[0]).cross(v[2] - v[0]).normalize();
                let cos = n.dot(d);
                let dist = (o - v[0]).dot(n);
                if cos == 0.0 || (cos * (t_end.min(1e300) - t_min)).abs() <= eps {
                    // In (or nearly in) the triangle's plane: how far from it the ray stays.
                    offer(prim, NearKind::Along, dist.abs());
                    return;
                }
                let t = -dist / cos;
                if t < t_min - eps || t > t_end + eps {
                    return;
                }
                let p = o + d * t;
                // Signed in-plane distance to the nearest edge, positive inside.
                let inside = (0..3)
                    .map(|k| {
                        let (a, b) = (v[k], v[(k + 1) % 3]);
                        (b - a).cross(p - a).dot(n) / (b - a).length()
                    })
                    .fold(f64::INFINITY, f64::min);
                offer(prim, NearKind::Edge, inside.abs());
                if inside >= -eps {
                    depths(prim, t, cos.abs(), &mut offer);
                }
            }
        });
        best
    }
}

/// Bins the surface area heuristic sorts centres into along each axis.
const BINS: usize = 16;

/// Surface area of a box (half of it: only ratios matter).
fn area(lo: DVec3, hi: DVec3) -> f64 {
    let e = (hi - lo).max(DVec3::ZERO);
    e.x * e.y + e.y * e.z + e.z * e.x
}

/// Orders `items` (more than [`LEAF`] of them, centres within `clo`..`chi`) so that the first
/// `mid` go to one child and the rest to the other, choosing the axis and the plane among
/// [`BINS`] bins that give the cheapest children by the surface area heuristic; at the median
/// of the widest axis when the centres do not spread.
fn sah_split(items: &mut [Item], clo: DVec3, chi: DVec3) -> (usize, usize) {
    let spread = chi - clo;
    let bin = |c: DVec3, axis: usize| (((c[axis] - clo[axis]) / spread[axis] * BINS as f64) as usize).min(BINS - 1);
    // The cheapest split: its cost, axis, and the first bin of its second child.
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        if spread[axis] <= 0.0 {
            continue;
        }
        let mut boxes = [(DVec3::INFINITY, DVec3::NEG_INFINITY, 0usize); BINS];
        for it in items.iter() {
            let b = &mut boxes[bin(it.c, axis)];
            (b.0, b.1, b.2) = (b.0.min(it.lo), b.1.max(it.hi), b.2 + 1);
        }
        // Costs of the planes after bins 0..BINS-1: the left side swept forwards, then the
        // right side backwards.
        let mut left = [0.0; BINS];
        let (mut lo, mut hi, mut count) = (DVec3::INFINITY, DVec3::NEG_INFINITY, 0);
        for (k, b) in boxes.iter().enumerate().take(BINS - 1) {
            (lo, hi, count) = (lo.min(b.0), hi.max(b.1), count + b.2);
            left[k] = if count == 0 { 0.0 } else { area(lo, hi) * count as f64 };
        }
        let (mut lo, mut hi, mut count) = (DVec3::INFINITY, DVec3::NEG_INFINITY, 0);
        for k in (1..BINS).rev() {
            let b = &boxes[k];
            (lo, hi, count) = (lo.min(b.0), hi.max(b.1), count + b.2);
            let right = if count == 0 { 0.0 } else { area(lo, hi) * count as f64 };
            let cost = left[k - 1] + right;
            if count > 0 && count < items.len() && best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, k));
            }
        }
    }
    if let Some((_, axis, k)) = best {
        let mut mid = 0;
        for i in 0..items.len() {
            if bin(items[i].c, axis) < k {
                items.swap(i, mid);
                mid += 1;
            }
        }
        if mid > 0 && mid < items.len() {
            return (axis, mid);
        }
    }
    let axis = if spread.x >= spread.y && spread.x >= spread.z {
        0
    } else if spread.y >= spread.z {
        1
    } else {
        2
    };
    let mid = items.len() / 2;
    items.select_nth_unstable_by(mid, |a, b| a.c[axis].total_cmp(&b.c[axis]));
    (axis, mid)
}

/// The course's pinhole camera in double precision, for the regular `-x N` grid (jittered and
/// thin-lens samples are random, so no single ray is "the" answer for them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OracleCamera {
    /// Camera position.
    pub origin: DVec3,
    /// World-from-camera rotation.
    pub rotation: DMat3,
    /// Half extents of the image plane at distance 1, (x, y).
    pub half: (f64, f64),
    width: f64,
    height: f64,
    /// Side of the sample grid: N for `-x N`, 1 where a pixel takes one sample.
    pub grid: u32,
}

impl OracleCamera {
    /// The camera of `settings`.
    #[must_use]
    pub fn new(settings: &RenderSettings) -> Self {
        let c = &settings.camera;
        let t = (f64::from(c.fov_deg).to_radians() * 0.5).tan();
        let (w, h) = (f64::from(settings.width), f64::from(settings.height));
        let half = match c.fov_axis {
            FovAxis::Horizontal => (t, t * h / w),
            FovAxis::Vertical => (t * w / h, t),
        };
        // Stage 1 (and the debug channels) take one ray through each pixel centre.
        let one = settings.stage == Stage::One || settings.channel != Channel::Color;
        Self {
            origin: c.position.as_dvec3(),
            rotation: rodrigues(c.axis.as_dvec3(), f64::from(c.angle_deg)),
            half,
            width: w,
            height: h,
            grid: if one { 1 } else { settings.aa.max(1) },
        }
    }

    /// Normalised image coordinates of sample `s` of pixel (`x`, `y`): (0, 0) the image's
    /// top-left corner, (1, 1) its bottom-right.
    #[must_use]
    pub fn sample_position(&self, x: u32, y: u32, s: u32) -> (f64, f64) {
        let n = self.grid;
        let cell = s % (n * n);
        let (i, j) = (f64::from(cell % n), f64::from(cell / n));
        let nf = f64::from(n);
        (
            (f64::from(x) + (i + 0.5) / nf) / self.width,
            (f64::from(y) + (j + 0.5) / nf) / self.height,
        )
    }

    /// The unit direction through normalised image coordinates (`u`, `v`).
    #[must_use]
    pub fn direction(&self, u: f64, v: f64) -> DVec3 {
        let c = DVec3::new((2.0 * u - 1.0) * self.half.0, (1.0 - 2.0 * v) * self.half.1, 1.0);
        (self.rotation * c).normalize()
    }

    /// The camera ray of sample `s` of pixel (`x`, `y`): origin and unit direction.
    #[must_use]
    pub fn ray(&self, x: u32, y: u32, s: u32) -> (DVec3, DVec3) {
        let (u, v) = self.sample_position(x, y, s);
        (self.origin, self.direction(u, v))
    }
}

/// Rotation by `angle_deg` degrees about `axis` (Rodrigues: R v = v cos θ + (k × v) sin θ +
/// k (k · v)(1 − cos θ), k the unit axis); the identity for a zero axis.
#[must_use]
pub fn rodrigues(axis: DVec3, angle_deg: f64) -> DMat3 {
    let Some(k) = axis.try_normalize() else {
        return DMat3::IDENTITY;
    };
    let (s, c) = angle_deg.to_radians().sin_cos();
    let r = |v: DVec3| v * c + k.cross(v) * s + k * k.dot(v) * (1.0 - c);
    DMat3::from_cols(r(DVec3::X), r(DVec3::Y), r(DVec3::Z))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(src: &str) -> Scene {
        Scene::from_file(&rayscope_scene::parse_str(src, std::path::Path::new("t.txt")).expect("scene"))
    }

    const QUAD: &str = "Material \"M\" Diffuse (1, 1, 1) 1\n\
        Triangle \"A\" (-1, -1, 2) (-1, 1, 2) (1, 1, 2) \"M\"\n\
        Triangle \"B\" (-1, -1, 2) (1, 1, 2) (1, -1, 2) \"M\"\n\
        Sphere \"S\" (0, 0, 5) 1 \"M\"\n\
        Plane \"P\" (0, 0, 9) (0, 0, -1) \"M\"\n";

    #[test]
    fn a_ray_through_a_shared_edge_or_corner_meets_a_triangle() {
        let s = scene(QUAD);
        let o = Oracle::new(&s);
        // The diagonal (−1, −1) to (1, 1) both triangles share, and their shared corners.
        for k in -10..=10 {
            let x = f64::from(k) * 0.1;
            for target in [
                DVec3::new(x, x, 2.0),
                DVec3::new(-1.0, -1.0, 2.0),
                DVec3::new(1.0, 1.0, 2.0),
            ] {
                let origin = DVec3::new(0.3, -0.7, -1.0);
                let d = (target - origin).normalize();
                let h = o.closest(origin, d, 0.0, f64::INFINITY).expect("hit");
                assert!(h.entity <= 1, "{target}: hit entity {}", h.entity);
                assert!((h.point.z - 2.0).abs() < 1e-12);
                let near = o
                    .near_boundary(origin, d, 0.0, f64::INFINITY, 1e-6)
                    .expect("on an edge");
                assert!(near.margin < 1e-9, "{target}: {near:?}");
            }
        }
    }

    #[test]
    fn the_walk_answers_as_the_general_visit_bit_for_bit() {
        let o = Oracle::new(&scene(&grid(6)));
        assert!(!o.brute);
        assert!(same_as_visit(&o) > 100_000);
    }

    #[test]
    fn testing_every_primitive_answers_as_the_walk_bit_for_bit() {
        // 18 triangles and 2 spheres: few enough to test them all.
        let o = Oracle::new(&scene(&grid(3)));
        assert!(o.brute);
        assert!(same_as_visit(&o) > 50_000);
    }

    /// A grid of n × n squares of two triangles each, sharing edges and corners (ties wherever a
    /// ray meets an edge), at staggered depths so that their sides make walls meeting at edges,
    /// with two spheres and two planes.
    fn grid(n: i32) -> String {
        let mut src = String::from("Material \"M\" Diffuse (1, 1, 1) 1\n");
        for i in 0..n {
            for j in 0..n {
                let (x, y) = (f64::from(i) - 3.0, f64::from(j) - 3.0);
                let z = f64::from((i * 7 + j * 3) % 5) * 0.25 + 4.0;
                src.push_str(&format!(
                    "Triangle \"T{i}{j}a\" ({x}, {y}, {z}) ({}, {y}, {z}) ({x}, {}, {z}) \"M\"\n",
                    x + 1.0,
                    y + 1.0
                ));
                src.push_str(&format!(
                    "Triangle \"T{i}{j}b\" ({}, {y}, {z}) ({}, {}, {z}) ({x}, {}, {z}) \"M\"\n",
                    x + 1.0,
                    x + 1.0,
                    y + 1.0,
                    y + 1.0
                ));
            }
        }
        src.push_str("Sphere \"S1\" (0, 0, 2) 0.5 \"M\"\nSphere \"S2\" (1, 1, 1) 0.25 \"M\"\n");
        src.push_str("Plane \"P1\" (0, -2, 0) (0, 1, 0) \"M\"\nPlane \"P2\" (0, 0, 6) (0, 0, -1) \"M\"\n");
        src
    }

    /// Asserts that [`Oracle::closest`] answers as [`Oracle::closest_by_visit`], bit for bit, for
    /// 200,000 rays from integer origins (on the squares' sides) along directions with zero
    /// components as well as random ones; returns how many met something.
    fn same_as_visit(o: &Oracle) -> usize {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        let mut met = 0;
        for k in 0..200_000 {
            let mut pick = |n: u64| (next() % n) as f64;
            let origin = DVec3::new(pick(7) - 3.0, pick(7) - 3.0, pick(4) - 1.0);
            let d = match k % 4 {
                // Along the axes and the diagonals, zero components included.
                0 => DVec3::new(pick(3) - 1.0, pick(3) - 1.0, pick(3) - 1.0),
                // Through a grid corner or edge midpoint.
                1 => DVec3::new(pick(13) * 0.5 - 3.0, pick(13) * 0.5 - 3.0, 4.0) - origin,
                _ => DVec3::new(pick(2001) - 1000.0, pick(2001) - 1000.0, pick(2001) - 1000.0),
            };
            let Some(d) = d.try_normalize() else {
                continue;
            };
            let (t_min, t_max) = match k % 3 {
                0 => (0.0, f64::INFINITY),
                1 => (1e-4, pick(8) + 0.5),
                _ => (pick(3), f64::INFINITY),
            };
            let (a, b) = (
                o.closest(origin, d, t_min, t_max),
                o.closest_by_visit(origin, d, t_min, t_max),
            );
            assert_eq!(
                a.map(|h| (h.prim, h.t.to_bits(), h.point.to_array().map(f64::to_bits))),
                b.map(|h| (h.prim, h.t.to_bits(), h.point.to_array().map(f64::to_bits))),
                "{origin} {d} {t_min} {t_max}"
            );
            met += usize::from(a.is_some());
        }
        met
    }

    #[test]
    fn closest_hit_normals_and_sides() {
        let s = scene(QUAD);
        let o = Oracle::new(&s);
        // Through the quad's middle of triangle A: front face is (v1 − v0) × (v2 − v0) = −z.
        let h = o
            .closest(DVec3::new(-0.5, 0.3, 0.0), DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!((h.entity, h.t), (0, 2.0));
        assert_eq!(h.normal, DVec3::NEG_Z);
        assert!(h.front);
        // Beside the quad: the sphere, from outside, then from inside, then the plane.
        let h = o.closest(
            DVec3::new(3.0, 0.0, 0.0),
            DVec3::new(-3.0, 0.0, 5.0).normalize(),
            0.0,
            f64::INFINITY,
        );
        let h = h.unwrap();
        assert_eq!(h.entity, 2);
        assert!(((h.point - DVec3::new(0.0, 0.0, 5.0)).length() - 1.0).abs() < 1e-12);
        assert!(h.front && h.normal.dot(h.point - DVec3::new(0.0, 0.0, 5.0)) > 0.0);
        let h = o
            .closest(DVec3::new(0.0, 0.0, 5.0), DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!((h.entity, h.t, h.front), (2, 1.0, false));
        let h = o
            .closest(DVec3::new(0.0, 0.0, 6.5), DVec3::Z, 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!((h.entity, h.t, h.front), (3, 2.5, true));
        // Backwards from the plane through the quad's back face; t_max stops short of it.
        let h = o
            .closest(DVec3::new(-0.5, 0.3, 3.0), DVec3::NEG_Z, 0.0, f64::INFINITY)
            .unwrap();
        assert_eq!((h.entity, h.front), (0, false));
        assert!(o.closest(DVec3::new(-0.5, 0.3, 3.0), DVec3::NEG_Z, 0.0, 0.9).is_none());
        assert!(o
            .closest(DVec3::new(0.0, 3.0, 0.0), DVec3::Y, 0.0, f64::INFINITY)
            .is_none());
    }

    #[test]
    fn near_boundary_names_rims_and_edges_only_when_close() {
        let s = scene(QUAD);
        let o = Oracle::new(&s);
        // Grazing the sphere's rim (x = 1, beside the quad's edge at x = 1 too).
        let n = o.near_boundary(DVec3::new(1.0 + 1e-9, 0.5, 0.0), DVec3::Z, 0.0, f64::INFINITY, 1e-6);
        assert!(n.is_some_and(|n| n.margin < 1e-8), "{n:?}");
        // Well inside a triangle and the sphere: nothing close.
        let n = o.near_boundary(DVec3::new(-0.5, 0.3, 0.0), DVec3::Z, 0.0, f64::INFINITY, 1e-6);
        assert_eq!(n, None);
        // The plane at z = 9 seen by a ray that ends just short of it.
        let n = o.near_boundary(DVec3::new(3.0, 0.0, 0.0), DVec3::Z, 0.0, 9.0 - 1e-9, 1e-6);
        assert!(n.is_some_and(|n| n.entity == 3), "{n:?}");
    }

    #[test]
    fn camera_follows_the_course() {
        let mut s = RenderSettings {
            width: 400,
            height: 200,
            ..RenderSettings::default()
        };
        let cam = OracleCamera::new(&s);
        let t = (30f64).to_radians().tan();
        assert_eq!(cam.half, (t, t / 2.0));
        // Pixel (0, 0)'s centre is up and to the left.
        let (_, d) = cam.ray(0, 0, 0);
        let c = d / d.z;
        assert!((c.x - (-1.0 + 1.0 / 400.0) * t).abs() < 1e-15 && (c.y - (1.0 - 1.0 / 200.0) * t / 2.0).abs() < 1e-15);
        // -x 2: sample 1 is cell (1, 0), sample 2 is cell (0, 1); five samples wrap around.
        s.aa = 2;
        let cam = OracleCamera::new(&s);
        assert_eq!(cam.sample_position(0, 0, 1), (0.75 / 400.0, 0.25 / 200.0));
        assert_eq!(cam.sample_position(0, 0, 2), (0.25 / 400.0, 0.75 / 200.0));
        assert_eq!(cam.sample_position(3, 4, 5), cam.sample_position(3, 4, 1));
        s.stage = Stage::One;
        assert_eq!(OracleCamera::new(&s).grid, 1, "stage 1: one ray through each centre");
        // Axis (1, 0, 0) at +45° looks down.
        let r = rodrigues(DVec3::X, 45.0) * DVec3::Z;
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((r - DVec3::new(0.0, -h, h)).length() < 1e-15);
        s.camera.fov_axis = FovAxis::Vertical;
        assert_eq!(OracleCamera::new(&s).half, (2.0 * t, t));
    }
}
