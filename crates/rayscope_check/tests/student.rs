//! `check` against a student-style Python tracer (tests/student/tracer.py) with one realistic
//! mistake at a time: each must be named, and the correct tracer must get no verdict.

mod common;

use std::path::PathBuf;
use std::process::Command;

use common::{check_log, python, root, text};

use rayscope_check::log::open;
use rayscope_check::{check, CheckOptions, Code, Judge, LogContext, Report};
use rayscope_core::{RenderSettings, Scene, Stage};

struct Run<'a> {
    scene: PathBuf,
    w: u32,
    h: u32,
    aa: u32,
    region: Option<[u32; 4]>,
    bug: &'a str,
    /// Whether the log names entities and lights (and gives t), or is shaped like the course
    /// template's tracer, which has none.
    names: bool,
    /// The sample numbers logged, as `0,3` (all when `None`).
    log_samples: Option<&'a str>,
    /// More of the tracer's options (its offset, where shadow rays are aimed from).
    options: &'a [&'a str],
}

impl Run<'_> {
    fn new(scene: PathBuf, w: u32, h: u32) -> Self {
        Run {
            scene,
            w,
            h,
            aa: 1,
            region: None,
            bug: "none",
            names: true,
            log_samples: None,
            options: &[],
        }
    }

    /// Runs the student tracer and checks its log; `None` when python3 is missing.
    fn check(&self) -> Option<Report> {
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
        if !self.names {
            cmd.arg("--no-names");
        }
        if let Some(k) = self.log_samples {
            cmd.args(["--log-samples", k]);
        }
        cmd.args(self.options);
        if let Some([a, b, c, d]) = self.region {
            cmd.arg("--region").arg(format!("{a},{b},{c},{d}"));
        }
        let out = cmd.output().expect("run the student tracer");
        assert!(
            out.status.success(),
            "tracer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let settings = RenderSettings {
            width: self.w,
            height: self.h,
            aa: self.aa,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        Some(check_log(&self.scene, settings, &log, 3))
    }
}

/// The correct tracer: no verdict at all.
fn assert_clean(run: Run<'_>) {
    let Some(r) = run.check() else {
        return;
    };
    assert!(r.rays > 1000, "too few rays: {}", r.rays);
    assert_eq!(r.disagree, 0, "the correct tracer got verdicts:\n{}", text(&r));
}

/// A mistake: named by `code` on the report's first line, as the one cause, and no verdict (nor a
/// second cause) outside `allowed`.
fn assert_named(run: Run<'_>, code: Code, allowed: &[Code]) {
    let Some(r) = run.check() else {
        return;
    };
    let t = text(&r);
    assert!(r.disagree > 0, "bug '{}' went unnoticed:\n{t}", run.bug);
    let first = &r.causes[0];
    assert!(
        first.code == code || first.or == Some(code),
        "bug '{}' is not named first:\n{t}",
        run.bug
    );
    assert!(
        t.lines().next().is_some_and(|l| l.contains(code.as_str())),
        "bug '{}': the first line does not name it:\n{t}",
        run.bug
    );
    for c in &r.causes[1..] {
        assert!(
            allowed.contains(&c.code),
            "bug '{}' gave a second headline, {}:\n{t}",
            run.bug,
            c.name()
        );
    }
    for v in &r.verdicts {
        assert!(
            v.code == code || first.or == Some(v.code) || allowed.contains(&v.code),
            "bug '{}' also gave {}:\n{t}",
            run.bug,
            v.code.as_str()
        );
    }
}

#[test]
fn correct_tracer_gets_no_verdict_on_course_scene_1() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_clean(Run::new(course.scene("sample_scene_1.txt"), 40, 40));
}

#[test]
fn correct_tracer_gets_no_verdict_on_course_scene_2_with_aa() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_clean(Run {
        aa: 2,
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    });
}

#[test]
fn shadow_rays_aimed_from_the_hit_point_before_a_large_offset_get_no_verdict() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // light − point with the point before it is offset 1e-4 off the surface: the course's rule,
    // about 0.006° from light − origin.
    for scene in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        assert_clean(Run {
            options: &["--eps", "1e-4", "--aim-from-hit"],
            ..Run::new(course.scene(scene), 40, 40)
        });
    }
}

#[test]
fn unnamed_blockers_behind_a_small_offset_are_not_called_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = || course.scene("sample_scene_2.txt");
    // The template's log (no names) with an offset of 1e-6: the surface a shadow ray leaves lies
    // 1e-6 / cos behind its origin, which no rounding brings in front, so a light blocked by
    // something past it is not shadow acne; the first example says what lies where.
    for eps in ["1e-5", "1e-6"] {
        let Some(r) = assert_one_headline(
            Run {
                bug: "shadow-t-dist-squared",
                names: false,
                options: &["--eps", eps],
                ..Run::new(scene(), 40, 40)
            },
            Code::ShadowPhantomBlocker,
        ) else {
            return;
        };
        first_example_says(
            &r,
            &[
                "lies beyond the light",
                "(a blocker test that does not stop at the light counts it)",
            ],
        );
    }
    // With no offset at all it is acne, and the correct tracer's log gets no verdict.
    assert_one_headline(
        Run {
            bug: "shadow-no-offset",
            names: false,
            ..Run::new(scene(), 40, 40)
        },
        Code::ShadowAcne,
    );
    assert_clean(Run {
        names: false,
        options: &["--eps", "1e-6"],
        ..Run::new(scene(), 40, 40)
    });
}

