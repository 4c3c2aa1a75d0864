//! The 4-wide BVH against the binary BVH and against the parry3d brute force, on scenes that mix
//! spheres, triangles and planes (mixed leaves, padded packets, flat packet lists for tiny scenes,
//! plane packets) and on rays from inside and outside.

use glam::{DVec3, Vec3A};
use rayscope_core::accel::{Bvh, Bvh4, BvhNode, WideHit, INTERLEAVE_BYTES};
use rayscope_core::geometry::{Primitive, Triangle};
use rayscope_core::math::{Ray, RayPacket};
use rayscope_core::reference::ReferenceIntersector;
use rayscope_core::rng::Rng;
use rayscope_core::scene::{BinaryReference, Intersect, PrimRef, Scene};
use rayscope_core::simd::LANES;
use rayscope_scene::{EntityDef, Shape};

mod common;
use common::one_material_file;

fn random_scene(seed: u64, spheres: usize, triangles: usize) -> Scene {
    random_scene_with_planes(seed, spheres, triangles, 0)
}

/// A scene file with one diffuse material, "M", and no entities yet.
fn random_scene_with_planes(seed: u64, spheres: usize, triangles: usize, planes: usize) -> Scene {
    let mut rng = Rng::for_sample(seed, 0, 0);
    let mut r = move || rng.next_f32() as f64;
    let mut file = one_material_file(Vec::new());
    for i in 0..spheres {
        let c = DVec3::new(r() * 8.0 - 4.0, r() * 8.0 - 4.0, r() * 8.0 + 1.0);
        file.entities.push(EntityDef {
            name: format!("S{i}"),
            shape: Shape::Sphere {
                center: c,
                radius: 0.05 + r() * 0.6,
            },
            material: 0,
            line: i + 2,
        });
    }
    for i in 0..triangles {
        let c = DVec3::new(r() * 8.0 - 4.0, r() * 8.0 - 4.0, r() * 8.0 + 1.0);
        let mut v = || c + DVec3::new(r() - 0.5, r() - 0.5, r() - 0.5) * 1.5;
        let vertices = [v(), v(), v()];
        file.entities.push(EntityDef {
            name: format!("T{i}"),
            shape: Shape::Triangle { vertices },
            material: 0,
            line: i + 2,
        });
    }
    for i in 0..planes {
        let normal = loop {
            let n = DVec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0);
            if n.length_squared() > 0.01 {
                break n.normalize();
            }
        };
        file.entities.push(EntityDef {
            name: format!("P{i}"),
            shape: Shape::Plane {
                point: DVec3::new(r() * 8.0 - 4.0, r() * 8.0 - 4.0, r() * 8.0 + 1.0),
                normal,
            },
            material: 0,
            line: i + 2,
        });
    }
    Scene::from_file(&file)
}

fn random_rays(seed: u64, n: usize) -> Vec<Ray> {
    let mut rng = Rng::for_sample(seed, 1, 0);
    (0..n)
        .map(|_| {
            let o = Vec3A::new(
                rng.next_f32() * 10.0 - 5.0,
                rng.next_f32() * 10.0 - 5.0,
                rng.next_f32() * 10.0,
            );
            let d = loop {
                let d = Vec3A::new(
                    rng.next_f32() * 2.0 - 1.0,
                    rng.next_f32() * 2.0 - 1.0,
                    rng.next_f32() * 2.0 - 1.0,
                );
                if d.length_squared() > 0.01 && d.length_squared() <= 1.0 {
                    break d.normalize();
                }
            };
            Ray::new(o, d)
        })
        .collect()
}

