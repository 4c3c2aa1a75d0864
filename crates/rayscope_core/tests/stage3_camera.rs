//! Custom camera (E) and depth of field (G).

use std::path::Path;
use std::sync::atomic::AtomicBool;

use glam::{Mat3A, Vec2, Vec3, Vec3A};
use rayscope_core::camera::{rodrigues, Camera};
use rayscope_core::compare::compare_rgb8;
use rayscope_core::integrator::{Counters, Integrator};
use rayscope_core::{render, CameraSettings, NoObserver, RenderSettings, Scene, Stage};

fn scene(text: &str) -> Scene {
    let file = rayscope_scene::parse_str(text, Path::new("camera.txt")).expect("scene parses");
    Scene::from_file(&file)
}

fn render_rgb(scene: &Scene, s: &RenderSettings) -> Vec<u8> {
    render(scene, s, &|_, _| {}, &AtomicBool::new(false))
        .expect("not cancelled")
        .film
        .to_rgb8()
}

/// An asymmetric stage-2 scene, with every point passed through `f` and every normal through `g`.
fn transformed_scene(f: impl Fn(Vec3A) -> Vec3A, g: impl Fn(Vec3A) -> Vec3A) -> String {
    let p = |v: [f32; 3]| {
        let v = f(Vec3A::from(v));
        format!("({}, {}, {})", v.x, v.y, v.z)
    };
    let n = |v: [f32; 3]| {
        let v = g(Vec3A::from(v));
        format!("({}, {}, {})", v.x, v.y, v.z)
    };
    format!(
        "Material \"Red\" Diffuse (0.9, 0.2, 0.2) 1\nMaterial \"Green\" Diffuse (0.2, 0.8, 0.3) 1\n\
         Material \"Blue\" Diffuse (0.2, 0.3, 0.9) 1\nMaterial \"Mirror\" Reflective (0, 0, 0) 1\n\
         PointLight \"Key\" {} (0.8, 0.8, 0.8)\nPointLight \"Fill\" {} (0.3, 0.3, 0.4)\n\
         Plane \"Floor\" {} {} \"Blue\"\n\
         Sphere \"Ball\" {} 0.7 \"Red\"\nSphere \"Chrome\" {} 0.5 \"Mirror\"\n\
         Triangle \"Tri\" {} {} {} \"Green\"\n",
        p([2.0, 4.0, 1.0]),
        p([-3.0, 2.0, 6.0]),
        p([0.0, -1.2, 0.0]),
        n([0.0, 1.0, 0.0]),
        p([-0.8, -0.5, 5.0]),
        p([1.0, -0.7, 4.0]),
        p([0.5, 0.2, 7.0]),
        p([2.5, 1.5, 6.5]),
        p([1.8, -1.2, 5.0]),
    )
}