#[test]
fn correct_tracer_gets_no_verdict_on_our_scenes() {
    assert_clean(Run::new(root().join("scenes/whitted.txt"), 40, 40));
    assert_clean(Run::new(
        root().join("crates/rayscope_check/tests/scenes/glass_cube.txt"),
        40,
        30,
    ));
}

/// A tracer shaped like the course's template has no names and no t: its log gives hits by point
/// and normal, lights by position and blockers only as `true`. rayscope finds the entities by
/// geometry, so the correct tracer still gets no verdict and each mistake the same headline as
/// with names.
#[test]
fn a_log_without_names_or_t_is_judged_like_a_named_one() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let nameless = |run: Run<'static>| Run { names: false, ..run };
    assert_clean(nameless(Run::new(course.scene("sample_scene_1.txt"), 40, 40)));
    assert_clean(nameless(Run {
        aa: 2,
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    }));
    let scene2 = || Run::new(course.scene("sample_scene_2.txt"), 40, 40);
    for (bug, code, allowed) in [
        ("shadow-no-offset", Code::ShadowAcne, &[][..]),
        ("refraction-normal", Code::RefractionNormalNotFlipped, &[]),
        ("reflect-no-2", Code::ReflectionNotMirror, &[]),
    ] {
        assert_named(nameless(Run { bug, ..scene2() }), code, allowed);
    }
    // Scene 1's floor in the triangle's shadow: blockers logged as `true` still tell a shadow
    // test that misses the triangle's back face.
    assert_named(
        nameless(Run {
            bug: "one-sided",
            region: Some([200, 250, 280, 300]),
            ..Run::new(course.scene("sample_scene_1.txt"), 400, 400)
        }),
        Code::ShadowOneSidedTriangle,
        &[Code::HitOneSidedTriangle],
    );
}

#[test]
fn refraction_normal_not_flipped_is_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for scene in [course.scene("sample_scene_2.txt"), root().join("scenes/whitted.txt")] {
        assert_named(
            Run {
                bug: "refraction-normal",
                ..Run::new(scene, 40, 40)
            },
            Code::RefractionNormalNotFlipped,
            &[],
        );
    }
}

#[test]
fn shadow_rays_without_offset_are_named_as_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for scene in [course.scene("sample_scene_1.txt"), course.scene("sample_scene_2.txt")] {
        assert_named(
            Run {
                bug: "shadow-no-offset",
                ..Run::new(scene, 40, 40)
            },
            Code::ShadowAcne,
            &[],
        );
    }
}

#[test]
fn vertical_fov_on_a_400x300_image_is_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_named(
        Run {
            bug: "vertical-fov",
            region: Some([0, 0, 400, 3]),
            ..Run::new(course.scene("sample_scene_1.txt"), 400, 300)
        },
        Code::CameraFovAxis,
        &[],
    );
}

#[test]
fn wrong_aspect_ratio_is_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_named(
        Run {
            bug: "aspect",
            region: Some([0, 140, 400, 143]),
            ..Run::new(course.scene("sample_scene_1.txt"), 400, 300)
        },
        Code::CameraAspect,
        &[],
    );
}

#[test]
fn one_sided_triangles_are_named_where_they_fail_to_cast_shadows() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // The floor behind scene 1's triangle, in its shadow: the shadow rays meet its back face.
    assert_named(
        Run {
            bug: "one-sided",
            region: Some([200, 250, 280, 300]),
            ..Run::new(course.scene("sample_scene_1.txt"), 400, 400)
        },
        Code::ShadowOneSidedTriangle,
        &[Code::HitOneSidedTriangle],
    );
}

#[test]
fn refraction_without_total_internal_reflection_is_named() {
    assert_named(
        Run {
            bug: "no-tir",
            ..Run::new(root().join("crates/rayscope_check/tests/scenes/glass_cube.txt"), 40, 30)
        },
        Code::RefractionTirMissed,
        &[],
    );
}

/// A normal flipped to face the camera instead of the ray faces out of the glass inside it: the
/// reflected ray's origin is offset to the wrong side, by 1e-6, within the tolerance for an
/// origin, and the ray meets the sphere again at once. That is the offset, not rounding (acne).
#[test]
fn self_hits_from_origins_offset_to_the_wrong_side_are_that_offset() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "normal-toward-camera",
        options: &["--eps", "1e-6"],
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    assert_eq!(r.causes[0].code, Code::SecondaryOffsetWrongSide, "{t}");
    assert!(r.causes.iter().all(|c| c.code != Code::SecondaryAcne), "{t}");
    first_example_says(&r, &["to the wrong side of the surface"]);
}

/// Refraction formulas no catalogue has: the cosine's sign not turned, a direction that is not
/// unit (the camera's, not normalised) given to a formula that needs one, η where η² belongs,
/// the square root left out. Each is Snell's law broken, with the formula it fits said on the
/// ray.
#[test]
fn refraction_formulas_given_the_wrong_cosine_or_direction_say_which() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for (bug, words) in [
        ("refract-cos-sign", "with cos θi = d·n = -"),
        (
            "refract-unnormalised-d",
            "given the incoming direction as your log has it, of length",
        ),
        ("refract-eta-not-squared", "where η² belongs"),
        ("refract-no-sqrt", "without its square root"),
    ] {
        let Some(r) = (Run {
            bug,
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        })
        .check() else {
            return;
        };
        let d = r
            .causes
            .iter()
            .find(|c| c.code == Code::RefractionSnell)
            .and_then(|c| c.examples.first())
            .map(|e| e.detail.clone())
            .unwrap_or_default();
        assert!(d.contains(words), "{bug}: {}", text(&r));
    }
    let Some(r) = assert_one_headline(
        Run {
            bug: "refract-cos-sign",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::RefractionSnell,
    ) else {
        return;
    };
    first_example_says(&r, &["the cosine's sign is not turned"]);
}

