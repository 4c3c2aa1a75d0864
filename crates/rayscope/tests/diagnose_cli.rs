//! `--mistake`, `rayscope mistakes` and `rayscope diagnose` as a student runs them: the
//! catalogue, exit codes 0 / 1 / 2, the text and the JSON.

mod common;

use common::{rayscope, render};
use predicates::prelude::*;

#[test]
fn the_catalogue_is_listed_two_ways() {
    for args in [&["mistakes"][..], &["--mistake", "help"][..]] {
        rayscope()
            .args(args)
            .assert()
            .success()
            .stdout(predicate::str::contains("no-shadow-offset").and(predicate::str::contains("obj-no-z-flip")));
    }
    rayscope()
        .args(["-f", "x.txt", "-o", "x.png", "--mistake", "no-tir,nope"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("unknown mistake 'nope'"));
}

#[test]
fn a_mistake_renders_differently_and_replays_in_trace() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = course.scene("sample_scene_1.txt");
    let right = render(&scene, &dir.path().join("a.png"), &["-w", "40", "-h", "30"]);
    let wrong = render(
        &scene,
        &dir.path().join("b.png"),
        &["-w", "40", "-h", "30", "--mistake", "image-flipped"],
    );
    for y in 0..30 {
        for x in 0..40 {
            assert_eq!(wrong.get_pixel(x, y), right.get_pixel(x, 29 - y));
        }
    }
    // The trace of a mistaken render is that render's ray tree: row 0 shows the bottom row.
    rayscope()
        .args([
            "trace",
            "-w",
            "40",
            "-h",
            "30",
            "--pixel",
            "5,0",
            "--mistake",
            "image-flipped",
            "-f",
        ])
        .arg(&scene)
        .assert()
        .success()
        .stdout(predicate::str::contains("hit 'Plane'"));
}

#[test]
fn diagnose_exits_0_1_or_2() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = course.scene("sample_scene_2.txt");
    let flags = ["-w", "48", "-h", "36", "--stage", "2"];
    let right = dir.path().join("right.png");
    let wrong = dir.path().join("wrong.png");
    render(&scene, &right, &flags);
    render(&scene, &wrong, &[&flags[..], &["--mistake", "no-fresnel"]].concat());

    rayscope()
        .args(["diagnose", "--stage", "2", "-f"])
        .arg(&scene)
        .arg(&right)
        .assert()
        .code(0)
        .stdout(predicate::str::contains("matches rayscope's render"));

    let out = rayscope()
        .args(["diagnose", "--stage", "2", "--json", "-f"])
        .arg(&scene)
        .arg(&wrong)
        .assert()
        .code(1)
        .get_output()
        .stdout
        .clone();
    let d: serde_json::Value = serde_json::from_slice(&out).expect("JSON");
    assert_eq!(d["matches"], false);
    assert_eq!(d["explanations"][0]["mistakes"][0], "no-fresnel", "{d:#}");
    assert!(
        d["explanations"][0]["psnr_db"].is_null(),
        "rayscope's own mistake is exact: {d:#}"
    );
    assert_eq!(d["attribution"][0]["entity"], "GlassSphere", "{d:#}");

    rayscope()
        .args(["diagnose", "--stage", "2", "-f"])
        .arg(&scene)
        .arg(&wrong)
        .assert()
        .code(1)
        .stdout(
            predicate::str::contains("GlassSphere")
                .and(predicate::str::contains("your image matches 'no-fresnel'"))
                .and(predicate::str::contains(
                    "-o explained.png -w 48 -h 36 --stage 2 --mistake no-fresnel",
                )),
        );

    // Flags that name another size than the image's.
    rayscope()
        .args(["diagnose", "-w", "400", "-h", "400", "-f"])
        .arg(&scene)
        .arg(&right)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("48×36").and(predicate::str::contains("400×400")));
    // Not an image.
    rayscope()
        .args(["diagnose", "-f"])
        .arg(&scene)
        .arg(&scene)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("cannot read image"));
}

