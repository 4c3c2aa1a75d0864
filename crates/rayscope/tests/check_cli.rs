//! `rayscope check`: exit codes, malformed logs, `--lenient`, `.rays` files and `--json`.

mod common;

use std::path::Path;

use common::rayscope;
use glam::Vec3A;
use rayscope_core::{Camera, CameraSettings, Ray, Scene};

/// rayscope's camera ray for the centre of pixel (`x`, `y`) of a `w`×`h` image.
fn camera_ray(w: u32, h: u32, x: u32, y: u32) -> Ray {
    let cam = Camera::new(CameraSettings::default(), w, h);
    let (u, v) = cam.pixel_center(x, y);
    cam.ray(u, v)
}

fn scene1() -> Scene {
    Scene::from_file(&rayscope_scene::load(&rayscope_testkit::scene("basic.txt")).expect("scene"))
}

fn write(path: &Path, text: &str) {
    std::fs::write(path, text).expect("write log");
}

fn camera_line(x: u32, y: u32, d: Vec3A) -> String {
    format!(
        "{{\"pixel\": [{x}, {y}], \"id\": {}, \"kind\": \"camera\", \"origin\": [0, 0, 0], \"direction\": [{}, {}, {}]}}\n",
        y * 100 + x,
        d.x,
        d.y,
        d.z
    )
}

fn check_cmd(log: &Path) -> assert_cmd::Command {
    let mut c = rayscope();
    c.arg("check")
        .arg("-f")
        .arg(rayscope_testkit::scene("basic.txt"))
        .arg("--rays")
        .arg(log)
        .args(["-w", "8", "-h", "6", "--quiet"]);
    c
}

#[test]
fn agreeing_log_exits_0_and_a_malformed_line_exits_2_with_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rays.jsonl");
    let good: String = (0..6)
        .flat_map(|y| (0..8).map(move |x| camera_line(x, y, camera_ray(8, 6, x, y).dir)))
        .collect();
    write(&log, &good);
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stdout));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("checked 48 rays") && stdout.contains("every ray agrees"),
        "{stdout}"
    );

    // Line 3's direction has a string where a number belongs.
    let lines: Vec<&str> = good.lines().collect();
    let bad = format!(
        "{}\n{}\n{{\"pixel\": [2, 0], \"origin\": [0, 0, 0], \"direction\": [0, \"x\", 1]}}\n{}\n",
        lines[0], lines[1], lines[3]
    );
    write(&log, &bad);
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(out.stdout.is_empty(), "no report on bad input");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("rays.jsonl:3:"), "{err}");
    assert!(
        err.contains("expected a JSON ray record") && err.contains("f64"),
        "{err}"
    );

    // --lenient skips it, counts it and judges the rest.
    let out = check_cmd(&log).arg("--lenient").output().unwrap();
    assert_eq!(out.status.code(), Some(0));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("checked 3 rays"), "{stdout}");
    assert!(stdout.contains("skipped 1 malformed line (--lenient)"), "{stdout}");
    assert!(stdout.contains("rays.jsonl:3:"), "{stdout}");
}

#[test]
fn names_and_ranges_are_checked_against_the_scene_and_flags() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rays.jsonl");
    write(
        &log,
        "{\"origin\": [0, 0, 0], \"direction\": [0, 0, 1], \"hit\": {\"t\": 2, \"entity\": \"Shpere\"}}\n",
    );
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("rays.jsonl:1:73"), "{err}");
    assert!(
        err.contains("no entity named 'Shpere'") && err.contains("'Sphere'"),
        "{err}"
    );

    // A tracer whose lights have no names gives the light's position; one that is no light is
    // refused where it stands.
    write(
        &log,
        "{\"origin\": [0, 0, 0], \"direction\": [0, 1, 0], \"light\": [9, 9, 9], \"blocked_by\": true}\n",
    );
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("rays.jsonl:1:47"), "{err}");
    assert!(
        err.contains("no light at [9.0, 9.0, 9.0]") && err.contains("its lights: 'Light' at [1, 1.4, 0.4]"),
        "{err}"
    );

    write(&log, &camera_line(8, 0, Vec3A::Z));
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("outside the 8×6 image") && err.contains("-w and -h"),
        "{err}"
    );

    write(
        &log,
        "{\"sample\": 3, \"origin\": [0, 0, 0], \"direction\": [0, 0, 1]}\n",
    );
    let out = check_cmd(&log).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("pass the -x your tracer used"));
}

