//! One 960×640 scene-view frame of the course's scenes with every ray of a 9×9 image, the traced
//! image on the grid, ground grid and silhouette anti-aliasing on (the debugger's defaults).
//! Target: ≤ 50 ms a frame on 2 cores.
//!
//! `cargo bench -p rayscope_debug --bench scene_view`

// criterion_group! generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::sync::atomic::AtomicBool;

use criterion::{criterion_group, criterion_main, Criterion};
use rayscope_core::{CameraSettings, FovAxis, RenderSettings, Scene};
use rayscope_debug::view::{auto_view, render_view, ImageMode, RayMode, RgbImage, ViewOptions};

fn bench(c: &mut Criterion) {
    let Some(course) = rayscope_testkit::Course::find() else {
        eprintln!(
            "scene view benchmark skipped: no course folder with tests/ and images/ at {} (set {})",
            rayscope_testkit::course_dir().display(),
            rayscope_testkit::COURSE_DIR_VAR
        );
        return;
    };
    let mut g = c.benchmark_group("scene_view_960x640_all_rays_9x9");
    g.sample_size(20);
    for name in ["sample_scene_1.txt", "sample_scene_2.txt", "sample_scene_obj.txt"] {
        let file = rayscope_scene::load(&course.scene(name)).expect("scene loads");
        let scene = Scene::from_file(&file);
        let settings = RenderSettings {
            width: 9,
            height: 9,
            camera: CameraSettings {
                fov_axis: FovAxis::Vertical,
                ..CameraSettings::default()
            },
            ..RenderSettings::default()
        };
        let never = AtomicBool::new(false);
        let out = rayscope_core::render(&scene, &settings, &|_, _| {}, &never).unwrap();
        let image = RgbImage {
            width: 9,
            height: 9,
            rgb: out.film.to_rgb8(),
        };
        let mut opts = ViewOptions::new(960, 640, auto_view(&scene, &settings, 1.5));
        opts.rays = RayMode::All;
        opts.image = ImageMode::Traced;
        // CPU time per frame (all threads), which does not depend on what else the machine
        // runs: on an idle machine with N cores a frame takes about cpu / N plus the serial
        // overlay.
        let cpu0 = cpu_millis();
        let frames = 20;
        let mut overlay = 0.0;
        for _ in 0..frames {
            let f = render_view(&scene, &settings, Some(&image), &opts);
            overlay += f.info.millis - f.info.scene_millis;
        }
        if let (Some(a), Some(b)) = (cpu0, cpu_millis()) {
            eprintln!(
                "{name}: {:.1} ms CPU a frame, of which the serial overlay is {:.1} ms wall",
                (b - a) / frames as f64,
                overlay / frames as f64
            );
        }
        g.bench_function(name.trim_end_matches(".txt"), |b| {
            b.iter(|| render_view(&scene, &settings, Some(&image), &opts));
        });
    }
    g.finish();
}

/// User + system CPU time of this process in milliseconds (Linux `/proc`; `None` elsewhere).
fn cpu_millis() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = stat.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on Linux.
    Some(ticks * 10.0)
}

criterion_group!(benches, bench);
criterion_main!(benches);
