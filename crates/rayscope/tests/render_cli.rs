//! The render command as a user runs it: flags, exit codes, messages, and files left alone on failure.

mod common;

use std::fs;

use common::{rayscope, render, scenes};
use predicates::prelude::*;
use rayscope_core::settings::{Ranges, Setting};

#[test]
fn renders_png_exr_and_ppm() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["png", "exr", "ppm"] {
        let out = dir.path().join(format!("a.{ext}"));
        rayscope()
            .args(["-w", "32", "-h", "24", "-f"])
            .arg(scenes("basic.txt"))
            .arg("-o")
            .arg(&out)
            .assert()
            .success()
            .stderr(predicate::str::contains("32×24"));
        let img = image::open(&out).unwrap();
        assert_eq!((img.width(), img.height()), (32, 24), "{ext}");
    }
    let names: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 3, "no temporary files left: {names:?}");
}

#[test]
fn output_is_identical_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("room.txt");
    let imgs: Vec<_> = ["1", "2", "3"]
        .iter()
        .map(|t| {
            render(
                &scene,
                &dir.path().join(format!("t{t}.png")),
                &["-w", "120", "-h", "90", "-x", "2", "--threads", t],
            )
        })
        .collect();
    assert_eq!(imgs[0], imgs[1]);
    assert_eq!(imgs[0], imgs[2]);
}

#[test]
fn non_square_image_uses_horizontal_fov() {
    // 400×200: the centre pixel column looks along +z; the left edge spans 30° horizontally.
    let out = rayscope()
        .args(["trace", "--json", "-w", "400", "-h", "200", "--pixel", "0,0", "-f"])
        .arg(scenes("basic.txt"))
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
    let d: Vec<f64> = v["nodes"][0]["direction"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let t = 30f64.to_radians().tan();
    let (x, y) = ((0.5 / 400.0 * 2.0 - 1.0) * t, (1.0 - 0.5 / 200.0 * 2.0) * t * 0.5);
    let len = (x * x + y * y + 1.0).sqrt();
    let want = [x / len, y / len, 1.0 / len];
    for i in 0..3 {
        assert!((d[i] - want[i]).abs() < 1e-5, "direction {d:?}, expected {want:?}");
    }
    // And the render itself has the requested shape.
    let dir = tempfile::tempdir().unwrap();
    let img = render(
        &scenes("basic.txt"),
        &dir.path().join("w.png"),
        &["-w", "400", "-h", "200"],
    );
    assert_eq!(img.dimensions(), (400, 200));
}

#[test]
fn vertical_fov_axis_widens_a_wide_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("basic.txt");
    let h = render(
        &scene,
        &dir.path().join("h.png"),
        &["-w", "200", "-h", "100", "--stage", "1"],
    );
    let v = render(
        &scene,
        &dir.path().join("v.png"),
        &["-w", "200", "-h", "100", "--stage", "1", "--fov-axis", "vertical"],
    );
    assert_ne!(
        h, v,
        "a vertical 60° FOV on a 2:1 image sees more than a horizontal one"
    );
}

fn assert_usage_error(args: &[&str], message: &str) {
    rayscope()
        .args(args)
        .assert()
        .code(2)
        .stderr(predicate::str::contains(message));
}

#[test]
fn invalid_flags_exit_with_2_and_say_why() {
    let scene = scenes("basic.txt");
    let s = scene.to_str().unwrap();
    assert_usage_error(&["-f", s, "-o", "x.png", "-w", "0"], "--width");
    assert_usage_error(&["-f", s, "-o", "x.png", "-h", "-5"], "--height");
    assert_usage_error(&["-f", s, "-o", "x.png", "-x", "0"], "--aa-mult");
    assert_usage_error(&["-f", s, "-o", "x.png", "-p", "1,2"], "expected three numbers");
    assert_usage_error(
        &["-f", s, "-o", "x.png", "-a", "0,0,0", "-n", "45"],
        "-a (camera axis) must not be (0, 0, 0)",
    );
    assert_usage_error(&["-f", s, "-o", "x.png", "-r", "-1"], "0 or more");
    // The core's words for the ranges, the ones the debugger's settings API answers with too.
    let core = |setting, v| Ranges::COMMAND_LINE.real(setting, v).unwrap_err();
    assert_usage_error(&["-f", s, "-o", "x.png", "--fov", "180"], &core(Setting::Fov, 180.0));
    assert_usage_error(&["-f", s, "-o", "x.png", "-t", "0"], &core(Setting::FocalLength, 0.0));
    assert_usage_error(
        &["-f", s, "-o", "x.png", "-q", "17"],
        &Ranges::COMMAND_LINE.whole(Setting::Quality, 17).unwrap_err(),
    );
    assert_usage_error(
        &["-f", s, "-o", "x.png", "-w", "100000", "-h", "100000"],
        "--allow-large",
    );
    assert_usage_error(&["-o", "x.png"], "--file");
    assert_usage_error(&["-f", s, "-o", "x.jpg"], "unsupported output format");
    assert!(!std::path::Path::new("x.png").exists() && !std::path::Path::new("x.jpg").exists());
}

