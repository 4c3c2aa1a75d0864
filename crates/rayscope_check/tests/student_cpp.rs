//! `check` against a student-style C++ tracer (tests/student/tracer.cpp, built with g++): the
//! correct tracer gets no verdict on any of the course's scenes, every pixel logged, and each of
//! its switchable mistakes is named on the report's first line.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{check_log, have, root, text};
use std::sync::OnceLock;
use std::time::Instant;

use rayscope_check::{Code, Report};
use rayscope_core::{RenderSettings, Stage};

/// The tracer, compiled once per test run with `g++ -O2 -std=c++17`; `None` (loudly) when g++ is
/// missing outside CI.
fn tracer() -> Option<&'static Path> {
    static BUILT: OnceLock<Option<PathBuf>> = OnceLock::new();
    BUILT
        .get_or_init(|| {
            if !have("g++", "the C++ student-tracer tests") {
                return None;
            }
            let dir = tempfile::tempdir().expect("temp dir").keep();
            let exe = dir.join("tracer");
            let out = Command::new("g++")
                .args(["-O2", "-std=c++17", "-o"])
                .arg(&exe)
                .arg(root().join("crates/rayscope_check/tests/student/tracer.cpp"))
                .output()
                .expect("run g++");
            assert!(
                out.status.success(),
                "g++ failed:\n{}",
                String::from_utf8_lossy(&out.stderr)
            );
            Some(exe)
        })
        .as_deref()
}

struct Run<'a> {
    scene: PathBuf,
    w: u32,
    h: u32,
    aa: u32,
    stage: Stage,
    /// Rows `[y0, y1)` only, every column.
    rows: Option<(u32, u32)>,
    bug: &'a str,
}

impl Run<'_> {
    fn new(scene: PathBuf, w: u32, h: u32) -> Self {
        Run {
            scene,
            w,
            h,
            aa: 1,
            stage: Stage::Two,
            rows: None,
            bug: "none",
        }
    }

    /// Runs the tracer and checks its log, printing how long each took; `None` without g++.
    fn check(&self) -> Option<Report> {
        let exe = tracer()?;
        let dir = tempfile::tempdir().expect("temp dir");
        let log = dir.path().join("rays.jsonl");
        let stage = if self.stage == Stage::One { "1" } else { "2" };
        let mut cmd = Command::new(exe);
        cmd.arg("-f")
            .arg(&self.scene)
            .args([
                "-w",
                &self.w.to_string(),
                "-h",
                &self.h.to_string(),
                "-x",
                &self.aa.to_string(),
                "--stage",
                stage,
                "--bug",
                self.bug,
            ])
            .arg("--log")
            .arg(&log);
        if let Some((y0, y1)) = self.rows {
            cmd.arg("--region").arg(format!("0,{y0},{},{y1}", self.w));
        }
        let start = Instant::now();
        let out = cmd.output().expect("run the C++ tracer");
        assert!(
            out.status.success(),
            "tracer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let traced = start.elapsed().as_secs_f64();
        let settings = RenderSettings {
            width: self.w,
            height: self.h,
            aa: self.aa,
            stage: self.stage,
            ..RenderSettings::default()
        };
        let r = check_log(&self.scene, settings, &log, 3);
        eprintln!(
            "{} {}x{} -x {} stage {stage} rows {:?} bug {}: {} rays, traced in {traced:.2} s, checked in {:.2} s",
            self.scene.file_name().unwrap_or_default().to_string_lossy(),
            self.w,
            self.h,
            self.aa,
            self.rows,
            self.bug,
            r.rays,
            start.elapsed().as_secs_f64() - traced
        );
        Some(r)
    }
}

/// The correct tracer: no verdict, and every camera ray of the image (or of its rows) logged.
fn assert_clean(run: Run<'_>) {
    let Some(r) = run.check() else {
        return;
    };
    let rows = run.rows.map_or(run.h, |(a, b)| b - a);
    let per_pixel = if run.stage == Stage::One { 1 } else { run.aa * run.aa };
    assert_eq!(r.camera_rays, u64::from(run.w * rows * per_pixel), "{}", text(&r));
    assert_eq!(r.disagree, 0, "the correct tracer got verdicts:\n{}", text(&r));
    assert!(r.causes.is_empty(), "{}", text(&r));
    if run.stage == Stage::Two {
        // A camera ray whose hit is a tie leaves its colour unjudged.
        assert!(r.shaded_judged + r.ties >= r.camera_rays, "{}", text(&r));
    }
}

