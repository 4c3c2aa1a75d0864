//! The catalogue of the course's mistakes against `check`: rayscope traces each course scene as a
//! tracer making one catalogued mistake would (`--mistake`), writes that tracer's ray log, and
//! `check` must name the mistake on the report's first line with one of the verdicts the
//! catalogue says it shows as — or, where the catalogue says a log cannot show it, find nothing.

use rayscope_check::image::PixelSums;
use rayscope_check::log::open;
use rayscope_check::selflog::write_log;
use rayscope_check::{check, CheckOptions, Judge, LogContext, Report};
use rayscope_core::{Mistake, Mistakes, RenderSettings, Scene, Stage};

/// The scene, image size and rows where a mistake shows.
fn case(m: Mistake) -> (&'static str, u32, u32, std::ops::Range<u32>) {
    let info = m.info();
    match m {
        // A pane of glass 0.03 thick: the course's scenes have nothing that near another surface.
        Mistake::MinHitDistance => return ("thin_pane.txt", 40, 40, 0..40),
        Mistake::NearestByOriginDistance | Mistake::SphereNearRootBehind => {
            return ("sample_scene_2.txt", 40, 40, 0..40);
        }
        // Only interpolated normals turn from a light the face sees: a coarse smooth ball.
        Mistake::NdotLUnclamped => return ("smooth_ball.txt", 64, 48, 0..48),
        Mistake::FirstHitInSceneOrder | Mistake::CamAngleRadians | Mistake::AccumulatorNotReset => {
            return ("sample_scene_1.txt", 40, 40, 0..40);
        }
        _ => {}
    }
    match info.rubric {
        r if r.starts_with("Stage 1") => ("sample_scene_1.txt", 400, 300, 140..143),
        _ if matches!(m, Mistake::NoTir) => ("glass_cube.txt", 40, 30, 0..30),
        r if r.contains("refraction") || r.contains("Fresnel") => ("sample_scene_2.txt", 40, 40, 0..40),
        r if r.contains("OBJ") => ("sample_scene_obj.txt", 32, 32, 0..32),
        _ if matches!(
            m,
            Mistake::RecursionLimit3 | Mistake::ShadowPastLight | Mistake::FirstLightOnly
        ) =>
        {
            ("sample_scene_2.txt", 40, 40, 0..40)
        }
        _ => ("sample_scene_1.txt", 40, 40, 0..40),
    }
}