/// rayscope's own trace, logged in the documented format (f32 numbers, the facing-normal
/// convention, per-sample ids): the judge's tolerances must accept it everywhere.
#[test]
fn rayscope_own_log_gets_no_verdict() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for (scene, w, aa) in [
        (course.scene("sample_scene_1.txt"), 32, 1),
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
        let n = rayscope_check::selflog::write_log(&scene, &settings, 0..w, &mut f).expect("write");
        drop(f);
        let judge = Judge::new(&scene, &settings);
        let ctx = LogContext::new(&scene, w, w, judge.samples_per_pixel(), aa);
        let mut src = open(&log, ctx, false, &[]).expect("open");
        let r = check(&judge, src.as_mut(), CheckOptions::default(), &|_, _| {}).expect("check");
        assert_eq!(r.rays, n);
        assert_eq!(r.disagree, 0, "{}", text(&r));
        assert_eq!(r.camera_rays, u64::from(w * w * aa * aa));
    }
}

#[test]
fn camera_mistakes_are_named_by_their_cause() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = || course.scene("sample_scene_1.txt");
    for (bug, aa, code) in [
        ("pixel-corner", 1, Code::CameraPixelCorner),
        ("plane-distance", 1, Code::CameraPlaneDistance),
        // Three times as wide: at -x 2 a few samples near the image's centre land on the centre
        // of another cell of their pixel.
        ("fov-not-halved", 2, Code::CameraPlaneDistance),
        ("pixel-transposed", 1, Code::CameraTransposed),
        ("pixel-transposed", 2, Code::CameraTransposed),
    ] {
        assert_named(
            Run {
                bug,
                aa,
                ..Run::new(scene(), 40, 40)
            },
            code,
            &[],
        );
    }
}

#[test]
fn glass_mistakes_on_the_way_out_and_in_are_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for scene in [course.scene("sample_scene_2.txt"), root().join("scenes/whitted.txt")] {
        assert_named(
            Run {
                bug: "indices-not-swapped",
                ..Run::new(scene.clone(), 40, 40)
            },
            Code::RefractionIndicesNotSwapped,
            &[],
        );
        assert_named(
            Run {
                bug: "tir-entering",
                ..Run::new(scene, 40, 40)
            },
            Code::RefractionTirInvented,
            &[],
        );
    }
}

#[test]
fn a_shadow_ray_naming_the_shaded_surface_as_its_blocker_is_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_named(
        Run {
            bug: "blocker-name",
            ..Run::new(course.scene("sample_scene_1.txt"), 40, 40)
        },
        Code::ShadowWrongBlocker,
        &[],
    );
    // Scene 2 has shadow rays that graze a blocker: named right they are ties, named wrong they
    // are blocked by nothing in rayscope's trace.
    assert_named(
        Run {
            bug: "blocker-name",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::ShadowWrongBlocker,
        &[Code::ShadowPhantomBlocker],
    );
}

#[test]
fn refracted_rays_leaving_a_mirror_are_named() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    assert_named(
        Run {
            bug: "mirror-as-glass",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::SecondaryWrongMaterial,
        &[],
    );
}

/// A mistake that must be the report's one headline, whatever verdicts follow from it; the
/// report, where the tracer ran.
fn assert_one_headline(run: Run<'_>, code: Code) -> Option<Report> {
    let r = run.check()?;
    let t = text(&r);
    assert!(
        t.lines().next().is_some_and(|l| l.contains(code.as_str())),
        "bug '{}': the first line does not name {}:\n{t}",
        run.bug,
        code.as_str()
    );
    assert_eq!(r.causes.len(), 1, "bug '{}' has more than one headline:\n{t}", run.bug);
    assert!(r.causes[0].code == code || r.causes[0].or == Some(code), "{t}");
    Some(r)
}

/// Asserts that the report's first line says `words`.
fn first_line_says(r: &Report, words: &str) {
    let t = text(r);
    assert!(t.lines().next().is_some_and(|l| l.contains(words)), "{t}");
}

/// Asserts that the first example of the report's first cause says each of `words`.
fn first_example_says(r: &Report, words: &[&str]) {
    let detail = &r.causes[0].examples[0].detail;
    assert!(words.iter().all(|w| detail.contains(w)), "{}", text(r));
}

/// Asserts that every example of the report's first cause says each of `words`.
fn every_example_says(r: &Report, words: &[&str]) {
    for ex in &r.causes[0].examples {
        assert!(words.iter().all(|w| ex.detail.contains(w)), "{}", text(r));
    }
}

/// Mistakes whose consequences outnumber them: each is the report's one headline, and what it
/// causes below it is listed under it, not as mistakes of its own.
#[test]
fn a_mistake_heads_the_report_above_its_consequences() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // With the catalogue's name for the mistake where the tracer makes it as the catalogue
    // describes it (its eta-inverted inverts η leaving the glass too).
    for (bug, code, catalogued) in [
        ("reflect-no-2", Code::ReflectionNotMirror, Some("reflect-no-2")),
        (
            "sphere-normal-unnormalised",
            Code::HitNormalNotUnit,
            Some("sphere-normal-unnormalised"),
        ),
        ("eta-inverted", Code::RefractionIndicesNotSwapped, None),
        (
            "near-root-inside",
            Code::HitBehindOrigin,
            Some("sphere-near-root-behind"),
        ),
    ] {
        let r = assert_one_headline(
            Run {
                bug,
                ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
            },
            code,
        );
        if let (Some(r), Some(name)) = (r, catalogued) {
            assert!(
                r.causes[0].catalogue.contains(&name),
                "{bug}:
{}",
                text(&r)
            );
        }
    }
}

