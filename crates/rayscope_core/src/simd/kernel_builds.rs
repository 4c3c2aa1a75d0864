//! Every instruction-set build of the sixteen-lane kernels this CPU can run returns what the
//! baseline build returns, bit for bit (the render path picks one at run time; none may drift).
#![allow(unsafe_code)]

use std::fmt::Write;
use std::path::Path;

use glam::Vec3A;

use crate::accel::packet::*;
use crate::accel::PacketHits;
use crate::camera::{camera_dirs, Camera};
use crate::math::{Ray, RayPacket};
use crate::optics::{specular_rays_avx2, specular_rays_avx512, specular_rays_impl, SpecularRays};
use crate::rng::Rng;
use crate::scene::Scene;
use crate::simd::LANES;
use crate::surface::*;

fn scene(triangles: usize, spheres: usize, seed: u64) -> Scene {
    let mut rng = Rng::for_sample(seed, 0, 0);
    let mut r = move || rng.next_f32();
    let mut text = String::from("Material \"M\" Diffuse (1, 1, 1) 1\nPlane \"P\" (0, -3, 0) (0, 1, 0) \"M\"\n");
    for i in 0..triangles {
        let c = [r() * 8.0 - 4.0, r() * 8.0 - 4.0, r() * 8.0 + 1.0];
        let mut v = || format!("({}, {}, {})", c[0] + r() - 0.5, c[1] + r() - 0.5, c[2] + r() - 0.5);
        let (a, b, d) = (v(), v(), v());
        writeln!(text, "Triangle \"T{i}\" {a} {b} {d} \"M\"").unwrap();
    }
    for i in 0..spheres {
        let (x, y, z, rad) = (r() * 8.0 - 4.0, r() * 8.0 - 4.0, r() * 8.0 + 1.0, 0.1 + r() * 0.5);
        writeln!(text, "Sphere \"S{i}\" ({x}, {y}, {z}) {rad} \"M\"").unwrap();
    }
    Scene::from_file(&rayscope_scene::parse_str(&text, Path::new("k.txt")).unwrap())
}

/// The instruction-set builds (besides the baseline) this CPU can run.
#[cfg(target_arch = "x86_64")]
fn builds() -> Vec<&'static str> {
    let mut v = Vec::new();
    for (name, feature) in [
        ("avx2", std::arch::is_x86_feature_detected!("avx2")),
        ("avx512f", std::arch::is_x86_feature_detected!("avx512f")),
    ] {
        if feature {
            v.push(name);
        }
    }
    v
}

