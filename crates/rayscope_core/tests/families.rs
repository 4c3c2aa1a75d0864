//! `diagnose` fits the Fresnel weight of the student's glass to their picture: a constant share
//! and an uncatalogued curve are fitted back to what the student's tracer (`student/`) planted,
//! catalogued Fresnel mistakes keep their name with the fitted weight beneath, and a correct
//! picture or a mistake that is not about the weight gets no Fresnel finding.

mod diagnosing;
mod student;

use std::path::{Path, PathBuf};

use diagnosing::{diagnosed, diagnosed_edited, Flags};
use rayscope_core::diagnose::{report_text, Diagnosis};
use student::Options;

const W: u32 = 80;
const H: u32 = 60;

fn scene2() -> Option<PathBuf> {
    rayscope_testkit::course().map(|c| c.scene("sample_scene_2.txt"))
}

/// The diagnosis of the student's picture of `path` with `bugs` and `opts`, under stage-2 flags.
fn run(path: &Path, bugs: &[&'static str], opts: Options) -> Diagnosis {
    diagnosed(path, bugs, opts, Flags::of(opts)).0
}

/// The planted share of a glass that reflects a constant one is fitted back, and said as the
/// finding: no catalogued mistake is that glass.
#[test]
fn a_constant_reflectance_is_fitted_back() {
    let Some(scene) = scene2() else {
        return;
    };
    for c in [0.028, 0.12] {
        let opts = Options {
            fresnel_constant: Some(c),
            ..Options::new(W, H)
        };
        let d = run(&scene, &[], opts);
        let text = report_text(&d, "scene.txt");
        let f = d
            .fitted
            .first()
            .unwrap_or_else(|| panic!("{c}: nothing fitted\n{text}"));
        assert_eq!(f.code, "fresnel-constant", "{c}:\n{text}");
        let fitted = f.numbers["constant"];
        assert!((fitted - c).abs() <= 0.002, "{c}: fitted {fitted}\n{text}");
        assert!(d.explanations.iter().all(|e| !e.cause), "{c}:\n{text}");
        let first = text.lines().next().unwrap_or_default();
        let share = format!("{:.1} %", 100.0 * c);
        let share = if c >= 0.1 { format!("{:.0} %", 100.0 * c) } else { share };
        assert!(
            first.starts_with(
                "No known mistake explains your picture; your glass's Fresnel weight differs: Your glass reflects "
            ) && first.contains(&format!("reflects {share} at every angle"))
                && first.contains(
                    "the exact Fresnel weight goes from 2.8 % at normal incidence to 100 % at grazing angles"
                ),
            "{c}:\n{text}"
        );
    }
}

/// A constant share is fitted back from every sample of anti-aliased pixels, and in a scene of
/// ours with two glasses of other indices (1.5 and 1.33).
#[test]
fn a_constant_reflectance_is_fitted_back_anti_aliased_and_in_our_scene() {
    let Some(course) = scene2() else {
        return;
    };
    let ours = rayscope_testkit::scene("whitted.txt");
    for (path, aa) in [(&course, 2), (&ours, 1)] {
        let opts = Options {
            fresnel_constant: Some(0.12),
            aa,
            ..Options::new(W, H)
        };
        let d = run(path, &[], opts);
        let text = report_text(&d, "scene.txt");
        let f = d
            .fitted
            .first()
            .unwrap_or_else(|| panic!("{}: nothing fitted\n{text}", path.display()));
        assert_eq!(f.code, "fresnel-constant", "{}:\n{text}", path.display());
        let fitted = f.numbers["constant"];
        assert!(
            (fitted - 0.12).abs() <= 0.002,
            "{}: fitted {fitted}\n{text}",
            path.display()
        );
    }
}

/// (1 + I·N)², an uncatalogued curve, is fitted at the angles reported to within a few
/// percent of what the student's tracer computes there, and named by no catalogue mistake.
#[test]
fn an_uncatalogued_curve_is_fitted_at_the_angles_reported() {
    let Some(scene) = scene2() else {
        return;
    };
    let d = run(&scene, &["fresnel-one-plus-i-dot-n-facing"], Options::new(W, H));
    let text = report_text(&d, "scene.txt");
    let f = d.fitted.first().unwrap_or_else(|| panic!("nothing fitted\n{text}"));
    assert_eq!(f.code, "fresnel-curve", "{text}");
    for (key, deg) in [("fitted_0", 0.0f64), ("fitted_60", 60.0), ("fitted_80", 80.0)] {
        let planted = (1.0 - deg.to_radians().cos()).powi(2);
        let fitted = f.numbers[key];
        assert!(
            (fitted - planted).abs() <= 0.03,
            "{key}: fitted {fitted}, planted {planted}\n{text}"
        );
    }
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with("No known mistake explains your picture; your glass's Fresnel weight differs: Your glass's reflected share, fitted from "),
        "{text}"
    );
}