/// [`assert_one_headline`] for `bug` on course scene 2 at 40×40; `None` without the course's
/// files or Python.
fn one_headline_on_scene_2(bug: &str, code: Code) -> Option<Report> {
    let course = rayscope_testkit::course()?;
    assert_one_headline(
        Run {
            bug,
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        code,
    )
}

/// A mistake no catalogue has (the shadow ray aimed along the light's position, as if from the
/// camera, with N·L along it too): one headline, the shadow rays that miss their lights, and the
/// colours that follow from them listed under it, not as a diffuse-shading mistake of their own
/// with guesses at fall-off or ambient light.
#[test]
fn colours_made_with_wrong_shadow_rays_follow_from_those_rays() {
    let Some(r) = one_headline_on_scene_2("light-as-direction", Code::ShadowNotAtLight) else {
        return;
    };
    let t = text(&r);
    let follows = r.causes[0]
        .consequences
        .iter()
        .find(|c| c.code == Code::ShadingShadowDirection);
    assert!(follows.is_some_and(|c| c.count > 100), "{t}");
    assert!(r.verdicts.iter().all(|v| v.code != Code::ShadingDiffuse), "{t}");
    assert!(!t.contains("light-falloff") && !t.contains("ambient-term"), "{t}");
    // Each example says what the direction is instead: the light's own position.
    assert!(
        r.causes[0]
            .examples
            .iter()
            .all(|e| e.detail.contains("light − point without the point")),
        "{t}"
    );
}

/// Camera rays left unnormalised with a sphere test that takes a = d·d = 1 (no catalogue has
/// it): one headline on the spheres' intersection, and each example on a sphere says its t is
/// that test's root (or miss) for a direction of that length.
#[test]
fn a_sphere_test_that_takes_unit_directions_is_told_the_directions_length() {
    let Some(r) = one_headline_on_scene_2("camera-unnormalised", Code::HitSurfaceWrong) else {
        return;
    };
    let t = text(&r);
    assert!(t.lines().next().is_some_and(|l| l.contains("spheres")), "{t}");
    assert!(!r.causes[0].examples.is_empty(), "{t}");
    for e in &r.causes[0].examples {
        assert!(e.detail.contains("takes the direction as unit length"), "{t}");
    }
}

#[test]
fn a_too_strict_triangle_test_is_named_as_such_not_as_one_sided() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for scene in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        assert_named(
            Run {
                bug: "strict-edges",
                ..Run::new(course.scene(scene), 40, 40)
            },
            Code::HitTriangleEdge,
            &[],
        );
    }
}

/// A mistake no catalogue has (a sphere test that compares with r, not r²): the report's one
/// headline says the spheres' intersection is wrong and names them, offers no catalogued mistake
/// that cannot show in the scene, and its examples are rays that meet a sphere, with the
/// tracer's numbers beside rayscope's.
#[test]
fn an_uncatalogued_mistake_gets_a_truthful_headline_with_the_numbers() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "radius-not-squared",
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    assert_eq!(r.causes.len(), 1, "{t}");
    let first = &r.causes[0];
    assert_eq!(first.code, Code::HitSurfaceWrong, "{t}");
    let head = t.lines().next().unwrap_or_default();
    assert!(
        head.contains("spheres") && head.contains("'MirrorSphere'") && head.contains("'GlassSphere'"),
        "{t}"
    );
    // The scene has no OBJ model: the catalogue's OBJ mistakes, which show as the same verdict,
    // are not offered.
    assert!(first.catalogue.iter().all(|n| !n.starts_with("obj-")), "{t}");
    assert!(!t.contains("obj-no-z-flip"), "{t}");
    for ex in &first.examples {
        let entity = ex
            .values
            .iter()
            .find(|v| v.what.starts_with("entity") || v.what.starts_with("blocker"));
        let entity = entity.expect("entity values");
        assert!(
            [&entity.yours, &entity.rayscope]
                .iter()
                .any(|v| v.as_str().is_some_and(|s| s.ends_with("Sphere"))),
            "an example is not about a sphere:\n{t}"
        );
    }
}

/// Rules that pass over the nearest hit are named by what every passed-over hit has in common,
/// log-wide: a minimum distance (on a pane of glass 0.03 thick, where 0.05 loses the back face),
/// the scene's order, the distance from the world's origin. A tracer that keeps the farthest
/// hit, which no catalogue has, is told only what is true of each ray.
#[test]
fn rules_that_pass_over_the_nearest_hit_are_named_by_what_they_share() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let pane = root().join("crates/rayscope_core/tests/scenes/thin_pane.txt");
    assert_one_headline(
        Run {
            bug: "min-distance",
            ..Run::new(pane, 40, 30)
        },
        Code::HitNearSkipped,
    );
    assert_one_headline(
        Run {
            bug: "first-in-list",
            ..Run::new(course.scene("sample_scene_1.txt"), 40, 30)
        },
        Code::HitSceneOrder,
    );
    // The nearest t never updated: the last entity hit in the file's order is kept (scene 2
    // lists its spheres before the box around them; on scene 1 the last is the nearest).
    if let Some(r) = assert_one_headline(
        Run {
            bug: "best-t-stale",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::HitSceneOrder,
    ) {
        first_example_says(&r, &["an entity listed later in the scene file"]);
    }
    assert_one_headline(
        Run {
            bug: "origin-distance",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::HitOriginDistance,
    );
    let Some(r) = Run {
        bug: "farthest-hit",
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    }
    .check() else {
        return;
    };
    let t = text(&r);
    for wrong in [Code::HitNearSkipped, Code::HitSceneOrder, Code::HitOriginDistance] {
        assert!(r.causes.iter().all(|c| !c.codes().contains(&wrong)), "{t}");
    }
    assert!(
        t.lines().next().is_some_and(|l| l.contains(Code::HitFarther.as_str())),
        "{t}"
    );
}

/// Glass whose reflected ray starts along the incident ray (inside the glass), or whose
/// refracted ray starts on the incoming side, is named as the offset to the wrong side it is,
/// grazing rays included; the catalogue's mistakes listed beside it are those of that ray.
#[test]
fn a_glass_ray_started_on_the_wrong_side_is_an_offset_to_the_wrong_side() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for (bug, listed) in [
        (
            "reflect-along-ray",
            &["glass-reflection-along-ray", "glass-reflection-outward"][..],
        ),
        ("refraction-origin-outside", &["refraction-offset-outside"][..]),
    ] {
        let r = assert_one_headline(
            Run {
                bug,
                ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
            },
            Code::SecondaryOffsetWrongSide,
        );
        if let Some(r) = r {
            assert_eq!(r.causes[0].catalogue, listed, "{bug}:\n{}", text(&r));
        }
    }
}