#[test]
fn wide_equals_binary_and_brute_force() {
    // Up to four packets are tested as a flat list, more through the tree; planes go in packets
    // of four (five planes leave three padding lanes).
    for (seed, spheres, tris, planes) in [
        (1, 0, 1, 0),
        (2, 1, 0, 0),
        (3, 3, 5, 0),
        (4, 40, 0, 0),
        (5, 0, 300, 0),
        (6, 200, 800, 0),
        (7, 2, 6, 1),
        (8, 0, 0, 5),
        (9, 30, 120, 5),
        // Large enough (over 1 MiB of nodes and packets) for the walks to prefetch.
        (10, 100, 16_000, 0),
    ] {
        let scene = random_scene_with_planes(seed, spheres, tris, planes);
        assert!(
            !scene.wide.deep,
            "seed {seed}: ordinary trees fit the fixed traversal stack"
        );
        assert_eq!(
            scene.wide.prefetch,
            scene.wide.memory_bytes() > 1 << 20,
            "seed {seed}: prefetching only for trees larger than a core's cache"
        );
        assert_eq!(scene.wide.prefetch, seed == 10, "seed {seed}");
        let packets = tris.div_ceil(4) + spheres.div_ceil(4);
        assert_eq!(
            scene.wide.flat.len(),
            if packets <= 4 { packets } else { 0 },
            "seed {seed}: flat list only for tiny scenes"
        );
        let reference = ReferenceIntersector { scene: &scene };
        let binary = BinaryReference::new(&scene);
        let mut disagree = 0;
        let rays = random_rays(seed, 3000);
        for ray in &rays {
            let w = scene.intersect(ray, 0.0, f32::INFINITY);
            let b = binary.intersect(ray, 0.0, f32::INFINITY);
            // The wide and binary BVH run the same arithmetic on the same primitives.
            match (w, b) {
                (Some(w), Some(b)) => assert!((w.t - b.t).abs() <= 1e-5 * (1.0 + b.t), "seed {seed}: {w:?} vs {b:?}"),
                (None, None) => {}
                _ => panic!("seed {seed}: wide {w:?} vs binary {b:?} for {ray:?}"),
            }
            let r = reference.intersect(ray, 0.0, f32::INFINITY);
            match (w, r) {
                (Some(w), Some(r)) if (w.t - r.t).abs() <= 1e-3 * (1.0 + r.t) => {}
                (None, None) => {}
                // Silhouettes and edges may legitimately differ in the last bits.
                _ => disagree += 1,
            }
            // Any-hit agrees with closest-hit about whether something is there.
            assert_eq!(scene.occluded(ray, 0.0, f32::INFINITY), w.is_some());
            if let Some(w) = w {
                let t_max = w.t * 1.0001 + 1e-6;
                assert!(scene.occluded(ray, 0.0, t_max));
                assert!(
                    !scene.occluded(ray, 0.0, w.t * 0.999),
                    "nothing is nearer than the closest hit"
                );
                // The occluder it names (the debugger shows it) really lies on the ray.
                let p = scene.occluder(ray, 0.0, t_max).expect("occluded");
                assert!(
                    prim_hit(&scene, p, ray, t_max),
                    "seed {seed}: {p:?} named as the occluder is not on the ray"
                );
            }
        }
        assert!(
            disagree <= rays.len() / 500,
            "seed {seed}: {disagree} of {} rays disagree with parry3d",
            rays.len()
        );
    }
}

/// True when primitive `p` of `scene` meets `ray` with `0 < t < t_max`, by its own test.
fn prim_hit(scene: &Scene, p: PrimRef, ray: &Ray, t_max: f32) -> bool {
    match p {
        PrimRef::Plane(i) => scene.planes[i as usize].intersect(ray, 0.0, t_max).is_some(),
        PrimRef::Sphere(i) => scene.spheres[i as usize].intersect(ray, 0.0, t_max).is_some(),
        PrimRef::Triangle(i) => scene.triangles[i as usize].intersect(ray, 0.0, t_max).is_some(),
    }
}

#[test]
fn paired_queries_return_what_the_two_queries_return() {
    // The path tracer asks for a bounce ray's closest hit and a shadow ray's any hit together.
    // In a small room (the single-ray list) and in a tiny scene (the flat list) both go through
    // the list in one loop; in a tree one after the other. Either way the answers are the
    // separate queries' answers, with the shadow ray's end placed just before, at and just after
    // what it meets.
    let room = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/emissive.txt");
    let room = Scene::from_file(&rayscope_scene::load(&room).expect("our scene loads"));
    assert!(!room.wide.single.is_empty(), "the room is a list for single rays");
    let mut scenes = vec![("room", room)];
    for (seed, spheres, tris, planes) in [(61, 3, 10, 2), (62, 40, 300, 0), (63, 30, 120, 5)] {
        scenes.push(("random", random_scene_with_planes(seed, spheres, tris, planes)));
    }
    let w = |k: usize| &scenes[k].1.wide;
    assert!(
        w(1).root == u32::MAX && !w(1).flat.is_empty(),
        "a tiny scene, one flat list"
    );
    assert!(w(2).root != u32::MAX && w(2).single.is_empty(), "a tree");
    for (k, (name, scene)) in scenes.iter().enumerate() {
        // Rays from inside the scene's bounds, as from a path's vertices; a shadow ray starts
        // where its bounce ray does.
        let mut rng = Rng::for_sample(70 + k as u64, 0, 0);
        let mut r = move || rng.next_f32();
        let (lo, size) = (scene.bounds.min, scene.bounds.max - scene.bounds.min);
        let (mut blocked, mut clear) = (0, 0);
        for _ in 0..1000 {
            let o = lo + size * Vec3A::new(r(), r(), r()).clamp(Vec3A::splat(0.05), Vec3A::splat(0.95));
            let mut dir = || (Vec3A::new(r(), r(), r()) - Vec3A::splat(0.5)).normalize();
            let (bounce, shadow) = (Ray::new(o, dir()), Ray::new(o, dir()));
            let bounce = &bounce;
            let first = scene.intersect(&shadow, 0.0, f32::INFINITY).map_or(5.0, |h| h.t);
            for t_max in [first * 0.999, first, first * 1.001, f32::INFINITY] {
                let want = (
                    scene.intersect(bounce, 0.0, f32::INFINITY),
                    scene.occluded(&shadow, 0.0, t_max),
                );
                assert_eq!(
                    scene.intersect_and_occluded(bounce, &shadow, t_max),
                    want,
                    "{name} {k}: {bounce:?}, {shadow:?} to {t_max}"
                );
                if want.1 {
                    blocked += 1;
                } else {
                    clear += 1;
                }
            }
        }
        assert!(
            blocked > 200 && clear > 200,
            "{name} {k}: {blocked} blocked, {clear} clear"
        );
    }
}

