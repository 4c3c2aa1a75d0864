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
    // The same change as data, in the debugger's settings keys, for a front end to apply.
    assert_eq!(
        e["patch"],
        serde_json::json!({"max_depth": 3, "depth_limit": "all"}),
        "{d:#}"
    );
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

/// `rayscope diagnose` of `image` as text and as JSON (single mistakes only, to stay quick),
/// expecting exit `code` from both.
fn diagnosed(
    scene: &std::path::Path,
    image: &std::path::Path,
    flags: &[&str],
    code: i32,
) -> (String, serde_json::Value) {
    let flags = [flags, &["--no-pairs"]].concat();
    let out = rayscope()
        .arg("diagnose")
        .args(&flags)
        .arg("-f")
        .arg(scene)
        .arg(image)
        .assert()
        .code(code)
        .get_output()
        .stdout
        .clone();
    let text = String::from_utf8(out).expect("UTF-8");
    (text, diagnosis(scene, image, &flags, code))
}

/// The codes of `d`'s plain findings, in its order.
fn obvious_codes(d: &serde_json::Value) -> Vec<String> {
    d["obvious"]
        .as_array()
        .expect("an obvious array")
        .iter()
        .map(|o| o["code"].as_str().unwrap().to_string())
        .collect()
}

/// rayscope's correct render of the whitted scene at 64×48, saved as `right.png` in `dir`.
fn correct_64x48(dir: &std::path::Path) -> (std::path::PathBuf, image::RgbImage) {
    let scene = common::scenes("whitted.txt");
    let img = render(
        &scene,
        &dir.join("right.png"),
        &["-w", "64", "-h", "48", "--stage", "2"],
    );
    (scene, img)
}

#[test]
fn a_constant_picture_is_said_first_and_explained_by_no_near_miss() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    let (text, d) = diagnosed(&scene, &dir.path().join("right.png"), &["--stage", "2"], 0);
    assert!(obvious_codes(&d).is_empty(), "{d:#}");
    assert!(text.starts_with("Your image matches rayscope's render"), "{text}");

    for (name, colour, code, words) in [
        (
            "black.png",
            [0u8, 0, 0],
            "black",
            "Your image is entirely black: every byte is 0 (64×48 pixels)",
        ),
        (
            "white.png",
            [255, 255, 255],
            "white",
            "Your image is entirely white: every byte is 255",
        ),
        (
            "grey.png",
            [128, 128, 128],
            "constant",
            "one constant colour: every pixel is (128, 128, 128)",
        ),
    ] {
        let path = dir.path().join(name);
        image::RgbImage::from_pixel(64, 48, image::Rgb(colour))
            .save(&path)
            .unwrap();
        let (text, d) = diagnosed(&scene, &path, &["--stage", "2"], 1);
        let first = text.lines().next().unwrap();
        assert!(first.contains(words), "{name}: {text}");
        assert_eq!(obvious_codes(&d), [code], "{name}: {d:#}");
        let others = right.pixels().filter(|p| p.0 != colour).count();
        assert_eq!(
            d["obvious"][0]["numbers"]["rayscope_other_pixels"], others as f64,
            "{d:#}"
        );
        assert!(
            first.contains(&format!("while {others} of rayscope's 3072 pixels")),
            "{first}"
        );
        // Only a render identical pixel for pixel is this picture's match, and the text calls
        // it a lead: many mistakes give a one-coloured picture.
        for e in d["explanations"].as_array().unwrap() {
            assert_eq!(e["matches"].as_bool(), Some(e["psnr_db"].is_null()), "{d:#}");
        }
        assert!(
            !text.contains("exactly") && !text.contains("your image matches"),
            "{text}"
        );
        if code == "black" {
            // Here a shadow ray blocked beyond its light leaves every pixel black.
            assert!(
                text.contains("Many mistakes give a picture that is black everywhere")
                    && text.contains("'shadow-past-light' (")
                    && text.contains("renders it too, black everywhere (yours was 7.3 dB from rayscope's render)"),
                "{text}"
            );
        }
    }

    // In the course's scene 1 only a plane test that accepts hits behind the ray renders black
    // everywhere (the picture the tester saw): it is offered as one way to get this
    // picture, a lead the text does not call the cause.
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = course.scene("sample_scene_1.txt");
    let black = dir.path().join("black.png");
    let (text, d) = diagnosed(&scene, &black, &[], 1);
    assert!(
        text.starts_with("Your image is entirely black: every byte is 0 (64×48 pixels)"),
        "{text}"
    );
    let names: Vec<&str> = (d["explanations"].as_array().unwrap().iter())
        .flat_map(|e| e["mistakes"].as_array().unwrap())
        .filter_map(|m| m.as_str())
        .collect();
    assert_eq!(names, ["plane-hits-behind"], "{d:#}");
    assert!(
        text.contains("Many mistakes give a picture that is black everywhere")
            && text.contains("'plane-hits-behind' (")
            && text.contains("renders it too, black everywhere")
            && text.contains("one way to get this picture"),
        "{text}"
    );
    assert!(!text.contains("your image matches"), "{text}");
}

