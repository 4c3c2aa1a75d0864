//! Analytic scenes with closed-form radiance: the emitter sampling, MIS, BRDF normalisation,
//! path tracing (`-l`) and Beer's law must converge to them.

use std::path::Path;

use glam::{Vec3, Vec3A};
use rayscope_core::integrator::{Counters, Integrator};
use rayscope_core::{CameraSettings, NoObserver, RenderSettings, Scene};

fn scene(text: &str) -> Scene {
    let file = rayscope_scene::parse_str(text, Path::new("furnace.txt")).expect("scene parses");
    Scene::from_file(&file)
}

/// Image size for the estimates: odd, so the centre pixel ([`CENTRE`]) is centred on the
/// camera's axis, and large, so its rays (spread over the pixel) stay within 0.15° of it.
const SIZE: u32 = 201;
/// The pixel the estimates sample.
const CENTRE: u32 = SIZE / 2;

/// An image whose centre pixel looks along the camera's axis.
fn settings(camera: CameraSettings, ambient: bool) -> RenderSettings {
    RenderSettings {
        width: SIZE,
        height: SIZE,
        ambient,
        camera,
        seed: 11,
        ..RenderSettings::default()
    }
}

/// Mean and standard error of `n` samples of the centre pixel.
fn estimate(scene: &Scene, s: &RenderSettings, n: u32) -> (Vec3A, Vec3A) {
    let integ = Integrator::new(scene, s);
    let mut c = Counters::default();
    let (mut sum, mut sum2) = (Vec3A::ZERO, Vec3A::ZERO);
    for i in 0..n {
        let v = integ.sample(CENTRE, CENTRE, i, &mut NoObserver, &mut c);
        assert!(v.is_finite());
        sum += v;
        sum2 += v * v;
    }
    let mean = sum / n as f32;
    let var = (sum2 / n as f32 - mean * mean).max(Vec3A::ZERO);
    (mean, (var / n as f32).powf(0.5))
}

fn assert_converges(name: &str, got: (Vec3A, Vec3A), want: Vec3A) {
    let (mean, se) = got;
    let tol = se * 5.0 + want.abs() * 0.005 + Vec3A::splat(1e-6);
    eprintln!("{name}: got {mean} ± {se}, want {want}");
    assert!(
        (mean - want).abs().cmple(tol).all(),
        "{name}: got {mean} ± {se}, want {want}"
    );
}

fn look_down() -> (Vec3, f32) {
    // Axis (1, 0, 0) by +90° turns +z into −y.
    (Vec3::X, 90.0)
}

/// A closed diffuse sphere of albedo a with an emitting sphere of radiance L at its centre.
/// Seen from any wall point the emitter covers the fraction s = (r/R)² of the cosine-weighted
/// hemisphere and the rest is wall of the same (by symmetry uniform) radiance B, so
/// B = a (s L + (1 − s) B), i.e. B = a s L / (1 − a (1 − s)). This is the furnace
/// L/(1 − a) with the emission moved onto a separate surface (the scene format cannot give
/// one surface both an albedo and an emission); with s → 1 it is the white furnace B = L.
#[test]
fn closed_sphere_furnace_converges_with_path_tracing() {
    for (a, l) in [(0.5f32, Vec3A::new(2.0, 1.0, 0.5)), (0.8, Vec3A::new(1.0, 1.0, 1.0))] {
        let (big, small) = (2.0f32, 0.4f32);
        let text = format!(
            "Material \"Wall\" Diffuse ({a}, {a}, {a}) 1\nMaterial \"Glow\" Emissive ({}, {}, {}) 1\n\
             Sphere \"Room\" (0, 0, 5) {big} \"Wall\"\nSphere \"Lamp\" (0, 0, 5) {small} \"Glow\"\n",
            l.x, l.y, l.z
        );
        let sc = scene(&text);
        let cam = CameraSettings {
            position: Vec3::new(0.0, 1.0, 5.0),
            ..CameraSettings::default()
        };
        let s = (small / big).powi(2);
        let want = l * (a * s / (1.0 - a * (1.0 - s)));
        assert_converges(
            &format!("furnace a={a} -l"),
            estimate(&sc, &settings(cam, true), 40_000),
            want,
        );
        // Without -l only the direct part a·s·L remains.
        assert_converges(
            &format!("furnace a={a} direct"),
            estimate(&sc, &settings(cam, false), 4_000),
            l * (a * s),
        );
    }
}