#[test]
fn hits_report_the_right_primitive_kind() {
    let scene = random_scene(9, 1, 0);
    let s = scene.spheres[0];
    let ray = Ray::new(s.center - Vec3A::Z * (s.radius + 1.0), Vec3A::Z);
    let h = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap();
    assert_eq!(h.prim, PrimRef::Sphere(0));
    assert!((h.t - 1.0).abs() < 1e-4);
    // From inside, the far side is hit.
    let inside = Ray::new(s.center, Vec3A::Z);
    assert!((scene.intersect(&inside, 0.0, f32::INFINITY).unwrap().t - s.radius).abs() < 1e-4);
}

#[test]
fn axis_parallel_rays_through_slab_planes() {
    // Rays exactly along an axis, starting on a bounding-box plane, must still find the geometry.
    let scene = random_scene(11, 0, 200);
    let binary = BinaryReference::new(&scene);
    for t in 0..scene.triangles.len() {
        let [a, b, c] = scene.triangles[t].vertices();
        let centroid = (a + b + c) / 3.0;
        for d in [Vec3A::X, Vec3A::Y, Vec3A::Z, -Vec3A::X, -Vec3A::Y, -Vec3A::Z] {
            let ray = Ray::new(centroid - d * 20.0, d);
            let w = scene.intersect(&ray, 0.0, f32::INFINITY);
            let b = binary.intersect(&ray, 0.0, f32::INFINITY);
            assert_eq!(w.map(|h| h.prim), b.map(|h| h.prim));
            // In a packet, beside an oblique ray (the packet opens nodes for either).
            let oblique = Ray::new(Vec3A::new(-9.0, 3.0, -2.0), Vec3A::new(1.0, -0.3, 0.8).normalize());
            let mut p = packet_of(&[ray, oblique], &[f32::INFINITY; 2]);
            assert_eq!(
                scene.wide.closest_rays(&mut p, 0.0).get(0).map(|h| h.3),
                w.map(|h| h.prim)
            );
        }
    }
}

#[test]
fn degenerate_rays_hit_nothing_and_never_panic() {
    // Found by the render_tiny property test: a NaN ray passed every slab test and followed an
    // empty child slot.
    for (spheres, tris) in [(1, 0), (0, 1), (2, 3), (5, 40)] {
        let scene = random_scene(13, spheres, tris);
        for (o, d) in [
            (Vec3A::ZERO, Vec3A::new(f32::NAN, 0.0, 1.0)),
            (Vec3A::new(f32::NAN, 0.0, 0.0), Vec3A::Z),
            (Vec3A::ZERO, Vec3A::new(f32::INFINITY, 0.0, 0.0)),
            (Vec3A::splat(f32::NEG_INFINITY), Vec3A::Z),
            (Vec3A::ZERO, Vec3A::ZERO),
        ] {
            let ray = Ray::new(o, d);
            assert!(scene.intersect(&ray, 0.0, f32::INFINITY).is_none());
            assert!(!scene.occluded(&ray, 0.0, f32::INFINITY));
            let mut p = packet_of(&[ray; LANES], &[f32::INFINITY; LANES]);
            let hits = scene.wide.closest_rays(&mut p, 0.0);
            assert!((0..LANES).all(|i| hits.get(i).is_none()));
            let mut p = packet_of(&[ray; LANES], &[f32::INFINITY; LANES]);
            assert_eq!(scene.wide.occluded_rays(&mut p, 0.0), [false; LANES]);
        }
    }
}

