//! How long `diagnose` takes on each case a student brings (issue #42's benchmark, not a timed
//! test): the test student's 400×400 stage-2 picture of a course scene with each mistake it can
//! make — catalogued or not — and without any, diagnosed with the command line's defaults (pairs
//! included). `every_case` is ignored by default; `bench/diagnose_cases.sh` runs it in release
//! and prints one row per case: the scene, the mistake, the seconds of the diagnosis, and the
//! start of the report's first line. With `RAYSCOPE_CASE=MISTAKE` it runs that case alone and
//! prints its whole report.

mod student;

use std::path::Path;
use std::time::Instant;

use rayscope_core::diagnose::{diagnose, report_text, DiagnoseOptions, Image};
use rayscope_core::{RenderSettings, Stage};
use student::{Options, Student};

/// The mistakes the test student makes, each on the course scene that shows it.
const CASES: [(&str, &str); 48] = [
    ("sample_scene_2.txt", "none"),
    ("sample_scene_1.txt", "none"),
    ("sample_scene_obj.txt", "none"),
    ("sample_scene_2.txt", "accumulator-not-reset"),
    ("sample_scene_2.txt", "ambient-term"),
    ("sample_scene_2.txt", "aspect-ignored"),
    ("sample_scene_2.txt", "cam-angle-radians"),
    ("sample_scene_2.txt", "cos-t-as-cos-i"),
    ("sample_scene_2.txt", "eta-entering-inverted"),
    ("sample_scene_2.txt", "first-hit-in-scene-order"),
    ("sample_scene_2.txt", "first-light-only"),
    ("sample_scene_1.txt", "fov-not-halved"),
    ("sample_scene_2.txt", "fov-in-radians"),
    ("sample_scene_2.txt", "fov-vertical"),
    ("sample_scene_2.txt", "fresnel-half"),
    ("sample_scene_2.txt", "fresnel-one-plus-i-dot-n"),
    ("sample_scene_2.txt", "fresnel-one-plus-i-dot-n-facing"),
    ("sample_scene_2.txt", "fresnel-swapped"),
    ("sample_scene_2.txt", "gamma"),
    ("sample_scene_2.txt", "glass-reflection-along-ray"),
    ("sample_scene_2.txt", "glass-reflection-outward"),
    ("sample_scene_2.txt", "huge-shadow-offset"),
    ("sample_scene_2.txt", "image-flipped"),
    ("sample_scene_2.txt", "light-falloff"),
    ("sample_scene_2.txt", "min-hit-distance"),
    ("sample_scene_obj.txt", "n-dot-l-unclamped"),
    ("sample_scene_2.txt", "nearest-by-origin-distance"),
    ("sample_scene_2.txt", "no-fresnel"),
    ("sample_scene_2.txt", "no-mirror-offset"),
    ("sample_scene_2.txt", "no-shadow-offset"),
    ("sample_scene_2.txt", "no-shadow-offset-single"),
    ("sample_scene_2.txt", "no-tir"),
    ("sample_scene_obj.txt", "obj-flat-normals"),
    ("sample_scene_2.txt", "one-sided-triangles"),
    ("sample_scene_2.txt", "pixel-corners"),
    ("sample_scene_1.txt", "plane-hits-behind"),
    ("sample_scene_2.txt", "recursion-limit-3"),
    ("sample_scene_2.txt", "reflect-no-2"),
    ("sample_scene_2.txt", "reflect-sign"),
    ("sample_scene_2.txt", "refraction-no-index-swap"),
    ("sample_scene_2.txt", "refraction-no-normal-flip"),
    ("sample_scene_2.txt", "reversed-normals"),
    ("sample_scene_2.txt", "rounded-colours"),
    ("sample_scene_2.txt", "schlick"),
    ("sample_scene_2.txt", "shadow-past-light"),
    ("sample_scene_2.txt", "sphere-near-root-behind"),
    ("sample_scene_2.txt", "sphere-near-root-only"),
    ("sample_scene_1.txt", "sphere-normal-unnormalised"),
];

#[test]
#[ignore = "a benchmark: bench/diagnose_cases.sh runs it in release"]
fn every_case() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (w, h) = (400, 400);
    println!("{:<22} {:<32} {:>8}  first line", "scene", "mistake", "seconds");
    let mut slowest = 0.0f64;
    let only = std::env::var("RAYSCOPE_CASE").ok();
    for (scene, bug) in CASES {
        if only.as_deref().is_some_and(|o| o != bug) {
            continue;
        }
        let path = course.scene(scene);
        let file = load(&path);
        let bugs: Vec<&'static str> = if bug == "none" { Vec::new() } else { vec![bug] };
        let rgb = Student::new(&file, &bugs, Options::new(w, h)).render();
        let image = Image {
            width: w,
            height: h,
            rgb: &rgb,
            alpha: None,
        };
        let flags = RenderSettings {
            width: w,
            height: h,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        let start = Instant::now();
        let d = diagnose(&file, &flags, image, &DiagnoseOptions::default()).expect("the sizes agree");
        let secs = start.elapsed().as_secs_f64();
        slowest = slowest.max(secs);
        let first = if d.matches {
            "matches".to_string()
        } else {
            report_text(&d, scene)
                .lines()
                .next()
                .unwrap_or_default()
                .chars()
                .take(90)
                .collect()
        };
        println!("{scene:<22} {bug:<32} {secs:>8.2}  {first}");
        if only.is_some() {
            println!("{}", report_text(&d, scene));
        }
    }
    println!("slowest: {slowest:.2} s");
}

fn load(path: &Path) -> rayscope_scene::SceneFile {
    rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}
