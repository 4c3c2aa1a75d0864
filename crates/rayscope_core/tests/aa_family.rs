//! `diagnose` fits the student's anti-aliasing sample grid to their picture: grids the
//! student's tracer (`student/`) plants (cells' corners, spaced inside the pixel, shifted by
//! 3/8 px, 3×3 where the flags say 4×4) are fitted back and said against the course's; the
//! correct grid, samples jittered within each cell, a stage-1 picture anti-aliased as `-x`
//! asks, and rayscope's own picture with one pixel off give no finding; samples on the pixel's
//! diagonal are fitted as that.

mod diagnosing;
mod student;

use std::path::{Path, PathBuf};

use diagnosing::{diagnosed, Flags};
use rayscope_core::diagnose::{report_text, Diagnosis, Fitted};
use rayscope_core::{RenderSettings, Stage};
use student::Options;

const W: u32 = 80;
const H: u32 = 60;

fn scene(name: &str) -> Option<PathBuf> {
    rayscope_testkit::course().map(|c| c.scene(name))
}

/// The diagnosis of the student's picture of `path` with `opts`, under flags of `stage` that
/// ask for `-x declared`.
fn run(path: &Path, opts: Options, declared: u32, stage: Stage) -> Diagnosis {
    let flags = Flags {
        aa: declared,
        stage,
        ..Flags::of(opts)
    };
    diagnosed(path, &[], opts, flags).0
}

/// The anti-aliasing finding of `d`, or a panic that shows the report.
fn aa_finding(d: &Diagnosis) -> &Fitted {
    let text = report_text(d, "scene.txt");
    d.fitted
        .iter()
        .find(|f| f.code.starts_with("aa-"))
        .unwrap_or_else(|| panic!("no anti-aliasing fitted\n{text}"))
}

/// Samples at k/(N + 1) are fitted back as such, with the course's positions beside them, and
/// head the report: no catalogued mistake is that grid.
#[test]
fn samples_spaced_inside_the_pixel_are_fitted_back() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        grid: [1.0, 1.0],
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::Two);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!(f.code, "aa-interior", "{text}");
    assert!(!f.allowed, "{text}");
    assert_eq!((f.numbers["start_x"], f.numbers["step_x"]), (0.2, 0.2), "{text}");
    assert_eq!(f.numbers["level"], 4.0, "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with(
            "No known mistake explains your picture; your anti-aliasing differs: Your anti-aliasing samples sit at k/5 of the pixel (from its corner: 0.2, 0.4, 0.6, 0.8)"
        ) && text.contains("the course's sit at cell centres (0.125, 0.375, 0.625, 0.875)"),
        "{text}"
    );
}

/// Samples at k/N (the cells' corners) are the catalogue's 'pixel-corners': it is named, and
/// the fitted positions are said beneath it.
#[test]
fn samples_at_the_cells_corners_are_fitted_beneath_their_catalogue_name() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        grid: [0.0, 0.0],
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::Two);
    let text = report_text(&d, "scene.txt");
    let e = d
        .explanations
        .first()
        .unwrap_or_else(|| panic!("no explanation\n{text}"));
    assert!(e.cause && e.mistakes == ["pixel-corners"], "{text}");
    let f = aa_finding(&d);
    assert_eq!(f.code, "aa-corner", "{text}");
    assert_eq!((f.numbers["start_x"], f.numbers["step_x"]), (0.0, 0.25), "{text}");
    assert!(
        text.contains(
            "  and your anti-aliasing, fitted: Your anti-aliasing samples sit at k/4 of the pixel (from its corner: 0, 0.25, 0.5, 0.75)"
        ),
        "{text}"
    );
}

/// The course's grid moved by 3/8 px on both axes: the shift is fitted back to within a
/// sixty-fourth of a pixel.
#[test]
fn a_grid_shifted_by_three_eighths_is_fitted_back() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        shift: [0.375, 0.375],
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::Two);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!(f.code, "aa-shifted", "{text}");
    for key in ["shift_x", "shift_y"] {
        let s = f.numbers[key];
        assert!((s - 0.375).abs() <= 1.0 / 64.0, "{key} {s}\n{text}");
    }
    assert!(
        text.contains("0.375 px right and 0.375 px down of the course's"),
        "{text}"
    );
}