#[test]
fn help_is_long_only_because_h_is_height() {
    rayscope()
        .arg("--help")
        .assert()
        .success()
        .stdout(predicate::str::contains("--aa-mult"));
}

#[test]
fn bad_scene_reports_file_line_column_and_leaves_existing_output_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("bad.txt");
    fs::write(
        &scene,
        "Material \"M\" Diffuse (1, 1, 1) 1\nSphere \"S\" (0, 0, 2) 0.5 \"Nope\"\n",
    )
    .unwrap();
    let out = dir.path().join("keep.png");
    fs::write(&out, b"precious").unwrap();
    rayscope()
        .arg("-f")
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(
            predicate::str::contains("bad.txt:2:")
                .and(predicate::str::contains("Nope"))
                .and(predicate::str::contains("^")),
        );
    assert_eq!(fs::read(&out).unwrap(), b"precious");
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        2,
        "no temporary file left behind"
    );
}

#[test]
fn missing_scene_and_missing_output_folder_fail_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    rayscope()
        .arg("-f")
        .arg(dir.path().join("nope.txt"))
        .arg("-o")
        .arg(dir.path().join("a.png"))
        .assert()
        .code(2)
        .stderr(predicate::str::contains("nope.txt"));
    rayscope()
        .arg("-f")
        .arg(scenes("basic.txt"))
        .arg("-o")
        .arg(dir.path().join("no/such/folder/a.png"))
        .assert()
        .code(2)
        .stderr(predicate::str::contains("does not exist"));
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn scene_warnings_are_printed_unless_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("w.txt");
    fs::write(&scene, "Material \"M\" Diffuse (1, 1, 1) 1 extra\n").unwrap();
    let out = dir.path().join("a.png");
    rayscope()
        .args(["-w", "8", "-h", "8", "-f"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .success()
        .stderr(predicate::str::contains("warning"));
    rayscope()
        .args(["-w", "8", "-h", "8", "--quiet", "-f"])
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .success()
        .stderr(predicate::str::is_empty());
}

#[test]
fn empty_scene_renders_black() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("empty.txt");
    fs::write(&scene, "").unwrap();
    let img = render(&scene, &dir.path().join("a.png"), &["-w", "4", "-h", "4"]);
    assert!(img.pixels().all(|p| p.0 == [0, 0, 0]));
}

#[test]
fn diff_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.png");
    let b = dir.path().join("b.png");
    render(&scenes("basic.txt"), &a, &["-w", "40", "-h", "40", "--stage", "1"]);
    render(&scenes("basic.txt"), &b, &["-w", "40", "-h", "40", "--stage", "2"]);
    rayscope()
        .arg("diff")
        .arg(&a)
        .arg(&a)
        .assert()
        .success()
        .stdout(predicate::str::contains("psnr_db=inf"));
    let heat = dir.path().join("heat.png");
    rayscope()
        .arg("diff")
        .arg(&a)
        .arg(&b)
        .arg("-o")
        .arg(&heat)
        .assert()
        .code(1);
    assert!(heat.exists());
    rayscope()
        .arg("diff")
        .arg(&a)
        .arg(&b)
        .args(["--tol", "1"])
        .assert()
        .success();
}

#[test]
fn ctrl_c_stops_promptly_writes_nothing_and_exits_130() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("big.png");
    fs::write(&out, b"precious").unwrap();
    let bin = assert_cmd::cargo::cargo_bin("rayscope");
    let mut child = std::process::Command::new(bin)
        .args(["-w", "3000", "-h", "3000", "-x", "8", "--quiet", "-f"])
        .arg(scenes("room.txt"))
        .arg("-o")
        .arg(&out)
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(700));
    let sent = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success());
    let start = std::time::Instant::now();
    let status = child.wait().unwrap();
    assert!(start.elapsed() < std::time::Duration::from_secs(10), "stopped promptly");
    assert_eq!(status.code(), Some(130));
    assert_eq!(fs::read(&out).unwrap(), b"precious", "the existing file is untouched");
    assert_eq!(
        fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary file left behind"
    );
}

