//! Farm renders: parts (`--part K/N`) merged by `rayscope merge` give the very bytes of one
//! render; the merge refuses parts of other renders and names missing or repeated parts;
//! animations (`--frames`) give numbered frames that parts reproduce too.

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use common::{rayscope, scenes};
use predicates::prelude::*;

/// Renders `scene` with `flags` into `out` (quietly) and returns the file's bytes.
fn full(scene: &Path, out: &Path, flags: &[&str]) -> Vec<u8> {
    common::render_to(scene, out, flags);
    fs::read(out).unwrap()
}

/// Renders the `n` parts of `scene` into `dir` and returns their paths.
fn parts(scene: &Path, dir: &Path, n: u32, flags: &[&str]) -> Vec<PathBuf> {
    (0..n)
        .map(|k| {
            let p = dir.join(format!("part_{k}_of_{n}.exr"));
            rayscope()
                .arg("-f")
                .arg(scene)
                .arg("-o")
                .arg(&p)
                .args(["--quiet", "--part", &format!("{k}/{n}")])
                .args(flags)
                .assert()
                .success();
            p
        })
        .collect()
}

/// Merges `parts` into `out` and returns the file's bytes.
fn merge(parts: &[PathBuf], out: &Path) -> Vec<u8> {
    rayscope()
        .arg("merge")
        .args(parts)
        .arg("-o")
        .arg(out)
        .assert()
        .success()
        .stderr(predicate::str::contains("merged"));
    fs::read(out).unwrap()
}

/// Checks that the parts of `scene`, for each part count, merge into the bytes of one render,
/// in PNG and in EXR.
fn merges_bit_for_bit(scene: &Path, flags: &[&str], counts: &[u32]) {
    let dir = tempfile::tempdir().unwrap();
    let png = full(scene, &dir.path().join("one.png"), flags);
    let exr = full(scene, &dir.path().join("one.exr"), flags);
    for &n in counts {
        let sub = dir.path().join(format!("n{n}"));
        fs::create_dir(&sub).unwrap();
        let mut p = parts(scene, &sub, n, flags);
        // The order the parts are given in does not matter.
        p.reverse();
        assert!(
            merge(&p, &sub.join("merged.png")) == png,
            "{} {flags:?}: {n} parts merged to PNG differ from one render",
            scene.display()
        );
        assert!(
            merge(&p, &sub.join("merged.exr")) == exr,
            "{} {flags:?}: {n} parts merged to EXR differ from one render",
            scene.display()
        );
    }
}

#[test]
fn parts_of_our_scenes_merge_into_the_bytes_of_one_render() {
    // Path tracing at -q 2 (noise that depends on every sample's number), glossy coats, OBJ
    // meshes, an image whose sides are not whole tiles, and more parts than tile columns.
    merges_bit_for_bit(
        &scenes("glossy.txt"),
        &["-w", "75", "-h", "50", "-x", "2", "-q", "2", "-l"],
        &[1, 3, 8],
    );
    merges_bit_for_bit(&scenes("obj.txt"), &["-w", "72", "-h", "40", "--stage", "2"], &[2, 12]);
}

#[test]
fn parts_of_the_course_scenes_merge_into_the_bytes_of_one_render() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    merges_bit_for_bit(
        &course.scene("sample_scene_2.txt"),
        &["-w", "64", "-h", "64", "-x", "2"],
        &[3],
    );
    merges_bit_for_bit(
        &course.scene("sample_scene_obj.txt"),
        &["-w", "48", "-h", "48", "-q", "1", "-l"],
        &[4],
    );
}

#[test]
fn a_debug_channel_and_a_mistake_merge_too() {
    merges_bit_for_bit(
        &scenes("whitted.txt"),
        &["-w", "40", "-h", "30", "--aov", "depth"],
        &[3],
    );
    merges_bit_for_bit(
        &scenes("whitted.txt"),
        &["-w", "40", "-h", "30", "--mistake", "gamma"],
        &[2],
    );
}

#[test]
fn missing_parts_are_named_and_allow_missing_writes_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("whitted.txt");
    let flags = ["-w", "64", "-h", "48"];
    let p = parts(&scene, dir.path(), 5, &flags);
    let out = dir.path().join("merged.png");
    fs::write(&out, b"the user's own file").unwrap();
    let given = [p[0].clone(), p[2].clone(), p[3].clone()];
    rayscope()
        .arg("merge")
        .args(&given)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("2 of 5 parts are missing: 1, 4"))
        .stderr(predicate::str::contains("--allow-missing"));
    assert_eq!(
        fs::read(&out).unwrap(),
        b"the user's own file",
        "a failed merge leaves the output alone"
    );

    rayscope()
        .arg("merge")
        .args(&given)
        .arg("-o")
        .arg(&out)
        .arg("--allow-missing")
        .assert()
        .success()
        .stderr(predicate::str::contains("parts 1, 4 of 5 are missing"))
        .stderr(predicate::str::contains("tiles are black: x "));
    let merged = common::rgb(&out);
    let whole = common::rgb(&dir.path().join("whole.png").tap(|o| {
        full(&scene, o, &flags);
    }));
    // Every tile of the given parts is the render's; the others are black.
    let given_tiles: Vec<u32> = [0u32, 2, 3]
        .iter()
        .flat_map(|&k| rayscope_core::farm::deal(4, 3, rayscope_core::farm::PartSpec { index: k, count: 5 }))
        .collect();
    for y in 0..48 {
        for x in 0..64 {
            let t = y / 16 * 4 + x / 16;
            let want = if given_tiles.contains(&t) {
                *whole.get_pixel(x, y)
            } else {
                image::Rgb([0, 0, 0])
            };
            assert_eq!(*merged.get_pixel(x, y), want, "pixel ({x}, {y}) of tile {t}");
        }
    }
}

