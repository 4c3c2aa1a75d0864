//! `-q` sample enumeration, determinism, replay, convergence, and the rule that stage-2 scenes
//! render as stage 2 under the full renderer.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use glam::Vec3A;
use rayscope_core::integrator::Integrator;
use rayscope_core::{render, trace_pixel, CameraSettings, Film, RenderSettings, Scene, Stage};

fn scene(text: &str) -> Scene {
    let file = rayscope_scene::parse_str(text, Path::new("q.txt")).expect("scene parses");
    Scene::from_file(&file)
}

fn film(scene: &Scene, s: &RenderSettings) -> Film {
    render(scene, s, &|_, _| {}, &AtomicBool::new(false))
        .expect("not cancelled")
        .film
}

const LIT_BOX: &str = "Material \"White\" Diffuse (0.7, 0.7, 0.7) 1\nMaterial \"Red\" Diffuse (0.8, 0.1, 0.1) 1\n\
    Material \"Lamp\" Emissive (6, 6, 6) 1\nMaterial \"Gloss\" Glossy (0.1, 0.3, 0.8) 2\n\
    Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"White\"\nPlane \"Back\" (0, 0, 5) (0, 0, -1) \"Red\"\n\
    Sphere \"Bulb\" (0, 1.2, 3) 0.3 \"Lamp\"\nSphere \"Ball\" (0.5, -0.5, 3.5) 0.5 \"Gloss\"\n\
    Triangle \"Tile\" (-1.5, -1, 2) (-0.5, -1, 4) (-1.5, 0.5, 4) \"Lamp\"\n";

fn small(q: u32) -> RenderSettings {
    RenderSettings {
        width: 24,
        height: 16,
        aa: 2,
        quality: q,
        ..RenderSettings::default()
    }
}

#[test]
fn samples_per_pixel_follow_the_quality_rule() {
    let sc = scene(LIT_BOX);
    for q in 0..4 {
        let s = small(q);
        let integ = Integrator::new(&sc, &s);
        assert!(integ.stochastic);
        assert_eq!(integ.samples_per_pixel(), 4 << q);
        // Sample s lies in grid cell s mod N², at a point of its own within it (stratified
        // jitter, so pixels converge to their area's mean), the same every time it is asked for.
        let (w, h) = (s.width as f32, s.height as f32);
        let mut seen = Vec::new();
        for sample in 0..integ.samples_per_pixel() {
            let (u, v) = integ.sample_position(3, 5, sample);
            assert_eq!(integ.sample_position(3, 5, sample), (u, v), "deterministic");
            let cell = sample % 4;
            let (i, j) = ((cell % 2) as f32, (cell / 2) as f32);
            let (fx, fy) = (u * w - 3.0, v * h - 5.0);
            assert!(
                fx > i / 2.0 - 1e-4
                    && fx < (i + 1.0) / 2.0 + 1e-4
                    && fy > j / 2.0 - 1e-4
                    && fy < (j + 1.0) / 2.0 + 1e-4,
                "sample {sample} at ({fx}, {fy}) in the pixel, outside cell {cell}"
            );
            assert!(!seen.contains(&(u, v)), "sample {sample} repeats a position");
            seen.push((u, v));
        }
    }
    // Nothing stochastic: -q changes nothing.
    let plain = scene(
        "Material \"W\" Diffuse (1, 1, 1) 1\nPointLight \"L\" (0, 2, 0) (1, 1, 1)\nSphere \"S\" (0, 0, 3) 1 \"W\"\n",
    );
    let s = small(5);
    let integ = Integrator::new(&plain, &s);
    assert!(!integ.stochastic);
    assert_eq!(integ.samples_per_pixel(), 4);
    // ... and samples sit at the centres of their cells, as the course's grid has them.
    for cell in 0..4 {
        let (i, j) = ((cell % 2) as f32, (cell / 2) as f32);
        let want = (
            (3.0 + (i + 0.5) / 2.0) / s.width as f32,
            (5.0 + (j + 0.5) / 2.0) / s.height as f32,
        );
        assert_eq!(integ.sample_position(3, 5, cell), want, "cell {cell}");
    }
    assert_eq!(film(&plain, &s), film(&plain, &small(0)));
    // -l, an aperture or a stage-2 render decide too.
    for (s, want) in [
        (
            RenderSettings {
                ambient: true,
                ..small(2)
            },
            16,
        ),
        (
            RenderSettings {
                camera: CameraSettings {
                    aperture_radius: 0.1,
                    ..CameraSettings::default()
                },
                ..small(2)
            },
            16,
        ),
        (
            RenderSettings {
                stage: Stage::Two,
                ambient: true,
                ..small(2)
            },
            4,
        ),
    ] {
        assert_eq!(Integrator::new(&plain, &s).samples_per_pixel(), want);
    }
}