/// The student's picture beside its log (`check --image`): written by the course's rule it gets
/// no verdict; each usual mistake in turning colours into bytes is named, and a picture from
/// other colours (no catalogue has it) is said not to be made from the logged ones.
#[test]
fn the_picture_is_judged_against_the_logged_colours() {
    let Some(py) = python() else {
        return;
    };
    let scene = root().join("crates/rayscope_check/tests/scenes/bright.txt");
    let file = rayscope_scene::load(&scene).expect("scene");
    let sc = Scene::from_file(&file);
    let settings = RenderSettings {
        width: 40,
        height: 30,
        aa: 2,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let judge = Judge::new(&sc, &settings);
    for (bug, want) in [
        ("none", None),
        ("gamma-out", Some(Code::ImageGamma)),
        ("rounded-out", Some(Code::ImageRounded)),
        ("unclamped-out", Some(Code::ImageUnclamped)),
        ("byte-average-out", Some(Code::ImageByteAverage)),
        ("flipped-out", Some(Code::ImageFlipped)),
        ("bgr-out", Some(Code::ImageChannels)),
        ("stale-image", Some(Code::ImageDiffers)),
        ("accumulator-out", Some(Code::ImageAccumulated)),
        ("summed-out", Some(Code::ImageSummed)),
        ("aa-divided-by-n", Some(Code::ImageScaled)),
        ("mirrored-out", Some(Code::ImageMirrored)),
        ("rotated-out", Some(Code::ImageRotated)),
        ("flipped-gamma-out", Some(Code::ImageFlipped)),
        ("stray-pixels-out", Some(Code::ImageDiffers)),
        ("last-sample-out", Some(Code::ImageOneSample)),
        ("row-accumulator-out", Some(Code::ImageAccumulated)),
        ("sqrt-out", Some(Code::ImageGamma)),
        ("times-256-out", Some(Code::ImageTimes256)),
    ] {
        let dir = tempfile::tempdir().expect("temp dir");
        let (log, ppm) = (dir.path().join("rays.jsonl"), dir.path().join("out.ppm"));
        let out = Command::new(py)
            .arg(root().join("crates/rayscope_check/tests/student/tracer.py"))
            .arg("-f")
            .arg(&scene)
            .args(["-w", "40", "-h", "30", "-x", "2", "--bug", bug, "--log"])
            .arg(&log)
            .arg("--image")
            .arg(&ppm)
            .output()
            .expect("run the student tracer");
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        // The tracer writes plain PPM (P3): a header of three numbers, then the bytes.
        let text = std::fs::read_to_string(&ppm).expect("picture");
        let bytes: Vec<u8> = text
            .split_whitespace()
            .skip(4)
            .map(|t| t.parse().expect("a byte"))
            .collect();
        assert_eq!(bytes.len(), 40 * 30 * 3);
        let ctx = LogContext::new(&sc, 40, 30, judge.samples_per_pixel(), 2);
        let mut src = open(&log, ctx, false, &[]).expect("open");
        let mut sums = rayscope_check::image::PixelSums::new(40, 30, judge.samples_per_pixel());
        sums.read(src.as_mut(), &|r| judge.kind_of(r) == rayscope_check::log::Kind::Camera)
            .expect("read");
        let j = rayscope_check::image::judge(&sums, &bytes, 3);
        assert_eq!(j.compared, 1200, "{bug}: {}", j.detail);
        assert_eq!(j.verdict, want, "{bug}: {}", j.detail);
        if want == Some(Code::ImageDiffers) {
            assert!(!j.examples.is_empty(), "{bug}: no example");
        }
        if bug == "flipped-gamma-out" {
            assert!(
                j.detail.contains("two mistakes") && j.detail.contains("image.gamma"),
                "{bug}: {}",
                j.detail
            );
        }
        if bug == "sqrt-out" {
            assert!(
                j.detail.contains("raised to the power 1/2 (a square root)") && j.exponent == Some(0.5),
                "{bug}: {}",
                j.detail
            );
        }
        if bug == "aa-divided-by-n" {
            assert!(j.detail.contains("divided by 2, not by 4"), "{bug}: {}", j.detail);
        }
        if bug == "row-accumulator-out" {
            assert!(
                j.detail.contains("set to black at the start of each row"),
                "{bug}: {}",
                j.detail
            );
        }
        if bug == "last-sample-out" {
            assert!(
                j.detail.contains("its last sample's colour alone"),
                "{bug}: {}",
                j.detail
            );
        }
        if bug == "stray-pixels-out" {
            // One pixel in 97 holds its neighbour's colour (a few the same colour anyway): those
            // few are named, not the rest.
            let n: u32 = j.detail.split(' ').next().and_then(|w| w.parse().ok()).unwrap_or(0);
            assert!(
                (1..=13).contains(&n) && j.detail.contains("pixels are not your logged colours"),
                "{bug}: {}",
                j.detail
            );
        }
    }
}

/// A shadow test whose plane intersection accepts t < 0 (the tester's "shadow rays that hit a
/// plane behind their origin"): never excused as a tie, named as a blocker that is not in the
/// way, and each example says the plane lies behind the ray's origin.
#[test]
fn a_blocker_behind_the_shadow_rays_origin_is_no_tie() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "plane-behind",
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    assert_eq!(r.causes.len(), 1, "{t}");
    assert_eq!(r.causes[0].code, Code::ShadowPhantomBlocker, "{t}");
    for ex in &r.causes[0].examples {
        assert!(ex.detail.contains("behind its origin"), "{t}");
    }
    assert!(r.ties < 50, "rays excused as ties:\n{t}");
}