/// cos θt taken for cos θi makes the Fresnel terms a constant, ((n₁ − n₂)/(n₁ + n₂))²: the fit
/// says so, and no catalogued mistake is named for it.
#[test]
fn cos_t_as_cos_i_is_described_by_its_fitted_weight() {
    let Some(scene) = scene2() else {
        return;
    };
    let d = run(&scene, &["cos-t-as-cos-i"], Options::new(W, H));
    let text = report_text(&d, "scene.txt");
    let f = d.fitted.first().unwrap_or_else(|| panic!("nothing fitted\n{text}"));
    let r0 = (0.4f64 / 2.4).powi(2);
    assert_eq!(f.code, "fresnel-constant", "{text}");
    assert!((f.numbers["constant"] - r0).abs() <= 0.002, "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(text.starts_with("No known mistake explains"), "{text}");
}

/// The catalogued Fresnel mistakes keep their catalogue headline, with the fitted weight
/// beneath it.
#[test]
fn catalogued_fresnel_mistakes_keep_their_name_and_get_the_fit_beneath() {
    let Some(scene) = scene2() else {
        return;
    };
    for (bug, code) in [
        ("no-fresnel", "fresnel-none"),
        ("fresnel-half", "fresnel-half"),
        ("schlick", "fresnel-schlick"),
        ("fresnel-swapped", "fresnel-curve"),
    ] {
        let d = run(&scene, &[bug], Options::new(W, H));
        let text = report_text(&d, "scene.txt");
        let e = d
            .explanations
            .first()
            .unwrap_or_else(|| panic!("{bug}: no explanation\n{text}"));
        assert!(e.cause && e.mistakes == [bug], "{bug}:\n{text}");
        assert!(text.starts_with("Explained: "), "{bug}:\n{text}");
        let codes: Vec<&str> = d.fitted.iter().map(|f| f.code).collect();
        assert_eq!(codes, [code], "{bug}:\n{text}");
        let second = text.lines().nth(1).unwrap_or_default();
        assert!(
            second.starts_with("  and your glass's fitted weight: "),
            "{bug}:\n{text}"
        );
    }
}

/// A correct picture, and mistakes that are not about the weight, get no Fresnel finding.
#[test]
fn no_fresnel_finding_without_a_fresnel_mistake() {
    let Some(scene) = scene2() else {
        return;
    };
    let ours = rayscope_testkit::scene("whitted.txt");
    for (path, bugs) in [
        (&scene, &[][..]),
        (&ours, &[][..]),
        (&scene, &["first-light-only"][..]),
        (&scene, &["sphere-near-root-only"][..]),
        (&scene, &["refraction-no-index-swap"][..]),
        (&ours, &["refraction-no-index-swap"][..]),
    ] {
        let d = run(path, bugs, Options::new(W, H));
        let text = report_text(&d, "scene.txt");
        assert!(
            d.fitted.is_empty(),
            "{} {bugs:?}: {:?}\n{text}",
            path.display(),
            d.fitted
        );
        assert!(!text.contains("fitted"), "{bugs:?}:\n{text}");
    }
}

/// (1 + I·N)² with the outward normal is at least 1 leaving the glass, which turns the glass
/// black or white: clipped bytes that tell no weight. Nothing is fitted and no mistake named:
/// the report says the sphere is black, as painting it black renders it, which many mistakes do.
#[test]
fn a_weight_past_one_is_said_as_a_black_sphere_with_no_name() {
    let Some(scene) = scene2() else {
        return;
    };
    let d = run(&scene, &["fresnel-one-plus-i-dot-n"], Options::new(W, H));
    let text = report_text(&d, "scene.txt");
    assert!(d.fitted.is_empty(), "{:?}\n{text}", d.fitted);
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with(
            "Recognised from how your picture looks: Your GlassSphere is black where rayscope's is lit: rayscope's render with it painted black gives"
        ),
        "{text}"
    );
    assert!(d.recognised.iter().all(|r| r.mistake.is_empty()), "{text}");
}