/// Every instruction-set build of the kernels this CPU can run returns the same hits, bit
/// for bit, as the baseline build (the render path picks one at run time; none may drift).
#[test]
fn every_kernel_build_agrees() {
    // A tree, and a flat scene of groups.
    for (tris, spheres, seed) in [(300, 20, 7), (8, 3, 8)] {
        let scene = scene(tris, spheres, seed);
        assert_eq!(scene.wide.flat.is_empty(), tris > 16, "flat only when small");
        let bvh = &scene.wide;
        let mut split = bvh.clone();
        (split.split_packets, split.split_shadows) = (true, true);
        let mut tree_hits = 0;
        let mut rng = Rng::for_sample(seed, 1, 0);
        let mut r = move || rng.next_f32();
        for _ in 0..200 {
            let mut rays = RayPacket::default();
            let o = Vec3A::new(r() - 0.5, r() - 0.5, r() - 2.0);
            for i in 0..LANES {
                let d = Vec3A::new(r() - 0.5, r() - 0.5, 1.0).normalize();
                let t_max = if i % 3 == 0 { 6.0 } else { f32::INFINITY };
                rays.set(i, &Ray::new(o, d), t_max);
            }
            let (mut base_rays, mut base) = (rays.clone(), PacketHits::default());
            bvh.closest_rays_impl(&mut base_rays, 0.0, &mut base, None);
            base.divide();
            let blocked = bvh.occluded_rays_impl(&mut rays.clone(), 0.0, None);
            #[cfg(target_arch = "x86_64")]
            for name in builds() {
                let (mut wide_rays, mut wide) = (rays.clone(), PacketHits::default());
                // SAFETY: the CPU supports the instruction set the kernels are built for
                // (`builds`).
                let wide_blocked = unsafe {
                    if name == "avx2" {
                        closest_rays_avx2(bvh, &mut wide_rays, 0.0, &mut wide, None);
                        occluded_rays_avx2(bvh, &mut rays.clone(), 0.0)
                    } else {
                        closest_rays_avx512(bvh, &mut wide_rays, 0.0, &mut wide, None);
                        occluded_rays_avx512(bvh, &mut rays.clone(), 0.0)
                    }
                };
                wide.divide();
                for i in 0..LANES {
                    assert_eq!(wide.get(i), base.get(i), "{name} lane {i}");
                }
                assert_eq!(wide_blocked, blocked, "{name}");
            }
            assert!((0..LANES).any(|i| base.get(i).is_some()), "some rays hit");
            // The tree walks that split packets where their rays part (`tests/wide_bvh.rs`
            // checks them against single rays); the flat scene has no tree.
            if !bvh.flat.is_empty() {
                continue;
            }
            let (mut split_rays, mut split_hits) = (rays.clone(), PacketHits::default());
            split.closest_rays_split_impl(&mut split_rays, 0.0, &mut split_hits);
            split_hits.divide();
            let mut split_blocked = [false; LANES];
            split.occluded_rays_split_impl(&mut rays.clone(), 0.0, &mut split_blocked);
            #[cfg(target_arch = "x86_64")]
            for name in builds() {
                let (mut wide_rays, mut wide) = (rays.clone(), PacketHits::default());
                let mut wide_blocked = [false; LANES];
                // SAFETY: the CPU supports the instruction set the kernels are built for
                // (`builds`).
                unsafe {
                    if name == "avx2" {
                        closest_rays_split_avx2(&split, &mut wide_rays, 0.0, &mut wide);
                        occluded_rays_split_avx2(&split, &mut rays.clone(), 0.0, &mut wide_blocked);
                    } else {
                        closest_rays_split_avx512(&split, &mut wide_rays, 0.0, &mut wide);
                        occluded_rays_split_avx512(&split, &mut rays.clone(), 0.0, &mut wide_blocked);
                    }
                }
                wide.divide();
                for i in 0..LANES {
                    assert_eq!(wide.get(i), split_hits.get(i), "split, {name} lane {i}");
                }
                assert_eq!(wide_blocked, split_blocked, "split, {name}");
            }
            tree_hits += (0..LANES).filter(|&i| split_hits.get(i).is_some()).count();
        }
        assert_eq!(tree_hits > 1000, bvh.flat.is_empty(), "rays hit the tree: {tree_hits}");
    }
}