/// A shadow test given an unnormalised direction (no catalogue has it): only shadow rays go
/// wrong, so the first line is about shadow rays, never that the spheres' intersection is wrong.
#[test]
fn a_mistake_in_the_shadow_test_alone_is_not_blamed_on_the_surfaces() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = (Run {
        bug: "shadow-unnormalised",
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    })
    .check() else {
        return;
    };
    let t = text(&r);
    assert!(!r.causes.is_empty(), "{t}");
    assert!(r.causes.iter().all(|c| c.code.as_str().starts_with("shadow.")), "{t}");
}

/// Shadow-test mistakes no catalogue has, on blockers logged with names and as `true`: a blocker
/// never reset between lights is named as carried over from the light before; a test that stops
/// at t = 1 misses blockers from either side, one headline, with no one-sided triangles blamed;
/// an inside test that lets points past a triangle's third edge through is that triangle's
/// intersection, each unnamed hit and blocker saying how far outside the triangle it lies.
#[test]
fn shadow_and_triangle_mistakes_no_catalogue_has_get_one_true_headline() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene1 = || Run::new(course.scene("sample_scene_1.txt"), 40, 40);
    let scene2 = || Run::new(course.scene("sample_scene_2.txt"), 40, 40);
    for names in [true, false] {
        assert_one_headline(
            Run {
                bug: "blocked-not-reset",
                names,
                ..scene2()
            },
            Code::ShadowBlockedCarriedOver,
        );
        let Some(r) = assert_one_headline(
            Run {
                bug: "parallelogram",
                names,
                ..scene1()
            },
            Code::HitSurfaceWrong,
        ) else {
            return;
        };
        let t = text(&r);
        assert!(r.causes[0].summary.contains("'Triangle'"), "{t}");
        for ex in &r.causes[0].examples {
            assert!(ex.detail.contains("outside the triangle by"), "{t}");
        }
    }
    let Some(r) = assert_one_headline(
        Run {
            bug: "shadow-t-below-1",
            ..scene1()
        },
        Code::ShadowMissedBlocker,
    ) else {
        return;
    };
    assert!(
        r.verdicts.iter().all(|v| v.code == Code::ShadowMissedBlocker),
        "{}",
        text(&r)
    );
    // Blocked at t < |light − point|², blockers logged as `true`: a ray blocked past its light
    // after a sibling blocked in earnest reads like a flag not reset, but the rays blocked with
    // no blocked sibling show the test itself counts what lies beyond.
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = assert_one_headline(
        Run {
            bug: "shadow-t-dist-squared",
            names: false,
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::ShadowPhantomBlocker,
    ) else {
        return;
    };
    first_example_says(&r, &["lies beyond the light"]);
}

/// The half angle in degrees given to a tangent that takes radians (no catalogue has it): tan(30)
/// is −6.41, an image plane of negative size; the camera rays fit it, and the report says so with
/// the number and how to convert, not that the rays point "elsewhere".
#[test]
fn a_field_of_view_in_degrees_given_to_tan_is_said_with_its_numbers() {
    for scene in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        let Some(course) = rayscope_testkit::course() else {
            return;
        };
        let Some(r) = assert_one_headline(
            Run {
                bug: "fov-degrees",
                ..Run::new(course.scene(scene), 40, 40)
            },
            Code::CameraPlaneDistance,
        ) else {
            return;
        };
        every_example_says(&r, &["half-width is -6.4053", "tan(30) with 30 read as radians"]);
    }
}