#[test]
fn deep_trees_never_lose_a_branch() {
    // A binary BVH shaped like a chain (each node: one triangle, then the rest), as a binned SAH
    // can build for pathological inputs. Collapsed, every 4-wide level holds three leaves and the
    // rest of the chain, so a ray meeting every triangle keeps three entries per level on its
    // stack: 40 levels need 120, more than the 64 kept on the machine stack. The deepest triangle
    // is the nearest and must still be found.
    let depth = 120;
    let triangles: Vec<Triangle> = (0..depth)
        .map(|i| {
            let x = 0.5 + 0.001 * i as f32;
            Triangle::new(
                Vec3A::new(x, -1.0, -1.0),
                Vec3A::new(x, 2.0, -1.0),
                Vec3A::new(x, -1.0, 2.0),
            )
        })
        .collect();
    let bounds_from = |i: usize| {
        triangles[i..]
            .iter()
            .fold(rayscope_core::math::Aabb::EMPTY, |b, t| b.union(t.bounds()))
    };
    let mut nodes = Vec::new();
    for (i, t) in triangles.iter().enumerate() {
        if i + 1 < depth {
            // Interior node at 2i: left child (its triangle) at 2i + 1, the rest at 2i + 2.
            let all = bounds_from(i);
            nodes.push(BvhNode {
                min: all.min.into(),
                max: all.max.into(),
                offset: 2 * i as u32 + 2,
                count: 0,
                axis: 0,
            });
        }
        let own = t.bounds();
        nodes.push(BvhNode {
            min: own.min.into(),
            max: own.max.into(),
            offset: i as u32,
            count: 1,
            axis: 0,
        });
    }
    let bvh = Bvh {
        nodes,
        prims: (0..depth as u32).collect(),
    };
    let wide = Bvh4::from_binary(&bvh, &triangles, &[], 1 << 31, &[]);
    assert!(
        wide.depth() > 21,
        "deeper than 64 stack entries cover: {}",
        wide.depth()
    );
    for (y, z) in [(0.1, 0.1), (0.0, 0.0), (-0.5, 0.7)] {
        let ray = Ray::new(Vec3A::new(2.0, y, z), -Vec3A::X);
        let hit = wide.closest::<false>(&ray, 0.0, f32::INFINITY, &mut 0).map(|h| h.prim);
        assert_eq!(
            hit,
            Some(PrimRef::Triangle(depth as u32 - 1)),
            "the nearest triangle is the deepest"
        );
        assert_eq!(wide.any(&ray, 0.0, 1.3).map(|_| ()), None, "nothing nearer than 1.38");
        assert!(wide.any(&ray, 0.0, 1.4).is_some());
        let mut p = packet_of(&[ray], &[f32::INFINITY]);
        assert_eq!(
            wide.closest_rays(&mut p, 0.0).get(0).map(|h| h.3),
            Some(PrimRef::Triangle(depth as u32 - 1)),
            "packets too"
        );
        let mut p = packet_of(&[ray, ray], &[1.3, 1.4]);
        assert_eq!(wide.occluded_rays(&mut p, 0.0)[..2], [false, true]);
    }
}

/// Packs `rays[..16]` into a ray packet with interval ends `t_max`.
fn packet_of(rays: &[Ray], t_max: &[f32]) -> RayPacket {
    let mut p = RayPacket::default();
    for (i, (r, &t)) in rays.iter().zip(t_max).enumerate() {
        p.set(i, r, t);
    }
    p
}

/// `rays` (at most sixteen) as one shadow packet with interval ends `ends`: each lane is blocked
/// exactly when the ray alone is, and unused lanes never are.
fn assert_shadow_packet(scene: &Scene, rays: &[Ray], ends: &[f32], context: &str) {
    let mut p = packet_of(rays, ends);
    let blocked = scene.wide.occluded_rays(&mut p, 0.0);
    for (i, ray) in rays.iter().enumerate() {
        assert_eq!(
            blocked[i],
            scene.occluded(ray, 0.0, ends[i]),
            "{context}: shadow lane {i}"
        );
    }
    assert!(blocked[rays.len()..].iter().all(|b| !b), "{context}: unused lanes");
}