#[test]
fn renders_are_deterministic_and_samples_replay_exactly() {
    let sc = scene(LIT_BOX);
    let s = RenderSettings {
        ambient: true,
        ..small(1)
    };
    let a = film(&sc, &s);
    assert_eq!(a, film(&sc, &s), "same flags, same image");
    assert_ne!(a, film(&sc, &RenderSettings { seed: 1, ..s }), "the seed matters");
    // The pixel is the mean of its samples, and `trace` replays each one exactly.
    let spp = Integrator::new(&sc, &s).samples_per_pixel();
    for (x, y) in [(3, 4), (12, 9), (20, 2)] {
        let mean = (0..spp)
            .map(|i| Vec3A::from(trace_pixel(&sc, &s, x, y, i).color))
            .sum::<Vec3A>()
            / spp as f32;
        let p = Vec3A::from(a.get(x, y));
        assert!((mean - p).abs().max_element() < 1e-5, "pixel ({x}, {y}): {mean} vs {p}");
    }
}

fn rms(a: &Film, b: &Film) -> f32 {
    let n = a.pixels.len() as f32;
    (a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).length_squared())
        .sum::<f32>()
        / n)
        .sqrt()
}

#[test]
fn raising_quality_converges() {
    let sc = scene(LIT_BOX);
    let s = |q| RenderSettings {
        ambient: true,
        ..small(q)
    };
    let reference = film(&sc, &s(9));
    let errors: Vec<f32> = [0, 2, 4, 6]
        .iter()
        .map(|&q| rms(&film(&sc, &s(q)), &reference))
        .collect();
    eprintln!("rms error against q = 9: {errors:?}");
    for w in errors.windows(2) {
        // Four times the samples: about half the error.
        assert!(w[1] < w[0] * 0.75, "{errors:?}");
    }
}

/// Scenes with only stage-2 content render identically under `Stage::Full` and `Stage::Two`.
#[test]
fn stage_two_scenes_are_unchanged_by_the_full_renderer() {
    let own = "Material \"W\" Diffuse (0.9, 0.9, 0.9) 1\nMaterial \"M\" Reflective (0, 0, 0) 1\n\
        Material \"G\" Refractive (0, 0, 0) 1.5\nPointLight \"L\" (1, 2, 0) (1, 1, 1)\n\
        PointLight \"L2\" (-2, 1, 1) (0.3, 0.2, 0.5)\nPlane \"F\" (0, -1, 0) (0, 1, 0) \"W\"\n\
        Sphere \"Mirror\" (-0.8, 0, 4) 0.7 \"M\"\nSphere \"Glass\" (0.8, -0.2, 3) 0.6 \"G\"\n\
        Triangle \"T\" (-2, -1, 6) (0, 2, 6) (2, -1, 6) \"W\"\n";
    let mut scenes = vec![scene(own)];
    if let Some(course) = rayscope_testkit::course_part() {
        for name in ["sample_scene_1.txt", "sample_scene_2.txt"] {
            scenes.push(Scene::from_file(&rayscope_scene::load(&course.scene(name)).unwrap()));
        }
    }
    for sc in &scenes {
        let s = RenderSettings {
            width: 64,
            height: 64,
            aa: 2,
            quality: 3,
            ..RenderSettings::default()
        };
        assert_eq!(film(sc, &s), film(sc, &RenderSettings { stage: Stage::Two, ..s }));
    }
}

