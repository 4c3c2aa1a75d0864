//! Analytic ray–primitive intersection: plane, sphere and triangle.
//!
//! Every routine is two-sided and returns the nearest `t` in the open interval `(t_min, t_max)`.
//! Rays must have unit-length directions.
//!
//! Each test's arithmetic is written once, generic over the SIMD module's `Lanes`: the one-ray
//! tests here run it on `f32`, the BVH's 1×4 tests (one ray, four primitives) on `Vec4`, and its
//! 16×1 tests (one primitive, sixteen rays) on `f32` in a loop the compiler vectorises. All of
//! them therefore return the same bits for the same ray and primitive.

use glam::{Vec3A, Vec4};
use serde::Serialize;

use crate::math::{Aabb, Ray};
use crate::simd::Lanes;

/// A vector stored per axis: x, y and z, each a [`Lanes`] value.
pub(crate) type Axes<L> = [L; 3];

#[inline(always)]
fn sub<L: Lanes>(a: &Axes<L>, b: &Axes<L>) -> Axes<L> {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn dot<L: Lanes>(a: &Axes<L>, b: &Axes<L>) -> L {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// a × b.
#[inline(always)]
pub(crate) fn cross<L: Lanes>(a: &Axes<L>, b: &Axes<L>) -> Axes<L> {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `x < t_max`, or with `TIES` `x <= t_max`: a closest-hit query through the BVH keeps hits at
/// exactly the best distance so far for its tie rule to decide; every other bound is strict.
#[inline(always)]
fn below<L: Lanes, const TIES: bool>(x: L, t_max: L) -> L::Mask {
    if TIES {
        x.cmple(t_max)
    } else {
        x.cmplt(t_max)
    }
}

/// The plane test: where the ray meets the plane through `p` with normal `n`, and whether that
/// is inside `(t_min, t_max)`.
#[inline(always)]
pub(crate) fn plane_hit<L: Lanes, const TIES: bool>(
    p: &Axes<L>,
    n: &Axes<L>,
    o: &Axes<L>,
    d: &Axes<L>,
    t_min: L,
    t_max: L,
) -> (L::Mask, L) {
    // A ray parallel to the plane never meets it (one lying in it is treated as a miss too).
    let den = dot(n, d);
    let t = dot(&sub(p, o), n) / den;
    let hit = den.cmpne(L::splat(0.0)) & t.cmpgt(t_min) & below::<L, TIES>(t, t_max);
    (hit, t)
}

/// The first half of the sphere test: the ray's offset from the centre, and the discriminant,
/// negative when the ray's line misses the sphere.
pub(crate) struct SphereLine<L: Lanes> {
    /// Origin − centre.
    pub(crate) f: Axes<L>,
    /// −(f · d), the distance along the ray to the point of its line nearest the centre.
    pub(crate) b: L,
    /// r² minus the squared distance of the line from the centre.
    pub(crate) disc: L,
}

/// Where the ray's line passes the sphere with centre `c` and squared radius `r2`.
#[inline(always)]
pub(crate) fn sphere_line<L: Lanes>(c: &Axes<L>, r2: L, o: &Axes<L>, d: &Axes<L>) -> SphereLine<L> {
    // Numerically careful form (Haines et al., "Precision Improvements for Ray/Sphere
    // Intersection", Ray Tracing Gems ch. 7): the discriminant is computed from the distance of
    // the centre to the ray's line rather than as b² − c, which cancels catastrophically for
    // small or distant spheres.
    let f = sub(o, c);
    let b = -dot(&f, d);
    let l = [f[0] + d[0] * b, f[1] + d[1] * b, f[2] + d[2] * b];
    let disc = r2 - dot(&l, &l);
    SphereLine { f, b, disc }
}

impl<L: Lanes> SphereLine<L> {
    /// The second half: whether the ray meets the sphere inside `(t_min, t_max)`, and the nearer
    /// such distance.
    #[inline(always)]
    pub(crate) fn hit<const TIES: bool>(&self, r2: L, t_min: L, t_max: L) -> (L::Mask, L) {
        let zero = L::splat(0.0);
        let c = dot(&self.f, &self.f) - r2;
        let q = self.b + self.disc.maxps(zero).sqrt().copysign(self.b);
        // Roots c/q and q: the stable pair whatever the sign of b (none when q is 0).
        let (t0, t1) = (c / q, q);
        let (lo, hi) = (t0.minps(t1), t0.maxps(t1));
        let lo_ok = lo.cmpgt(t_min) & below::<L, TIES>(lo, t_max);
        let hi_ok = hi.cmpgt(t_min) & below::<L, TIES>(hi, t_max);
        let hit = self.disc.cmpge(zero) & q.cmpne(zero) & (lo_ok | hi_ok);
        (hit, L::select(lo_ok, lo, hi))
    }
}

/// The first half of the triangle test, up to the supporting plane: Möller–Trumbore, two-sided,
/// rearranged around the normal n = e1 × e2 (as Embree does). With c = v0 − o and r = d × c the
/// barycentrics and the distance are −(e2·r), e1·r and c·n over d·n; everything is kept
/// multiplied by a = |d·n|, so the division is made only for a hit.
pub(crate) struct TrianglePlane<L: Lanes> {
    /// v0 − origin.
    pub(crate) c: Axes<L>,
    /// The sign of d·n.
    pub(crate) s: L,
    /// |d·n|.
    pub(crate) a: L,
    /// The distance times `a`.
    pub(crate) t: L,
    /// The ray meets the plane with `t_min < t < t_far` (compared undivided).
    pub(crate) hit: L::Mask,
}

/// Where the ray meets the plane of the triangle with corner `v0` and normal `n` = e1 × e2.
#[inline(always)]
pub(crate) fn triangle_plane<L: Lanes>(
    v0: &Axes<L>,
    n: &Axes<L>,
    o: &Axes<L>,
    d: &Axes<L>,
    t_min: L,
    t_far: L,
) -> TrianglePlane<L> {
    let c = sub(v0, o);
    let den = dot(d, n);
    let s = L::splat(1.0).copysign(den);
    let a = den.abs();
    let t = dot(&c, n) * s;
    let hit = den.cmpne(L::splat(0.0)) & t.cmpgt(t_min * a) & t.cmplt(t_far * a);
    TrianglePlane { c, s, a, t, hit }
}

impl<L: Lanes> TrianglePlane<L> {
    /// The second half, the edges: the barycentrics (times `a`) of the point where the ray `d`
    /// meets the plane, and where the ray meets the triangle with edges `e1`, `e2` inside
    /// `(t_min, t_far)`.
    #[inline(always)]
    pub(crate) fn edges(&self, e1: &Axes<L>, e2: &Axes<L>, d: &Axes<L>) -> (L, L, L::Mask) {
        let r = cross(d, &self.c);
        let u = dot(e2, &r) * -self.s;
        let v = dot(e1, &r) * self.s;
        let zero = L::splat(0.0);
        (u, v, self.hit & u.cmpge(zero) & v.cmpge(zero) & (u + v).cmple(self.a))
    }
}

/// Where a ray met a primitive: distance plus the two surface parameters the primitive needs to
/// rebuild its normal (barycentrics for triangles, unused elsewhere).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PrimHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// First barycentric coordinate (weight of v1) for triangles.
    pub u: f32,
    /// Second barycentric coordinate (weight of v2) for triangles.
    pub v: f32,
}

/// A surface a ray can be intersected with.
pub trait Primitive {
    /// The nearest hit with `t_min < t < t_max`, if any.
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit>;
    /// The unit geometric normal at a hit found by [`Primitive::intersect`] (not flipped to face the ray).
    fn normal(&self, ray: &Ray, hit: &PrimHit) -> Vec3A;
}

/// An infinite plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    /// A point on the plane.
    pub point: Vec3A,
    /// Unit normal.
    pub normal: Vec3A,
}

impl Primitive for Plane {
    #[inline]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
        let (hit, t) = plane_hit::<f32, false>(&self.point.to_array(), &self.normal.to_array(), &o, &d, t_min, t_max);
        hit.then_some(PrimHit { t, u: 0.0, v: 0.0 })
    }

    #[inline]
    fn normal(&self, _ray: &Ray, _hit: &PrimHit) -> Vec3A {
        self.normal
    }
}

