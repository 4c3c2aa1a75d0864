//! `check` judging colours: the student-style Python tracer (tests/student/tracer.py) logs the
//! colour every ray brought back, with one shading mistake at a time. Each must be named on the
//! ray whose colour it makes, and the correct tracer must get no verdict.

mod common;

use std::path::PathBuf;
use std::process::Command;

use common::{check_log, python, root};

use rayscope_check::log::open;
use rayscope_check::{check, CheckOptions, Code, Judge, LogContext, Report};
use rayscope_core::{RenderSettings, Scene, Stage};

struct Run<'a> {
    scene: PathBuf,
    w: u32,
    h: u32,
    aa: u32,
    bug: &'a str,
    colors: bool,
    examples: usize,
    stage: Stage,
    /// Rays of this kind are taken out of the log, as a tracer that does not log them writes it.
    unlogged: Option<&'a str>,
}

impl Run<'_> {
    fn new(scene: PathBuf, w: u32, h: u32) -> Self {
        Run {
            scene,
            w,
            h,
            aa: 1,
            bug: "none",
            colors: true,
            examples: 3,
            stage: Stage::Two,
            unlogged: None,
        }
    }

    /// Runs the student tracer; its log's lines and the check's report. `None` when python3 is
    /// missing.
    fn check(&self) -> Option<(Vec<String>, Report)> {
        let py = python()?;
        let dir = tempfile::tempdir().expect("temp dir");
        let log = dir.path().join("rays.jsonl");
        let mut cmd = Command::new(py);
        cmd.arg(root().join("crates/rayscope_check/tests/student/tracer.py"))
            .arg("-f")
            .arg(&self.scene)
            .args([
                "-w",
                &self.w.to_string(),
                "-h",
                &self.h.to_string(),
                "-x",
                &self.aa.to_string(),
            ])
            .args(["--bug", self.bug])
            .arg("--log")
            .arg(&log);
        if !self.colors {
            cmd.arg("--no-colors");
        }
        let out = cmd.output().expect("run the student tracer");
        assert!(
            out.status.success(),
            "tracer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        if let Some(kind) = self.unlogged {
            let text = std::fs::read_to_string(&log).expect("read log");
            let kept: String = text
                .lines()
                .filter(|l| !l.contains(&format!("\"kind\": \"{kind}\"")))
                .map(|l| format!("{l}\n"))
                .collect();
            assert!(kept.len() < text.len(), "no {kind} ray to take out");
            std::fs::write(&log, kept).expect("write log");
        }
        let settings = RenderSettings {
            width: self.w,
            height: self.h,
            aa: self.aa,
            stage: self.stage,
            ..RenderSettings::default()
        };
        let report = check_log(&self.scene, settings, &log, self.examples);
        let lines = std::fs::read_to_string(&log)
            .expect("read log")
            .lines()
            .map(str::to_string)
            .collect();
        Some((lines, report))
    }
}

fn text(r: &Report) -> String {
    r.to_text(&|_| None)
}

fn course_scene(name: &str) -> Option<PathBuf> {
    rayscope_testkit::course().map(|c| c.scene(name))
}

/// A mistake: named by `code`, the most frequent verdict, and no verdict outside `allowed`.
fn assert_named(run: Run<'_>, code: Code, allowed: &[Code]) -> Option<Report> {
    let (_, r) = run.check()?;
    let t = text(&r);
    assert!(r.disagree > 0, "bug '{}' went unnoticed:\n{t}", run.bug);
    assert_eq!(r.verdicts[0].code, code, "bug '{}' is not named first:\n{t}", run.bug);
    for v in &r.verdicts {
        assert!(
            v.code == code || allowed.contains(&v.code),
            "bug '{}' also gave {}:\n{t}",
            run.bug,
            v.code.as_str()
        );
    }
    Some(r)
}

/// The first examples' details of `code`.
fn details(r: &Report, code: Code) -> Vec<String> {
    r.verdicts
        .iter()
        .filter(|g| g.code == code)
        .flat_map(|g| g.examples.iter().map(|e| e.detail.clone()))
        .collect()
}

