//! Shadow acne is recognised by what it looks like — specks of lost light on lit surfaces where
//! rayscope's picture is smooth — wherever the student's own rounding puts the specks, and
//! named on the report's first line; pictures with other mistakes, speckled ones included, are
//! never called acne.

mod diagnosing;
mod student;

use std::path::Path;

use diagnosing::{diagnosed, Flags};
use rayscope_core::diagnose::Diagnosis;
use student::Options;

/// The diagnosis of the student's stage-2 picture of `path` with `bugs`, `w`×`h` at `-x aa`, and
/// its report.
fn run(path: &Path, bugs: &[&'static str], w: u32, h: u32, aa: u32) -> (Diagnosis, String) {
    let opts = Options {
        aa,
        ..Options::new(w, h)
    };
    diagnosed(path, bugs, opts, Flags::of(opts))
}

/// A shadow ray that starts on its surface, with the hit point in double or in single precision
/// (whose specks fall on other pixels than any render of rayscope's): the first line names
/// shadow acne, and the recognised finding says which lights the specks lose.
#[test]
fn shadow_acne_is_named_wherever_the_tracer_s_rounding_puts_it() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = course.scene("sample_scene_2.txt");
    // With anti-aliasing, a speck darkens its pixel by the share of the samples it hit.
    for (bug, aa) in [
        ("no-shadow-offset-single", 1),
        ("no-shadow-offset", 1),
        ("no-shadow-offset-single", 3),
    ] {
        let (d, text) = run(&scene, &[bug], 160, 120, aa);
        let first = text.lines().next().unwrap_or_default();
        assert!(first.contains("'no-shadow-offset'"), "{bug} -x {aa}:\n{text}");
        if bug == "no-shadow-offset-single" {
            let r = d
                .recognised
                .first()
                .unwrap_or_else(|| panic!("{bug}: not recognised:\n{text}"));
            assert_eq!(r.code, "shadow-acne");
            assert!(
                first.starts_with("Recognised from how your picture looks: shadow acne"),
                "{text}"
            );
            assert!(r.text.contains("Light1") && r.text.contains("Light2"), "{}", r.text);
            assert!(r.share > 0.8, "acne is most of the difference: {r:?}");
        }
    }
}

/// Mistakes that darken, brighten or speckle other things than shadows are never called acne:
/// whole shadows too long or missing, a light left out, fall-off, the mirror's own rays starting
/// on the mirror (black specks on the mirror), a hit rule that skips near surfaces.
#[test]
fn other_mistakes_are_not_called_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = course.scene("sample_scene_2.txt");
    for bug in [
        "shadow-past-light",
        "huge-shadow-offset",
        "first-light-only",
        "light-falloff",
        "no-mirror-offset",
        "min-hit-distance",
        "strict-edges",
        "reflect-sign",
    ] {
        let (d, text) = run(&scene, &[bug], 160, 120, 1);
        assert!(
            d.recognised.iter().all(|r| r.code != "shadow-acne"),
            "{bug}: called acne:\n{text}"
        );
        let first = text.lines().next().unwrap_or_default();
        assert!(!first.contains("acne"), "{bug}:\n{text}");
        // A reflection sent into the mirror leaves the mirror black: said as what it is.
        if bug == "reflect-sign" {
            assert!(
                first.starts_with("Recognised from how your picture looks: Your MirrorSphere is black"),
                "{text}"
            );
        }
    }
}