/// (1 + I·N)² with the outward normal turns the glass sphere black; with pairs, a recursion
/// limit of 1 with 'no-fresnel' renders the same picture. So does painting the sphere black:
/// the picture cannot tell which mistake blackened it, and the report says it is one way to
/// get it, not the cause, and sends the student to the rays.
#[test]
fn a_sphere_turned_black_is_one_way_to_get_the_picture_not_its_cause() {
    let Some(path) = scene2() else {
        return;
    };
    let (d, text) = searched(&path, &["fresnel-one-plus-i-dot-n"], Options::new(120, 120));
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.starts_with(
            "One way to get your picture, not necessarily yours: your GlassSphere is black where rayscope's is not"
        ),
        "{text}"
    );
    assert_eq!(d.explanations[0].blackens, ["GlassSphere"], "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
}

/// Mirrors and glass that bring back black (not written yet), a mistake no catalogue has: the
/// picture is one way to get, whichever render also gives it, and no render is named its cause,
/// at 40×40 and 120×120.
#[test]
fn black_mirrors_and_glass_are_one_way_to_get_the_picture() {
    let Some(path) = scene2() else {
        return;
    };
    for side in [40, 120] {
        let (d, text) = searched(&path, &["mirrors-and-glass-unwritten"], Options::new(side, side));
        assert!(d.explanations.iter().all(|e| !e.cause), "{side}: {text}");
        assert!(
            text.starts_with("One way to get your picture, not necessarily yours: "),
            "{side}: {text}"
        );
    }
}

/// The diagnosis of the student's picture under stage-2 flags, with the command line's search.
fn searched(path: &Path, bugs: &[&'static str], opts: Options) -> (Diagnosis, String) {
    let flags = Flags {
        full_search: true,
        ..Flags::of(opts)
    };
    diagnosed(path, bugs, opts, flags)
}

/// The tangent of the whole angle instead of its half, a mistake the catalogue does not hold, is
/// a field of view of 120°: fitted, confirmed by the tie rule and named by how it comes about.
#[test]
fn a_field_of_view_not_halved_is_fitted_to_its_angle() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (d, text) = searched(
        &course.scene("sample_scene_1.txt"),
        &["fov-not-halved"],
        Options::new(96, 72),
    );
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause && e.matches, "{text}");
    assert_eq!(e.settings, ["--fov 120"], "{text}");
    assert!(
        text.starts_with(
            "Explained: your image is rayscope's render with a field of view of 120° (horizontal) instead of 60°"
        ),
        "{text}"
    );
    assert!(text.contains("the angle not halved before its tangent"), "{text}");
}

/// The half angle in degrees given to a tangent that takes radians — tan(30) for the course's
/// 60°, negative — is a picture turned half a turn and eleven times as wide: fitted above 180°,
/// confirmed by the tie rule, and named by how it comes about, upside down and mirrored said.
#[test]
fn a_field_of_view_given_in_degrees_to_a_tangent_of_radians_is_named() {
    let Some(path) = scene2() else {
        return;
    };
    let (d, text) = searched(&path, &["fov-in-radians"], Options::new(96, 72));
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause && e.matches, "{text}");
    let want = 360.0 + 2.0 * 30f64.tan().atan().to_degrees();
    assert_eq!(e.settings, [format!("--fov {}", want as f32)], "{text}");
    let first = text.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("Explained: your image is rayscope's render with a field of view of 197.7"),
        "{text}"
    );
    assert!(first.contains("upside down and mirrored"), "{text}");
    assert!(
        first.contains("tan(30) — the half angle in degrees given to a tangent that takes radians"),
        "{text}"
    );
}

/// Another angle, anti-aliased, is fitted back to the value planted, with no way named for it.
#[test]
fn another_field_of_view_is_fitted_back() {
    let Some(path) = scene2() else {
        return;
    };
    let opts = Options {
        fov: 47.5,
        aa: 2,
        ..Options::new(90, 90)
    };
    let (d, text) = searched(&path, &[], opts);
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause, "{text}");
    assert_eq!(e.settings, ["--fov 47.5"], "{text}");
    assert!(
        !text.contains(" — "),
        "no way is named for an angle no known mistake gives\n{text}"
    );
}