#[test]
fn ray_packets_return_what_single_rays_return() {
    for (seed, spheres, tris, planes) in [
        (21, 0, 1, 0),
        (22, 2, 6, 1),
        (23, 3, 5, 3),
        (24, 40, 0, 0),
        (25, 0, 300, 0),
        (26, 200, 800, 5),
        // Over 1 MiB: the packet walks prefetch.
        (27, 100, 16_000, 0),
    ] {
        let scene = random_scene_with_planes(seed, spheres, tris, planes);
        assert_eq!(scene.wide.prefetch, seed == 27, "seed {seed}");
        let mut rng = Rng::for_sample(seed, 2, 0);
        // Incoherent packets, and coherent ones (a shared origin, nearby directions), some
        // partly filled.
        let mut packets: Vec<Vec<Ray>> = random_rays(seed, 16 * 150).chunks(16).map(<[Ray]>::to_vec).collect();
        for (k, r) in random_rays(seed + 100, 150).iter().enumerate() {
            let n = if k % 5 == 0 { 1 + k % 16 } else { LANES };
            let spread = 0.05 + 0.2 * rng.next_f32();
            packets.push(
                (0..n)
                    .map(|_| {
                        let j = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - Vec3A::splat(0.5);
                        Ray::new(r.origin, (r.dir + j * spread).normalize())
                    })
                    .collect(),
            );
        }
        for rays in &packets {
            let inf = vec![f32::INFINITY; rays.len()];
            let mut p = packet_of(rays, &inf);
            let hits = scene.wide.closest_rays(&mut p, 0.0);
            for (i, ray) in rays.iter().enumerate() {
                let single = scene
                    .intersect(ray, 0.0, f32::INFINITY)
                    .map(|h| (h.t, h.u, h.v, h.prim));
                assert_eq!(hits.get(i), single, "seed {seed}: lane {i} of {}, {ray:?}", rays.len());
            }
            for i in rays.len()..LANES {
                assert_eq!(hits.get(i), None, "unused lanes hit nothing");
            }
            // Shadow queries with random interval ends around the closest hit.
            let ends: Vec<f32> = rays
                .iter()
                .enumerate()
                .map(|(i, _)| hits.get(i).map_or(5.0, |h| h.0 * (0.5 + rng.next_f32())))
                .collect();
            assert_shadow_packet(&scene, rays, &ends, &format!("seed {seed}"));
        }
    }
}

#[test]
fn exact_ties_go_to_the_lower_primitive_whatever_the_walk_order() {
    // This camera ray of `scenes/emissive.txt` meets the edge where the ceiling (triangle 2) and
    // the right wall (triangle 7) touch, at exactly the same distance on both. The single-ray
    // walk and packet walks (whose leaf order depends on the other rays in the packet) must all
    // return the same hit: the lower-indexed triangle.
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/emissive.txt");
    let scene = Scene::from_file(&rayscope_scene::load(&path).unwrap());
    let edge = Ray::new(Vec3A::ZERO, Vec3A::new(0.33964857, 0.3396486, 0.8770848));
    let ts = [2usize, 7].map(|i| scene.triangles[i].intersect(&edge, 0.0, f32::INFINITY).map(|h| h.t));
    assert!(ts[0].is_some() && ts[0] == ts[1], "a tie: {ts:?}");
    let single = scene.intersect(&edge, 0.0, f32::INFINITY).expect("a hit");
    assert_eq!(single.prim, PrimRef::Triangle(2));
    let mut rng = Rng::for_sample(7, 0, 0);
    let mut in_packets = 0;
    for k in 0..400 {
        let mut rays: Vec<Ray> = (0..LANES)
            .map(|_| {
                let d = Vec3A::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5);
                Ray::new(Vec3A::new(0.0, 0.0, 0.5 * rng.next_f32()), d.normalize())
            })
            .collect();
        rays[k % LANES] = edge;
        let mut p = packet_of(&rays, &[f32::INFINITY; LANES]);
        let hits = scene.wide.closest_rays(&mut p, 0.0);
        for (i, ray) in rays.iter().enumerate() {
            let one = scene
                .intersect(ray, 0.0, f32::INFINITY)
                .map(|h| (h.t, h.u, h.v, h.prim));
            assert_eq!(hits.get(i), one, "packet {k}, lane {i}");
        }
        in_packets += 1;
    }
    assert_eq!(in_packets, 400);
}

#[test]
fn many_rays_at_once_return_what_single_rays_return() {
    // Large enough that scattered rays' walks are interleaved (planes and spheres included, as
    // the walk tests them before the tree).
    let scene = random_scene_with_planes(31, 2000, 260_000, 3);
    assert!(
        scene.wide.memory_bytes() > INTERLEAVE_BYTES,
        "{} bytes",
        scene.wide.memory_bytes()
    );
    let scattered = random_rays(32, 4000);
    assert!(scene.wide.interleaves(&scattered));
    // Camera rays: one origin, neighbouring directions, walked one after another.
    let fan: Vec<Ray> = (0..4000)
        .map(|i| {
            let (x, y) = ((i % 80) as f32 / 80.0 - 0.5, (i / 80) as f32 / 50.0 - 0.5);
            Ray::new(Vec3A::new(0.0, 0.0, -2.0), Vec3A::new(x, y, 1.0).normalize())
        })
        .collect();
    assert!(!scene.wide.interleaves(&fan));
    // A tree that fits the caches never interleaves.
    assert!(!random_scene(33, 50, 3000).wide.interleaves(&scattered));
    for rays in [&scattered, &fan] {
        for (t_min, t_max) in [(0.0, f32::INFINITY), (0.5, 6.0)] {
            let mut got: Vec<Option<Option<WideHit>>> = vec![None; rays.len()];
            scene.wide.closest_many(rays, t_min, t_max, |i, h| {
                assert!(got[i].replace(h).is_none(), "ray {i} reported twice");
            });
            let mut hits = 0;
            for (i, (ray, got)) in rays.iter().zip(&got).enumerate() {
                let want = scene.wide.closest::<false>(ray, t_min, t_max, &mut 0);
                hits += usize::from(want.is_some());
                assert_eq!(*got, Some(want), "ray {i}, t in ({t_min}, {t_max})");
            }
            assert!(hits > rays.len() / 10, "the rays must mostly hit something: {hits}");
        }
    }
    // The scene-level query reports the same hits as `Scene::intersect`.
    let mut n = 0;
    scene.intersect_many(&scattered, 0.0, f32::INFINITY, |i, h| {
        n += 1;
        assert_eq!(h, scene.intersect(&scattered[i], 0.0, f32::INFINITY), "ray {i}");
    });
    assert_eq!(n, scattered.len());
}