#[test]
fn json_report_has_codes_counts_examples_and_replay_commands() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rays.jsonl");
    // Every ray through the image centre: pixel (0, 0)'s ray is far off.
    let text: String = (0..3).map(|x| camera_line(x, 0, Vec3A::Z)).collect();
    write(&log, &text);
    let out = check_cmd(&log).arg("--json").output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(v["rays"], 3);
    assert_eq!(v["disagree"], 3);
    assert_eq!(v["agree"], 0);
    let g = &v["verdicts"][0];
    assert_eq!(g["code"], "camera.direction");
    assert_eq!(g["count"], 3);
    assert!(g["explanation"].as_str().unwrap().len() > 40);
    let ex = &g["examples"][0];
    assert_eq!(ex["line"], 1);
    assert_eq!(ex["pixel"], serde_json::json!([0, 0]));
    assert_eq!(ex["sample"], 0);
    assert_eq!(ex["kind"], "camera");
    assert_eq!(ex["values"][0]["what"], "direction");
    assert_eq!(ex["values"][0]["yours"], serde_json::json!([0.0, 0.0, 1.0]));
    let cmd = ex["trace_command"].as_str().unwrap();
    assert!(
        cmd.starts_with("rayscope trace -f ") && cmd.contains("--pixel 0,0 --sample 0 -w 8 -h 6"),
        "{cmd}"
    );
    assert!(v["tie_verdicts"].as_array().unwrap().is_empty());
    assert!(v["tolerances"]["position"].as_f64().unwrap() > 0.0);
}

/// A RayTracer.Debug `.rays` file: int32 count, per ray a byte n, n int32 ids, from and to.
fn rays_file(rays: &[(Vec<i32>, Vec3A, Vec3A)]) -> Vec<u8> {
    let mut b = (rays.len() as i32).to_le_bytes().to_vec();
    for (ids, from, to) in rays {
        b.push(ids.len() as u8);
        for id in ids {
            b.extend(id.to_le_bytes());
        }
        for c in from.to_array().iter().chain(&to.to_array()) {
            b.extend(f64::from(*c).to_le_bytes());
        }
    }
    b
}

#[test]
fn binary_rays_files_are_read_and_judged() {
    let scene = scene1();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("log.rays");
    // Camera rays from the camera to their hit points (or a point along the ray on a miss).
    let seg = |x: u32, y: u32, flip: bool| {
        let r = camera_ray(8, 6, x, if flip { 5 - y } else { y });
        let t = scene.intersect(&r, 0.0, f32::INFINITY).map_or(3.0, |h| h.t);
        (vec![x as i32, y as i32], r.origin, r.at(t))
    };
    let good: Vec<_> = (0..6)
        .flat_map(|y| (0..8).map(move |x| (x, y)))
        .map(|(x, y)| seg(x, y, false))
        .collect();
    std::fs::write(&path, rays_file(&good)).unwrap();
    let out = check_cmd(&path).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{stdout}");
    assert!(stdout.contains("checked 48 rays (48 camera rays)"), "{stdout}");

    // An upside-down image.
    let flipped: Vec<_> = (0..6)
        .flat_map(|y| (0..8).map(move |x| (x, y)))
        .map(|(x, y)| seg(x, y, true))
        .collect();
    std::fs::write(&path, rays_file(&flipped)).unwrap();
    let out = check_cmd(&path).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    assert!(stdout.contains("camera.flipped"), "{stdout}");

    // Truncated in the middle of the last ray.
    let mut bytes = rays_file(&good);
    bytes.truncate(bytes.len() - 10);
    std::fs::write(&path, bytes).unwrap();
    let out = check_cmd(&path).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("ends inside ray 48") && err.contains("log.rays"), "{err}");
}