#[test]
fn a_turned_picture_is_said_first() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    let flipped = image::imageops::flip_vertical(&right);
    let mirrored = image::imageops::flip_horizontal(&right);
    let transposed = image::RgbImage::from_fn(48, 64, |x, y| *right.get_pixel(y, x));
    let half_turn = image::imageops::rotate180(&right);
    let clockwise = image::imageops::rotate90(&right);
    let anticlockwise = image::imageops::rotate270(&right);
    for (name, img, flags, code, words) in [
        (
            "flipped.png",
            &flipped,
            &[][..],
            "upside-down",
            "Your image is upside down",
        ),
        (
            "mirrored.png",
            &mirrored,
            &[],
            "mirrored",
            "Your image is mirrored left to right",
        ),
        // Saved 48×64, judged at its own size (no -w/-h) and at the size the flags name.
        (
            "transposed.png",
            &transposed,
            &[],
            "transposed",
            "Your image has rows and columns exchanged",
        ),
        (
            "transposed.png",
            &transposed,
            &["-w", "64", "-h", "48"],
            "transposed",
            "Your image is 48×64 but the flags ask for 64×48",
        ),
        (
            "half-turn.png",
            &half_turn,
            &[],
            "rotated-180",
            "Your image is turned 180° (upside down and mirrored left to right)",
        ),
        (
            "clockwise.png",
            &clockwise,
            &["-w", "64", "-h", "48"],
            "rotated-clockwise",
            "Your image is 48×64 but the flags ask for 64×48. Your image is turned 90° clockwise",
        ),
        (
            "anticlockwise.png",
            &anticlockwise,
            &[],
            "rotated-anticlockwise",
            "Your image is turned 90° anticlockwise",
        ),
    ] {
        let path = dir.path().join(name);
        img.save(&path).unwrap();
        let flags = [flags, &["--stage", "2"]].concat();
        let (text, d) = diagnosed(&scene, &path, &flags, 1);
        assert!(
            text.lines().next().unwrap().starts_with(words),
            "{name} {flags:?}: {text}"
        );
        assert_eq!(obvious_codes(&d), [code], "{name} {flags:?}: {d:#}");
        assert!(
            d["obvious"][0]["numbers"]["psnr_db_turned"].is_null(),
            "turned back it is rayscope's render: {d:#}"
        );
    }
    // Upside down is also the catalogue's mistake, found below the first line.
    let (text, _) = diagnosed(&scene, &dir.path().join("flipped.png"), &["--stage", "2"], 1);
    assert!(text.contains("your image matches 'image-flipped'"), "{text}");
    // Mirrored and transposed images are judged turned back: nothing else differs, yet as
    // they stand they are wrong (exit 1).
    for name in [
        "mirrored.png",
        "transposed.png",
        "half-turn.png",
        "clockwise.png",
        "anticlockwise.png",
    ] {
        let (text, d) = diagnosed(&scene, &dir.path().join(name), &["--stage", "2"], 1);
        assert_eq!(
            (d["matches"].as_bool(), d["differing_pixels"].as_u64()),
            (Some(false), Some(0)),
            "{name}: {d:#}"
        );
        assert!(
            text.lines()
                .nth(1)
                .unwrap()
                .starts_with("Turned back, your image matches rayscope's render"),
            "{name}: {text}"
        );
    }
}

/// Channels written in another order (a bitmap's BGR memory, a slip in a colour constructor)
/// are said first, with the order; the rest is judged with the channels put back.
#[test]
fn channels_in_another_order_are_said_first() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    for (name, order, words) in [
        (
            "bgr.png",
            [2usize, 1, 0],
            "Your image's colour channels are in the order blue, green, red: red and blue exchanged",
        ),
        (
            "gbr.png",
            [1, 2, 0],
            "Your image's colour channels are in the order green, blue, red: your red byte holds green, your green byte holds blue, your blue byte holds red",
        ),
    ] {
        let swapped = image::RgbImage::from_fn(64, 48, |x, y| {
            let p = right.get_pixel(x, y).0;
            image::Rgb([p[order[0]], p[order[1]], p[order[2]]])
        });
        let path = dir.path().join(name);
        swapped.save(&path).unwrap();
        let (text, d) = diagnosed(&scene, &path, &["--stage", "2"], 1);
        let mut lines = text.lines();
        assert!(lines.next().unwrap().starts_with(words), "{name}: {text}");
        assert!(
            lines
                .next()
                .unwrap()
                .starts_with("With its channels in order, your image matches rayscope's render: identical"),
            "{name}: {text}"
        );
        assert_eq!(obvious_codes(&d), ["channels"], "{name}: {d:#}");
        assert_eq!(d["obvious"][0]["turned_back"], true, "{d:#}");
    }
}

