//! Analytic ray–primitive intersection: plane, sphere and triangle.
//!
//! Every routine is two-sided and returns the nearest `t` in the open interval `(t_min, t_max)`.
//! Rays must have unit-length directions.

use glam::{Vec3A, Vec4};
use serde::Serialize;

use crate::math::{Aabb, Ray};

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
        let denom = self.normal.dot(ray.dir);
        // A ray parallel to the plane never meets it (one lying in it is treated as a miss too).
        if denom == 0.0 {
            return None;
        }
        let t = (self.point - ray.origin).dot(self.normal) / denom;
        (t > t_min && t < t_max).then_some(PrimHit { t, u: 0.0, v: 0.0 })
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
        // Numerically careful form (Haines et al., "Precision Improvements for Ray/Sphere
        // Intersection", Ray Tracing Gems ch. 7): the discriminant is computed from the distance
        // of the centre to the ray's line rather than as b² − c, which cancels catastrophically
        // for small or distant spheres.
        let f = ray.origin - self.center;
        let b = -f.dot(ray.dir);
        let l = f + ray.dir * b;
        let r2 = self.radius * self.radius;
        let disc = r2 - l.length_squared();
        if disc < 0.0 {
            return None;
        }
        let c = f.length_squared() - r2;
        let q = b + disc.sqrt().copysign(b);
        // Roots c/q and q: the stable pair whatever the sign of b.
        let (mut t0, mut t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
        if t0 > t1 {
            std::mem::swap(&mut t0, &mut t1);
        }
        if t0 > t_min && t0 < t_max {
            Some(PrimHit { t: t0, u: 0.0, v: 0.0 })
        } else if t1 > t_min && t1 < t_max {
            Some(PrimHit { t: t1, u: 0.0, v: 0.0 })
        } else {
            None
        }
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
    pub fn closest_point(&self, p: Vec3A) -> Vec3A {
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
        // Möller–Trumbore, two-sided, rearranged around the normal n = e1 × e2 (as Embree does):
        // with c = v0 − o and r = d × c, the barycentrics and distance are −(e2·r), e1·r and c·n
        // over d·n. Comparing numerators against |d·n| defers the division to a hit. The 4-wide
        // packets run exactly this arithmetic.
        let (e1, e2) = (self.e1(), self.e2());
        let n = e1.cross(e2);
        let c = self.v0() - ray.origin;
        let r = ray.dir.cross(c);
        let den = ray.dir.dot(n);
        if den == 0.0 {
            return None;
        }
        let s = 1f32.copysign(den);
        let a = den.abs();
        let u = e2.dot(r) * -s;
        let v = e1.dot(r) * s;
        let t = c.dot(n) * s;
        let inside = u >= 0.0 && v >= 0.0 && u + v <= a;
        if !(inside && t > t_min * a && t < t_max * a) {
            return None;
        }
        // The scaled test can pass by a rounding error for a hit no nearer than `t_max`.
        let t = t / a;
        (t < t_max).then(|| PrimHit { t, u: u / a, v: v / a })
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