/// `tap` for building a path inline.
trait Tap: Sized {
    fn tap(self, f: impl FnOnce(&Self)) -> Self {
        f(&self);
        self
    }
}
impl Tap for PathBuf {}

#[test]
fn a_part_given_twice_or_parts_of_other_renders_do_not_merge() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("whitted.txt");
    let flags = ["-w", "48", "-h", "32"];
    let p = parts(&scene, dir.path(), 2, &flags);
    let out = dir.path().join("m.png");
    let copy = dir.path().join("copy_of_part_0.exr");
    fs::copy(&p[0], &copy).unwrap();
    rayscope()
        .arg("merge")
        .args([&p[0], &p[1], &copy])
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("part 0 of 2 is given twice"))
        .stderr(predicate::str::contains("copy_of_part_0.exr"));

    // Other flags: the message names both files' flags.
    let other = dir.path().join("other");
    fs::create_dir(&other).unwrap();
    let q = parts(&scene, &other, 2, &["-w", "48", "-h", "32", "--seed", "7"]);
    rayscope()
        .arg("merge")
        .args([&p[0], &q[1]])
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("the render flags differ"))
        .stderr(predicate::str::contains("--seed 7"));

    // Another part count.
    let three = dir.path().join("three");
    fs::create_dir(&three).unwrap();
    let r = parts(&scene, &three, 3, &flags);
    rayscope()
        .arg("merge")
        .args([&p[0], &r[1]])
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("the part counts differ"));

    // An EXR that is not a part, and a file that is not an image.
    let plain = dir.path().join("plain.exr");
    full(&scene, &plain, &flags);
    rayscope()
        .arg("merge")
        .arg(&plain)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains(
            "plain.exr' is an OpenEXR image but not a rayscope part",
        ));
    rayscope()
        .arg("merge")
        .arg(&scene)
        .arg("-o")
        .arg(&out)
        .assert()
        .code(2)
        .stderr(predicate::str::contains("not an OpenEXR file"));
    assert!(!out.exists(), "no output after failed merges");
}

#[test]
fn the_scene_hash_covers_its_obj_files() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("scene");
    fs::create_dir_all(src.join("models")).unwrap();
    fs::copy(scenes("obj.txt"), src.join("obj.txt")).unwrap();
    fs::copy(scenes("models/torus.obj"), src.join("models/torus.obj")).unwrap();
    let flags = ["-w", "32", "-h", "32", "--stage", "1"];
    let a = parts(&src.join("obj.txt"), dir.path(), 2, &flags);
    // The same mesh with one more (unused) vertex: the scene file is unchanged.
    let mut obj = fs::read_to_string(src.join("models/torus.obj")).unwrap();
    obj.push_str("\nv 0 0 0\n");
    fs::write(src.join("models/torus.obj"), obj).unwrap();
    let later = dir.path().join("later");
    fs::create_dir(&later).unwrap();
    let b = parts(&src.join("obj.txt"), &later, 2, &flags);
    rayscope()
        .arg("merge")
        .args([&a[0], &b[1]])
        .arg("-o")
        .arg(dir.path().join("m.png"))
        .assert()
        .code(2)
        .stderr(predicate::str::contains(
            "the scenes' contents (scene file or OBJ files) differ",
        ));
}

