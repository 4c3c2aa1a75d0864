//! An independent intersector built on parry3d, used to check rayscope's own routines (tests,
//! and the debugger's per-pixel self-test of the intersector).
//!
//! It tests every primitive for every ray (no BVH), so it is slow but shares no code with
//! [`crate::geometry`] or [`crate::accel`].

use glam::Vec3A;
use parry3d::math::{Pose, Vector};
use parry3d::query::{Ray as PRay, RayCast};
use parry3d::shape::{Ball, HalfSpace, Triangle as PTriangle};

use crate::geometry::{Plane, PrimHit, PrimRef, Sphere, Triangle};
use crate::math::Ray;
use crate::scene::{Hit, Intersect, Scene};

fn pray(ray: &Ray, t_min: f32) -> PRay {
    let o = ray.at(t_min);
    PRay::new(Vector::new(o.x, o.y, o.z), Vector::new(ray.dir.x, ray.dir.y, ray.dir.z))
}

/// parry3d's answer for a sphere, as a [`PrimHit`] (two-sided: hits from inside too).
#[must_use]
pub fn sphere(s: &Sphere, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
    let iso = Pose::translation(s.center.x, s.center.y, s.center.z);
    let t = Ball::new(s.radius).cast_ray(&iso, &pray(ray, t_min), t_max - t_min, false)?;
    let t = t + t_min;
    (t > t_min && t < t_max).then_some(PrimHit { t, u: 0.0, v: 0.0 })
}

/// parry3d's answer for a triangle (two-sided), with barycentrics recomputed from the hit point.
#[must_use]
pub fn triangle(tri: &Triangle, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
    let [a, b, c] = tri.vertices();
    let p = |v: Vec3A| Vector::new(v.x, v.y, v.z);
    let shape = PTriangle::new(p(a), p(b), p(c));
    let t = shape.cast_local_ray(&pray(ray, t_min), t_max - t_min, false)? + t_min;
    if !(t > t_min && t < t_max) {
        return None;
    }
    // Barycentrics of the hit point, for smooth normals.
    let (q, e1, e2) = (ray.at(t) - a, tri.e1(), tri.e2());
    let (d00, d01, d11) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (d20, d21) = (q.dot(e1), q.dot(e2));
    let den = d00 * d11 - d01 * d01;
    let u = (d11 * d20 - d01 * d21) / den;
    let v = (d00 * d21 - d01 * d20) / den;
    Some(PrimHit { t, u, v })
}

/// parry3d's answer for an infinite plane, seen from either side.
#[must_use]
pub fn plane(pl: &Plane, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimHit> {
    // parry's half-space is solid; cast from the side the origin is on so it reports the boundary.
    let o = ray.at(t_min);
    let side = (o - pl.point).dot(pl.normal);
    let n = if side >= 0.0 { pl.normal } else { -pl.normal };
    let shape = HalfSpace::new(Vector::new(n.x, n.y, n.z).normalize());
    let iso = Pose::translation(pl.point.x, pl.point.y, pl.point.z);
    let t = shape.cast_ray(&iso, &pray(ray, t_min), t_max - t_min, false)? + t_min;
    (t > t_min && t < t_max).then_some(PrimHit { t, u: 0.0, v: 0.0 })
}

/// Brute-force scene intersection through parry3d.
#[derive(Debug, Clone, Copy)]
pub struct ReferenceIntersector<'a> {
    /// The scene whose primitives are tested.
    pub scene: &'a Scene,
}

impl Intersect for ReferenceIntersector<'_> {
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let s = self.scene;
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        let mut take = |h: Option<PrimHit>, prim: PrimRef, t_max: &mut f32| {
            if let Some(h) = h {
                *t_max = h.t;
                best = Some(Hit {
                    t: h.t,
                    u: h.u,
                    v: h.v,
                    prim,
                });
            }
        };
        for (i, p) in s.planes.iter().enumerate() {
            take(plane(p, ray, t_min, t_max), PrimRef::Plane(i as u32), &mut t_max);
        }
        for (i, p) in s.spheres.iter().enumerate() {
            take(sphere(p, ray, t_min, t_max), PrimRef::Sphere(i as u32), &mut t_max);
        }
        for (i, p) in s.triangles.iter().enumerate() {
            take(triangle(p, ray, t_min, t_max), PrimRef::Triangle(i as u32), &mut t_max);
        }
        best
    }

    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        self.intersect(ray, t_min, t_max).map(|h| h.prim)
    }
}
