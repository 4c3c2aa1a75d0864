//! rayscope's own plane, sphere and triangle routines against parry3d on many random rays, plus
//! the classic hard cases: grazing rays, rays from on or inside a sphere, degenerate triangles,
//! rays parallel to planes, and "reintersect" (a ray leaving a hit must not hit the same surface).

use glam::Vec3A;
use proptest::prelude::*;
use rayscope_core::geometry::{Plane, PrimHit, Primitive, Sphere, Triangle};
use rayscope_core::math::{offset_eps, Ray};
use rayscope_core::optics::reflect;
use rayscope_core::reference;

fn v3() -> impl Strategy<Value = Vec3A> {
    (-3.0f32..3.0, -3.0f32..3.0, -3.0f32..3.0).prop_map(|(x, y, z)| Vec3A::new(x, y, z))
}

fn dir() -> impl Strategy<Value = Vec3A> {
    v3().prop_filter("non-zero", |d| d.length() > 0.1)
        .prop_map(|d| d.normalize())
}

/// Agreement up to the tolerance of f32 arithmetic, ignoring rays that graze within `margin` of
/// a silhouette or edge (where either answer is right).
fn agree(own: Option<PrimHit>, refh: Option<PrimHit>, graze: bool, what: &str) -> Result<(), TestCaseError> {
    agree_within(own, refh, graze, 1e-3, what)
}