/// What `bench rays` prints on one pass over the rays, on 2 threads.
fn bench_rays_text(args: &[&str], scene: &std::path::Path) -> String {
    let out = rayscope()
        .args(["bench", "rays", "--repeat", "1", "--threads", "2", "-f"])
        .arg(scene)
        .args(args)
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    String::from_utf8(out).unwrap()
}

/// (rays, hits) from the last line of `bench rays`: `rays=N hits=H seconds=S mrays_per_s=M threads=T`.
fn bench_rays(args: &[&str], scene: &std::path::Path) -> (u64, u64) {
    rays_and_hits(&bench_rays_text(args, scene))
}

/// (rays, hits) from `bench rays` output, after checking its last line's other fields.
fn rays_and_hits(text: &str) -> (u64, u64) {
    let last = text.lines().last().unwrap();
    let field = |k: &str| -> String {
        last.split_whitespace()
            .find_map(|f| f.strip_prefix(&format!("{k}=")).map(str::to_owned))
            .unwrap_or_else(|| panic!("no {k}= in {last:?}"))
    };
    assert!(field("seconds").parse::<f64>().unwrap() > 0.0);
    assert!(field("mrays_per_s").parse::<f64>().unwrap() > 0.0);
    assert_eq!(field("threads"), "2");
    (field("rays").parse().unwrap(), field("hits").parse().unwrap())
}