/// A bumpy grid of `n`×`n` quads (two triangles each), like a finely tessellated mesh.
fn grid_scene(n: usize) -> Scene {
    let mut file = one_material_file(Vec::new());
    let p = |i: usize, j: usize| {
        let (x, y) = (i as f64 / n as f64 * 4.0 - 2.0, j as f64 / n as f64 * 4.0 - 2.0);
        DVec3::new(x, y, 3.0 + 0.2 * (3.0 * x).sin() * (2.0 * y).cos())
    };
    for i in 0..n {
        for j in 0..n {
            for vertices in [
                [p(i, j), p(i + 1, j), p(i + 1, j + 1)],
                [p(i, j), p(i + 1, j + 1), p(i, j + 1)],
            ] {
                file.entities.push(EntityDef {
                    name: format!("T{i}_{j}"),
                    shape: Shape::Triangle { vertices },
                    material: 0,
                    line: file.entities.len() + 2,
                });
            }
        }
    }
    Scene::from_file(&file)
}

#[test]
fn a_fine_mesh_gets_about_one_node_per_three_packets() {
    // A collapse that left a node over each pair of packets it could not give a slot of its own
    // would make half the nodes of a million-triangle mesh; leaves hold such runs instead, so
    // nodes are few, and a query must still test every packet of a run.
    let scene = grid_scene(120);
    let reference = BinaryReference::new(&scene);
    let wide = &scene.wide;
    assert!(
        wide.nodes.len() * 3 <= wide.tris.len(),
        "{} nodes for {} packets",
        wide.nodes.len(),
        wide.tris.len()
    );
    let mut rng = Rng::for_sample(41, 0, 0);
    for k in 0..20_000 {
        let o = Vec3A::new(rng.next_f32() * 4.0 - 2.0, rng.next_f32() * 4.0 - 2.0, 0.0);
        let d = Vec3A::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, 2.0).normalize();
        let ray = Ray::new(o, d);
        let one = scene.intersect(&ray, 0.0, f32::INFINITY).map(|h| h.prim);
        let binary = reference.intersect(&ray, 0.0, f32::INFINITY).map(|h| h.prim);
        assert_eq!(one, binary, "ray {k}");
        assert_eq!(
            scene.occluded(&ray, 0.0, f32::INFINITY),
            binary.is_some(),
            "ray {k}, any hit"
        );
    }
}

#[test]
fn packets_that_part_in_a_fine_mesh_return_what_single_rays_return() {
    // Triangles 0.02 wide, camera rays 0.06–0.2 apart where they meet the grid: the sixteen rays
    // of a packet share the top of the tree and part below it. With `split_packets` the rays
    // finish alone the subtrees at most two of them enter; without it the packet walks them
    // all. The same for shadow packets from the hits toward a light (which start on the
    // surface, where rays part soonest) with `split_shadows`. Both must give what each ray
    // traced alone gives, bit for bit.
    let mut scene = grid_scene(200);
    assert!(
        scene.wide.split_shadows && !scene.wide.split_packets,
        "80,000 triangles: shadow packets split, camera packets not (under 64 MiB)"
    );
    let mut rng = Rng::for_sample(43, 0, 0);
    let light = Vec3A::new(0.3, 1.5, 0.5);
    let mut parted = 0;
    for split in [false, true] {
        (scene.wide.split_packets, scene.wide.split_shadows) = (split, split);
        for k in 0..600 {
            let centre = Vec3A::new(rng.next_f32() * 1.2 - 0.6, rng.next_f32() * 1.2 - 0.6, 1.0);
            let step = 0.02 + 0.05 * rng.next_f32();
            let n = if k % 7 == 0 { 1 + k % LANES } else { LANES };
            let rays: Vec<Ray> = (0..n)
                .map(|i| {
                    let (x, y) = ((i % 4) as f32 - 1.5, (i / 4) as f32 - 1.5);
                    Ray::new(Vec3A::ZERO, (centre + Vec3A::new(x, y, 0.0) * step).normalize())
                })
                .collect();
            let mut p = packet_of(&rays, &vec![f32::INFINITY; n]);
            let hits = scene.wide.closest_rays(&mut p, 0.0);
            let mut prims = std::collections::HashSet::new();
            let mut shadows = Vec::new();
            for (i, ray) in rays.iter().enumerate() {
                let single = scene
                    .intersect(ray, 0.0, f32::INFINITY)
                    .map(|h| (h.t, h.u, h.v, h.prim));
                assert_eq!(hits.get(i), single, "split {split}, packet {k}, lane {i}");
                if let Some((t, _, _, prim)) = single {
                    prims.insert(prim);
                    let at = ray.at(t) + Vec3A::Z * -1e-4;
                    let to = light - at;
                    shadows.push((Ray::new(at, to.normalize()), to.length()));
                }
            }
            parted += usize::from(prims.len() > 8);
            if shadows.is_empty() {
                continue;
            }
            let (srays, ends): (Vec<Ray>, Vec<f32>) = shadows.into_iter().unzip();
            assert_shadow_packet(&scene, &srays, &ends, &format!("split {split}, packet {k}"));
        }
    }
    assert!(parted > 500, "most packets must meet many triangles: {parted}");
}