/// A sphere.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3A,
    /// Radius (> 0).
    pub radius: f32,
}

impl Sphere {
    /// Bounding box.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.center - Vec3A::splat(self.radius),
            max: self.center + Vec3A::splat(self.radius),
        }
    }
}

impl Primitive for Sphere {
    #[inline]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
        let r2 = self.radius * self.radius;
        let line = sphere_line(&self.center.to_array(), r2, &o, &d);
        if line.disc < 0.0 {
            return None;
        }
        let (hit, t) = line.hit::<false>(r2, t_min, t_max);
        hit.then_some(PrimHit { t, u: 0.0, v: 0.0 })
    }

    #[inline]
    fn normal(&self, ray: &Ray, hit: &PrimHit) -> Vec3A {
        ((ray.at(hit.t) - self.center) / self.radius).normalize()
    }
}

/// A triangle prepared for intersection: first corner, the two edges from it, and its unit
/// normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Triangle {
    // The unit normal's x, y and z ride in the fourth lanes of the three vectors, which a
    // `Vec3A` leaves as padding: shading needs the normal at every hit, and storing it costs no
    // memory this way (a path-traced box 3 % faster than normalising e1 × e2 per hit).
    v0: Vec4,
    e1: Vec4,
    e2: Vec4,
}

impl Triangle {
    /// The triangle with corners `a`, `b`, `c`.
    #[must_use]
    pub fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Self {
        let (e1, e2) = (b - a, c - a);
        // `normalize` divides (`normalize_or_zero` multiplies by a reciprocal, which rounds
        // differently), so the normal is bit for bit the one the packet kernels compute from the
        // edges (`surface/lanes.rs`). A degenerate triangle, never hit, stores zero, not NaN.
        let n = e1.cross(e2).normalize();
        let n = if n.is_finite() { n } else { Vec3A::ZERO };
        Self {
            v0: a.extend(n.x),
            e1: e1.extend(n.y),
            e2: e2.extend(n.z),
        }
    }