/// A stochastic render spreads each pixel's paths over the pixel, so a pixel an edge crosses
/// converges to the share of it the lit side covers (as a box filter gives it), not to whatever
/// its sample points happen to see. A lamp covers everything right of a vertical edge that
/// crosses pixel 32 of a 64-pixel row 30 % of the way in; the pixel must converge to 0.7, at
/// `-x 1` (where a sample at the pixel centre would give 1) and at `-x 2` (cell centres: 0.5).
#[test]
fn a_pixel_an_edge_crosses_converges_to_the_covered_share() {
    let pixel = 2.0 * 30f32.to_radians().tan() / 64.0;
    let e = 4.0 * 0.3 * pixel;
    let sc = scene(&format!(
        "Material \"Lamp\" Emissive (1, 1, 1) 1\n\
         Triangle \"A\" ({e}, -100, 4) ({e}, 100, 4) (100, 100, 4) \"Lamp\"\n\
         Triangle \"B\" ({e}, -100, 4) (100, 100, 4) (100, -100, 4) \"Lamp\"\n"
    ));
    for aa in [1, 2] {
        let s = RenderSettings {
            width: 64,
            height: 1,
            aa,
            quality: 10,
            ..RenderSettings::default()
        };
        let integ = Integrator::new(&sc, &s);
        assert!(integ.stochastic);
        let mut c = rayscope_core::integrator::Counters::default();
        let n = integ.samples_per_pixel();
        let mut value = |x: u32| {
            (0..n)
                .map(|k| integ.sample(x, 0, k, &mut rayscope_core::NoObserver, &mut c).x)
                .sum::<f32>()
                / n as f32
        };
        let v = value(32);
        // 1024 or 4096 samples of a 0/1 value with mean 0.7: standard error under 0.015.
        assert!(
            (v - 0.7).abs() < 0.05,
            "-x {aa}: the edge pixel converges to {v}, not 0.7"
        );
        assert_eq!(
            (value(31), value(33)),
            (0.0, 1.0),
            "-x {aa}: its neighbours are dark and lit"
        );
    }
}

/// The sampler is unbiased: the image mean of a 4-sample path-traced render, averaged over
/// independent seeds, converges to the mean of a 2048-sample render (within four standard
/// errors of the seeds' spread plus the reference's own noise). A sampler whose dimensions were
/// correlated (the light's numbers reused for the bounce, a 1-sample render not uniform over
/// the pixel) would miss it by far more.
#[test]
fn low_sample_renders_average_to_the_converged_image() {
    let sc = scene(LIT_BOX);
    let s = |q, seed| RenderSettings {
        ambient: true,
        seed,
        ..small(q)
    };
    let mean = |f: &Film| f.pixels.iter().map(|&p| Vec3A::from(p)).sum::<Vec3A>() / f.pixels.len() as f32;
    let reference = mean(&film(&sc, &s(9, 1000)));
    let seeds = 48;
    let means: Vec<Vec3A> = (0..seeds).map(|seed| mean(&film(&sc, &s(0, seed)))).collect();
    let avg = means.iter().sum::<Vec3A>() / seeds as f32;
    let var = means.iter().map(|m| (*m - avg) * (*m - avg)).sum::<Vec3A>() / (seeds - 1) as f32;
    // The mean of `seeds` renders' means: its standard error. The reference has 512 times the
    // samples of one render, so its error is the seed spread / √512.
    let sqrt = |v: Vec3A| Vec3A::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt());
    let se = sqrt(var / seeds as f32) + sqrt(var / 512.0);
    eprintln!("4-spp mean over {seeds} seeds {avg}, reference {reference}, standard error {se}");
    assert!(
        se.max_element() < 0.01 * reference.max_element(),
        "the test can see a 1 % bias: {se}"
    );
    for a in 0..3 {
        assert!(
            (avg[a] - reference[a]).abs() < 4.0 * se[a],
            "channel {a}: 4-spp renders average {avg}, the converged image {reference} (standard error {se})"
        );
    }
}