/// Shading from the shadow ray's start, 0.02 off the surface, changes every lit pixel by a few
/// levels; where that crosses byte boundaries the lost light lies in scattered specks, but a
/// speck of acne loses a light's whole share. Not acne, and no catalogued name: nothing known
/// explains it, and the report says so.
#[test]
fn shading_a_little_off_the_surface_is_not_called_acne() {
    let Some(path) = scene2() else {
        return;
    };
    let opts = Options {
        shadow_offset: Some(0.02),
        ..Options::new(160, 120)
    };
    let (d, text) = searched(&path, &["light-from-shadow-origin"], opts);
    assert!(d.recognised.iter().all(|r| r.code != "shadow-acne"), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(text.starts_with("No known mistake explains your picture"), "{text}");
}

/// Triangle normals left at the cross product's length brighten the walls until they clip,
/// and any mistake that brightens enough clips them alike ('accumulator-not-reset' matched one
/// wall's clipped green exactly): clipped pixels are no evidence, and no name is given.
#[test]
fn clipped_walls_are_not_explained_by_another_mistake_that_clips() {
    let Some(path) = scene2() else {
        return;
    };
    let (d, text) = searched(&path, &["triangle-normal-unnormalised"], Options::new(60, 45));
    let first = text.lines().next().unwrap_or_default();
    assert!(first.starts_with("No known mistake explains"), "{text}");
    assert!(!first.contains("accumulator-not-reset"), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
}

/// An epsilon of the student's own, 0.02 (neither the course's 1e-5 nor the catalogue's 0.1),
/// is fitted back to the value planted and confirmed as the picture.
#[test]
fn a_shadow_offset_of_the_student_s_own_is_fitted_back() {
    let Some(path) = scene2() else {
        return;
    };
    let opts = Options {
        shadow_offset: Some(0.02),
        ..Options::new(160, 120)
    };
    let (d, text) = searched(&path, &[], opts);
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause, "{text}");
    assert_eq!(e.mistakes, ["shadow-offset=0.02"], "{text}");
    assert!(
        text.starts_with("Explained: your image is rayscope's render with shadow rays started 0.02 off the surface"),
        "{text}"
    );
    assert!(
        text.contains("--mistake shadow-offset=0.02"),
        "the command renders it\n{text}"
    );
}

/// One epsilon of the student's own, 0.03, used for every ray leaving a surface (shadows,
/// the mirror, the glass's reflections and refractions) is fitted back as that, not as a
/// shadow offset alone.
#[test]
fn an_offset_of_the_student_s_own_for_every_ray_is_fitted_back() {
    let Some(path) = scene2() else {
        return;
    };
    let opts = Options {
        ray_offset: Some(0.03),
        ..Options::new(160, 120)
    };
    let (d, text) = searched(&path, &[], opts);
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause, "{text}");
    assert_eq!(e.mistakes, ["ray-offset=0.03"], "{text}");
    assert!(
        text.starts_with("Explained: your image is rayscope's render with every ray leaving a surface (shadow, mirror, glass) started 0.03 off it"),
        "{text}"
    );
    assert!(
        text.contains("--mistake ray-offset=0.03"),
        "the command renders it\n{text}"
    );
}

/// Lights averaged instead of added (uncatalogued) darken the whole of course scene 2, with its
/// two lights, by one factor: fitted as 0.5, confirmed, and named by how it comes about.
#[test]
fn lights_averaged_are_fitted_as_one_factor() {
    let Some(path) = scene2() else {
        return;
    };
    let opts = Options::new(160, 120);
    let (d, text) = searched(&path, &["lights-averaged"], opts);
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause && e.matches, "{text}");
    assert_eq!(e.mistakes, ["colour-scale=0.5"], "{text}");
    assert!(
        text.starts_with("Explained: your image is rayscope's render with every colour multiplied by 0.5 before it is written as bytes (the whole picture darker by that one factor) — the sum over the 2 lights divided by their number"),
        "{text}"
    );
    assert!(
        text.contains("--mistake colour-scale=0.5"),
        "the command renders it\n{text}"
    );
}