fn check_mistake(course: &rayscope_testkit::Course, m: Mistake) -> Report {
    let (file, w, h, rows) = case(m);
    let path = match file {
        "glass_cube.txt" => std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/glass_cube.txt"),
        "thin_pane.txt" | "smooth_ball.txt" => rayscope_testkit::workspace()
            .join("crates/rayscope_core/tests/scenes")
            .join(file),
        _ => course.scene(file),
    };
    let parsed = rayscope_scene::load(&path).expect("scene");
    let scene = Scene::from_file(&parsed);
    // The OBJ mistakes are in how the student's program builds the model.
    let mut mistaken_file = parsed.clone();
    Mistakes::NONE.with(m).apply_to_file(&mut mistaken_file);
    let traced = Scene::from_owned_file(mistaken_file);
    let mut correct = RenderSettings {
        width: w,
        height: h,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    if m == Mistake::CamAngleRadians {
        // Turned a little about the vertical: by half a degree, or half a radian in the tracer.
        correct.camera.axis = glam::Vec3::Y;
        correct.camera.angle_deg = 0.5;
    }
    let mistaken = RenderSettings {
        mistakes: Mistakes::NONE.with(m),
        ..correct
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("rays.jsonl");
    let mut f = std::fs::File::create(&log).expect("log");
    write_log(&traced, &mistaken, rows, &mut f).expect("write");
    drop(f);
    let judge = Judge::new(&scene, &correct);
    let ctx = LogContext::new(&scene, w, h, judge.samples_per_pixel(), 1);
    let mut src = open(&log, ctx.clone(), false, &[]).expect("open");
    let mut report = check(&judge, src.as_mut(), CheckOptions::default(), &|_, _| {}).expect("check");
    // The tracer's picture: its film as the mistaken output writes it, in the course's bytes.
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let film = rayscope_core::render(&traced, &mistaken, &|_, _| {}, &cancel)
        .expect("render")
        .film;
    let bytes: Vec<u8> = film
        .pixels
        .iter()
        .flat_map(|p| p.to_array().map(|v| (v.clamp(0.0, 1.0) * 255.0) as u8))
        .collect();
    let mut sums = PixelSums::new(w, h, judge.samples_per_pixel());
    let mut src = open(&log, ctx, false, &[]).expect("open");
    sums.read(src.as_mut(), &|r| judge.kind_of(r) == rayscope_check::log::Kind::Camera)
        .expect("read");
    report.image = Some(rayscope_check::image::judge(&sums, &bytes, 3));
    report
}

#[test]
fn every_catalogued_mistake_heads_checks_report_with_a_verdict_the_catalogue_names() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let mut wrong = Vec::new();
    for m in Mistake::ALL {
        let info = m.info();
        let r = check_mistake(&course, m);
        let text = r.to_text(&|_| None);
        if let Some(code) = r.image.as_ref().and_then(|i| i.verdict) {
            if !info.check.contains(&code.as_str()) || !r.causes.is_empty() {
                wrong.push(format!(
                    "{}: picture judged {}, the catalogue says {:?}\n{text}",
                    info.name,
                    code.as_str(),
                    info.check
                ));
            }
            if !text.lines().next().is_some_and(|l| l.contains(code.as_str())) {
                wrong.push(format!(
                    "{}: the first line does not name {}\n{text}",
                    info.name,
                    code.as_str()
                ));
            }
            continue;
        }
        let Some(first) = r.causes.first() else {
            wrong.push(format!(
                "{}: no verdict, the catalogue says {:?}\n{text}",
                info.name, info.check
            ));
            continue;
        };
        let named = first.codes().iter().any(|c| info.check.contains(&c.as_str()));
        if !named {
            wrong.push(format!(
                "{}: headed by {}, the catalogue says {:?}\n{text}",
                info.name,
                first.name(),
                info.check
            ));
        }
        if r.causes.len() > 1 {
            wrong.push(format!("{}: {} headlines\n{text}", info.name, r.causes.len()));
        }
        if !first.catalogue.contains(&info.name) {
            wrong.push(format!("{}: the report does not point to it\n{text}", info.name));
        }
    }
    assert!(wrong.is_empty(), "{}", wrong.join("\n\n"));
}

/// The catalogue's scenes traced without a mistake, OBJ model included: no verdict.
#[test]
fn the_same_scenes_traced_correctly_get_no_verdict() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for file in ["sample_scene_1.txt", "sample_scene_2.txt", "sample_scene_obj.txt"] {
        let parsed = rayscope_scene::load(&course.scene(file)).expect("scene");
        let scene = Scene::from_file(&parsed);
        let settings = RenderSettings {
            width: 32,
            height: 32,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        let dir = tempfile::tempdir().expect("temp dir");
        let log = dir.path().join("rays.jsonl");
        let mut f = std::fs::File::create(&log).expect("log");
        write_log(&scene, &settings, 0..32, &mut f).expect("write");
        drop(f);
        let judge = Judge::new(&scene, &settings);
        let ctx = LogContext::new(&scene, 32, 32, judge.samples_per_pixel(), 1);
        let mut src = open(&log, ctx, false, &[]).expect("open");
        let r = check(&judge, src.as_mut(), CheckOptions::default(), &|_, _| {}).expect("check");
        assert!(r.causes.is_empty(), "{file}:\n{}", r.to_text(&|_| None));
        assert!(r.shaded_judged > 0, "{file}: no colour judged");
    }
}

/// docs/mistakes.md says how `check` and `probe` show each mistake, as the catalogue does.
#[test]
fn the_manual_says_how_check_shows_each_mistake() {
    let doc = std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/mistakes.md"))
        .expect("docs/mistakes.md");
    for m in Mistake::ALL {
        let i = m.info();
        let codes: Vec<String> = i.check.iter().map(|c| format!("`{c}`")).collect();
        let image = i.check.iter().any(|c| c.starts_with("image."));
        let probe: Vec<String> = i.probe.iter().map(|c| format!("`{c}`")).collect();
        let row = format!(
            "| `{}` | {}{} | {} |",
            i.name,
            codes.join(", "),
            if image { " (with `--image`)" } else { "" },
            if probe.is_empty() {
                "—".to_string()
            } else {
                probe.join(", ")
            }
        );
        assert!(doc.contains(&row), "docs/mistakes.md lacks or differs on:\n{row}");
        for c in i.check {
            assert!(rayscope_check::Code::parse(c).is_some(), "{}: no verdict {c}", i.name);
        }
        for c in i.probe {
            assert!(
                rayscope_check::probe::parse_catalogue_code(c).is_some(),
                "{}: no probe finding {c}",
                i.name
            );
        }
    }
}