/// Rendering with the camera at P rotated by R equals rendering the scene moved by
/// x → Rᵀ (x − P) from the default camera.
#[test]
fn rotating_the_camera_equals_inverse_rotating_the_scene() {
    let (pos, axis, angle) = (Vec3::new(0.4, 0.3, -0.5), Vec3::new(0.3, 1.0, 0.2), 17.0);
    let r: Mat3A = rodrigues(axis, angle);
    let base = RenderSettings {
        width: 96,
        height: 72,
        aa: 2,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let moved = scene(&transformed_scene(|v| v, |n| n));
    let with_camera = render_rgb(
        &moved,
        &RenderSettings {
            camera: CameraSettings {
                position: pos,
                axis,
                angle_deg: angle,
                ..CameraSettings::default()
            },
            ..base
        },
    );
    let rt = r.transpose();
    let inverse = scene(&transformed_scene(|v| rt * (v - Vec3A::from(pos)), |n| rt * n));
    let with_scene = render_rgb(&inverse, &base);
    let c = compare_rgb8(&with_camera, &with_scene);
    assert!(c.psnr > 45.0, "camera vs scene transform: {c:?}");
    // The check can fail: rotating the scene the wrong way gives a different image.
    let wrong = scene(&transformed_scene(|v| r * (v - Vec3A::from(pos)), |n| r * n));
    let c = compare_rgb8(&with_camera, &render_rgb(&wrong, &base));
    assert!(c.psnr < 25.0, "wrong rotation should differ: {c:?}");
}

/// Every lens ray through an image point meets the pinhole ray's point on the focal plane.
#[test]
fn lens_rays_converge_on_the_focal_plane() {
    let s = CameraSettings {
        position: Vec3::new(1.0, -2.0, 0.5),
        axis: Vec3::new(1.0, 0.5, 0.0),
        angle_deg: 25.0,
        aperture_radius: 0.3,
        focal_length: 4.0,
        ..CameraSettings::default()
    };
    let cam = Camera::new(s, 64, 48);
    let forward = cam.rotation * Vec3A::Z;
    for (u, v) in [(0.5, 0.5), (0.1, 0.9), (0.8, 0.2)] {
        let pin = cam.ray(u, v);
        // Point of the pinhole ray at camera-space depth f.
        let target = pin.at(4.0 / pin.dir.dot(forward));
        for lens in [Vec2::new(1.0, 0.0), Vec2::new(-0.6, 0.7), Vec2::new(0.0, -1.0)] {
            let r = cam.lens_ray(u, v, lens);
            let depth = (target - r.origin).dot(forward) / r.dir.dot(forward);
            assert!((r.at(depth) - target).length() < 1e-4);
            // Rays start on the lens disk.
            assert!(((r.origin - cam.origin).length() - 0.3 * lens.length()).abs() < 1e-5);
        }
    }
}

/// Blur of a black-to-white edge, in pixels: an emitting wall covers the right half of the view
/// at distance `z`, seen through a lens of radius `aperture` focused at 4; returns
/// Σ |pixel − sharp edge| over a 64-pixel row.
fn edge_spread(z: f32, aperture: f32) -> f32 {
    let text = format!(
        "Material \"Lamp\" Emissive (1, 1, 1) 1\n\
         Triangle \"A\" (0, -100, {z}) (0, 100, {z}) (100, 100, {z}) \"Lamp\"\n\
         Triangle \"B\" (0, -100, {z}) (100, 100, {z}) (100, -100, {z}) \"Lamp\"\n"
    );
    let sc = scene(&text);
    let s = RenderSettings {
        width: 64,
        height: 1,
        camera: CameraSettings {
            aperture_radius: aperture,
            focal_length: 4.0,
            ..CameraSettings::default()
        },
        ..RenderSettings::default()
    };
    let integ = Integrator::new(&sc, &s);
    let mut c = Counters::default();
    let n = 1024;
    (0..64)
        .map(|x| {
            let v: f32 = (0..n)
                .map(|i| integ.sample(x, 0, i, &mut NoObserver, &mut c).x)
                .sum::<f32>()
                / n as f32;
            if x < 32 {
                v
            } else {
                1.0 - v
            }
        })
        .sum()
}

#[test]
fn depth_of_field_is_sharp_at_the_focal_distance_and_blurs_away_from_it() {
    // Pinhole and in focus: the edge falls between two pixels.
    assert!(edge_spread(4.0, 0.0) < 1e-6);
    let sharp = edge_spread(4.0, 0.2);
    assert!(sharp < 1e-3, "in focus: {sharp}");
    // The circle of confusion on the image plane (distance 1) has diameter 2 r |1/z − 1/f|;
    // pixels of a 64-pixel-wide 60° image are 2 tan 30° / 64 wide. A point d pixels from the
    // edge is wrong by P(X > d), X one coordinate of a uniform point on a disk of radius R:
    // (acos(a) − a √(1 − a²)) / π with a = d / R. Samples spread over their pixel, so pixel k
    // is wrong by the mean of that over d in [k, k + 1].
    let expected = |z: f32| {
        let radius = 0.2 * (1.0 / z - 0.25f32).abs() / (2.0 * 30f32.to_radians().tan() / 64.0);
        let wrong = |d: f32| {
            let a = (d / radius).min(1.0);
            (a.acos() - a * (1.0 - a * a).sqrt()) / std::f32::consts::PI
        };
        let steps = 64;
        (0..32 * steps)
            .map(|i| 2.0 * wrong((i as f32 + 0.5) / steps as f32) / steps as f32)
            .sum::<f32>()
    };
    let mut last = sharp;
    for z in [5.0, 6.0, 8.0, 40.0] {
        let b = edge_spread(z, 0.2);
        eprintln!("z {z}: spread {b}, expected {}", expected(z));
        assert!(b > last, "blur grows behind the focal plane: z {z}: {b} after {last}");
        assert!(
            (b - expected(z)).abs() < 0.1 * expected(z) + 0.05,
            "z {z}: {b} vs {}",
            expected(z)
        );
        last = b;
    }
    let mut last = sharp;
    for z in [3.0, 2.0, 1.0] {
        let b = edge_spread(z, 0.2);
        eprintln!("z {z}: spread {b}, expected {}", expected(z));
        assert!(
            b > last,
            "blur grows in front of the focal plane: z {z}: {b} after {last}"
        );
        assert!(
            (b - expected(z)).abs() < 0.1 * expected(z) + 0.05,
            "z {z}: {b} vs {}",
            expected(z)
        );
        last = b;
    }
}

/// With a lens, a pixel's samples take their pixel and lens points from one sequence over the
/// whole pixel where the grid side is a power of two: still 2^q samples in every `-x` cell. For
/// other grids sample s stays in cell s mod N², as without a lens.
#[test]
fn lens_samples_fill_every_grid_cell_equally() {
    let sc = scene(&transformed_scene(|v| v, |n| n));
    for (aa, q) in [(1, 3), (2, 2), (2, 4), (4, 1), (3, 2)] {
        let s = RenderSettings {
            width: 16,
            height: 12,
            aa,
            quality: q,
            stage: Stage::Full,
            camera: CameraSettings {
                aperture_radius: 0.2,
                focal_length: 4.0,
                ..CameraSettings::default()
            },
            ..RenderSettings::default()
        };
        let integ = Integrator::new(&sc, &s);
        let spp = integ.samples_per_pixel();
        assert_eq!(spp, (aa * aa) << q);
        let mut count = vec![0u32; (aa * aa) as usize];
        for sample in 0..spp {
            let (u, v) = integ.sample_position(5, 7, sample);
            let (fx, fy) = (u * 16.0 - 5.0, v * 12.0 - 7.0);
            assert!(
                (0.0..1.0).contains(&fx) && (0.0..1.0).contains(&fy),
                "-x {aa} -q {q}: {fx}, {fy}"
            );
            let n = aa as f32;
            let cell = (fy * n) as u32 * aa + (fx * n) as u32;
            if !aa.is_power_of_two() {
                assert_eq!(cell, sample % (aa * aa), "-x {aa}: sample {sample}");
            }
            count[cell as usize] += 1;
        }
        assert!(count.iter().all(|&c| c == 1 << q), "-x {aa} -q {q}: {count:?}");
    }
}