/// A diffuse triangle at the centre of a large emitting sphere sees radiance L over its whole
/// hemisphere: it reflects a·L (area sampling from inside the sphere + BRDF sampling, MIS).
#[test]
fn diffuse_surface_inside_uniform_emitter_reflects_albedo_times_radiance() {
    let text = "Material \"Grey\" Diffuse (0.6, 0.3, 0.9) 1\nMaterial \"Sky\" Emissive (1, 2, 0.5) 1\n\
                Sphere \"Dome\" (0, 0, 0) 10 \"Sky\"\n\
                Triangle \"T\" (-1, -1, 2) (0, 1, 2) (1, -1, 2) \"Grey\"\n";
    let sc = scene(text);
    let want = Vec3A::new(0.6, 0.3, 0.9) * Vec3A::new(1.0, 2.0, 0.5);
    for ambient in [false, true] {
        assert_converges(
            "dome",
            estimate(&sc, &settings(CameraSettings::default(), ambient), 4_000),
            want,
        );
    }
}

/// A Phong triangle at the centre of a large emitting sphere, seen along its normal, sees
/// radiance L over its whole hemisphere and reflects all of it that its albedo allows: the
/// Lambert half's a/2 and, the lobe lying whole above the surface at normal incidence, the
/// lobe's a/2, so B = a·L whatever the exponent (emitter sampling + the model's own mixture
/// sampling, MIS; with -l the bounces that carry the lobe too).
#[test]
fn phong_surface_inside_uniform_emitter_reflects_albedo_times_radiance() {
    for n in [0, 12, 300] {
        let text = format!(
            "Material \"Shiny\" Phong (0.6, 0.3, 0.9) {n}\nMaterial \"Sky\" Emissive (1, 2, 0.5) 1\n\
             Sphere \"Dome\" (0, 0, 0) 10 \"Sky\"\n\
             Triangle \"T\" (-1, -1, 2) (0, 1, 2) (1, -1, 2) \"Shiny\"\n"
        );
        let sc = scene(&text);
        let want = Vec3A::new(0.6, 0.3, 0.9) * Vec3A::new(1.0, 2.0, 0.5);
        for ambient in [false, true] {
            assert_converges(
                &format!("Phong {n} in a dome, -l {ambient}"),
                estimate(&sc, &settings(CameraSettings::default(), ambient), 8_000),
                want,
            );
        }
    }
}

/// A point on a diffuse floor under a square emitter (two triangles) of half-side w at height h,
/// centred above it: B = a · L · F with the point-to-rectangle form factor F.
#[test]
fn floor_under_square_emitter_matches_form_factor() {
    let (w, h, a) = (0.5f64, 1.0f64, 0.7f32);
    let text = format!(
        "Material \"Floor\" Diffuse ({a}, {a}, {a}) 1\nMaterial \"Lamp\" Emissive (3, 2, 1) 1\n\
         Plane \"Ground\" (0, 0, 0) (0, 1, 0) \"Floor\"\n\
         Triangle \"L1\" ({x0}, {h}, {z0}) ({x1}, {h}, {z0}) ({x1}, {h}, {z1}) \"Lamp\"\n\
         Triangle \"L2\" ({x0}, {h}, {z0}) ({x1}, {h}, {z1}) ({x0}, {h}, {z1}) \"Lamp\"\n",
        x0 = -w,
        x1 = w,
        z0 = 3.0 - w,
        z1 = 3.0 + w,
    );
    let sc = scene(&text);
    let (axis, angle) = look_down();
    let cam = CameraSettings {
        position: Vec3::new(0.0, 0.5, 3.0),
        axis,
        angle_deg: angle,
        ..CameraSettings::default()
    };
    // Form factor from a point below a corner of an X·h by Y·h rectangle, four times.
    let (x, y) = (w / h, w / h);
    let corner = (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
        + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan())
        / (2.0 * std::f64::consts::PI);
    let f = (4.0 * corner) as f32;
    let want = Vec3A::new(3.0, 2.0, 1.0) * (a * f);
    for ambient in [false, true] {
        assert_converges("square lamp", estimate(&sc, &settings(cam, ambient), 8_000), want);
    }
}