#[test]
fn correct_tracer_with_colours_gets_no_verdict_and_its_colours_are_judged() {
    let Some(scene2) = course_scene("sample_scene_2.txt") else {
        return;
    };
    for run in [
        Run {
            aa: 2,
            ..Run::new(scene2, 30, 30)
        },
        Run::new(course_scene("sample_scene_1.txt").unwrap_or_default(), 30, 30),
        Run::new(root().join("crates/rayscope_check/tests/scenes/glass_cube.txt"), 40, 30),
        Run::new(course_scene("sample_scene_2_2021.txt").unwrap_or_default(), 30, 30),
        // The full renderer (`check`'s default) shades these scenes as stage 2 does.
        Run {
            stage: Stage::Full,
            ..Run::new(course_scene("sample_scene_2.txt").unwrap_or_default(), 30, 30)
        },
    ] {
        let Some((_, r)) = run.check() else {
            return;
        };
        assert_eq!(r.disagree, 0, "the correct tracer got verdicts:\n{}", text(&r));
        // Every camera ray's decision at least, and only the few the rules leave open unjudged.
        assert!(r.shaded_judged >= r.camera_rays, "{}", text(&r));
        assert!(r.shaded_unjudged * 100 <= r.shaded_judged, "{}", text(&r));
    }
}

#[test]
fn a_log_without_colours_is_not_judged_on_them_and_says_so() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    let Some((_, r)) = Run {
        colors: false,
        ..Run::new(scene, 30, 30)
    }
    .check() else {
        return;
    };
    assert_eq!(r.disagree, 0, "{}", text(&r));
    assert_eq!(r.shaded_judged, 0);
    assert!(r.shaded_unjudged >= r.camera_rays);
    assert!(text(&r).contains(&format!("0 surface decisions judged; {} not judged", r.shaded_unjudged)));
}

#[test]
fn fresnel_mistakes_are_named_by_the_formula_they_fit() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    for (bug, code, words) in [
        ("no-fresnel", Code::ShadingFresnelNone, "no reflection at all"),
        ("fresnel-swapped", Code::ShadingFresnelSwappedCosines, "rs² alone"),
        ("schlick", Code::ShadingFresnelSchlick, "Schlick"),
        ("fresnel-half", Code::ShadingFresnelHalf, "half and half"),
        (
            "fresnel-weights-exchanged",
            Code::ShadingFresnelWeightsExchanged,
            "the Fresnel share given to the refracted colour",
        ),
    ] {
        let Some(r) = assert_named(
            Run {
                bug,
                ..Run::new(scene.clone(), 40, 40)
            },
            code,
            &[],
        ) else {
            return;
        };
        for d in details(&r, code) {
            assert!(d.contains(words) && d.contains("GlassSphere"), "{bug}: {d}");
        }
    }
}