/// Each light's colour left out of the diffuse term (uncatalogued): scene 2's lights are all
/// (0.5, 0.5, 0.5), so the picture is twice as bright, fitted as 2 and named by that way.
#[test]
fn light_colours_left_out_are_fitted_as_one_factor() {
    let Some(path) = scene2() else {
        return;
    };
    let (d, text) = searched(&path, &["light-colour-ignored"], Options::new(80, 60));
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause && e.matches, "{text}");
    assert_eq!(e.mistakes, ["colour-scale=2"], "{text}");
    assert!(
        text.lines().next().unwrap_or_default().contains(
            "each light's colour (0.5, 0.5, 0.5) left out of the diffuse term (albedo × N·L, as if every light were white) gives exactly this"
        ),
        "{text}"
    );
}

/// The -x 2 grid's four samples divided by 2 (uncatalogued): twice as bright, clipped where
/// rayscope's colour is over one half, fitted as 2 and named.
#[test]
fn samples_divided_by_n_are_fitted_as_one_factor() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let opts = Options {
        aa: 2,
        ..Options::new(96, 72)
    };
    let (d, text) = searched(&course.scene("sample_scene_1.txt"), &["samples-divided-by-n"], opts);
    let e = d.explanations.first().unwrap_or_else(|| panic!("{text}"));
    assert!(e.cause && e.matches, "{text}");
    assert_eq!(e.mistakes, ["colour-scale=2"], "{text}");
    assert!(
        text.contains("the -x 2 grid's 4 samples divided by 2 instead of 4 gives exactly this"),
        "{text}"
    );
}

/// A picture made grey before it is written (uncatalogued) is said first, with the mix of the
/// colour it holds, and the one factor beside it where there is one.
#[test]
fn a_grey_picture_is_said_first_with_its_mix() {
    let Some(scene) = scene2() else {
        return;
    };
    let opts = Options::new(W, H);
    for (bugs, words) in [
        (
            &["luminance-written"][..],
            "Each pixel is rayscope's colour made grey by its luminance, 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709) (within PSNR ",
        ),
        (
            &["red-in-every-channel"][..],
            "Each pixel is rayscope's colour made grey by copying its red into all three channels (within PSNR ",
        ),
        (
            &["luminance-written", "lights-averaged"][..],
            "Each pixel is rayscope's colour made grey by its luminance, 0.2126 R + 0.7152 G + 0.0722 B (Rec. 709) and multiplied by 0.5 (within PSNR ",
        ),
    ] {
        let (d, text) = diagnosed(&scene, bugs, opts, Flags::of(opts));
        let first = text.lines().next().unwrap_or_default();
        assert!(
            first.starts_with("Your image has no colour: red, green and blue are equal in every pixel, while ")
                && first.contains(words),
            "{bugs:?}:\n{text}"
        );
        assert_eq!(d.obvious.first().map(|o| o.code), Some("grey"), "{bugs:?}:\n{text}");
        assert!(d.explanations.iter().all(|e| !e.cause), "{bugs:?}:\n{text}");
    }
    let (d, text) = diagnosed(&scene, &[], opts, Flags::of(opts));
    assert!(d.obvious.is_empty(), "a correct picture:\n{text}");
}