/// The course scene `name` at 400×300 `-x 1`, every pixel, then at 400×400 `-x 4` on `rows`.
fn assert_clean_on_course_scene(name: &str, rows: (u32, u32)) {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_clean(Run::new(course.scene(name), 400, 300));
    assert_clean(Run {
        aa: 4,
        rows: Some(rows),
        ..Run::new(course.scene(name), 400, 400)
    });
}

#[test]
fn correct_tracer_gets_no_verdict_on_course_scene_1() {
    // Rows through the sphere, the triangle and the triangle's shadow on the floor.
    assert_clean_on_course_scene("sample_scene_1.txt", (196, 200));
}

#[test]
fn correct_tracer_gets_no_verdict_on_course_scene_2() {
    // Rows through the glass sphere.
    assert_clean_on_course_scene("sample_scene_2.txt", (244, 247));
}

#[test]
fn correct_tracer_gets_no_verdict_on_course_scene_2_2021() {
    // Rows through the mirror sphere.
    assert_clean_on_course_scene("sample_scene_2_2021.txt", (164, 167));
}

#[test]
fn correct_tracer_gets_no_verdict_on_the_obj_scene() {
    // Rows through the bunny and its shadow.
    assert_clean_on_course_scene("sample_scene_obj.txt", (270, 274));
}

/// Stage 1 (the closest hit's material colour, one ray through each pixel centre, whatever `-x`
/// says) is judged on the rays alone.
#[test]
fn correct_stage_1_tracer_gets_no_verdict_on_every_course_scene() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for name in [
        "sample_scene_1.txt",
        "sample_scene_2.txt",
        "sample_scene_2_2021.txt",
        "sample_scene_obj.txt",
    ] {
        assert_clean(Run {
            aa: 4,
            stage: Stage::One,
            ..Run::new(course.scene(name), 400, 300)
        });
    }
}

/// A mistake: `code` heads the report's first line, as its one cause.
fn assert_one_headline(run: Run<'_>, code: Code) -> Option<Report> {
    let r = run.check()?;
    let t = text(&r);
    assert!(r.disagree > 0, "bug '{}' went unnoticed:\n{t}", run.bug);
    assert!(
        t.lines().next().is_some_and(|l| l.contains(code.as_str())),
        "bug '{}': the first line does not name {}:\n{t}",
        run.bug,
        code.as_str()
    );
    assert!(r.causes[0].code == code || r.causes[0].or == Some(code), "{t}");
    assert_eq!(r.causes.len(), 1, "bug '{}' has more than one headline:\n{t}", run.bug);
    Some(r)
}

#[test]
fn shadow_rays_without_offset_are_named_as_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for name in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        assert_one_headline(
            Run {
                bug: "shadow-no-offset",
                ..Run::new(course.scene(name), 80, 60)
            },
            Code::ShadowAcne,
        );
    }
}

#[test]
fn one_sided_triangles_are_named_where_they_fail_to_cast_shadows() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // The floor behind scene 1's triangle, in its shadow: the shadow rays meet its back face.
    assert_one_headline(
        Run {
            bug: "one-sided",
            rows: Some((250, 300)),
            ..Run::new(course.scene("sample_scene_1.txt"), 400, 400)
        },
        Code::ShadowOneSidedTriangle,
    );
}

#[test]
fn glass_without_fresnel_is_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = assert_one_headline(
        Run {
            bug: "no-fresnel",
            ..Run::new(course.scene("sample_scene_2.txt"), 80, 60)
        },
        Code::ShadingFresnelNone,
    ) else {
        return;
    };
    assert!(r.causes[0].examples[0].detail.contains("GlassSphere"), "{}", text(&r));
}

#[test]
fn an_obj_shaded_flat_is_named_on_its_diffuse_colour() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = assert_one_headline(
        Run {
            bug: "obj-flat-normals",
            ..Run::new(course.scene("sample_scene_obj.txt"), 80, 60)
        },
        Code::ShadingDiffuse,
    ) else {
        return;
    };
    assert!(r.causes[0].examples[0].detail.contains("'Bunny'"), "{}", text(&r));
}