#[test]
fn samples_cast_through_one_point_of_their_pixel_are_one_headline_and_other_layouts_say_where() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = || course.scene("sample_scene_1.txt");
    // The sub-pixel offset never added: every sample through the pixel's centre, or its corner.
    // Some of those samples are where a cell corner is, or where rayscope puts them; the log as a
    // whole still has one mistake.
    for (bug, said) in [
        ("aa-same-ray", "through the centre of its pixel"),
        ("aa-same-corner", "through the top-left corner of its pixel"),
    ] {
        for aa in [2, 3] {
            let Some(r) = assert_one_headline(
                Run {
                    bug,
                    aa,
                    ..Run::new(scene(), 40, 40)
                },
                Code::CameraOnePoint,
            ) else {
                return;
            };
            assert!(
                r.causes[0].examples.iter().any(|e| e.detail.contains(said)),
                "{}",
                text(&r)
            );
        }
    }
    // A layout no rule names, samples at (i + 1) / (N + 1): where the rays cross their pixel,
    // beside where rayscope puts them, and no name.
    let Some(r) = assert_one_headline(
        Run {
            bug: "aa-evenly-spaced",
            aa: 2,
            ..Run::new(scene(), 40, 40)
        },
        Code::CameraSubpixelGrid,
    ) else {
        return;
    };
    first_example_says(
        &r,
        &[
            "crosses its pixel at (0.333, 0.333)",
            "puts sample 0 at (0.250, 0.250)",
            "a sub-pixel layout rayscope does not know",
        ],
    );
    // Half a pixel added on top of each cell's corner: every sample a quarter pixel off, which
    // ray by ray fits a pixel centre, a neighbouring pixel or a grid over the corners.
    for scene in [scene(), course.scene("sample_scene_2.txt")] {
        let Some(r) = assert_one_headline(
            Run {
                bug: "aa-half-twice",
                aa: 2,
                ..Run::new(scene, 40, 40)
            },
            Code::CameraShifted,
        ) else {
            return;
        };
        first_line_says(&r, "shifted 0.250 of a pixel to the right and 0.250 of a pixel down");
    }
    // Every sample through the centre of the pixel's first cell: each ray is where another
    // sample of rayscope's goes, but the cells are not the samples in another order.
    for aa in [2, 3] {
        let Some(r) = assert_one_headline(
            Run {
                bug: "aa-one-cell",
                aa,
                ..Run::new(scene(), 40, 40)
            },
            Code::CameraSubpixelGrid,
        ) else {
            return;
        };
        first_line_says(&r, "several samples of a pixel go through the same cell");
        first_example_says(
            &r,
            &[
                "the centre of cell (0, 0)",
                "where rayscope puts sample 0; rayscope puts sample 1 at",
            ],
        );
    }
}

#[test]
fn samples_numbered_in_another_order_are_no_mistake() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // Column by column, or from the last cell: the same rays as rayscope's, the same picture.
    for (bug, aa, said) in [
        (
            "aa-column-major",
            2,
            [
                "pixel (0, 0) sample 2, camera ray ",
                "0.9150° off; it goes through (0.750, 0.250) of the way across and down its pixel: the centre of cell (1, 0) of the 2×2 grid, where rayscope puts sample 1; rayscope puts sample 2 at (0.250, 0.750)",
            ],
        ),
        (
            "aa-reversed",
            3,
            [
                "pixel (0, 0) sample 8, camera ray ",
                "it goes through (0.167, 0.167) of the way across and down its pixel: the centre of cell (0, 0) of the 3×3 grid, where rayscope puts sample 0; rayscope puts sample 8 at (0.833, 0.833)",
            ],
        ),
    ] {
        for scene in ["sample_scene_1.txt", "sample_scene_2.txt"] {
            let Some(r) = (Run {
                bug,
                aa,
                ..Run::new(course.scene(scene), 40, 40)
            })
            .check() else {
                return;
            };
            let t = text(&r);
            assert!(r.passed() && r.causes.is_empty(), "{bug} -x {aa} on {scene}: {t}");
            let n = r.renumbered.as_ref().map_or(0, |g| g.count);
            assert!(n > 0, "{t}");
            assert!(t.contains("numbered in another order, which changes nothing in the picture"), "{t}");
            for words in said {
                assert!(t.contains(words), "{bug}: {words:?} in {t}");
            }
        }
    }
    // Only some of each pixel's samples logged: a numbering cannot be told from samples sharing
    // a cell, and the report says so, counting neither against the tracer.
    for bug in ["aa-column-major", "aa-one-cell"] {
        let Some(r) = (Run {
            bug,
            aa: 2,
            log_samples: Some("1"),
            ..Run::new(course.scene("sample_scene_1.txt"), 40, 40)
        })
        .check() else {
            return;
        };
        let t = text(&r);
        assert!(r.passed() && r.renumbered.is_some(), "{bug}: {t}");
        assert!(
            t.contains("rayscope cannot tell whether that is only another numbering (no mistake) or several samples through the same cell (a mistake)"),
            "{bug}: {t}"
        );
    }
}

#[test]
fn a_sphere_quadratic_without_its_4_and_a_plane_test_on_n_dot_d_abs_name_their_surfaces() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // b = 2 oc·d with a discriminant of b² − c: hits where there are none and hits short of the
    // sphere, on the spheres alone; no rule about which hit is kept.
    for (scene, named) in [
        ("sample_scene_1.txt", "sphere 'Sphere'"),
        ("sample_scene_2.txt", "spheres ('MirrorSphere', 'GlassSphere')"),
    ] {
        let Some(r) = assert_one_headline(
            Run {
                bug: "sphere-disc-no-4",
                ..Run::new(course.scene(scene), 40, 40)
            },
            Code::HitSurfaceWrong,
        ) else {
            return;
        };
        first_line_says(&r, &format!("intersection with the {named} is wrong"));
    }
    // Dividing by |n·d| makes t negative wherever a ray meets a plane's front: the planes are
    // never hit, and the headline says so.
    for (scene, named) in [
        (
            "sample_scene_1.txt",
            "plane 'Plane', and your tracer never reports a hit on it",
        ),
        (
            "sample_scene_2.txt",
            "planes ('Floor', 'Roof'), and your tracer never reports a hit on any of them",
        ),
    ] {
        let Some(r) = assert_one_headline(
            Run {
                bug: "plane-abs-den",
                ..Run::new(course.scene(scene), 40, 40)
            },
            Code::HitMissed,
        ) else {
            return;
        };
        first_line_says(&r, &format!("every ray it missed meets the {named}"));
    }
}