/// [`agree`] with relative distance tolerance `tol`.
fn agree_within(
    own: Option<PrimHit>,
    refh: Option<PrimHit>,
    graze: bool,
    tol: f32,
    what: &str,
) -> Result<(), TestCaseError> {
    match (own, refh) {
        (Some(a), Some(b)) => {
            prop_assert!(
                (a.t - b.t).abs() <= tol * (1.0 + b.t),
                "{what}: t {} vs reference {}",
                a.t,
                b.t
            );
        }
        (None, None) => {}
        (a, b) => prop_assert!(graze, "{what}: own {a:?} vs reference {b:?}"),
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn sphere_matches_parry(o in v3(), d in dir(), c in v3(), r in 0.05f32..2.0) {
        let s = Sphere { center: c, radius: r };
        let ray = Ray::new(o, d);
        let own = s.intersect(&ray, 0.0, f32::INFINITY);
        let refh = reference::sphere(&s, &ray, 0.0, f32::INFINITY);
        // Distance of the centre from the ray's line, relative to the radius: ~1 means tangent.
        let along = (c - o).dot(d);
        let miss_dist = ((c - o) - d * along).length();
        let on_surface = ((o - c).length() - r).abs() < 1e-3;
        agree(own, refh, (miss_dist - r).abs() < 1e-3 * (1.0 + r) || on_surface, "sphere")?;
        if let Some(h) = own {
            let n = s.normal(&ray, &h);
            prop_assert!((n.length() - 1.0).abs() < 1e-4);
            prop_assert!(((ray.at(h.t) - c).length() - r).abs() < 1e-3 * (1.0 + r));
        }
    }

    #[test]
    fn triangle_matches_parry(o in v3(), d in dir(), a in v3(), b in v3(), c in v3()) {
        let t = Triangle::new(a, b, c);
        prop_assume!(!t.is_degenerate());
        let ray = Ray::new(o, d);
        let own = t.intersect(&ray, 0.0, f32::INFINITY);
        let refh = reference::triangle(&t, &ray, 0.0, f32::INFINITY);
        // Near an edge, or nearly parallel to the triangle's plane, either answer is right.
        let n = t.geometric_normal();
        let grazing_plane = n.dot(d).abs() < 1e-3;
        let near_edge = own.or(refh).is_some_and(|h| h.u.min(h.v).min(1.0 - h.u - h.v).abs() < 1e-3);
        let edge_from_ref = refh.is_some_and(|h| h.u < 1e-3 || h.v < 1e-3 || h.u + h.v > 1.0 - 1e-3);
        agree(own, refh, grazing_plane || near_edge || edge_from_ref || ray_near_triangle_edge(&ray, &t), "triangle")?;
        if let Some(h) = own {
            prop_assert!(h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0);
        }
    }

    #[test]
    fn plane_matches_parry(o in v3(), d in dir(), p in v3(), n in dir()) {
        let pl = Plane { point: p, normal: n };
        let ray = Ray::new(o, d);
        let own = pl.intersect(&ray, 0.0, f32::INFINITY);
        let refh = reference::plane(&pl, &ray, 0.0, f32::INFINITY);
        let parallel = n.dot(d).abs() < 1e-4;
        let on_plane = (o - p).dot(n).abs() < 1e-4;
        // t = (p − o)·n / d·n: the denominator's rounding (~1e-7) is relative to d·n, so a ray
        // nearly parallel to the plane gets a distance correct only to about 1e-7 / |d·n|
        // (a case found with |d·n| ≈ 3e-5 and the two distances 0.13 % apart).
        let tol = 1e-3f32.max(1e-7 / n.dot(d).abs());
        agree_within(own, refh, parallel || on_plane, tol, "plane")?;
    }

    #[test]
    fn reintersect_sphere_outside_and_inside(c in v3(), r in 0.05f32..2.0, d in dir(), o in v3()) {
        let s = Sphere { center: c, radius: r };
        let ray = Ray::new(o, d);
        if let Some(h) = s.intersect(&ray, 0.0, f32::INFINITY) {
            let p = ray.at(h.t);
            let mut n = s.normal(&ray, &h);
            if n.dot(d) > 0.0 { n = -n; }
            let eps = offset_eps(p, o);
            // Reflected ray leaving the outside (or inside) surface must not hit it again
            // on the same side: from outside it escapes, from inside it hits the far side.
            let refl = Ray::new(p + n * eps, reflect(d, n).normalize());
            let again = s.intersect(&refl, 0.0, f32::INFINITY);
            let inside = (o - c).length() < r;
            if !inside {
                prop_assert!(again.is_none(), "reflected ray re-hit the sphere at t={:?}", again);
            } else {
                prop_assert!(again.is_none_or(|g| g.t > eps), "self-hit at t={:?}", again);
            }
        }
    }

    #[test]
    fn reintersect_triangle_and_plane(o in v3(), d in dir(), a in v3(), b in v3(), c in v3()) {
        let t = Triangle::new(a, b, c);
        prop_assume!(!t.is_degenerate());
        let ray = Ray::new(o, d);
        if let Some(h) = t.intersect(&ray, 0.0, f32::INFINITY) {
            let p = ray.at(h.t);
            let mut n = t.geometric_normal();
            if n.dot(d) > 0.0 { n = -n; }
            let refl = Ray::new(p + n * offset_eps(p, o), reflect(d, n).normalize());
            prop_assert!(t.intersect(&refl, 0.0, f32::INFINITY).is_none());
            let pl = Plane { point: a, normal: t.geometric_normal() };
            prop_assert!(pl.intersect(&refl, 0.0, f32::INFINITY).is_none());
        }
    }
}

fn ray_near_triangle_edge(ray: &Ray, t: &Triangle) -> bool {
    // Distance between the ray's line and each edge line, relative to the scene scale.
    let [a, b, c] = t.vertices();
    [(a, b), (b, c), (c, a)].iter().any(|&(p, q)| {
        let e = q - p;
        let n = ray.dir.cross(e);
        n.length() > 1e-6 && ((p - ray.origin).dot(n) / n.length()).abs() < 1e-3
    })
}

#[test]
fn rays_starting_on_a_sphere_surface() {
    let s = Sphere {
        center: Vec3A::ZERO,
        radius: 1.0,
    };
    // Outward from a surface point: no hit once offset; inward: the far side at t ≈ 2.
    let p = Vec3A::new(0.0, 0.0, -1.0);
    assert!(s
        .intersect(&Ray::new(p - Vec3A::Z * 1e-5, -Vec3A::Z), 0.0, f32::INFINITY)
        .is_none());
    let h = s
        .intersect(&Ray::new(p + Vec3A::Z * 1e-5, Vec3A::Z), 0.0, f32::INFINITY)
        .unwrap();
    assert!((h.t - 2.0).abs() < 1e-4);
}

#[test]
fn ray_parallel_to_plane_and_inside_it() {
    let pl = Plane {
        point: Vec3A::ZERO,
        normal: Vec3A::Y,
    };
    assert!(pl
        .intersect(&Ray::new(Vec3A::Y, Vec3A::X), 0.0, f32::INFINITY)
        .is_none());
    assert!(pl
        .intersect(&Ray::new(Vec3A::ZERO, Vec3A::X), 0.0, f32::INFINITY)
        .is_none());
}

#[test]
fn degenerate_triangles_are_never_hit() {
    let cases = [
        Triangle::new(Vec3A::ZERO, Vec3A::ZERO, Vec3A::ZERO),
        Triangle::new(Vec3A::ZERO, Vec3A::X, Vec3A::X * 3.0),
        Triangle::new(Vec3A::ONE, Vec3A::ONE, Vec3A::Z),
    ];
    for t in cases {
        assert!(t.is_degenerate());
        for d in [Vec3A::X, Vec3A::Y, Vec3A::Z, Vec3A::ONE.normalize()] {
            assert!(t
                .intersect(&Ray::new(Vec3A::new(0.3, -2.0, -2.0), d), 0.0, f32::INFINITY)
                .is_none());
        }
    }
}

#[test]
fn grazing_sphere_rays_do_not_produce_nan() {
    let s = Sphere {
        center: Vec3A::new(0.0, 0.0, 5.0),
        radius: 1.0,
    };
    for i in 0..1000 {
        let x = 1.0 - 1e-3 + i as f32 * 2e-6;
        let ray = Ray::new(Vec3A::new(x, 0.0, 0.0), Vec3A::Z);
        if let Some(h) = s.intersect(&ray, 0.0, f32::INFINITY) {
            assert!(h.t.is_finite() && s.normal(&ray, &h).is_finite());
        }
    }
}