/// A sample at x − ½ where the course takes x + ½ (a sign slip): the whole picture one pixel
/// left and up, fitted back as a shift of a whole pixel on each axis, on course scene 2 too.
#[test]
fn a_grid_shifted_by_a_whole_pixel_is_fitted_back() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for name in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        let opts = Options {
            shift: [-1.0, -1.0],
            ..Options::new(W, H)
        };
        let d = run(&course.scene(name), opts, 1, Stage::Two);
        let text = report_text(&d, "scene.txt");
        let f = aa_finding(&d);
        assert_eq!(f.code, "aa-shifted", "{name}\n{text}");
        for key in ["shift_x", "shift_y"] {
            let s = f.numbers[key];
            assert!((s + 1.0).abs() <= 1.0 / 64.0, "{name}: {key} {s}\n{text}");
        }
        assert!(text.contains("1 px left and 1 px up of the course's"), "{name}\n{text}");
        assert!(d.explanations.iter().all(|e| !e.cause), "{name}\n{text}");
        // Rays through the pixels' corners (half a pixel) move the same smooth walls the same
        // way: they explain a part by chance and are not listed.
        assert!(
            d.explanations
                .iter()
                .all(|e| !e.mistakes.iter().any(|m| m == "pixel-corners")),
            "{name}\n{text}"
        );
    }
}

/// 3×3 samples where the flags say 4×4: the edges show the level, and the search's `-x 3` is
/// the cause, with the level read beneath it.
#[test]
fn three_by_three_samples_under_a_declared_four_are_read_from_the_edges() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let d = run(
        &path,
        Options {
            aa: 3,
            ..Options::new(W, H)
        },
        4,
        Stage::Two,
    );
    let text = report_text(&d, "scene.txt");
    let e = d
        .explanations
        .first()
        .unwrap_or_else(|| panic!("no explanation\n{text}"));
    assert!(e.matches && e.settings == ["-x 3"], "{text}");
    // No other level is proposed: the edges contradict them.
    assert!(
        d.explanations
            .iter()
            .all(|e| e.settings.iter().all(|s| s == "-x 3" || !s.starts_with("-x"))),
        "{text}"
    );
    let f = aa_finding(&d);
    assert_eq!((f.code, f.numbers["level"]), ("aa-level", 3.0), "{text}");
    assert!(
        text.contains("  and your anti-aliasing, fitted: Your picture has 3×3 samples a pixel, not 4×4"),
        "{text}"
    );
}

/// 6×6 samples, a level the search does not try by itself, is read from the edges and offered.
#[test]
fn a_level_past_four_is_read_and_offered() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let d = run(
        &path,
        Options {
            aa: 6,
            ..Options::new(W, H)
        },
        4,
        Stage::Two,
    );
    let text = report_text(&d, "scene.txt");
    let e = d
        .explanations
        .first()
        .unwrap_or_else(|| panic!("no explanation\n{text}"));
    assert!(e.matches && e.settings == ["-x 6"], "{text}");
    assert_eq!(aa_finding(&d).numbers["level"], 6.0, "{text}");
}

/// The course's grid, at -x 1 and -x 4, gives no finding, nor does a glass scene's.
#[test]
fn the_course_s_grid_gives_no_finding() {
    for (name, aa) in [
        ("sample_scene_1.txt", 1),
        ("sample_scene_1.txt", 4),
        ("sample_scene_2.txt", 2),
    ] {
        let Some(path) = scene(name) else {
            return;
        };
        let d = run(
            &path,
            Options {
                aa,
                ..Options::new(W, H)
            },
            aa,
            Stage::Two,
        );
        let text = report_text(&d, "scene.txt");
        assert!(d.matches, "{name} -x {aa}:\n{text}");
        assert!(d.fitted.is_empty(), "{name} -x {aa}: {:?}\n{text}", d.fitted);
    }
}

/// One sample at random in each of the 4×4 cells is a correct anti-aliasing: it is said to be
/// allowed, no mistake is named and no pixels are sent to be logged.
#[test]
fn samples_jittered_within_their_cells_are_allowed() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        jitter: Some(7),
        jitter_in_cells: true,
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::Two);
    let text = report_text(&d, "scene.txt");
    assert!(!d.fitted.is_empty() && d.fitted.iter().all(|f| f.allowed), "{text}");
    let f = aa_finding(&d);
    assert_eq!((f.code, f.numbers["level"]), ("aa-jittered-cells", 4.0), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(d.next.is_none(), "{text}");
    assert!(
        text.starts_with("Your image is rayscope's render but for its anti-aliasing: Your anti-aliasing samples are jittered at random within each cell of the pixel's 4×4 grid"),
        "{text}"
    );
}