/// `--image`: the picture a tracer wrote beside its log. Camera rays whose logged colour is
/// (0.5, 0.5, 0.5) make bytes 127 by the course's rule; a picture with 186 there is that colour
/// gamma-corrected, which is the report's first line (exit 1); one of another size is refused.
#[test]
fn the_picture_is_checked_against_the_logged_colours() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("rays.jsonl");
    let mut text = String::new();
    let scene = scene1();
    // Rays that hit something bring back grey; misses black, as the course has them.
    let mut hits = [[false; 4]; 4];
    for y in 0..4 {
        for x in 0..4 {
            let ray = camera_ray(4, 4, x, y);
            hits[y as usize][x as usize] = scene.intersect(&ray, 0.0, f32::INFINITY).is_some();
            let v = if hits[y as usize][x as usize] { 0.5 } else { 0.0 };
            let d = ray.dir;
            text.push_str(&format!(
                "{{\"pixel\": [{x}, {y}], \"kind\": \"camera\", \"origin\": [0, 0, 0], \"direction\": [{}, {}, {}], \"color\": [{v}, {v}, {v}]}}\n",
                d.x, d.y, d.z
            ));
        }
    }
    assert!(hits.iter().flatten().any(|&h| h), "no camera ray hits the scene");
    write(&log, &text);
    let picture = |grey: u8| {
        image::RgbImage::from_fn(4, 4, |x, y| {
            image::Rgb([if hits[y as usize][x as usize] { grey } else { 0 }; 3])
        })
    };
    let png = dir.path().join("gamma.png");
    picture(186).save(&png).expect("png");
    let cmd = |w: &str| {
        let mut c = rayscope();
        c.arg("check")
            .arg("-f")
            .arg(rayscope_testkit::scene("basic.txt"))
            .arg("--rays")
            .arg(&log)
            .args(["-w", w, "-h", "4", "--quiet", "--image"]);
        c
    };
    let out = cmd("4").arg(&png).assert().code(1).get_output().stdout.clone();
    let stdout = String::from_utf8_lossy(&out);
    assert!(
        stdout.lines().next().is_some_and(|l| l.contains("image.gamma")),
        "{stdout}"
    );
    let right = dir.path().join("right.png");
    picture(127).save(&right).expect("png");
    cmd("4").arg(&right).assert().code(0);
    cmd("5")
        .arg(&right)
        .assert()
        .code(2)
        .stderr(predicates::str::contains("4×4 but the flags ask for 5×4"));
}

/// `--image` with flags for a picture past check's budget is refused before anything is read.
#[test]
fn a_picture_past_the_budget_is_refused_from_the_flags() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("rays.jsonl");
    write(
        &log,
        "{\"pixel\": [0, 0], \"kind\": \"camera\", \"origin\": [0, 0, 0], \"direction\": [0, 0, 1]}\n",
    );
    rayscope()
        .arg("check")
        .arg("-f")
        .arg(rayscope_testkit::scene("basic.txt"))
        .arg("--rays")
        .arg(&log)
        .args(["-w", "4096", "-h", "2048", "--quiet", "--image"])
        .arg(dir.path().join("absent.png"))
        .assert()
        .code(2)
        .stderr(predicates::str::contains("over check's 4 megapixels"));
}

/// The tests' student tracer in Python (`--bug`, `--log`, `--image`; a PPM picture).
fn student_tracer(scene: &Path, (w, h): (u32, u32), bug: &str, log: &Path, picture: &Path) {
    let script = rayscope_testkit::workspace().join("crates/rayscope_check/tests/student/tracer.py");
    let out = std::process::Command::new("python3")
        .arg(script)
        .arg("-f")
        .arg(scene)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "--bug", bug, "--log"])
        .arg(log)
        .arg("--image")
        .arg(picture)
        .output()
        .expect("python3 runs the student tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
}

/// The log's lines of the pixels `keep` chooses, as the logging kits write them when
/// `RAYSCOPE_LOG_PIXELS` or `RAYSCOPE_LOG_RECT` is set.
fn lines_of(log: &Path, keep: &dyn Fn(u32, u32) -> bool) -> String {
    let text = std::fs::read_to_string(log).expect("log");
    text.lines()
        .filter(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("a JSON line");
            let p = &v["pixel"];
            keep(p[0].as_u64().unwrap_or(0) as u32, p[1].as_u64().unwrap_or(0) as u32)
        })
        .map(|l| format!("{l}\n"))
        .collect()
}