/// The instruction-set builds of the surface kernel agree with the baseline bit for bit,
/// on random lanes of every kind (smooth triangles included) and on degenerate ones.
#[test]
fn every_surface_kernel_build_agrees() {
    // The geometry kernel, and the mirror and glass kernel on its output.

    let mut rng = Rng::for_sample(11, 0, 0);
    let mut r = move || rng.next_f32() * 4.0 - 2.0;
    for round in 0..100 {
        let mut rays = RayPacket::default();
        let mut g = HitPrims::default();
        let mut sm = SmoothNormals::default();
        for i in 0..LANES {
            let d = Vec3A::new(r(), r(), r()).normalize();
            rays.set(i, &Ray::new(Vec3A::new(r(), r(), r()), d), f32::INFINITY);
            g.hit[i] = i != 5;
            g.t[i] = r().abs() * 3.0;
            g.sphere[i] = i % 3 == 1;
            g.triangle[i] = i % 3 == 2;
            g.radius[i] = if g.sphere[i] { 0.1 + r().abs() } else { 1.0 };
            for ax in 0..3 {
                g.a[ax][i] = r();
                g.b[ax][i] = if i == 8 { 0.0 } else { r() };
                for c in 0..3 {
                    // Lane 11's vertex normals cancel out: the geometric normal is used.
                    sm.vn[c][ax][i] = if i == 11 { 0.0 } else { r() };
                }
            }
            sm.on[i] = g.triangle[i] && round % 2 == 0;
            (sm.bu[i], sm.bv[i]) = (r().abs() / 4.0, r().abs() / 4.0);
        }
        g.smooth = (round % 2 == 0).then_some(sm);
        let base = surface_frames_impl(&rays, &g);
        // Glass of index 1 to 2.5 and one of 0.5 (total internal reflection from outside).
        let ior: [f32; LANES] = std::array::from_fn(|i| if i == 2 { 0.5 } else { 1.75 + r() * 0.375 });
        let base_spec = specular_rays_impl(&rays, &base, &ior);
        // Bits, except that a NaN is any NaN: which operand's NaN an addition or a product
        // passes on is not fixed (the compiler may swap them), and a NaN's sign with it.
        let canon = |x: &f32| if x.is_nan() { f32::NAN.to_bits() } else { x.to_bits() };
        let spec_bits = |s: &SpecularRays| {
            let mut v: Vec<u32> = [s.reflected, s.refracted, s.inside]
                .iter()
                .flat_map(|a| a.iter().flatten().map(canon))
                .collect();
            v.extend(s.kr.iter().map(canon));
            v.extend(s.has_refracted.iter().map(|&b| u32::from(b)));
            v
        };
        let bits = |f: &SurfaceFrames| {
            let mut v: Vec<u32> = [f.point, f.normal, f.shading_normal, f.outside]
                .iter()
                .flat_map(|a| a.iter().flatten().map(|x| x.to_bits()))
                .collect();
            v.extend(f.front_face.iter().map(|&b| u32::from(b)));
            v
        };
        #[cfg(target_arch = "x86_64")]
        for name in builds() {
            // SAFETY: the CPU supports the instruction set the kernel is built for (`builds`).
            let wide = unsafe {
                if name == "avx2" {
                    surface_frames_avx2(&rays, &g)
                } else {
                    surface_frames_avx512(&rays, &g)
                }
            };
            assert_eq!(bits(&wide), bits(&base), "{name}, round {round}");
            // SAFETY: as above.
            let wide_spec = unsafe {
                if name == "avx2" {
                    specular_rays_avx2(&rays, &base, &ior)
                } else {
                    specular_rays_avx512(&rays, &base, &ior)
                }
            };
            assert_eq!(spec_bits(&wide_spec), spec_bits(&base_spec), "{name}, round {round}");
        }
    }
}

/// The instruction-set builds of the camera kernel agree with `Camera::ray` bit for bit.
#[test]
fn every_camera_kernel_build_agrees() {
    use crate::camera::{camera_dirs_avx2, camera_dirs_avx512, CameraSettings};
    let settings = CameraSettings {
        axis: glam::Vec3::new(0.2, 1.0, -0.4),
        angle_deg: 23.0,
        ..CameraSettings::default()
    };
    let cam = Camera::new(settings, 333, 190);
    let px: [f32; LANES] = std::array::from_fn(|i| i as f32 * 20.7 + 0.125);
    let py: [f32; LANES] = std::array::from_fn(|i| 189.875 - i as f32 * 11.3);
    let want: Vec<u32> = (0..LANES)
        .flat_map(|i| cam.ray(px[i] / 333.0, py[i] / 190.0).dir.to_array())
        .map(f32::to_bits)
        .collect();
    let bits = |d: [[f32; LANES]; 3]| -> Vec<u32> {
        (0..LANES)
            .flat_map(|i| [d[0][i], d[1][i], d[2][i]])
            .map(f32::to_bits)
            .collect()
    };
    assert_eq!(bits(camera_dirs(&cam, &px, &py, 333.0, 190.0)), want);
    #[cfg(target_arch = "x86_64")]
    for name in builds() {
        // SAFETY: the CPU supports the instruction set the kernel is built for (`builds`).
        let d = unsafe {
            if name == "avx2" {
                camera_dirs_avx2(&cam, &px, &py, 333.0, 190.0)
            } else {
                camera_dirs_avx512(&cam, &px, &py, 333.0, 190.0)
            }
        };
        assert_eq!(bits(d), want, "{name}");
    }
}