#[test]
fn diffuse_mistakes_are_named_by_what_they_fit() {
    let (Some(scene1), Some(scene2)) = (course_scene("sample_scene_1.txt"), course_scene("sample_scene_2.txt")) else {
        return;
    };
    // Scene 2's lights are inside the box, in front of every wall: N·L < 0 happens on scene 1's
    // sphere, whose shadow rays toward the light behind it the tracer lets through.
    for (bug, scene, words) in [
        ("no-clamp", scene1.clone(), "without the clamp at 0"),
        ("falloff", scene2.clone(), "squared distance"),
        ("ambient", scene2.clone(), "ambient term of 0.1000 × the albedo"),
        // Not in the catalogue: under scene 2's grey lights both fit the albedo alone or one
        // factor on the course's sum, never an ambient term or the camera flags.
        (
            "light-colour-ignored",
            scene2.clone(),
            "the albedo without the lights' colour",
        ),
        // Not in the catalogue either: the light's vector not normalised in N·L.
        ("l-unnormalised", scene2.clone(), "L = light − point not normalised"),
        // Nor the light's position taken for L, the hit point left out (the shadow rays right).
        ("l-from-origin", scene1, "L = the light's position normalised"),
        ("l-from-origin", scene2.clone(), "L = the light's position normalised"),
        // Not in the catalogue: each light's term written over the sum, and N·V for N·L.
        ("light-overwrite", scene2.clone(), "the last lit light's term alone"),
        (
            "n-dot-view",
            scene2.clone(),
            "N·V, the cosine toward where the ray came from",
        ),
        (
            "lights-averaged",
            scene2,
            "the course's sum × 0.5000 in every channel (the sum over the 2 lights divided by their number",
        ),
    ] {
        let Some(r) = assert_named(
            Run {
                bug,
                ..Run::new(scene, 40, 40)
            },
            Code::ShadingDiffuse,
            &[],
        ) else {
            return;
        };
        for d in details(&r, Code::ShadingDiffuse) {
            assert!(d.contains(words), "{bug}: {d}");
        }
        let t = text(&r);
        assert!(
            !t.contains("most camera rays disagree"),
            "{bug}: wrong colours are no flag mismatch\n{t}"
        );
    }
}

#[test]
fn missing_shadow_and_reflected_rays_are_named_on_the_hit_that_needs_them() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    // The last light skipped, or every light after a blocked one (a break at the first blocked
    // light, which the details say, not an off-by-one).
    for (bug, words) in [
        ("skip-shadow-ray", &["light 'Light2'"][..]),
        (
            "shadow-loop-break",
            &["toward light 'Light1', is blocked", "stops at a blocked light"][..],
        ),
    ] {
        let Some(r) = assert_named(
            Run {
                bug,
                ..Run::new(scene.clone(), 40, 40)
            },
            Code::MissingShadowRay,
            &[],
        ) else {
            return;
        };
        for d in details(&r, Code::MissingShadowRay) {
            assert!(words.iter().all(|w| d.contains(w)), "{bug}: {d}");
        }
    }
    let Some(r) = assert_named(
        Run {
            bug: "no-reflection-ray",
            ..Run::new(scene, 40, 40)
        },
        Code::MissingReflection,
        &[],
    ) else {
        return;
    };
    for g in r.verdicts.iter().filter(|g| g.code == Code::MissingReflection) {
        for e in &g.examples {
            assert!(e.detail.contains("GlassSphere"), "{}", e.detail);
            assert_ne!(e.kind, "shadow");
        }
    }
}

/// A mistake rayscope has no name for (the cosine applied twice) is pointed at on the ray whose
/// colour it makes, described as an unknown mistake, with the colour the correct tracer logs for
/// that very ray as rayscope's.
#[test]
fn an_unknown_diffuse_mistake_gets_the_right_ray_and_the_right_numbers() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    let run = |bug| Run {
        bug,
        examples: 50,
        ..Run::new(scene.clone(), 20, 20)
    };
    let Some(r) = assert_named(run("cos-twice"), Code::ShadingDiffuse, &[]) else {
        return;
    };
    let Some((correct, _)) = run("none").check() else {
        return;
    };
    let g = &r.verdicts[0];
    assert!(g.count > 300, "{}", text(&r));
    let named = g
        .examples
        .iter()
        .filter(|e| !e.detail.contains("nor any of the usual mistakes"))
        .count();
    assert!(named <= 1, "a mistake rayscope does not know got a name:\n{}", text(&r));
    for e in &g.examples {
        let line: serde_json::Value = serde_json::from_str(&correct[e.line as usize - 1]).expect("json");
        let colour = e.values.iter().find(|v| v.what == "colour").expect("colour value");
        let want = line["color"].as_array().expect("colour logged");
        for (a, b) in colour.rayscope.as_array().expect("rayscope's").iter().zip(want) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(
                (a - b).abs() <= 1e-5,
                "line {}: rayscope's {a} against the correct tracer's {b}",
                e.line
            );
        }
        assert_ne!(colour.yours, colour.rayscope);
    }
}