/// The refraction formula without its square root (uncatalogued) sends the refracted ray along
/// the surface: the glass shows only its reflection. Catalogued mistakes give that picture too
/// (a depth limit with the normal not flipped), so none is named as the cause: the first line
/// says it is one way to get the picture, and what the glass lost.
#[test]
fn glass_that_shows_only_its_reflection_is_one_way_not_a_cause() {
    let Some(scene) = scene2() else {
        return;
    };
    let opts = Options::new(60, 45);
    let (d, text) = searched(&scene, &["refraction-no-root"], opts);
    assert!(
        text.starts_with(
            "One way to get your picture, not necessarily yours: your GlassSphere shows only its reflection, with nothing of the light through it where rayscope's shows both."
        ),
        "{text}"
    );
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert_eq!(d.explanations[0].loses_refraction, ["GlassSphere"], "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
}

/// The reflected and refracted weights exchanged where the colours are mixed (uncatalogued) are
/// fitted as 1 minus the exact weight and said as exchanged, not as a curve of numbers alone.
#[test]
fn exchanged_fresnel_weights_are_fitted_and_said() {
    let Some(scene) = scene2() else {
        return;
    };
    let d = run(&scene, &["fresnel-weights-exchanged"], Options::new(W, H));
    let text = report_text(&d, "scene.txt");
    let f = d.fitted.first().unwrap_or_else(|| panic!("nothing fitted\n{text}"));
    assert_eq!(f.code, "fresnel-exchanged", "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(
        text.lines()
            .next()
            .unwrap_or_default()
            .contains("Your glass's reflected and refracted weights are exchanged (fitted from "),
        "{text}"
    );
}

/// Entities the picture leaves out are said first, as what the picture shows, with no
/// catalogued mistake named: a sphere test that never hits (its quadratic's b not doubled,
/// uncatalogued) leaves out every sphere; a loader that stops one line short (uncatalogued)
/// leaves out the last entity.
#[test]
fn entities_the_picture_lacks_are_said_first() {
    let Some(scene) = scene2() else {
        return;
    };
    let cases: [(&'static str, &str, &[&str]); 2] = [
        (
            "sphere-b-not-doubled",
            "Recognised from how your picture looks: Your picture is rayscope's render without its spheres (MirrorSphere and GlassSphere): they are not seen, cast no shadows and show in no mirror, as if your tracer never found a hit on a sphere. Look at your sphere intersection test",
            &["MirrorSphere", "GlassSphere"],
        ),
        (
            "last-entity-skipped",
            "Recognised from how your picture looks: Your picture is rayscope's render without 'FarWallB' (a triangle): it is not seen, casts no shadow and shows in no mirror, as if your tracer never found a hit on it. The scene's other triangles are in your picture, so look at what sets this one apart: its line in the scene file (line 28)",
            &["FarWallB"],
        ),
    ];
    for (bug, first, entities) in cases {
        let (d, text) = searched(&scene, &[bug], Options::new(60, 45));
        assert!(text.starts_with(first), "{bug}:\n{text}");
        let r = d
            .recognised
            .first()
            .unwrap_or_else(|| panic!("{bug}: nothing recognised\n{text}"));
        assert_eq!(r.code, "entities-missing", "{bug}:\n{text}");
        assert_eq!(r.entities, entities, "{bug}:\n{text}");
        assert!(
            d.explanations.is_empty(),
            "{bug}: no catalogued render is offered\n{text}"
        );
        for e in entities {
            assert!(
                d.attribution.iter().any(|s| {
                    let front = s.seen_in.first().unwrap_or(&s.entity);
                    front == e && s.how.contains("missing: your picture shows what lies behind it")
                }),
                "{bug}: {e} is not said missing where it is\n{text}"
            );
        }
        assert!(d.next.is_some(), "{bug}: the pixels to log are given\n{text}");
    }
}

/// Two catalogued mistakes that give the same picture on a scene are both said, neither as the
/// cause: where all glass is spheres (course scene 2, our still life), a refracted ray started
/// on the incoming side and a sphere test that takes the root behind a ray from inside both make
/// the glass ray meet its entry point again.
#[test]
fn mistakes_that_give_the_same_picture_are_said_together() {
    let Some(scene) = scene2() else {
        return;
    };
    let scenes = [scene, rayscope_testkit::scene("whitted.txt")];
    for (scene, bug) in scenes
        .iter()
        .flat_map(|s| ["refraction-offset-outside", "sphere-near-root-behind"].map(|b| (s, b)))
    {
        let (d, text) = searched(scene, &[bug], Options::new(60, 45));
        let e = d
            .explanations
            .first()
            .unwrap_or_else(|| panic!("{bug}: nothing found\n{text}"));
        assert!(!e.cause && e.matches, "{bug}:\n{text}");
        assert_eq!(e.same_as.len(), 1, "{bug}:\n{text}");
        let first = text.lines().next().unwrap_or_default();
        assert!(
            first.starts_with(
                "One way to get your picture, not necessarily yours: your image is rayscope's render with "
            ) && first.contains("'refraction-offset-outside'")
                && first.contains("'sphere-near-root-behind'")
                && first.contains("the picture alone cannot tell which is yours"),
            "{bug}:\n{text}"
        );
        assert!(d.next.is_some(), "{bug}: the pixels to log are given\n{text}");
    }
}

/// A mistake that changes the whole picture (the lights' y read with the wrong sign,
/// uncatalogued) is not explained in part by catalogued renders that change the whole picture
/// too and match one surface by chance (an image upside down lights the floor as the roof): no
/// known mistake explains it, and the pixels to log are given.
#[test]
fn no_render_that_changes_everything_explains_a_part_by_chance() {
    let Some(scene) = scene2() else {
        return;
    };
    let (d, text) = searched(&scene, &["light-y-negated"], Options::new(60, 45));
    assert!(
        text.starts_with("No known mistake explains your picture: no setting or catalogued mistake"),
        "{text}"
    );
    assert!(d.explanations.is_empty(), "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
}

/// A sphere drawn smaller than it is (its radius read as a diameter, uncatalogued) lacks a ring
/// of itself: said as a part of the picture that shows what lies behind the sphere, never as a
/// sphere the tracer does not hit at all.
#[test]
fn a_sphere_partly_missing_is_said_as_partly_missing() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let opts = Options {
        aa: 2,
        ..Options::new(60, 45)
    };
    let (d, text) = searched(&course.scene("sample_scene_1.txt"), &["radius-halved"], opts);
    let first = text.lines().next().unwrap_or_default();
    assert!(
        first.starts_with(
            "Recognised from how your picture looks: Where your picture differs, much of it is what rayscope's render without its spheres (Sphere) shows: in places your picture shows what lies behind them"
        ),
        "{text}"
    );
    assert!(!first.contains("never found a hit"), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
}

/// A light read with its y negated lies in course scene 1's plane, which turns the plane black:
/// a black surface, not a fall-off whose render happens to be as dark on average. The report
/// says the plane is black and names no mistake.
#[test]
fn a_plane_the_light_lies_in_is_said_black_and_named_nothing() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (d, text) = searched(
        &course.scene("sample_scene_1.txt"),
        &["light-y-negated"],
        Options::new(60, 45),
    );
    assert!(
        text.starts_with("Recognised from how your picture looks: Your Plane is black where rayscope's is lit"),
        "{text}"
    );
    assert!(d.explanations.is_empty(), "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
}

/// Spheres drawn at half their radius (uncatalogued) leave shadows smaller and walls lit where
/// rayscope's are in shadow. A mistake that removes every shadow reproduces those pixels but
/// takes away the shadows the picture keeps: it explains no part, and nothing is named; the
/// report says the picture shows, in places, what lies behind the spheres.
#[test]
fn spheres_drawn_smaller_name_no_mistake() {
    let Some(scene) = scene2() else {
        return;
    };
    let (d, text) = searched(&scene, &["radius-halved"], Options::new(60, 45));
    assert!(d.explanations.is_empty(), "{text}");
    assert!(
        text.starts_with(
            "Recognised from how your picture looks: Where your picture differs, much of it is what rayscope's render without its spheres (MirrorSphere and GlassSphere) shows"
        ),
        "{text}"
    );
    assert!(!text.contains("never found a hit"), "{text}");
}

/// The student's picture of `path` read with `edit`, diagnosed with the full search.
fn edited(path: &Path, edit: &dyn Fn(&mut rayscope_scene::SceneFile), opts: Options) -> (Diagnosis, String) {
    let flags = Flags {
        full_search: true,
        ..Flags::of(opts)
    };
    diagnosed_edited(path, edit, &[], opts, flags)
}

/// A glass's index read wrong (1.36 or 1.45 instead of 1.4) bends what the glass shows, and
/// nothing else: not random anti-aliasing samples, whose noise is at every edge of the picture.
/// No mistake is named and nothing is said to be allowed.
#[test]
fn a_glass_index_read_wrong_is_not_called_jittered_anti_aliasing() {
    let Some(scene) = scene2() else {
        return;
    };
    for (ior, aa) in [(1.36, 1), (1.45, 2)] {
        let glass = move |f: &mut rayscope_scene::SceneFile| {
            for m in f.materials.iter_mut().filter(|m| m.name == "GlassMat") {
                m.value = ior;
            }
        };
        let (d, text) = edited(
            &scene,
            &glass,
            Options {
                aa,
                ..Options::new(80, 60)
            },
        );
        assert!(d.fitted.iter().all(|f| !f.allowed), "{ior} -x {aa}:\n{text}");
        assert!(!text.contains("jittered"), "{ior} -x {aa}:\n{text}");
        assert!(d.explanations.iter().all(|e| !e.cause), "{ior} -x {aa}:\n{text}");
        assert!(text.starts_with("No known mistake explains"), "{ior} -x {aa}:\n{text}");
    }
}

/// The sphere of course scene 1 given the blue material instead of the green: putting green
/// and blue back in order would turn it right and the blue triangle wrong, which a writer's
/// channel order never does. Not said to be the channel order.
#[test]
fn one_object_in_another_colour_is_not_a_channel_order() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let blue = |f: &mut rayscope_scene::SceneFile| {
        let b = f
            .materials
            .iter()
            .position(|m| m.name == "Blue")
            .expect("scene 1 has Blue");
        for e in f.entities.iter_mut().filter(|e| e.name == "Sphere") {
            e.material = b;
        }
    };
    let (d, text) = edited(&course.scene("sample_scene_1.txt"), &blue, Options::new(60, 45));
    assert!(d.obvious.iter().all(|o| o.code != "channels"), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(text.starts_with("No known mistake explains"), "{text}");
}

/// A glass that never traces its reflected ray (uncatalogued) shows only the light through it.
/// Catalogued renders that start the reflection in the wrong place match parts of it; the
/// report says instead what the picture shows, which any mistake that loses the reflection
/// gives, and names none.
#[test]
fn a_glass_without_its_reflection_is_said_so_and_named_nothing() {
    let Some(scene) = scene2() else {
        return;
    };
    let (d, text) = searched(&scene, &["glass-reflection-skipped"], Options::new(60, 45));
    assert!(
        text.starts_with(
            "Recognised from how your picture looks: Your GlassSphere shows only the light through it, with nothing of its reflection"
        ),
        "{text}"
    );
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(d.recognised.iter().all(|r| r.mistake.is_empty()), "{text}");
}

/// The bunny placed 0.1 to the right (its offset read wrong, uncatalogued) changes its shading
/// unevenly from pixel to pixel and moves its shadow: pixels lose light and as many gain it.
/// Acne only takes light away, so it is not said to be acne; nothing is named.
#[test]
fn a_model_placed_otherwise_is_not_called_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let moved = |f: &mut rayscope_scene::SceneFile| {
        for e in &mut f.entities {
            if let rayscope_scene::Shape::Mesh { offset, .. } = &mut e.shape {
                offset.x += 0.1;
            }
        }
    };
    let (d, text) = edited(&course.scene("sample_scene_obj.txt"), &moved, Options::new(80, 60));
    assert!(!d.matches, "{text}");
    assert!(d.recognised.iter().all(|r| r.code != "shadow-acne"), "{text}");
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(!text.contains("no-shadow-offset"), "{text}");
}

/// A shadow test that loops over the spheres alone (uncatalogued) takes away every shadow of
/// the other kinds. On course scene 1 that is the triangle's shadow, which a triangle test that
/// rejects back faces takes away too: that render is one way to get the picture, with the
/// triangles' missing shadows said beside it. On the course's OBJ scene no catalogued mistake
/// gives the bunny's missing shadows: the report says what the picture shows and names nothing.
#[test]
fn shadows_a_kind_of_entity_does_not_cast_are_said_and_named_nothing() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (d, text) = searched(
        &course.scene("sample_scene_1.txt"),
        &["shadows-from-spheres-only"],
        Options::new(60, 45),
    );
    assert!(
        text.starts_with(
            "One way to get your picture, not necessarily yours: your triangles cast no shadows where rayscope's do"
        ),
        "{text}"
    );
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert_eq!(d.explanations[0].shadowless, "Triangle", "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
    let (d, text) = searched(
        &course.scene("sample_scene_obj.txt"),
        &["shadows-from-spheres-only"],
        Options::new(60, 45),
    );
    assert!(
        text.starts_with(
            "Recognised from how your picture looks: Your OBJ models (Bunny) cast no shadows where rayscope's do"
        ),
        "{text}"
    );
    assert!(d.explanations.iter().all(|e| !e.cause), "{text}");
    assert!(d.recognised.iter().all(|r| r.mistake.is_empty()), "{text}");
    assert!(d.next.is_some(), "the pixels to log are given\n{text}");
}
