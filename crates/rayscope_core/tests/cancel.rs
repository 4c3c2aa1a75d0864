//! A cancel reaches inside one path: a scene whose every camera ray branches into a glass tree
//! of depth 1000 (thousands of nested glass spheres around the camera) stops within a fraction
//! of a second of the flag being set, on each engine, instead of finishing the samples it began.

use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use rayscope_core::mistakes::Mistakes;
use rayscope_core::{render, RenderSettings, Scene};

/// `n` glass spheres nested about the camera, with a light inside the innermost.
fn nested_glass(n: u32) -> Scene {
    let mut text = String::from("Material \"G\" Refractive (0, 0, 0) 1.5\nPointLight \"L\" (0, 0, 0.5) (1, 1, 1)\n");
    for i in 0..n {
        writeln!(text, "Sphere \"S{i}\" (0, 0, 0) {} \"G\"", 1.0 + f64::from(i) * 0.01).unwrap();
    }
    let file = rayscope_scene::parse_str(&text, Path::new("nested.txt")).expect("scene parses");
    Scene::from_file(&file)
}

/// Starts a render, sets the cancel flag after `after`, and returns how long the render took
/// to return once the flag was set.
fn stop_time(scene: &Scene, settings: &RenderSettings, after: Duration) -> Duration {
    let cancel = AtomicBool::new(false);
    let set_at = std::thread::scope(|s| {
        let setter = s.spawn(|| {
            std::thread::sleep(after);
            cancel.store(true, Ordering::Relaxed);
            Instant::now()
        });
        let result = render(scene, settings, &|_, _| {}, &cancel);
        assert!(result.is_err(), "the render was cancelled, so it returns no image");
        let set_at = setter.join().unwrap();
        (set_at, Instant::now())
    });
    set_at.1.saturating_duration_since(set_at.0)
}

#[test]
fn a_cancel_stops_a_branching_glass_path_at_once() {
    let scene = nested_glass(2000);
    let base = RenderSettings {
        width: 16,
        height: 16,
        max_depth: 1000,
        ..RenderSettings::default()
    };
    // The packet engine (plain colour render), then the one-path engine (every render with a
    // mistake goes through it).
    let one_path = RenderSettings {
        mistakes: Mistakes::parse("no-shadow-offset").unwrap(),
        ..base
    };
    for (engine, settings) in [("packets", &base), ("one path", &one_path)] {
        let took = stop_time(&scene, settings, Duration::from_millis(400));
        assert!(
            took < Duration::from_secs(2),
            "{engine}: the render went on for {took:?} after the cancel"
        );
    }
}