#[test]
fn a_small_room_is_a_list_for_single_rays_and_a_tree_for_packets() {
    // Our emitter-lit box (open at the front): ten walls, a block and two spheres. Single rays test a short list of
    // full packets (every wall's box overlaps the others, so the walk would open most of the
    // tree); ray packets walk the tree. Both must find the binary BVH's distances and the same
    // hits as one another, ties included (the block's floor lies on the room's floor).
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/emissive.txt");
    let scene = Scene::from_file(&rayscope_scene::load(&path).expect("our scene loads"));
    assert!(!scene.wide.single.is_empty(), "the room gets a list for single rays");
    let reference = BinaryReference::new(&scene);
    assert!(
        scene.wide.root != u32::MAX && scene.wide.flat.is_empty(),
        "and keeps its tree"
    );
    let mut rng = Rng::for_sample(51, 0, 0);
    let mut r = move || rng.next_f32();
    for k in 0..400 {
        let o = Vec3A::new(r() * 1.9 - 0.95, r() * 1.9 - 0.95, r() * 3.6 - 0.15);
        let rays: Vec<Ray> = (0..LANES)
            .map(|_| Ray::new(o, (Vec3A::new(r(), r(), r()) - Vec3A::splat(0.5)).normalize()))
            .collect();
        let mut p = packet_of(&rays, &[f32::INFINITY; LANES]);
        let hits = scene.wide.closest_rays(&mut p, 0.0);
        for (i, ray) in rays.iter().enumerate() {
            let one = scene
                .intersect(ray, 0.0, f32::INFINITY)
                .map(|h| (h.t, h.u, h.v, h.prim));
            // The binary BVH has no tie rule, so where the block's floor lies on the room's
            // floor it may name the other triangle; the distance must agree.
            let binary = reference.intersect(ray, 0.0, f32::INFINITY).map(|h| h.t);
            assert_eq!(hits.get(i), one, "ray {k}.{i}: packet against single");
            let Some((t, ..)) = one else {
                // Out through the open front.
                assert_eq!(binary, None, "ray {k}.{i}");
                assert!(!scene.occluded(ray, 0.0, f32::INFINITY), "ray {k}.{i}: any hit");
                continue;
            };
            let b = binary.expect("the binary BVH hits too");
            assert!((t - b).abs() <= 1e-5 * (1.0 + b), "ray {k}.{i}: {t} against {b}");
            assert!(scene.occluded(ray, 0.0, t * 1.0001 + 1e-6), "ray {k}.{i}: any hit");
            assert!(!scene.occluded(ray, 0.0, t * 0.999), "ray {k}.{i}: nothing nearer");
        }
    }
}

/// A scene from the course's text format.
fn scene_of(text: &str) -> Scene {
    let file = rayscope_scene::parse_str(text, std::path::Path::new("alone.txt")).unwrap();
    Scene::from_file(&file)
}