    /// First corner.
    #[must_use]
    #[inline(always)]
    pub fn v0(&self) -> Vec3A {
        Vec3A::from_vec4(self.v0)
    }

    /// v1 − v0.
    #[must_use]
    #[inline(always)]
    pub fn e1(&self) -> Vec3A {
        Vec3A::from_vec4(self.e1)
    }

    /// v2 − v0.
    #[must_use]
    #[inline(always)]
    pub fn e2(&self) -> Vec3A {
        Vec3A::from_vec4(self.e2)
    }

    /// The three corners.
    #[must_use]
    pub fn vertices(&self) -> [Vec3A; 3] {
        let v0 = self.v0();
        [v0, v0 + self.e1(), v0 + self.e2()]
    }

    /// The point of the triangle nearest to `p`.
    #[must_use]
    pub(crate) fn closest_point(&self, p: Vec3A) -> Vec3A {
        // By the Voronoi region of `p`: a corner, an edge or the face (Ericson, Real-Time
        // Collision Detection, 5.1.5).
        let (a, ab, ac) = (self.v0(), self.e1(), self.e2());
        let ap = p - a;
        let (d1, d2) = (ab.dot(ap), ac.dot(ap));
        if d1 <= 0.0 && d2 <= 0.0 {
            return a;
        }
        let bp = ap - ab;
        let (d3, d4) = (ab.dot(bp), ac.dot(bp));
        if d3 >= 0.0 && d4 <= d3 {
            return a + ab;
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            return a + ab * (d1 / (d1 - d3));
        }
        let cp = ap - ac;
        let (d5, d6) = (ab.dot(cp), ac.dot(cp));
        if d6 >= 0.0 && d5 <= d6 {
            return a + ac;
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            return a + ac * (d2 / (d2 - d6));
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
            return a + ab + (ac - ab) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
        }
        let denom = 1.0 / (va + vb + vc);
        a + ab * (vb * denom) + ac * (vc * denom)
    }

    /// Bounding box.
    #[must_use]
    pub fn bounds(&self) -> Aabb {
        let [a, b, c] = self.vertices();
        Aabb::EMPTY.grow(a).grow(b).grow(c)
    }

    /// True when the triangle has no area (it can never be hit).
    #[must_use]
    pub fn is_degenerate(&self) -> bool {
        let n = self.e1().cross(self.e2());
        n.length_squared() <= 0.0 || !n.is_finite()
    }

    /// Unit geometric normal (v1 − v0) × (v2 − v0), the course's convention (zero for a
    /// degenerate triangle).
    #[must_use]
    #[inline]
    pub fn geometric_normal(&self) -> Vec3A {
        Vec3A::new(self.v0.w, self.e1.w, self.e2.w)
    }
}

