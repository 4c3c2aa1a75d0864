//! `rayscope trace` showing every decision, `rayscope diff`'s heat map scale and attribution,
//! and `rayscope view --normals`, as a user runs them.

mod common;

use common::{rayscope, render, rgb, scenes};
use predicates::prelude::*;

fn trace(args: &[&str]) -> String {
    let out = rayscope()
        .arg("trace")
        .arg("-f")
        .arg(scenes("whitted.txt"))
        .args(args)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    String::from_utf8(out).expect("utf-8")
}

#[test]
fn trace_text_shows_blockers_with_distance_point_and_face() {
    // A mirror's view of the floor, whose shadow ray to the fill light the glass ball blocks.
    let t = trace(&["--pixel", "139,280"]);
    assert!(
        t.contains("to light 'Fill' (searched up to t=4.1939): blocked by 'GlassBall' (Refractive 'Glass') at t=0.8844 point (0.0670, -0.4728, 2.8233) normal (-0.8511, 0.1716, 0.4961) front face"),
        "{t}"
    );
    // Shadow rays carry the depth of the ray whose hit they light.
    assert!(
        t.contains("#3 shadow, depth 1, N·L 0.5961: from P + 3.308e-5·n = (-0.4496, -1.0000, 3.3105)"),
        "{t}"
    );
}

#[test]
fn trace_text_shows_offsets_and_glass_decisions() {
    let t = trace(&["--pixel", "316,273"]);
    assert!(
        t.contains("glass: entering, n₁ 1.0000 → n₂ 1.5000, cos θᵢ 0.4448, cos θₜ 0.8022, Fresnel reflectance 0.1101"),
        "{t}"
    );
    assert!(
        t.contains("glass: leaving, n₁ 1.5000 → n₂ 1.0000, cos θᵢ 0.8022"),
        "{t}"
    );
    assert!(t.contains("reflection: traced as #1, weight 0.1101"), "{t}");
    // Reflected rays start above the surface, refracted ones below it.
    assert!(t.contains("#1 reflection, depth 1, weight 0.1101: from P + "), "{t}");
    assert!(t.contains(" refraction, depth 1, weight 0.8899: from P − "), "{t}");
    // A branch too weak to matter is named, not silently missing.
    assert!(
        t.contains("reflection: pruned, not traced: weight 0.1099 makes the path's weight"),
        "{t}"
    );
    assert!(t.contains("would change an 8-bit value of the pixel"), "{t}");
}

#[test]
fn trace_text_shows_total_internal_reflection() {
    let cube = rayscope_testkit::workspace().join("crates/rayscope_check/tests/scenes/glass_cube.txt");
    let mut found = false;
    // Rays through the cube's front face that meet its right side from inside.
    for x in (220..260).step_by(4) {
        let out = rayscope()
            .arg("trace")
            .arg("-f")
            .arg(&cube)
            .args(["-w", "300", "-h", "300", "--pixel", &format!("{x},190")])
            .assert()
            .success()
            .get_output()
            .stdout
            .clone();
        let t = String::from_utf8(out).unwrap();
        if t.contains("total internal reflection (n₁/n₂·sin θᵢ = ") {
            assert!(t.contains("refraction: none (total internal reflection)"), "{t}");
            found = true;
            break;
        }
    }
    assert!(found, "no pixel of the row showed total internal reflection");
}

#[test]
fn trace_precision_sets_the_digits() {
    let four = trace(&["--pixel", "139,280"]);
    assert!(four.contains("dir (-0.1677, -0.2231, 0.9603)"), "{four}");
    let seven = trace(&["--pixel", "139,280", "--precision", "7"]);
    assert!(seven.contains("dir (-0.1677062, -0.2231463, 0.9602501)"), "{seven}");
    rayscope()
        .args(["trace", "--pixel", "1,1", "--precision", "0", "-f"])
        .arg(scenes("whitted.txt"))
        .assert()
        .code(2)
        .stderr(predicate::str::contains("precision"));
}