/// An OBJ model whose z is not negated is mirrored front to back: the tracer hits the bunny where
/// it is not, and the report's first line says so about the bunny, with both distances.
#[test]
fn an_obj_without_its_z_flip_is_described_on_the_bunny() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "obj-no-z-flip",
        ..Run::new(course.scene("sample_scene_obj.txt"), 80, 60)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    // Misses, phantom hits and wrong distances, all on the model: one headline naming it.
    assert_eq!(r.causes.len(), 1, "{t}");
    let first = &r.causes[0];
    assert_eq!(first.code, Code::HitSurfaceWrong, "{t}");
    assert!(t.lines().next().unwrap_or_default().contains("model 'Bunny'"), "{t}");
    let ex = &first.examples[0];
    let entity = ex.values.iter().find(|v| v.what == "entity").expect("entity values");
    assert!(
        [&entity.yours, &entity.rayscope]
            .iter()
            .any(|v| v.as_str() == Some("Bunny")),
        "{t}"
    );
    assert!(ex.values.iter().any(|v| v.what == "t" && v.yours != v.rayscope), "{t}");
}

/// A mistake no catalogue has (the triangle test without u + v ≤ 1 accepts the parallelogram the
/// triangle spans): the report's first line is a truthful description of the first wrong ray, a
/// hit on or a shadow blocked by scene 1's triangle where it is not, with rayscope's answer beside.
#[test]
fn an_uncatalogued_triangle_mistake_gets_a_truthful_headline() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "parallelogram",
        ..Run::new(course.scene("sample_scene_1.txt"), 80, 60)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    // Phantom hits and phantom blockers, all on the triangle: one headline naming it.
    assert_eq!(r.causes.len(), 1, "{t}");
    assert_eq!(r.causes[0].code, Code::HitSurfaceWrong, "{t}");
    assert!(
        t.lines().next().unwrap_or_default().contains("triangle 'Triangle'"),
        "{t}"
    );
    for ex in &r.causes[0].examples {
        let v = &ex.values[0];
        assert_eq!(v.yours.as_str(), Some("Triangle"), "{t}");
        assert_ne!(v.yours, v.rayscope, "{t}");
    }
}

/// The check of a single pixel of the correct tracer's image, `aa` samples a side; `None`
/// without g++.
fn check_pixel(scene: PathBuf, w: u32, h: u32, aa: u32, [x, y]: [u32; 2]) -> Option<Report> {
    let exe = tracer()?;
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("rays.jsonl");
    let out = Command::new(exe)
        .arg("-f")
        .arg(&scene)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "-x", &aa.to_string()])
        .args(["--region", &format!("{x},{y},{},{}", x + 1, y + 1)])
        .arg("--log")
        .arg(&log)
        .output()
        .expect("run the C++ tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let settings = RenderSettings {
        width: w,
        height: h,
        aa,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    Some(check_log(&scene, settings, &log, 3))
}

/// Where a camera ray meets the box's floor or roof exactly on its edge with a wall, the shadow
/// rays (offset along the floor's or roof's normal) start on the wall, and the tracer's t > 0 test
/// finds the wall at t ≈ 1e-16: rounding, which check excuses as a tie when the light is reached
/// otherwise, but not when something else blocks it too (shadow.wrong-blocker), nor when the
/// camera ray's tie went to the other surface (shadow.acne). Found by bench/check_course_scenes.sh.
#[test]
fn shadow_rays_from_the_edges_of_the_box_are_ties() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for (w, h, aa, pixel) in [
        (400, 400, 1, [84, 315]),
        (400, 400, 4, [358, 41]),
        (400, 300, 4, [318, 268]),
    ] {
        let Some(r) = check_pixel(course.scene("sample_scene_2.txt"), w, h, aa, pixel) else {
            return;
        };
        assert_eq!(r.disagree, 0, "pixel {pixel:?}:\n{}", text(&r));
    }
}

/// A camera ray through the edge two of the bunny's triangles share: the tracer (f64) hits one
/// 3e-6 of its barycentric range inside the edge; rayscope's trace slips through to the bunny's
/// far side, and check calls it hit.wrong-t instead of a tie. Found by bench/check_course_scenes.sh.
#[test]
fn a_ray_through_a_shared_edge_of_the_bunny_is_a_tie() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = check_pixel(course.scene("sample_scene_obj.txt"), 400, 400, 4, [206, 351]) else {
        return;
    };
    // Only the hit: the diffuse colours there are judged with the flat normal (see above).
    assert!(!r.verdicts.iter().any(|v| v.code == Code::HitWrongT), "{}", text(&r));
}
