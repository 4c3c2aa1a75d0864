//! OBJ models (C): the BVH's closest hit and any-hit answers equal a brute-force loop over every
//! primitive, for the course's bunny and for generated meshes.

use std::path::{Path, PathBuf};

use glam::Vec3A;
use rayscope_core::geometry::Primitive;
use rayscope_core::math::Ray;
use rayscope_core::rng::Rng;
use rayscope_core::sampling::uniform_sphere;
use rayscope_core::scene::PrimRef;
use rayscope_core::Scene;

/// The closest hit by testing every plane, sphere and triangle.
fn brute(scene: &Scene, ray: &Ray) -> Option<(f32, PrimRef)> {
    let mut best: Option<(f32, PrimRef)> = None;
    let mut t_max = f32::INFINITY;
    let mut take = |t: f32, p: PrimRef, t_max: &mut f32| {
        if t < *t_max {
            *t_max = t;
            best = Some((t, p));
        }
    };
    for (i, p) in scene.planes.iter().enumerate() {
        if let Some(h) = p.intersect(ray, 0.0, t_max) {
            take(h.t, PrimRef::Plane(i as u32), &mut t_max);
        }
    }
    for (i, s) in scene.spheres.iter().enumerate() {
        if let Some(h) = s.intersect(ray, 0.0, t_max) {
            take(h.t, PrimRef::Sphere(i as u32), &mut t_max);
        }
    }
    for (i, t) in scene.triangles.iter().enumerate() {
        if let Some(h) = t.intersect(ray, 0.0, t_max) {
            take(h.t, PrimRef::Triangle(i as u32), &mut t_max);
        }
    }
    best
}

/// Fires `n` random rays (from inside and around the scene's bounds, towards random points and
/// random directions) and compares the BVH with brute force. Returns the number of hits.
fn check(scene: &Scene, n: u32) -> u32 {
    let b = scene.bounds;
    let (c, ext) = (b.center(), (b.max - b.min).max_element());
    let mut rng = Rng::for_sample(3, 1, 4);
    let mut hits = 0;
    for i in 0..n {
        let mut p = || Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let inside = b.min + (b.max - b.min) * p();
        let around = c + (p() - Vec3A::splat(0.5)) * (3.0 * ext);
        let (origin, dir) = match i % 3 {
            0 => (around, (inside - around).normalize()),
            1 => (inside, uniform_sphere(rng.next_f32(), rng.next_f32())),
            _ => (around, uniform_sphere(rng.next_f32(), rng.next_f32())),
        };
        if !dir.is_finite() {
            continue;
        }
        let ray = Ray::new(origin, dir);
        let want = brute(scene, &ray);
        let got = scene.intersect(&ray, 0.0, f32::INFINITY);
        match (want, got) {
            (None, None) => {}
            (Some((t, p)), Some(h)) => {
                hits += 1;
                assert!((h.t - t).abs() <= 1e-6 * (1.0 + t), "ray {i}: t {} vs brute {t}", h.t);
                // Equal t from two primitives (shared edges) may pick either one.
                if h.prim != p {
                    assert_eq!(h.t, t, "ray {i}: {:?} vs brute {p:?}", h.prim);
                }
            }
            (w, g) => panic!("ray {i}: BVH {g:?} vs brute {w:?}"),
        }
        // Any-hit queries agree with the closest hit over shortened segments too.
        for frac in [0.5f32, 1.5] {
            let t_max = want.map_or(10.0 * ext, |(t, _)| t * frac);
            assert_eq!(
                scene.occluded(&ray, 0.0, t_max),
                brute(scene, &ray).is_some_and(|(t, _)| t < t_max),
                "ray {i}: occlusion to {t_max}"
            );
        }
    }
    hits
}

fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference")
}

#[test]
fn bunny_bvh_matches_brute_force() {
    let path = reference_dir().join("tests/sample_scene_obj.txt");
    if !path.exists() {
        eprintln!("skipped: {} not found", path.display());
        return;
    }
    let file = rayscope_scene::load(&path).expect("bunny scene loads");
    let scene = Scene::from_file(&file);
    assert!(scene.triangles.len() > 4968, "bunny plus walls");
    let hits = check(&scene, 3000);
    assert!(hits > 1500, "most rays should hit: {hits}");
}

/// A UV sphere with normals and a random triangle soup, written as OBJ files and loaded through
/// `ObjModel` lines.
#[test]
fn generated_meshes_bvh_matches_brute_force() {
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    let (nu, nv) = (40, 24);
    for j in 0..=nv {
        for i in 0..nu {
            let (th, ph) = (
                std::f32::consts::PI * j as f32 / nv as f32,
                2.0 * std::f32::consts::PI * i as f32 / nu as f32,
            );
            let (x, y, z) = (th.sin() * ph.cos(), th.cos(), th.sin() * ph.sin());
            obj += &format!("v {x} {y} {z}\nvn {x} {y} {z}\n");
        }
    }
    for j in 0..nv {
        for i in 0..nu {
            let a = j * nu + i + 1;
            let b = j * nu + (i + 1) % nu + 1;
            let (c, d) = (a + nu, b + nu);
            obj += &format!("f {a}//{a} {b}//{b} {d}//{d}\nf {a}//{a} {d}//{d} {c}//{c}\n");
        }
    }
    std::fs::write(dir.path().join("ball.obj"), obj).unwrap();
    let mut soup = String::new();
    let mut rng = Rng::for_sample(9, 9, 9);
    for k in 0..3000 {
        let c = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0;
        for _ in 0..3 {
            let v = c + Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.3;
            soup += &format!("v {} {} {}\n", v.x, v.y, v.z);
        }
        soup += &format!("f {} {} {}\n", 3 * k + 1, 3 * k + 2, 3 * k + 3);
    }
    std::fs::write(dir.path().join("soup.obj"), soup).unwrap();
    let scene_text = "Material \"M\" Diffuse (1, 1, 1) 1\n\
        ObjModel \"Ball\" \"ball.obj\" (0, 0, 3) 1 \"M\"\n\
        ObjModel \"Ball2\" \"ball.obj\" (2, 1, 5) 0.5 \"M\"\n\
        ObjModel \"Soup\" \"soup.obj\" (-2, -2, 2) 1 \"M\"\n\
        Sphere \"S\" (1, 0, 4) 0.5 \"M\"\nPlane \"P\" (0, -3, 0) (0, 1, 0) \"M\"\n";
    let scene_path = dir.path().join("scene.txt");
    std::fs::write(&scene_path, scene_text).unwrap();
    let file = rayscope_scene::load(&scene_path).expect("generated scene loads");
    let scene = Scene::from_file(&file);
    // Two balls (the poles' degenerate triangles are dropped) and the soup.
    assert!(scene.triangles.len() >= 2 * 2 * nu as usize * (nv as usize - 1) + 2900);
    let hits = check(&scene, 6000);
    assert!(hits > 3000, "most rays should hit: {hits}");
}