/// Channels left 0 in every pixel (a writer that fills only red) are said first, naming which.
#[test]
fn channels_left_empty_are_said_first() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    for (name, keep, words) in [
        (
            "red.png",
            [true, false, false],
            "Your image's green and blue bytes are 0 in every pixel, while rayscope's are not in ",
        ),
        (
            "no-blue.png",
            [true, true, false],
            "Your image's blue byte is 0 in every pixel, while rayscope's is not in ",
        ),
    ] {
        let only = image::RgbImage::from_fn(64, 48, |x, y| {
            let p = right.get_pixel(x, y).0;
            image::Rgb([0, 1, 2].map(|c| if keep[c] { p[c] } else { 0 }))
        });
        let path = dir.path().join(name);
        only.save(&path).unwrap();
        let (text, d) = diagnosed(&scene, &path, &["--stage", "2"], 1);
        let first = text.lines().next().unwrap();
        assert!(first.starts_with(words), "{name}: {text}");
        assert!(first.contains("Write all three channels."), "{name}: {text}");
        assert_eq!(obvious_codes(&d), ["channels-missing"], "{name}: {d:#}");
    }
}

#[test]
fn a_picture_of_another_size_names_both_sizes_and_the_flags() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    let half = dir.path().join("half.png");
    image::imageops::resize(&right, 32, 24, image::imageops::FilterType::Triangle)
        .save(&half)
        .unwrap();
    rayscope()
        .args(["diagnose", "--stage", "2", "-w", "64", "-h", "48", "-f"])
        .arg(&scene)
        .arg(&half)
        .assert()
        .code(2)
        .stderr(
            predicate::str::contains("your image is 32×24, the scene was rendered at 64×48")
                .and(predicate::str::contains("pass -w 32 -h 24"))
                .and(predicate::str::contains("the aspect is the same")),
        );
    let square = dir.path().join("square.png");
    image::imageops::crop_imm(&right, 0, 0, 48, 48)
        .to_image()
        .save(&square)
        .unwrap();
    rayscope()
        .args(["diagnose", "--stage", "2", "-w", "64", "-h", "48", "-f"])
        .arg(&scene)
        .arg(&square)
        .assert()
        .code(2)
        .stderr(predicate::str::contains(
            "the aspect differs too: 1.000 (width / height) against 1.333",
        ));
}

#[test]
fn an_alpha_channel_and_gamma_are_said_first() {
    let dir = tempfile::tempdir().unwrap();
    let (scene, right) = correct_64x48(dir.path());
    // Right colours, a 10×8 block of them transparent: the RGB matches, the alpha is said.
    let rgba = image::RgbaImage::from_fn(64, 48, |x, y| {
        let [r, g, b] = right.get_pixel(x, y).0;
        image::Rgba([r, g, b, if x < 10 && y < 8 { 0 } else { 255 }])
    });
    let path = dir.path().join("alpha.png");
    rgba.save(&path).unwrap();
    let (text, d) = diagnosed(&scene, &path, &["--stage", "2"], 0);
    assert!(
        text.lines().next().unwrap().starts_with(
            "Your PNG has an alpha channel that hides colour: 80 of its 3072 pixels (2.6 %) are not opaque, 80 of them fully transparent"
        ),
        "{text}"
    );
    assert!(text.lines().nth(1).unwrap().starts_with("Your image matches"), "{text}");
    assert_eq!(obvious_codes(&d), ["alpha"], "{d:#}");
    assert_eq!(d["obvious"][0]["numbers"]["transparent_pixels"], 80.0, "{d:#}");

    // Saved with gamma: each byte v written as 255·(v/255)^(1/2.2).
    let mut encoded = right.clone();
    for p in encoded.pixels_mut() {
        for c in &mut p.0 {
            *c = (255.0 * (f64::from(*c) / 255.0).powf(1.0 / 2.2)).round() as u8;
        }
    }
    let path = dir.path().join("gamma.png");
    encoded.save(&path).unwrap();
    let (text, d) = diagnosed(&scene, &path, &["--stage", "2"], 1);
    assert!(
        text.lines()
            .next()
            .unwrap()
            .starts_with("Your image looks saved with gamma"),
        "{text}"
    );
    assert_eq!(obvious_codes(&d), ["gamma"], "{d:#}");
}