#[test]
fn bench_rays_counts_hits_the_same_in_every_mode() {
    // Our meshes (and the course's bunny, where its files are): the same hits in every mode.
    let course = rayscope_testkit::course_part();
    let own = scenes("obj.txt");
    let bunny = course.as_ref().map(|c| c.scene("sample_scene_obj.txt"));
    for scene in std::iter::once(&own).chain(&bunny) {
        let single = bench_rays(&["--primary", "67x45"], scene);
        let packets = bench_rays(&["--primary", "67x45", "--packets"], scene);
        assert_eq!(single.0, 67 * 45);
        assert_eq!(single, packets, "same rays, same hits");
        assert_eq!(single, bench_rays(&["--primary", "67x45", "--no-interleave"], scene));
        assert!(single.1 > 0);
    }

    // A scene with an error is reported as every command reports it: one `error:`, then where.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.txt");
    fs::write(&bad, "Material \"M\" Diffuse (1, 1) 1\n").unwrap();
    let out = rayscope()
        .args(["bench", "rays", "--primary", "4x4", "-f"])
        .arg(&bad)
        .assert()
        .code(2)
        .get_output()
        .stderr
        .clone();
    let err = String::from_utf8(out).unwrap();
    assert!(err.starts_with("error: expected 3 numbers"), "{err}");
    assert!(!err.contains("error: error:"), "{err}");
    assert!(err.contains(&format!("{}:1:22", bad.display())), "{err}");

    // A file that is not whole records is refused, and so is an empty one, which would time
    // nothing.
    let path = dir.path().join("rays.bin");
    let file = path.to_str().unwrap();
    fs::write(&path, [0u8; 25]).unwrap();
    rayscope()
        .args(["bench", "rays", "--rays-file", file, "-f"])
        .arg(&own)
        .assert()
        .failure()
        .stderr(predicate::str::contains("not a whole number of 24-byte ray records"));
    fs::write(&path, b"").unwrap();
    rayscope()
        .args(["bench", "rays", "--rays-file", file, "-f"])
        .arg(&own)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("holds no rays"));

    // The counts below are of the course's room around the bunny.
    let Some(scene) = bunny else { return };

    // A rays file: one ray into the room (hits), one away from it through the open front
    // (misses), and one more lane than a packet holds.
    let mut bytes = Vec::new();
    let mut records = vec![[0.0, 0.0, 0.0, 0.0, 0.0, 1.0f32], [0.0, 0.0, 0.0, 0.0, 0.0, -1.0]];
    records.extend((0..15).map(|i| [0.0, 0.0, 0.0, 0.01 * i as f32, 0.1, 1.0]));
    for r in &records {
        for v in r {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    fs::write(&path, &bytes).unwrap();
    assert_eq!(bench_rays(&["--rays-file", file], &scene), (17, 16));
    assert_eq!(bench_rays(&["--rays-file", file, "--packets"], &scene), (17, 16));
    assert_eq!(bench_rays(&["--rays-file", file, "--no-interleave"], &scene), (17, 16));

    // `--visits` adds a line on how far the walks went and leaves the last line as it was.
    // Two rays: one from behind the rear wall away from the room, one from its middle into it.
    let visits_path = dir.path().join("visits.bin");
    let visit_bytes: Vec<u8> = [[0.0, 0.0, -0.5, 0.0, 0.0, -1.0f32], [0.0, 0.0, 1.5, 0.0, 0.0, 1.0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    fs::write(&visits_path, visit_bytes).unwrap();
    let visits_file = visits_path.to_str().unwrap();
    let text = bench_rays_text(&["--rays-file", visits_file, "--visits"], &scene);
    assert_eq!(rays_and_hits(&text), (2, 1));
    let line = text.lines().find(|l| l.starts_with("visits: ")).expect("a visits line");
    let means: Vec<f64> = line.split([' ', ',']).filter_map(|w| w.parse().ok()).collect();
    // The ray away from the room tests the floor and the roof (one each) and the root's boxes,
    // and enters none of them; the ray into the room goes down the tree to a leaf.
    assert_eq!(means.len(), 2, "{line}");
    assert_eq!(means[1], 3.0, "{line}");
    assert!(means[0] >= 5.0, "{line}");
}

/// A stage-2 scene whose glass has a colour, as the 2021 course's scenes and many students'
/// final scenes give it.
const TINTED_GLASS: &str = "Material \"Glass\" Refractive (1, 1, 1) 1.4\nMaterial \"Red\" Diffuse (1, 0.2, 0.2) 1\nMaterial \"White\" Diffuse (1, 1, 1) 1\nPlane \"Floor\" (0, -1, 0) (0, 1, 0) \"White\"\nPlane \"Back\" (0, 0, 6) (0, 0, -1) \"Red\"\nSphere \"Ball\" (0, 0, 3) 0.8 \"Glass\"\nPointLight \"L\" (0, 3, 1) (1, 1, 1)\n";

#[test]
fn coloured_glass_follows_the_edition_and_the_first_line_says_which() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("tinted.txt");
    fs::write(&scene, TINTED_GLASS).unwrap();
    let run = |name: &str, flags: &[&str]| -> (String, image::RgbImage) {
        let out = dir.path().join(name);
        let o = rayscope()
            .args(["-w", "32", "-h", "32", "-f"])
            .arg(&scene)
            .arg("-o")
            .arg(&out)
            .args(flags)
            .assert()
            .success()
            .get_output()
            .clone();
        assert!(o.stdout.is_empty(), "stdout stays empty");
        (String::from_utf8(o.stderr).unwrap(), common::rgb(&out))
    };
    let (now, beer) = run("2022.png", &[]);
    let first = now.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("note: glass 'Glass'") && first.contains("Beer") && first.contains("--edition 2021"),
        "{now}"
    );
    let (then, clear) = run("2021.png", &["--edition", "2021"]);
    let first = then.lines().next().unwrap_or_default();
    assert!(
        first.contains("plays no part") && first.contains("--edition 2022"),
        "{then}"
    );
    let (quiet, stage2) = run("s2.png", &["--stage", "2", "--quiet"]);
    assert_eq!(quiet, "");
    assert_eq!(clear, stage2, "in 2021 the glass colour plays no part, as at stage 2");
    assert!(common::psnr(&beer, &clear).1 > 0, "in 2022 the colour absorbs");

    // Clear glass, or tinted glass in a scene that is stage 3 anyway: no doubt, no note.
    fs::write(&scene, TINTED_GLASS.replace("(1, 1, 1) 1.4", "(0, 0, 0) 1.4")).unwrap();
    assert!(!run("c.png", &[]).0.contains("note:"));
    fs::write(&scene, TINTED_GLASS).unwrap();
    assert!(!run("l.png", &["-l"]).0.contains("note:"));
}

#[test]
fn depth_limit_all_stops_every_ray_past_the_depth() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("whitted.txt");
    let flags = ["-w", "32", "-h", "32", "--max-depth", "3"];
    let img = |name: &str, extra: &[&str]| render(&scene, &dir.path().join(name), &[&flags[..], extra].concat());
    // Mirrors and glass alone: stopping them at depth 3, or every ray past depth 3, is one image.
    assert_eq!(img("mg.png", &[]), img("all.png", &["--depth-limit", "all"]));
    // With -l the diffuse bounces count too, and past depth 3 they bring nothing.
    let mg = img("mgl.png", &["-l"]);
    let all = img("alll.png", &["-l", "--depth-limit", "all"]);
    assert!(common::psnr(&mg, &all).1 > 0, "-l bounces past depth 3 are cut");
    let light = |i: &image::RgbImage| i.as_raw().iter().map(|&c| u64::from(c)).sum::<u64>();
    assert!(light(&all) < light(&mg), "the cut paths' light is missing");
}