#[test]
fn the_manual_lists_every_mistake() {
    let readme =
        std::fs::read_to_string(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/mistakes.md"))
            .unwrap();
    for m in rayscope_core::Mistake::ALL {
        let i = m.info();
        let row = format!("| `{}` | {} | {} | {} |", i.name, i.wrong, i.looks, i.rubric);
        assert!(
            readme.contains(&row),
            "docs/mistakes.md's catalogue lacks or differs on:\n{row}"
        );
    }
}

/// `rayscope diagnose --json` of `image` against `scene` with `flags`, expecting exit `code`.
fn diagnosis(scene: &std::path::Path, image: &std::path::Path, flags: &[&str], code: i32) -> serde_json::Value {
    let out = rayscope()
        .args(["diagnose", "--json"])
        .args(flags)
        .arg("-f")
        .arg(scene)
        .arg(image)
        .assert()
        .code(code)
        .get_output()
        .stdout
        .clone();
    serde_json::from_slice(&out).expect("JSON")
}

#[test]
fn a_2021_image_matches_without_flags_and_names_its_edition() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = course.scene("sample_scene_2_2021.txt");
    let old = dir.path().join("2021.png");
    let now = dir.path().join("2022.png");
    render(&scene, &old, &["-w", "64", "-h", "64", "--stage", "2"]);
    render(&scene, &now, &["-w", "64", "-h", "64"]);

    // A 2021 student's Whitted image: glass colour ignored, as at stage 2.
    let d = diagnosis(&scene, &old, &[], 0);
    assert_eq!(d["matches"], true, "{d:#}");
    assert_eq!(d["edition"], "2021", "{d:#}");
    assert_eq!(d["edition_changed"], true, "{d:#}");
    rayscope()
        .args(["diagnose", "-f"])
        .arg(&scene)
        .arg(&old)
        .assert()
        .code(0)
        .stdout(
            predicate::str::contains("Your image matches rayscope's render")
                .and(predicate::str::contains("2021 edition"))
                .and(predicate::str::contains("add --edition 2021")),
        );
    // The same image, diagnosed as 2021 on purpose: no advice to change the flags.
    let d = diagnosis(&scene, &old, &["--edition", "2021"], 0);
    assert_eq!(
        (d["edition"].as_str(), d["edition_changed"].as_bool()),
        (Some("2021"), Some(false))
    );
    // An image with Beer's law is the 2022 edition's.
    let d = diagnosis(&scene, &now, &["--edition", "2021"], 0);
    assert_eq!(
        (d["edition"].as_str(), d["edition_changed"].as_bool()),
        (Some("2022"), Some(true)),
        "{d:#}"
    );
    // A scene whose glass is clear has one reading.
    let clear = course.scene("sample_scene_2.txt");
    let img = dir.path().join("clear.png");
    render(&clear, &img, &["-w", "64", "-h", "64"]);
    assert!(diagnosis(&clear, &img, &[], 0)["edition"].is_null());
}

#[test]
fn an_every_material_depth_limit_is_explained_not_matched() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scenes("whitted.txt");
    let img = dir.path().join("all3.png");
    let flags = ["-w", "48", "-h", "48", "-l"];
    render(
        &scene,
        &img,
        &[&flags[..], &["--depth-limit", "all", "--max-depth", "3"]].concat(),
    );
    let d = diagnosis(&scene, &img, &["-l", "--no-pairs"], 1);
    assert_eq!(d["matches"], false, "{d:#}");
    let e = &d["explanations"][0];
    assert_eq!(e["settings"][0], "--depth-limit all --max-depth 3", "{d:#}");
    assert!(e["psnr_db"].is_null(), "rayscope's own render is exact: {d:#}");
    assert!(
        e["flags"].as_str().unwrap().contains("--depth-limit all --max-depth 3"),
        "{d:#}"
    );
    assert!(e["summary"].as_str().unwrap().contains("every material"), "{d:#}");

    // Emissive light found by a sampled ray, through glass: at 64×64 the two limits of 3 differ
    // in a few pixels, few enough for the match rule's 1 % allowance, which must not hide them.
    let scene = common::scenes("beer.txt");
    let img = dir.path().join("beer3.png");
    let flags = ["-w", "64", "-h", "64", "--max-depth", "3"];
    render(&scene, &img, &[&flags[..], &["--depth-limit", "all"]].concat());
    let mirror_glass = render(&scene, &dir.path().join("mg3.png"), &flags);
    let (_, differing) = common::psnr(&common::rgb(&img), &mirror_glass);
    assert!(
        (1..41).contains(&differing),
        "under 1 % of the pixels differ: {differing}"
    );
    for flags in [&["--max-depth", "3"][..], &[]] {
        let d = diagnosis(&scene, &img, flags, 1);
        assert_eq!(d["matches"], false, "{flags:?}: {d:#}");
        let e = &d["explanations"][0];
        assert_eq!(e["settings"][0], "--depth-limit all --max-depth 3", "{flags:?}: {d:#}");
        assert!(e["psnr_db"].is_null(), "{flags:?}: {d:#}");
    }
    rayscope()
        .args(["diagnose", "--max-depth", "3", "-f"])
        .arg(&scene)
        .arg(&img)
        .assert()
        .code(1)
        .stdout(predicate::str::contains("for every material").and(predicate::str::contains("exactly")));
}