/// A sphere is alone only when no other primitive comes near it: a floor it rests on, a sphere
/// it overlaps, and a triangle whose face, edge or corner reaches into it all count.
#[test]
fn a_sphere_is_alone_only_when_nothing_comes_near() {
    let alone = |extra: &str| {
        scene_of(&format!(
            "Material \"M\" Diffuse (1, 1, 1) 1\nSphere \"S\" (0, 0, 2) 1 \"M\"\n{extra}"
        ))
        .sphere_alone(0)
    };
    assert!(alone(""), "by itself");
    assert!(alone("Plane \"F\" (0, -1.1, 0) (0, 1, 0) \"M\""));
    assert!(!alone("Plane \"F\" (0, -1, 0) (0, 1, 0) \"M\""), "resting on a floor");
    assert!(
        !alone("Plane \"F\" (0, -1.0005, 0) (0, 1, 0) \"M\""),
        "within the margin"
    );
    assert!(alone("Sphere \"T\" (2.2, 0, 2) 1 \"M\""));
    assert!(!alone("Sphere \"T\" (1.9, 0, 2) 1 \"M\""), "overlapping");
    assert!(!alone("Sphere \"T\" (0.2, 0, 2) 0.1 \"M\""), "inside it");
    // A big triangle in the plane z = 2.5 cuts the sphere though its corners are far away.
    assert!(
        !alone("Triangle \"A\" (-5, -5, 2.5) (5, -5, 2.5) (0, 5, 2.5) \"M\""),
        "face"
    );
    // An edge from (-3, 0.9, 2) to (3, 0.9, 2) passes 0.9 from the centre.
    assert!(
        !alone("Triangle \"A\" (-3, 0.9, 2) (3, 0.9, 2) (0, 5, 2) \"M\""),
        "edge"
    );
    assert!(alone("Triangle \"A\" (-3, 1.1, 2) (3, 1.1, 2) (0, 5, 2) \"M\""));
    // A corner at distance 0.95 from the centre, the rest of the triangle farther away.
    assert!(
        !alone("Triangle \"A\" (0.95, 0, 2) (3, 1, 2) (3, -1, 2.5) \"M\""),
        "corner"
    );
    assert!(alone("Triangle \"A\" (1.05, 0, 2) (3, 1, 2) (3, -1, 2.5) \"M\""));
}

/// Packets of rays inside a lone sphere (the glass ball of our room and of course scene 2) find
/// with the sphere alone exactly the hits the whole scene gives them, and a packet with a ray
/// that starts outside and misses the sphere is handed back untouched, so its hits are looked
/// for everywhere.
#[test]
fn rays_inside_a_lone_sphere_need_only_that_sphere() {
    rays_inside_the_smallest_sphere_need_only_it(&rayscope_testkit::scene("room.txt"));
    let Some(course) = rayscope_testkit::course_part() else {
        return;
    };
    rays_inside_the_smallest_sphere_need_only_it(&course.scene("sample_scene_2.txt"));
}

fn rays_inside_the_smallest_sphere_need_only_it(path: &std::path::Path) {
    let scene = Scene::from_file(&rayscope_scene::load(path).unwrap());
    let bvh = &scene.wide;
    let (k, glass) = (scene.spheres.iter().enumerate())
        .min_by(|a, b| a.1.radius.total_cmp(&b.1.radius))
        .unwrap();
    assert!(scene.sphere_alone(k), "nothing comes near the glass ball");
    let slot = bvh.sphere_slot(k as u32).unwrap();
    let mut rng = Rng::for_sample(77, 0, 0);
    let mut r = move || rng.next_f32() * 2.0 - 1.0;
    for round in 0..400 {
        let mut rays = RayPacket::default();
        for i in 0..LANES {
            // Points inside the ball (some a hair under its surface), lanes off now and then.
            let dir = Vec3A::new(r(), r(), r()).normalize_or(Vec3A::X);
            let depth = if round % 3 == 0 { 1.0 - 1e-5 } else { r().abs() };
            let o = glass.center + Vec3A::new(r(), r(), r()).normalize_or(Vec3A::Y) * (glass.radius * depth);
            if (round + i) % 9 != 4 {
                rays.set(i, &Ray::new(o, dir), f32::INFINITY);
            }
        }
        let (mut whole, mut alone) = (rays.clone(), rays.clone());
        let want = bvh.closest_rays(&mut whole, 0.0);
        let mut got = Default::default();
        assert!(
            bvh.closest_rays_inside(&mut alone, 0.0, slot, &mut got),
            "round {round}"
        );
        for i in 0..LANES {
            assert_eq!(got.get(i), want.get(i), "round {round} lane {i}");
            assert_eq!(
                alone.t_max[i].to_bits(),
                whole.t_max[i].to_bits(),
                "round {round} lane {i}"
            );
        }
    }
    // One ray starts outside, pointing away: the packet comes back as it was.
    let mut rays = RayPacket::default();
    let inside = Ray::new(glass.center, Vec3A::Z);
    let outside = Ray::new(glass.center + Vec3A::X * (glass.radius * 1.5), Vec3A::X);
    for i in 0..LANES {
        rays.set(i, if i == 5 { &outside } else { &inside }, f32::INFINITY);
    }
    let before = rays.clone();
    let mut got = Default::default();
    assert!(!bvh.closest_rays_inside(&mut rays, 0.0, slot, &mut got));
    assert_eq!(rays.t_max.map(f32::to_bits), before.t_max.map(f32::to_bits));
}