#[test]
fn a_shadow_ray_cast_towards_another_light_than_its_own_is_said_to_be() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(r) = assert_one_headline(
        Run {
            bug: "shadow-first-light",
            ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
        },
        Code::ShadowOtherLight,
    ) else {
        return;
    };
    first_example_says(&r, &["logged for light 'Light2' but aimed at light 'Light1'"]);
}

#[test]
fn a_sphere_shaded_with_a_normal_as_long_as_its_radius_is_said_to_be() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // P − C used for N·L on the sphere only (the normal logged is the unit one): every sphere
    // hit is the course's sum times the radius, 0.5, and the details say whose length it is.
    let Some(r) = assert_one_headline(
        Run {
            bug: "shade-normal-radius",
            ..Run::new(course.scene("sample_scene_1.txt"), 40, 40)
        },
        Code::ShadingDiffuse,
    ) else {
        return;
    };
    every_example_says(&r, &["× 0.5000", "the sphere's radius, 0.5"]);
}

/// A camera ray logged alone with its colour, none of the shadow rays it comes from: its colour
/// is judged against the course's sum over the lights the oracle sees, and a colour that is not
/// that sum is left unjudged (nothing says which lights the tracer saw), never called a missing
/// ray.
#[test]
fn colours_logged_without_the_rays_they_come_from_are_not_called_missing() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let Some(py) = python() else {
        return;
    };
    let scene = course.scene("sample_scene_1.txt");
    let dir = tempfile::tempdir().expect("temp dir");
    let (all, first) = (dir.path().join("all.jsonl"), dir.path().join("first.jsonl"));
    let out = Command::new(py)
        .arg(root().join("crates/rayscope_check/tests/student/tracer.py"))
        .arg("-f")
        .arg(&scene)
        .args(["-w", "40", "-h", "40", "-x", "1", "--log"])
        .arg(&all)
        .output()
        .expect("run the student tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The first camera ray that meets a surface, alone, with its colour, and none of the
    // shadow rays its colour comes from.
    let text_all = std::fs::read_to_string(&all).expect("log");
    let lines: Vec<&str> = text_all.lines().collect();
    let line = lines
        .windows(2)
        .find(|w| w[0].contains("\"camera\"") && w[1].contains("\"shadow\""))
        .map(|w| w[0])
        .expect("a camera ray with shadow rays");
    assert!(line.contains("\"color\""), "{line}");
    let settings = RenderSettings {
        width: 40,
        height: 40,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    std::fs::write(&first, format!("{line}\n")).expect("write");
    let r = check_log(&scene, settings, &first, 3);
    assert_eq!((r.disagree, r.shaded_judged), (0, 1), "{}", text(&r));
    first_line_says(&r, "no mistake found: every ray and every logged colour agrees");
    // The same ray with half its colour.
    let mut ray: serde_json::Value = serde_json::from_str(line).expect("a JSON line");
    let c = ray["color"]
        .as_array()
        .expect("colour")
        .iter()
        .map(|v| v.as_f64().expect("number") * 0.5);
    ray["color"] = c.collect::<Vec<f64>>().into();
    std::fs::write(&first, format!("{ray}\n")).expect("write");
    let r = check_log(&scene, settings, &first, 3);
    assert_eq!(r.disagree, 0, "{}", text(&r));
    first_line_says(&r, "colours were logged, but no surface's colour could be judged");
}

/// Rays never cast at all: mirrors and glass that bring back black (the student has not written
/// them yet), glass without its refracted ray; and rays into the entity they leave that pass its
/// far side by, by two mistakes no catalogue has; and a light's colour taken twice. Each is one
/// headline that says what is missing or wrong, not "no mistake" nor a closest-hit loop.
#[test]
fn rays_never_cast_and_rays_that_pass_their_own_entity_by_are_named() {
    for (bug, code, words) in [
        (
            "mirror-glass-black",
            Code::MissingSecondary,
            &["no ray leaves it and it brings back black"][..],
        ),
        (
            "no-refraction-ray",
            Code::MissingRefraction,
            &["no refracted ray, its colour weighted by"],
        ),
        (
            "sphere-no-far-root",
            Code::HitMissedFromInside,
            &["goes into 'GlassSphere'"],
        ),
        (
            "skip-own-entity",
            Code::HitMissedFromInside,
            &["goes into 'GlassSphere'"],
        ),
        ("light-twice", Code::ShadingDiffuse, &["multiplied in twice"]),
    ] {
        let Some(r) = one_headline_on_scene_2(bug, code) else {
            return;
        };
        first_example_says(&r, words);
    }
}

/// A tracer that logs its camera rays alone, with their colours: where they are the colours the
/// course's rules give, every surface is judged and nothing is a mistake; mirrors and glass that
/// bring back black are, though no ray in the log shows what they should have cast.
#[test]
fn a_log_of_camera_rays_alone_is_judged_by_their_colours() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let run = |bug| Run {
        aa: 2,
        bug,
        options: &["--log-kinds", "camera"],
        ..Run::new(course.scene("sample_scene_2.txt"), 40, 40)
    };
    let Some(r) = run("none").check() else {
        return;
    };
    assert_eq!(r.disagree, 0, "{}", text(&r));
    assert!(r.shaded_unjudged * 20 < r.shaded_judged, "{}", text(&r));
    first_line_says(&r, "no mistake found: every ray and every logged colour agrees");
    let r = assert_one_headline(run("mirror-glass-black"), Code::MissingSecondary);
    assert!(r.is_some_and(|r| r.disagree > 500));
}