/// A student logs a few rows where their tracer happens to be right while their picture is
/// wrong elsewhere (a sphere test that compares with r, not r²: no catalogue has it). `check`
/// does not say all is well: it compares the picture with rayscope's render, names the pixels
/// the log lacks as the kits' variables, and the log of those pixels shows the mistake.
#[test]
fn a_log_that_misses_the_mistake_is_told_which_pixels_to_log_next() {
    let dir = tempfile::tempdir().expect("temp dir");
    let scene = rayscope_testkit::scene("whitted.txt");
    let (w, h) = (48, 36);
    let (full, picture) = (dir.path().join("full.jsonl"), dir.path().join("yours.ppm"));
    student_tracer(&scene, (w, h), "radius-not-squared", &full, &picture);
    let check = |log: &Path, image: bool| {
        let mut c = rayscope();
        c.arg("check").arg("-f").arg(&scene).arg("--rays").arg(log);
        c.args(["-w", &w.to_string(), "-h", &h.to_string(), "--quiet"]);
        if image {
            c.arg("--image").arg(&picture);
        }
        let out = c.output().expect("rayscope check runs");
        (out.status.code(), String::from_utf8_lossy(&out.stdout).into_owned())
    };

    // RAYSCOPE_LOG_RECT="0,0,47,3": the top rows, wall and ceiling, far above every sphere.
    let top = dir.path().join("top.jsonl");
    write(&top, &lines_of(&full, &|_, y| y <= 3));
    let (code, text) = check(&top, true);
    assert_eq!(code, Some(0), "{text}");
    let first = text.lines().next().unwrap_or_default();
    assert!(
        first.starts_with("no mistake found in the log, but your picture differs from rayscope's at ")
            && first.contains("not in your log: log some of those next"),
        "{text}"
    );
    let env = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_PIXELS=\""))
        .unwrap_or_else(|| panic!("no pixels to log next:\n{text}"));
    let pixels: Vec<(u32, u32)> = env
        .split('"')
        .next()
        .unwrap_or_default()
        .split(' ')
        .map(|p| {
            let (x, y) = p.split_once(',').expect("x,y");
            (x.parse().expect("x"), y.parse().expect("y"))
        })
        .collect();
    assert!(!pixels.is_empty() && pixels.len() <= 6, "{text}");
    assert!(pixels.iter().all(|&(x, y)| x < w && y > 3 && y < h), "{pixels:?}");
    assert!(
        text.contains(&format!("rayscope check -f {} --rays rays.jsonl", scene.display()))
            && text.contains(&format!("--image {}", picture.display())),
        "{text}"
    );

    // What the student's kit logs with those variables: the mistake is there.
    let next = dir.path().join("next.jsonl");
    write(&next, &lines_of(&full, &|x, y| pixels.contains(&(x, y))));
    let (code, text) = check(&next, true);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.starts_with("mistake: "), "{text}");

    // Without the picture, the sparse log is said to be sparse, with a grid to log instead.
    let (code, text) = check(&top, false);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.starts_with("no mistake found"), "{text}");
    assert!(
        text.contains(&format!("your log has 192 of the picture's {} camera rays", w * h))
            && text.contains("RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_STEP=2 ")
            && text.contains("--image YOUR_PICTURE.png"),
        "{text}"
    );

    // The whole log of a correct tracer: nothing to log next.
    let (right_log, right) = (dir.path().join("right.jsonl"), dir.path().join("right.ppm"));
    student_tracer(&scene, (w, h), "none", &right_log, &right);
    let out = rayscope()
        .arg("check")
        .arg("-f")
        .arg(&scene)
        .arg("--rays")
        .arg(&right_log)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "--quiet", "--image"])
        .arg(&right)
        .output()
        .expect("rayscope check runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{text}");
    assert!(
        text.starts_with("no mistake found")
            && !text.contains("log these pixels next")
            && !text.contains("RAYSCOPE_LOG"),
        "{text}"
    );
}
