//! Times the checker's oracle against rayscope's renderer on the same rays, per ray:
//!
//! cargo run --release -p rayscope_check --example oracle_speed -- SCENE
//!
//! The rays: one through each pixel centre of a 400 × 400 image, and from each hit four random
//! rays leaving it and a shadow ray to each light.

use std::time::Instant;

use glam::{DVec3, Vec3A};
use rayscope_check::oracle::Oracle;
use rayscope_core::{Camera, CameraSettings, Ray, Scene};

fn main() {
    let Some(path) = std::env::args().nth(1) else {
        eprintln!("usage: oracle_speed SCENE");
        std::process::exit(2);
    };
    let file = rayscope_scene::load(std::path::Path::new(&path)).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let scene = Scene::from_owned_file(file);
    let oracle = Oracle::new(&scene);
    let camera = Camera::new(CameraSettings::default(), 400, 400);
    // (origin, unit direction, t_max) in f64, the same numbers the renderer gets in f32.
    let mut rays: Vec<(DVec3, DVec3, f64)> = Vec::new();
    let mut seed = 0x1234_5678_9abc_def0_u64;
    let mut next = || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    for y in 0..400 {
        for x in 0..400 {
            let (u, v) = camera.pixel_center(x, y);
            let r = camera.ray(u, v);
            let (o, d) = (r.origin.as_dvec3(), r.dir.as_dvec3().normalize());
            rays.push((o, d, f64::INFINITY));
            let Some(h) = oracle.closest(o, d, 0.0, f64::INFINITY) else {
                continue;
            };
            let n = if h.front { h.normal } else { -h.normal };
            for _ in 0..4 {
                let d = DVec3::new(next(), next(), next()).normalize();
                let side = if d.dot(n) >= 0.0 { n } else { -n };
                rays.push((h.point + side * 1e-5, d, f64::INFINITY));
            }
            for l in &scene.lights {
                let to = l.position.as_dvec3() - (h.point + n * 1e-5);
                rays.push((h.point + n * 1e-5, to.normalize(), to.length()));
            }
        }
    }
    let f32_rays: Vec<(Ray, f32)> = rays
        .iter()
        .map(|&(o, d, t)| (Ray::new(Vec3A::from(o.as_vec3()), Vec3A::from(d.as_vec3())), t as f32))
        .collect();
    for round in 0..3 {
        let t0 = Instant::now();
        let mut hits = 0u64;
        for &(o, d, t_max) in &rays {
            hits += u64::from(oracle.closest(o, d, 0.0, t_max).is_some());
        }
        let oracle_ns = t0.elapsed().as_secs_f64() * 1e9 / rays.len() as f64;
        let t1 = Instant::now();
        let mut rs_hits = 0u64;
        for (r, t_max) in &f32_rays {
            rs_hits += u64::from(scene.intersect(r, 0.0, *t_max).is_some());
        }
        let rs_ns = t1.elapsed().as_secs_f64() * 1e9 / rays.len() as f64;
        println!(
            "round {round}: {} rays; oracle {oracle_ns:.0} ns/ray ({hits} hits), renderer {rs_ns:.0} ns/ray ({rs_hits} hits)",
            rays.len()
        );
    }
}