/// A point on a diffuse floor at distance d below the centre of an emitting sphere of radius r:
/// irradiance π L (r/d)², so B = a L (r/d)² (cone sampling from outside + BRDF sampling).
#[test]
fn floor_under_sphere_emitter_matches_closed_form() {
    let text = "Material \"Floor\" Diffuse (0.5, 0.5, 0.5) 1\nMaterial \"Lamp\" Emissive (8, 8, 8) 1\n\
                Plane \"Ground\" (0, 0, 0) (0, 1, 0) \"Floor\"\nSphere \"Bulb\" (0, 2, 3) 0.5 \"Lamp\"\n";
    let sc = scene(text);
    let (axis, angle) = look_down();
    let cam = CameraSettings {
        position: Vec3::new(0.0, 1.0, 3.0) + Vec3::new(0.0, 0.0, 0.0),
        axis,
        angle_deg: angle,
        ..CameraSettings::default()
    };
    // The camera sits inside the lamp's shadow-free column, below the bulb.
    let want = Vec3A::splat(0.5 * 8.0 * (0.5f32 / 2.0).powi(2));
    assert_converges("bulb", estimate(&sc, &settings(cam, false), 8_000), want);
}

fn slab(sigma: [f32; 3], index: f32, d: f32) -> Scene {
    let (z0, z1) = (2.0, 2.0 + d);
    let mut t = format!(
        "Material \"Glass\" Refractive ({}, {}, {}) {index}\nMaterial \"Back\" Emissive (1, 1, 1) 1\n\
         Triangle \"B1\" (-50, -50, 6) (50, -50, 6) (50, 50, 6) \"Back\"\n\
         Triangle \"B2\" (-50, -50, 6) (50, 50, 6) (-50, 50, 6) \"Back\"\n",
        sigma[0], sigma[1], sigma[2]
    );
    // A closed box of glass, 10 wide, from z0 to z1.
    let (a, b) = (-5.0, 5.0);
    let quads = [
        [(a, a, z0), (b, a, z0), (b, b, z0), (a, b, z0)],
        [(a, a, z1), (a, b, z1), (b, b, z1), (b, a, z1)],
        [(a, a, z0), (a, b, z0), (a, b, z1), (a, a, z1)],
        [(b, a, z0), (b, a, z1), (b, b, z1), (b, b, z0)],
        [(a, a, z0), (a, a, z1), (b, a, z1), (b, a, z0)],
        [(a, b, z0), (b, b, z0), (b, b, z1), (a, b, z1)],
    ];
    let centre = Vec3A::new(0.0, 0.0, (z0 + z1) / 2.0);
    for (i, q) in quads.iter().enumerate() {
        let v = |v: (f32, f32, f32)| Vec3A::new(v.0, v.1, v.2);
        // The course's front face (normal (v1 − v0) × (v2 − v0)) must face outwards: that side is
        // outside the glass.
        let n = (v(q[1]) - v(q[0])).cross(v(q[2]) - v(q[0]));
        let mut q = *q;
        if n.dot(v(q[0]) - centre) < 0.0 {
            q.reverse();
        }
        let p = |v: (f32, f32, f32)| format!("({}, {}, {})", v.0, v.1, v.2);
        t += &format!(
            "Triangle \"S{i}a\" {} {} {} \"Glass\"\nTriangle \"S{i}b\" {} {} {} \"Glass\"\n",
            p(q[0]),
            p(q[1]),
            p(q[2]),
            p(q[0]),
            p(q[2]),
            p(q[3])
        );
    }
    scene(&t)
}

/// Beer's law: through a slab of thickness d and absorbance σ (index 1, so no Fresnel
/// reflection) the transmittance is exp(−σ d) per channel; σ = 0 absorbs nothing.
#[test]
fn beer_slab_transmittance() {
    for (sigma, d) in [
        ([0.5f32, 1.0, 2.0], 0.8f32),
        ([4.0, 1.0, 1.0], 0.3),
        ([0.0, 0.0, 0.0], 1.0),
    ] {
        let sc = slab(sigma, 1.0, d);
        let (mean, _) = estimate(&sc, &settings(CameraSettings::default(), false), 4);
        let want = (-Vec3A::from(sigma) * d).exp();
        assert!(
            (mean - want).abs().max_element() < 1e-4,
            "σ {sigma:?} d {d}: {mean} vs {want}"
        );
    }
    // With index 1.5 at normal incidence the two interfaces transmit (1 − R)² and internal
    // reflections add (1 − R)² e^{−σd} Σ (R² e^{−2σd})^k.
    let (sigma, d) = ([0.5f32, 1.0, 2.0], 0.8f32);
    let sc = slab(sigma, 1.5, d);
    let (mean, _) = estimate(&sc, &settings(CameraSettings::default(), false), 1);
    let r = (0.5f32 / 2.5).powi(2);
    let e = (-Vec3A::from(sigma) * d).exp();
    let want = e * (1.0 - r).powi(2) / (Vec3A::ONE - e * e * (r * r));
    assert!((mean - want).abs().max_element() < 1e-4, "{mean} vs {want}");
}