/// rayscope's own trace, with the colour each ray brought back: every surface decision is judged
/// and none disagrees.
#[test]
fn rayscope_own_colours_are_judged_without_a_verdict() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for (scene, w, aa) in [
        (course.scene("sample_scene_2.txt"), 24, 2),
        (root().join("crates/rayscope_check/tests/scenes/glass_cube.txt"), 24, 1),
    ] {
        let file = rayscope_scene::load(&scene).expect("scene");
        let scene = Scene::from_file(&file);
        let settings = RenderSettings {
            width: w,
            height: w,
            aa,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        let dir = tempfile::tempdir().expect("temp dir");
        let log = dir.path().join("own.jsonl");
        let mut f = std::fs::File::create(&log).expect("log");
        rayscope_check::selflog::write_log(&scene, &settings, 0..w, &mut f).expect("write");
        drop(f);
        let judge = Judge::new(&scene, &settings);
        let ctx = LogContext::new(&scene, w, w, judge.samples_per_pixel(), aa);
        let mut src = open(&log, ctx, false, &[]).expect("open");
        let r = check(&judge, src.as_mut(), CheckOptions::default(), &|_, _| {}).expect("check");
        assert_eq!(r.disagree, 0, "{}", text(&r));
        assert!(r.shaded_judged >= r.camera_rays, "{}", text(&r));
        // Left unjudged: glass hits deep in the tree whose reflected ray rayscope pruned (under
        // 1/4096 of the sample): 4 % in scene 2, 6 % in the glass cube.
        assert!(r.shaded_unjudged * 10 <= r.shaded_judged, "{}", text(&r));
    }
}

#[test]
fn a_recursion_that_stops_early_or_is_not_black_at_the_limit_is_named() {
    let (Some(scene2), Some(scene2021)) = (
        course_scene("sample_scene_2.txt"),
        course_scene("sample_scene_2_2021.txt"),
    ) else {
        return;
    };
    let Some(r) = assert_named(
        Run {
            bug: "depth-4",
            ..Run::new(scene2, 40, 40)
        },
        Code::MissingSecondary,
        &[],
    ) else {
        return;
    };
    for d in details(&r, Code::MissingSecondary) {
        assert!(d.contains("after 4 bounces, below the depth limit of 8"), "{d}");
    }
    // The 2021 scene's mirror and glass are white: returned at the limit, they are not black.
    let Some(r) = assert_named(
        Run {
            bug: "limit-colour",
            ..Run::new(scene2021, 40, 40)
        },
        Code::ShadingDepthLimit,
        &[],
    ) else {
        return;
    };
    for d in details(&r, Code::ShadingDepthLimit) {
        assert!(d.contains("after 8 bounces, at the depth limit of 8"), "{d}");
    }
}

/// A tracer that logs no shadow ray at all is not told that every diffuse hit lacks them; its
/// diffuse colours are judged against the course's sum over the lights the oracle sees.
#[test]
fn a_log_without_shadow_rays_gets_no_missing_shadow_ray_verdict() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    let Some((_, all)) = Run::new(scene.clone(), 30, 30).check() else {
        return;
    };
    let Some((_, r)) = Run {
        unlogged: Some("shadow"),
        ..Run::new(scene, 30, 30)
    }
    .check() else {
        return;
    };
    assert_eq!(r.disagree, 0, "{}", text(&r));
    assert_eq!(
        r.shaded_judged + r.shaded_unjudged,
        all.shaded_judged + all.shaded_unjudged
    );
    assert!(r.shaded_unjudged * 20 < r.shaded_judged, "{}", text(&r));
}