/// A stage-1 picture anti-aliased on the course's -x 4 grid (students honour -x at stage 1
/// too) is said to be allowed; one at 2×2 under -x 4, or at 4×4 under -x 1, is read as its
/// level.
#[test]
fn a_stage_one_picture_anti_aliased_as_asked_is_allowed() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        stage1: true,
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::One);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!(
        (f.code, f.allowed, f.numbers["level"]),
        ("aa-stage1", true, 4.0),
        "{text}"
    );
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(d.next.is_none(), "{text}");
    assert!(
        text.starts_with("Your image is rayscope's render but for its anti-aliasing: Your stage-1 picture is anti-aliased on the -x 4 grid"),
        "{text}"
    );
    let d = run(&path, Options { aa: 2, ..opts }, 4, Stage::One);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!(
        (f.code, f.allowed, f.numbers["level"]),
        ("aa-level", false, 2.0),
        "{text}"
    );
    assert!(
        f.text
            .starts_with("Your stage-1 picture has 2×2 samples a pixel where -x 4 asks for 4×4"),
        "{text}"
    );
    let d = run(&path, opts, 1, Stage::One);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!((f.code, f.allowed), ("aa-level", false), "{text}");
    assert!(
        f.text
            .starts_with("Your stage-1 picture has 4×4 samples a pixel where -x 1 asks for 1×1"),
        "{text}"
    );
    // The stage-1 picture without anti-aliasing is rayscope's, whatever -x says.
    let d = run(&path, Options { aa: 1, ..opts }, 4, Stage::One);
    assert!(d.matches && d.fitted.is_empty(), "{}", report_text(&d, "scene.txt"));
}

/// Samples anywhere in the pixel, at random, are allowed too, and no mistake is named.
#[test]
fn samples_jittered_over_the_pixel_are_allowed() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 4,
        jitter: Some(11),
        ..Options::new(W, H)
    };
    let d = run(&path, opts, 4, Stage::Two);
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!((f.code, f.allowed), ("aa-jittered", true), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with("Your image is rayscope's render but for its anti-aliasing: Your samples are jittered at random within the pixel"),
        "{text}"
    );
}

/// Samples whose inner loop reads the outer loop's counter (uncatalogued) lie on the pixel's
/// diagonal: no grid of the family is that, so it is fitted as the diagonal it is, with the
/// positions said, not as another grid, a jitter or another level.
#[test]
fn samples_on_the_pixel_s_diagonal_are_fitted_as_such() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let opts = Options {
        aa: 2,
        ..Options::new(W, H)
    };
    let flags = Flags {
        aa: 2,
        ..Flags::of(opts)
    };
    let d = diagnosed(&path, &["aa-one-counter"], opts, flags).0;
    let text = report_text(&d, "scene.txt");
    let f = aa_finding(&d);
    assert_eq!(f.code, "aa-diagonal", "{text}");
    assert!(!f.allowed, "{text}");
    assert_eq!((f.numbers["start_x"], f.numbers["step_x"]), (0.25, 0.5), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with(
            "No known mistake explains your picture; your anti-aliasing differs: Your anti-aliasing samples lie on the pixel's diagonal, at 2 places"
        ),
        "{text}"
    );
}

/// rayscope's own picture with one pixel a level brighter is a match with a pixel beyond its
/// ties: no anti-aliasing finding, whose grid would be the course's own.
#[test]
fn one_pixel_off_reads_no_anti_aliasing() {
    let Some(path) = scene("sample_scene_1.txt") else {
        return;
    };
    let file = rayscope_scene::load(&path).expect("scene");
    let settings = RenderSettings {
        width: W,
        height: H,
        aa: 1,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let never = std::sync::atomic::AtomicBool::new(false);
    let mut rgb = rayscope_core::render(&rayscope_core::Scene::from_file(&file), &settings, &|_, _| {}, &never)
        .expect("render")
        .film
        .to_rgb8();
    let p = ((30 * W + 50) * 3) as usize;
    rgb[p] = if rgb[p] == 255 { 254 } else { rgb[p] + 1 };
    let image = rayscope_core::diagnose::Image {
        width: W,
        height: H,
        rgb: &rgb,
        alpha: None,
    };
    let d = rayscope_core::diagnose::diagnose(&file, &settings, image, &Default::default()).expect("sizes agree");
    let text = report_text(&d, "scene.txt");
    assert!(d.fitted.iter().all(|f| !f.code.starts_with("aa-")), "{text}");
    assert!(!text.contains("anti-aliasing differs"), "{text}");
}