#[test]
fn part_flags_are_checked_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("basic.txt");
    let run = |out: &str, part: &str| {
        rayscope()
            .arg("-f")
            .arg(&scene)
            .arg("-o")
            .arg(dir.path().join(out))
            .args(["-w", "32", "-h", "32", "--part", part])
            .assert()
            .code(2)
    };
    run("p.png", "0/2").stderr(predicate::str::contains("give -o an .exr name"));
    run("p.exr", "2/2").stderr(predicate::str::contains("K counts from 0 to N-1"));
    run("p.exr", "0/5").stderr(predicate::str::contains("only 4 tiles"));
    run("p.exr", "1of2").stderr(predicate::str::contains("expected K/N"));
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn frames_are_numbered_and_a_merged_frame_is_that_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scenes("whitted.txt");
    let flags = [
        "-w",
        "48",
        "-h",
        "36",
        "--frames",
        "0..3",
        "--turntable",
        "0,0,4",
        "--turntable-frames",
        "8",
        "--key-n",
        "0:0",
        "--key-n",
        "3:-6",
    ];
    common::render_to(&scene, &dir.path().join("turn_##.png"), &flags);
    let names: Vec<String> = {
        let mut v: Vec<String> = fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    assert_eq!(names, ["turn_00.png", "turn_01.png", "turn_02.png", "turn_03.png"]);
    // Frame 0 of this path is the camera the flags place.
    let still = full(&scene, &dir.path().join("still.png"), &["-w", "48", "-h", "36"]);
    assert!(fs::read(dir.path().join("turn_00.png")).unwrap() == still);
    // The frames move.
    assert!(fs::read(dir.path().join("turn_01.png")).unwrap() != still);
    // Frame 2 in three parts, rendered on its own as a cluster task would, merges into frame 2.
    let mut one: Vec<&str> = flags.to_vec();
    let i = one.iter().position(|f| *f == "0..3").unwrap();
    one[i] = "2..2";
    let sub = dir.path().join("parts");
    fs::create_dir(&sub).unwrap();
    let p: Vec<PathBuf> = (0..3)
        .map(|k| {
            let pattern = sub.join(format!("f####_p{k}.exr"));
            rayscope()
                .arg("-f")
                .arg(&scene)
                .arg("-o")
                .arg(&pattern)
                .args(["--quiet", "--part", &format!("{k}/3")])
                .args(&one)
                .assert()
                .success();
            sub.join(format!("f0002_p{k}.exr"))
        })
        .collect();
    assert!(merge(&p, &dir.path().join("merged_2.png")) == fs::read(dir.path().join("turn_02.png")).unwrap());
    // Parts of different frames do not merge.
    let p1 = sub.join("f0001_p1.exr");
    one[i] = "1";
    rayscope()
        .arg("-f")
        .arg(&scene)
        .arg("-o")
        .arg(sub.join("f####_p1.exr"))
        .args(["--quiet", "--part", "1/3"])
        .args(&one)
        .assert()
        .success();
    rayscope()
        .arg("merge")
        .args([&p[0], &p1, &p[2]])
        .arg("-o")
        .arg(dir.path().join("bad.png"))
        .assert()
        .code(2)
        .stderr(predicate::str::contains("the frames differ (frame 1 against frame 2)"));
}

#[test]
fn camera_path_flags_need_frames() {
    rayscope()
        .arg("-f")
        .arg(scenes("basic.txt"))
        .args(["-o", "x.png", "--turntable", "0,0,4"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("--frames"));
    rayscope()
        .arg("-f")
        .arg(scenes("basic.txt"))
        .args(["-o", "x.png", "--frames", "3..1"])
        .assert()
        .code(2)
        .stderr(predicate::str::contains("the last frame comes before the first"));
}

/// The longest part's share of the work (rays cast, which the deal decides and the machine does
/// not), over the ideal 1/N; and the same for contiguous bands of tiles.
fn balance(scene: &Path, settings: &rayscope_core::RenderSettings, n: u32) -> (f64, f64) {
    use rayscope_core::farm::{deal, PartSpec};
    let file = rayscope_scene::load(scene).unwrap();
    let scene = rayscope_core::Scene::from_owned_file(file);
    let (tx, ty) = rayscope_core::render::tile_grid(settings.width, settings.height);
    let cancel = std::sync::atomic::AtomicBool::new(false);
    let rays = |tiles: &[u32]| {
        rayscope_core::render_tiles_of(&scene, settings, tiles, &|_, _| {}, &cancel)
            .unwrap()
            .counters
            .total() as f64
    };
    let dealt: Vec<f64> = (0..n)
        .map(|k| rays(&deal(tx, ty, PartSpec { index: k, count: n })))
        .collect();
    let per = (tx * ty).div_ceil(n);
    let bands: Vec<f64> = (0..n)
        .map(|k| rays(&(k * per..((k + 1) * per).min(tx * ty)).collect::<Vec<_>>()))
        .collect();
    let worst = |v: &[f64]| v.iter().cloned().fold(0.0, f64::max) / v.iter().sum::<f64>() * f64::from(n);
    (worst(&dealt), worst(&bands))
}

#[test]
fn parts_share_concentrated_cost_evenly() {
    // Whitted: almost all secondary rays come from the mirror and glass spheres, a small part of
    // the image; the sky costs one ray a pixel.
    let settings = rayscope_core::RenderSettings {
        width: 512,
        height: 384,
        stage: rayscope_core::Stage::Two,
        ..rayscope_core::RenderSettings::default()
    };
    for n in [4, 8] {
        let (dealt, bands) = balance(&scenes("whitted.txt"), &settings, n);
        eprintln!("whitted.txt {n} parts: longest part {dealt:.3}× the mean (contiguous bands {bands:.3}×)");
        // Measured: 1.042 for 4 parts and 1.057 for 8, against 1.406 and 1.773 for bands.
        assert!(
            dealt < 1.08,
            "{n} parts: the longest part does {dealt:.3}× the mean work"
        );
        assert!(bands - 1.0 > 3.0 * (dealt - 1.0), "bands {bands:.3}, dealt {dealt:.3}");
    }
}