#[test]
fn a_tinted_mirror_a_tinted_glass_and_a_background_colour_are_named() {
    let (Some(scene1), Some(scene2)) = (course_scene("sample_scene_1.txt"), course_scene("sample_scene_2.txt")) else {
        return;
    };
    // Scene 2's mirror material is black: multiplied in, it makes the mirror black.
    let Some(r) = assert_named(
        Run {
            bug: "mirror-tint",
            ..Run::new(scene2, 40, 40)
        },
        Code::ShadingMirror,
        &[],
    ) else {
        return;
    };
    for d in details(&r, Code::ShadingMirror) {
        assert!(
            d.contains("'MirrorSphere'") && d.contains("multiplied by the material colour"),
            "{d}"
        );
    }
    // A mirror that keeps 0.8 of what it reflects (no catalogue has it): the factor is given.
    let dim = assert_named(
        Run {
            bug: "mirror-dim",
            ..Run::new(course_scene("sample_scene_2.txt").expect("scene 2"), 40, 40)
        },
        Code::ShadingMirror,
        &[],
    )
    .expect("a report");
    for d in details(&dim, Code::ShadingMirror) {
        assert!(
            d.contains("'MirrorSphere'") && d.contains("0.8000 × what your reflected ray"),
            "{d}"
        );
    }
    // So is its glass material: the glass's mix multiplied by it is black, said as the tint, in
    // one headline.
    let glass = assert_named(
        Run {
            bug: "glass-tint",
            ..Run::new(course_scene("sample_scene_2.txt").expect("scene 2"), 40, 40)
        },
        Code::ShadingGlass,
        &[],
    )
    .expect("a report");
    assert_eq!(glass.causes.len(), 1, "{}", text(&glass));
    for d in details(&glass, Code::ShadingGlass) {
        assert!(
            d.contains("'GlassSphere'") && d.contains("multiplied by the material colour [0.0, 0.0, 0.0]"),
            "{d}"
        );
    }
    // Scene 1 has sky above its plane.
    assert_named(
        Run {
            bug: "background",
            ..Run::new(scene1, 40, 40)
        },
        Code::ShadingMissNotBlack,
        &[],
    );
}

/// Glass colours no catalogue has: R + T added with no weights, or kr·R + T, is named as such; a tracer whose
/// picture is right but whose log holds its glass children's colours after weighting them is
/// told that the log, not the shading, differs; a Fresnel reflectance with the indices exchanged
/// is one verdict with its share, never a formula it matches by chance near normal incidence.
#[test]
fn glass_weights_left_out_or_logged_in_and_an_unknown_share_get_one_true_headline() {
    let Some(scene) = course_scene("sample_scene_2.txt") else {
        return;
    };
    // The glass above rays that logged weighted colours is judged from those: what it reads
    // follows from them (where one colour is black, a share of 0 or 1 is the sum as well).
    let above = [
        Code::ShadingGlassSum,
        Code::ShadingTransmissionUnweighted,
        Code::ShadingGlass,
        Code::ShadingFresnel,
        Code::ShadingFresnelNone,
        Code::ShadingFresnelWeightsExchanged,
        Code::ShadingFresnelSchlick,
        Code::ShadingFresnelSwappedCosines,
        Code::ShadingFresnelHalf,
    ];
    for (bug, code, words, follows) in [
        ("glass-sum", Code::ShadingGlassSum, "R + T", &[][..]),
        (
            "glass-t-unweighted",
            Code::ShadingTransmissionUnweighted,
            "your refracted colour added whole",
            &[][..],
        ),
        (
            "logged-weighted",
            Code::ShadingLoggedWeighted,
            "what this ray brings back times",
            &above[..],
        ),
        (
            "fresnel-indices-swapped",
            Code::ShadingFresnel,
            "the Fresnel equations give",
            &[],
        ),
    ] {
        for aa in [1, 2] {
            let Some(r) = assert_named(
                Run {
                    bug,
                    aa,
                    ..Run::new(scene.clone(), 40, 40)
                },
                code,
                follows,
            ) else {
                return;
            };
            for d in details(&r, code) {
                assert!(d.contains(words) && d.contains("GlassSphere"), "{bug}: {d}");
            }
            assert_eq!(r.causes[0].code, code, "{}", text(&r));
        }
    }
}