impl Primitive for Triangle {
    #[inline]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
        let (o, d) = (ray.origin.to_array(), ray.dir.to_array());
        let (e1, e2) = (self.e1().to_array(), self.e2().to_array());
        let n = cross(&e1, &e2);
        let plane = triangle_plane(&self.v0().to_array(), &n, &o, &d, t_min, t_max);
        if !plane.hit {
            return None;
        }
        let (u, v, hit) = plane.edges(&e1, &e2, &d);
        if !hit {
            return None;
        }
        // The scaled test can pass by a rounding error for a hit no nearer than `t_max`.
        let t = plane.t / plane.a;
        (t < t_max).then(|| PrimHit {
            t,
            u: u / plane.a,
            v: v / plane.a,
        })
    }

    #[inline]
    fn normal(&self, _ray: &Ray, _hit: &PrimHit) -> Vec3A {
        self.geometric_normal()
    }
}

/// A primitive of a scene: its kind and its index in the scene's store of that kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
pub enum PrimRef {
    /// Index into `Scene::planes`.
    Plane(u32),
    /// Index into `Scene::spheres`.
    Sphere(u32),
    /// Index into `Scene::triangles`.
    Triangle(u32),
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        Ray::new(Vec3A::from(o), Vec3A::from(d).normalize())
    }

    /// Lane `k` of per-axis `Vec4`s.
    fn lane(v: &Axes<Vec4>, k: usize) -> Axes<f32> {
        v.map(|x| x.to_array()[k])
    }

    fn bits(x: f32) -> u32 {
        x.to_bits()
    }

    #[test]
    fn four_lanes_return_the_one_lane_bits() {
        // The BVH tests one ray against four primitives at once (`Vec4`) and one primitive
        // against sixteen rays (`f32` per ray); images stay the same across engines only if
        // every lane computes exactly what the one-value form computes.
        let mut rng = crate::rng::Rng::for_sample(11, 5, 3);
        let mut counts = [0u32; 3];
        for round in 0..20_000 {
            let rng = &mut rng;
            let mut f = || rng.next_f32();
            let mut point = |scale: f32| std::array::from_fn::<f32, 3, _>(|_| (f() * 2.0 - 1.0) * scale);
            let axes = |p: [[f32; 3]; 4]| -> Axes<Vec4> { std::array::from_fn(|a| Vec4::from_array(p.map(|q| q[a]))) };
            let tris: [Triangle; 4] = std::array::from_fn(|_| {
                Triangle::new(
                    Vec3A::from(point(4.0)),
                    Vec3A::from(point(4.0)),
                    Vec3A::from(point(4.0)),
                )
            });
            // Aim at a corner, an edge's midpoint or inside one of the triangles, or anywhere.
            let k = round % 4;
            let [a, b, c] = tris[k].vertices();
            let target = match round % 5 {
                0 => a,
                1 => (b + c) * 0.5,
                2 => a * 0.2 + b * 0.3 + c * 0.5,
                _ => Vec3A::from(point(4.0)),
            };
            let origin = Vec3A::from(point(10.0));
            let r = Ray::new(origin, (target - origin).normalize());
            let (o, d) = (r.origin.to_array(), r.dir.to_array());
            let (o4, d4) = (o.map(Vec4::splat), d.map(Vec4::splat));
            let t_min = if round % 2 == 0 { 0.0 } else { 1e-3 };
            let t_max = if round % 3 == 0 {
                f32::INFINITY
            } else {
                point(10.0)[0] + 10.0
            };

            let v0 = axes(tris.map(|t| t.v0().to_array()));
            let e1 = axes(tris.map(|t| t.e1().to_array()));
            let e2 = axes(tris.map(|t| t.e2().to_array()));
            let n = cross(&e1, &e2);
            let plane4 = triangle_plane(&v0, &n, &o4, &d4, Vec4::splat(t_min), Vec4::splat(t_max));
            let (u4, v4, hit4) = plane4.edges(&e1, &e2, &d4);
            for (k, tri) in tris.iter().enumerate() {
                let plane = triangle_plane(&lane(&v0, k), &lane(&n, k), &o, &d, t_min, t_max);
                let (u, v, hit) = plane.edges(&lane(&e1, k), &lane(&e2, k), &d);
                assert_eq!(plane.hit, plane4.hit.test(k), "round {round}: triangle {k}'s plane");
                assert_eq!(hit, hit4.test(k), "round {round}: triangle {k}");
                let four = [plane4.t, plane4.a, u4, v4].map(|x| bits(x.to_array()[k]));
                assert_eq!([plane.t, plane.a, u, v].map(bits), four, "round {round}: triangle {k}");
                // The one-ray test divides exactly these.
                let one = tri.intersect(&r, t_min, t_max).map(|h| [h.t, h.u, h.v].map(bits));
                let t = plane.t / plane.a;
                let expected = (hit && t < t_max).then(|| [t, u / plane.a, v / plane.a].map(bits));
                assert_eq!(one, expected, "round {round}: triangle {k}");
                counts[0] += u32::from(hit);
            }

            let spheres: [Sphere; 4] = std::array::from_fn(|_| Sphere {
                center: Vec3A::from(point(4.0)),
                radius: 1.6 + point(1.5)[0],
            });
            let centre = axes(spheres.map(|s| s.center.to_array()));
            let r2 = Vec4::from_array(spheres.map(|s| s.radius * s.radius));
            let line4 = sphere_line(&centre, r2, &o4, &d4);
            let closest4 = line4.hit::<true>(r2, Vec4::splat(t_min), Vec4::splat(t_max));
            let shadow4 = line4.hit::<false>(r2, Vec4::splat(t_min), Vec4::splat(t_max));
            for (k, sphere) in spheres.iter().enumerate() {
                let r2 = sphere.radius * sphere.radius;
                let line = sphere_line(&lane(&centre, k), r2, &o, &d);
                assert_eq!(
                    bits(line.disc),
                    bits(line4.disc.to_array()[k]),
                    "round {round}: sphere {k}"
                );
                for ((hit, t), (hit4, t4)) in [
                    (line.hit::<true>(r2, t_min, t_max), closest4),
                    (line.hit::<false>(r2, t_min, t_max), shadow4),
                ] {
                    assert_eq!(hit, hit4.test(k), "round {round}: sphere {k}");
                    if hit {
                        assert_eq!(bits(t), bits(t4.to_array()[k]), "round {round}: sphere {k}");
                    }
                }
                let (hit, t) = line.hit::<false>(r2, t_min, t_max);
                let one = sphere.intersect(&r, t_min, t_max).map(|h| bits(h.t));
                assert_eq!(one, hit.then(|| bits(t)), "round {round}: sphere {k}");
                counts[1] += u32::from(hit);
            }

            let planes: [Plane; 4] = std::array::from_fn(|_| Plane {
                point: Vec3A::from(point(4.0)),
                normal: Vec3A::from(point(1.0)).normalize_or(Vec3A::Y),
            });
            let p4 = axes(planes.map(|p| p.point.to_array()));
            let n4 = axes(planes.map(|p| p.normal.to_array()));
            for ties in [false, true] {
                let (hit4, t4) = if ties {
                    plane_hit::<_, true>(&p4, &n4, &o4, &d4, Vec4::splat(t_min), Vec4::splat(t_max))
                } else {
                    plane_hit::<_, false>(&p4, &n4, &o4, &d4, Vec4::splat(t_min), Vec4::splat(t_max))
                };
                for (k, plane) in planes.iter().enumerate() {
                    let (p, n) = (lane(&p4, k), lane(&n4, k));
                    let (hit, t) = if ties {
                        plane_hit::<_, true>(&p, &n, &o, &d, t_min, t_max)
                    } else {
                        plane_hit::<_, false>(&p, &n, &o, &d, t_min, t_max)
                    };
                    assert_eq!(hit, hit4.test(k), "round {round}: plane {k}");
                    if hit {
                        assert_eq!(bits(t), bits(t4.to_array()[k]), "round {round}: plane {k}");
                    }
                    if !ties {
                        let one = plane.intersect(&r, t_min, t_max).map(|h| bits(h.t));
                        assert_eq!(one, hit.then(|| bits(t)), "round {round}: plane {k}");
                        counts[2] += u32::from(hit);
                    }
                }
            }
        }
        // Enough of each kind hit for the comparison to mean something.
        assert!(counts.iter().all(|&c| c > 5_000), "hits per kind: {counts:?}");
    }

    #[test]
    fn sphere_from_outside_inside_and_behind() {
        let s = Sphere {
            center: Vec3A::new(0.0, 0.0, 5.0),
            radius: 1.0,
        };
        let h = s
            .intersect(&ray([0.0; 3], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - 4.0).abs() < 1e-6);
        let h = s
            .intersect(&ray([0.0, 0.0, 5.0], [0.0, 1.0, 0.0]), 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - 1.0).abs() < 1e-6, "from the centre the far side is hit");
        assert!(s
            .intersect(&ray([0.0; 3], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY)
            .is_none());
        assert!(
            s.intersect(&ray([0.0; 3], [0.0, 0.0, 1.0]), 0.0, 3.9).is_none(),
            "t_max respected"
        );
    }

    #[test]
    fn sphere_grazing_and_tiny_far_away() {
        let s = Sphere {
            center: Vec3A::new(1.0, 0.0, 5.0),
            radius: 1.0,
        };
        // Tangent ray along x = 0 touches at t = 5.
        let h = s.intersect(&ray([0.0; 3], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY);
        assert!(h.is_none_or(|h| (h.t - 5.0).abs() < 1e-3));
        assert!(s
            .intersect(&ray([-0.001, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY)
            .is_none());
        let tiny = Sphere {
            center: Vec3A::new(0.0, 0.0, 1e4),
            radius: 1e-2,
        };
        let h = tiny
            .intersect(&ray([0.0; 3], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - (1e4 - 1e-2)).abs() < 2e-3, "t = {}", h.t);
    }

    #[test]
    fn triangle_two_sided_and_edges() {
        let t = Triangle::new(
            Vec3A::new(-1.0, -1.0, 2.0),
            Vec3A::new(0.0, 1.0, 2.0),
            Vec3A::new(1.0, -1.0, 2.0),
        );
        let h = t
            .intersect(&ray([0.0; 3], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY)
            .unwrap();
        assert!((h.t - 2.0).abs() < 1e-6);
        let back = t
            .intersect(&ray([0.0, 0.0, 4.0], [0.0, 0.0, -1.0]), 0.0, f32::INFINITY)
            .unwrap();
        assert!((back.t - 2.0).abs() < 1e-6, "back face is hit too");
        assert!(t
            .intersect(&ray([5.0, 0.0, 0.0], [0.0, 0.0, 1.0]), 0.0, f32::INFINITY)
            .is_none());
        let n = t.geometric_normal();
        assert!(
            (n - Vec3A::new(0.0, 0.0, -1.0)).length() < 1e-6,
            "normal = (v1−v0)×(v2−v0) = {n}"
        );
    }

    #[test]
    fn stored_normal_is_the_edges_normalised_bit_for_bit() {
        // Shading reads the stored normal; it must be exactly what normalising e1 × e2 gives,
        // or every rendered image would shift in its last bits.
        let mut rng = crate::rng::Rng::for_sample(3, 1, 4);
        let mut v = || Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 20.0 - Vec3A::splat(10.0);
        for _ in 0..10_000 {
            let t = Triangle::new(v(), v(), v());
            let n = t.e1().cross(t.e2()).normalize();
            assert_eq!(
                t.geometric_normal().to_array().map(f32::to_bits),
                n.to_array().map(f32::to_bits)
            );
            assert_eq!(t.vertices()[0], t.v0());
        }
    }

    #[test]
    fn degenerate_triangle_never_hit() {
        let t = Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::X * 2.0);
        assert!(t.is_degenerate());
        assert_eq!(t.geometric_normal(), Vec3A::ZERO, "no NaN is stored");
        assert_eq!(t, t);
        for d in [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]] {
            assert!(t.intersect(&ray([0.5, -1.0, -1.0], d), 0.0, f32::INFINITY).is_none());
        }
    }

    #[test]
    fn plane_parallel_and_both_sides() {
        let p = Plane {
            point: Vec3A::new(0.0, -1.0, 0.0),
            normal: Vec3A::Y,
        };
        assert!(p
            .intersect(&ray([0.0; 3], [1.0, 0.0, 0.0]), 0.0, f32::INFINITY)
            .is_none());
        assert!(
            (p.intersect(&ray([0.0; 3], [0.0, -1.0, 0.0]), 0.0, f32::INFINITY)
                .unwrap()
                .t
                - 1.0)
                .abs()
                < 1e-6
        );
        assert!(
            (p.intersect(&ray([0.0, -3.0, 0.0], [0.0, 1.0, 0.0]), 0.0, f32::INFINITY)
                .unwrap()
                .t
                - 2.0)
                .abs()
                < 1e-6
        );
    }
}