#[test]
fn trace_json_has_blockers_offsets_glass_and_full_precision() {
    let out = trace(&["--pixel", "316,273", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let nodes = v["nodes"].as_array().expect("nodes");
    let mut pruned = 0;
    for n in nodes {
        if let Some(p) = n["parent"].as_u64() {
            // The origin is exactly the parent's hit point plus the offset: both at full precision.
            let point = &nodes[p as usize]["hit"]["point"];
            for i in 0..3 {
                let sum = point[i].as_f64().unwrap() + n["offset"][i].as_f64().unwrap();
                assert_eq!(sum as f32, n["origin"][i].as_f64().unwrap() as f32);
            }
            assert!(n["offset_along_normal"].is_f64());
        }
        if let Some(g) = n["glass"].as_object() {
            for k in [
                "entering",
                "n1",
                "n2",
                "cos_i",
                "cos_t",
                "tir",
                "reflectance",
                "prune_below",
            ] {
                assert!(g.contains_key(k), "glass.{k}");
            }
            for b in [&g["reflected"], &g["refracted"]] {
                pruned += usize::from(b["fate"] == "pruned");
            }
        }
    }
    assert!(pruned > 0);
    let out = trace(&["--pixel", "139,280", "--json"]);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let b = v["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["blocked_by"] == "GlassBall")
        .expect("a blocked shadow ray");
    assert_eq!(b["blocker"]["entity_name"], "GlassBall");
    assert_eq!(b["blocker"]["front_face"], true);
    let t = b["blocker"]["t"].as_f64().unwrap();
    assert!((t - 0.8844).abs() < 1e-4 && t.to_string().len() > 8, "{t}");
}

#[test]
fn diff_heat_map_is_graded_and_states_its_scale() {
    let dir = tempfile::tempdir().unwrap();
    // Errors of 1, 2 and 3 levels: the old heat map showed them all as one dark blue.
    let a = image::RgbImage::from_pixel(64, 40, image::Rgb([100, 100, 100]));
    let mut b = a.clone();
    for y in 0..40 {
        for x in 0..48 {
            b.put_pixel(x, y, image::Rgb([100, 100 + 1 + (x / 16) as u8, 100]));
        }
    }
    let (pa, pb) = (dir.path().join("a.png"), dir.path().join("b.png"));
    a.save(&pa).unwrap();
    b.save(&pb).unwrap();
    let heat = dir.path().join("heat.png");
    rayscope()
        .arg("diff")
        .arg(&pa)
        .arg(&pb)
        .arg("-o")
        .arg(&heat)
        .assert()
        .code(1)
        .stdout(predicate::str::contains(
            "full brightness at 3 levels or more (chosen from the images; 0 pixels beyond)",
        ));
    let h = rgb(&heat);
    assert_eq!(h.dimensions().0, 64);
    assert!(h.dimensions().1 > 40, "a scale bar under the image");
    let g: Vec<[u8; 3]> = [0, 16, 32, 48].iter().map(|&x| h.get_pixel(x, 10).0).collect();
    assert_eq!(g, [[0, 85, 0], [0, 170, 0], [0, 255, 0], [0, 0, 0]]);
    // The bar runs from black to white.
    let bar_y = 40 + 6;
    assert!(h.get_pixel(4, bar_y).0[0] < 10 && h.get_pixel(58, bar_y).0[0] > 245);

    // A chosen range, and no bar.
    rayscope()
        .arg("diff")
        .arg(&pa)
        .arg(&pb)
        .arg("-o")
        .arg(&heat)
        .args(["--range", "6", "--no-legend"])
        .assert()
        .code(1)
        .stdout(predicate::str::contains(
            "full brightness at 6 levels or more (--range; 0 pixels beyond)",
        ));
    let h = rgb(&heat);
    assert_eq!(h.dimensions(), (64, 40));
    assert_eq!(h.get_pixel(0, 0).0, [0, 43, 0]);
}

#[test]
fn diff_with_a_scene_says_which_entities_differ() {
    let dir = tempfile::tempdir().unwrap();
    let good = dir.path().join("good.png");
    let bad = dir.path().join("bad.png");
    let flags = ["-w", "80", "-h", "80"];
    render(&scenes("whitted.txt"), &good, &flags);
    render(
        &scenes("whitted.txt"),
        &bad,
        &["-w", "80", "-h", "80", "--mistake", "refraction-no-index-swap"],
    );
    let out = rayscope()
        .arg("diff")
        .arg(&good)
        .arg(&bad)
        .arg("--scene")
        .arg(scenes("whitted.txt"))
        .assert()
        .code(1)
        .get_output()
        .stdout
        .clone();
    let t = String::from_utf8(out).unwrap();
    let mut lines = t.lines().skip_while(|l| !l.starts_with("Where the "));
    assert!(lines.next().is_some(), "{t}");
    let first = lines.next().expect("a share");
    assert!(first.contains('%') && first.contains("GlassBall"), "{t}");
    // The size comes from the images; a wrong one is refused, as are render flags without a scene.
    rayscope()
        .arg("diff")
        .arg(&good)
        .arg(&bad)
        .arg("--scene")
        .arg(scenes("whitted.txt"))
        .args(["-w", "40"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("the images are 80×80"));
    rayscope()
        .arg("diff")
        .arg(&good)
        .arg(&bad)
        .args(["-x", "2"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("--scene"));
}

#[test]
fn view_draws_the_normals_of_an_entity() {
    let dir = tempfile::tempdir().unwrap();
    let view = |extra: &[&str], name: &str| {
        let out = dir.path().join(name);
        rayscope()
            .arg("view")
            .arg("-f")
            .arg(scenes("whitted.txt"))
            .arg("-o")
            .arg(&out)
            .args(["--image", "none", "--rays", "none", "--quiet", "-w", "20", "-h", "20"])
            .args(["--view-width", "320", "--view-height", "240"])
            .args(extra)
            .assert()
            .success();
        rgb(&out)
    };
    let yellow = |img: &image::RgbImage| {
        img.pixels()
            .filter(|p| p.0[0] > 200 && p.0[1] > 180 && p.0[2] < 90)
            .count()
    };
    let plain = view(&[], "plain.png");
    let tri = view(&["--normals", "PyrA"], "tri.png");
    let ball = view(&["--normals", "GlassBall"], "ball.png");
    assert!(
        yellow(&tri) > yellow(&plain) + 20,
        "{} vs {}",
        yellow(&tri),
        yellow(&plain)
    );
    assert!(yellow(&ball) > yellow(&tri), "a sphere gets arrows all round");
    rayscope()
        .arg("view")
        .arg("-f")
        .arg(scenes("whitted.txt"))
        .arg("-o")
        .arg(dir.path().join("x.png"))
        .args(["--normals", "Nope"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("no entity 'Nope'"));
}
