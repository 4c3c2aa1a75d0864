//! OBJ models (C): the BVH's closest hit and any-hit answers equal a brute-force loop over every
//! primitive, for the course's bunny and for generated meshes.

use glam::Vec3A;
use rayscope_core::geometry::Primitive;
use rayscope_core::math::Ray;
use rayscope_core::rng::Rng;
use rayscope_core::sampling::uniform_sphere;
use rayscope_core::scene::PrimRef;
use rayscope_core::Scene;

mod common;
use common::one_material_file;

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

#[test]
fn bunny_bvh_matches_brute_force() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let path = course.scene("sample_scene_obj.txt");
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

/// A mesh of two triangles, the first with vertex normals `normals` (the second flat).
fn two_triangle_mesh(x: f32, normals: [glam::Vec3; 3]) -> rayscope_scene::Shape {
    use glam::Vec3;
    use rayscope_scene::{Mesh, MeshTriangle, Shape};
    let p = |a: f32, b: f32| Vec3::new(x + a, b, 3.0);
    Shape::Mesh {
        source: "m.obj".into(),
        offset: glam::DVec3::ZERO,
        scale: 1.0,
        mesh: Mesh {
            positions: vec![p(0.0, 0.0), p(1.0, 0.0), p(0.0, 1.0), p(1.0, 1.0)],
            // An unused normal first, so the used ones are not at index 0.
            normals: [vec![Vec3::X], normals.to_vec()].concat(),
            triangles: vec![
                MeshTriangle {
                    positions: [0, 1, 2],
                    normals: Some([1, 2, 3]),
                },
                MeshTriangle {
                    positions: [1, 3, 2],
                    normals: None,
                },
            ],
        },
    }
}

#[test]
fn vertex_normals_stay_with_their_triangles() {
    use glam::{DVec3, Vec3};
    use rayscope_scene::Shape;
    let flat = |x: f64| Shape::Triangle {
        vertices: [
            DVec3::new(x, 0.0, 3.0),
            DVec3::new(x + 1.0, 0.0, 3.0),
            DVec3::new(x, 1.0, 3.0),
        ],
    };
    let a = [Vec3::Z, Vec3::Y, Vec3::new(0.6, 0.0, 0.8)];
    let b = [Vec3::new(0.0, 0.6, 0.8), Vec3::NEG_Z, Vec3::X];
    let shapes = vec![
        flat(-4.0),
        two_triangle_mesh(-2.0, a),
        two_triangle_mesh(0.0, b),
        flat(2.0),
    ];
    let file = one_material_file(shapes.clone());
    let scene = Scene::from_file(&file);
    // Triangles in file order: flat, mesh a (smooth, flat), mesh b (smooth, flat), flat.
    let got: Vec<Option<[Vec3; 3]>> = (0..6).map(|i| scene.vertex_normals(i)).collect();
    assert_eq!(got, [None, Some(a), None, Some(b), None, None]);
    assert_eq!(
        scene.triangle_normals.len(),
        6,
        "one entry per triangle once any is smooth"
    );

    // A scene without vertex normals keeps none, whatever its size.
    let plain = Scene::from_file(&one_material_file(vec![flat(0.0), flat(2.0)]));
    assert!(plain.triangle_normals.is_empty() && plain.normals.is_empty());
    assert_eq!(plain.vertex_normals(1), None);

    // Converting a file the caller gives away builds the same scene.
    let owned = Scene::from_owned_file(one_material_file(shapes));
    assert_eq!(owned.triangles, scene.triangles);
    assert_eq!(owned.triangle_info, scene.triangle_info);
    assert_eq!((0..6).map(|i| owned.vertex_normals(i)).collect::<Vec<_>>(), got);
    assert_eq!(owned.wide.nodes.len(), scene.wide.nodes.len());
    assert_eq!(owned.wide.tris.len(), scene.wide.tris.len());
    let ray = Ray::new(Vec3A::new(0.2, 0.2, 0.0), Vec3A::Z);
    let hit = owned.intersect(&ray, 0.0, f32::INFINITY).expect("the ray meets mesh b");
    assert_eq!(hit.prim, PrimRef::Triangle(3));
    // Smooth shading uses mesh b's normals (interpolated at the hit), not mesh a's.
    let s = owned.surface(&ray, &hit);
    let w = 1.0 - hit.u - hit.v;
    let expect = (Vec3A::from(b[0]) * w + Vec3A::from(b[1]) * hit.u + Vec3A::from(b[2]) * hit.v).normalize();
    let expect = if expect.dot(s.normal) < 0.0 { -expect } else { expect };
    assert!(
        (s.shading_normal - expect).length() < 1e-5,
        "{:?} vs {expect:?}",
        s.shading_normal
    );
}
