//! A student's ray log in the debugger, through its API: logs of the student-style Python tracer
//! (crates/rayscope_check/tests/student/tracer.py), correct and with a mistake switched on,
//! uploaded as the page does; the verdict map must mark the pixels the mistake shows in, and a
//! pixel's comparison must explain the divergence with its verdict code.

mod common;

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::{request, send, send_raw, wait_for_render};
use rayscope_core::{RayKind, RenderSettings, Scene, Stage};
use rayscope_debug::{RunningServer, ServeConfig, ServerLimits};
use serde_json::Value;

/// python3, or `None` (reported as not run; a failure under CI=true).
fn python() -> Option<&'static str> {
    let ok = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if ok {
        return Some("python3");
    }
    rayscope_testkit::not_run(
        "needs python3",
        "No python3 found on PATH: the student-style tracer that writes the logs is a Python script.",
        "To run them, install Python 3 (Debian: apt-get install python3).",
    );
    None
}

/// Runs the student tracer on `scene` at `w`×`h` with `bug` and returns its log's bytes.
fn student_log(scene: &Path, w: u32, h: u32, bug: &str, region: Option<[u32; 4]>) -> Option<Vec<u8>> {
    let py = python()?;
    let dir = std::env::temp_dir().join(format!("rayscope-student-log-{}-{bug}-{w}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("rays.jsonl");
    let mut cmd = Command::new(py);
    cmd.arg(rayscope_testkit::workspace().join("crates/rayscope_check/tests/student/tracer.py"))
        .arg("-f")
        .arg(scene)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "--bug", bug, "--log"])
        .arg(&log);
    if let Some([a, b, c, d]) = region {
        cmd.arg("--region").arg(format!("{a},{b},{c},{d}"));
    }
    let out = cmd.output().expect("run the student tracer");
    assert!(
        out.status.success(),
        "tracer failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let bytes = std::fs::read(&log).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    Some(bytes)
}

fn whitted() -> PathBuf {
    rayscope_testkit::scene("whitted.txt")
}

/// Stage 2 (what the student tracer renders) at `w`×`h`.
fn settings(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        stage: Stage::Two,
        ..RenderSettings::default()
    }
}

fn start(scene: &Path, w: u32, h: u32, student: rayscope_debug::student::StudentInput) -> RunningServer {
    let file = rayscope_scene::load(scene).expect("scene loads");
    let data = Scene::from_file(&file);
    rayscope_debug::start(ServeConfig {
        scene_path: scene.to_path_buf(),
        scene_file: file,
        scene: data,
        settings: settings(w, h),
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits: ServerLimits::default(),
        student,
    })
    .expect("debugger starts")
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(body)))
}

/// Uploads a log as the page does.
fn upload(addr: SocketAddr, log: &[u8]) -> Value {
    let a = send(
        addr,
        "POST",
        "/api/rays?name=rays.jsonl",
        &[("Content-Type", "application/x-ndjson")],
        log,
    );
    assert_eq!(a.code, 200, "upload: {}", a.text());
    json(&a.body)
}

fn get(addr: SocketAddr, path: &str) -> Value {
    let (code, body) = request(addr, "GET", path, b"");
    assert_eq!(code, 200, "{path}: {}", String::from_utf8_lossy(&body));
    json(&body)
}

/// The verdict map's pixels: (x, y) → status name.
fn map(addr: SocketAddr) -> (u32, u32, Vec<&'static str>) {
    let a = send(addr, "GET", "/api/rays/map.png", &[], b"");
    assert_eq!(a.code, 200);
    assert_eq!(a.header("content-type"), Some("image/png"));
    let img = image::load_from_memory(&a.body).expect("map PNG").into_rgb8();
    let names = img
        .pixels()
        .map(|p| match p.0 {
            [46, 204, 113] => "agrees",
            [241, 196, 15] => "tie",
            [255, 38, 38] => "disagrees",
            [70, 70, 76] => "not-logged",
            other => panic!("unexpected map colour {other:?}"),
        })
        .collect();
    (img.width(), img.height(), names)
}

/// Waits until the summary's state is one of `states`.
fn wait_state(addr: SocketAddr, states: &[&str]) -> Value {
    for _ in 0..600 {
        let s = get(addr, "/api/rays/summary");
        if states.contains(&s["state"].as_str().unwrap_or("")) {
            return s;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("the log was not judged within a minute");
}

/// A mistake the glass shows: every pixel whose camera ray meets glass (it refracts in and out
/// of the sphere) disagrees, no other pixel does, and a red pixel's comparison names the
/// refraction that leaves the glass as where the trees part.
#[test]
fn refraction_mistake_marks_the_glass_and_is_explained() {
    let (w, h) = (32, 24);
    let Some(log) = student_log(&whitted(), w, h, "refraction-normal", None) else {
        return;
    };
    let server = start(&whitted(), w, h, Default::default());
    let addr = server.addr;
    let s = upload(addr, &log);
    assert_eq!(s["state"], "done", "{s:#}");
    let j = &s["judged"];
    assert_eq!(j["verdicts"][0]["code"], "refraction.normal-not-flipped", "{j:#}");
    assert_eq!(j["pixels"]["not-logged"], 0);
    assert_eq!(j["capped"], false);

    // The map against rayscope's own trees: a pixel disagrees exactly when its tree leaves glass
    // through a refraction (a refraction ray whose parent is a refraction ray).
    let file = rayscope_scene::load(&whitted()).unwrap();
    let scene = Scene::from_file(&file);
    let (mw, mh, status) = map(addr);
    assert_eq!((mw, mh), (w, h));
    let mut red = 0;
    let mut wrong = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let tree = rayscope_core::trace_pixel(&scene, &settings(w, h), x, y, 0);
            let leaves_glass = tree.nodes.iter().any(|n| {
                n.kind == RayKind::Refraction
                    && n.parent
                        .is_some_and(|p| tree.nodes[p as usize].kind == RayKind::Refraction)
            });
            let st = status[(y * w + x) as usize];
            red += usize::from(st == "disagrees");
            if (st == "disagrees") != leaves_glass {
                wrong.push((x, y, st, leaves_glass));
            }
        }
    }
    assert!(red > 10, "too few red pixels: {red}");
    // Grazing rays at the glass's silhouette may go either way.
    assert!(wrong.len() <= 2, "map disagrees with the glass: {wrong:?}");
    assert_eq!(red as u64, j["pixels"]["disagrees"].as_u64().unwrap());

    // A red pixel: the two trees side by side, parted at the refraction out of the glass.
    let [x, y] = [
        j["disagreeing"][0][0].as_u64().unwrap(),
        j["disagreeing"][0][1].as_u64().unwrap(),
    ];
    let p = get(addr, &format!("/api/rays/pixel?x={x}&y={y}"));
    assert_eq!(p["status"], "disagrees");
    assert_eq!(p["code"], "refraction.normal-not-flipped");
    let d = &p["divergence"];
    assert_eq!(d["code"], "refraction.normal-not-flipped", "{p:#}");
    assert!(d["explanation"].as_str().unwrap().contains("flipped"), "{d:#}");
    assert!(
        d["detail"].as_str().unwrap().starts_with("your refraction ray"),
        "{d:#}"
    );
    let row = &p["alignment"]["rows"][d["row"].as_u64().unwrap() as usize];
    assert_eq!(row["shape"], "both");
    let yours = &p["yours"][row["yours"].as_u64().unwrap() as usize];
    assert_eq!(yours["kind"], "refraction");
    let rs = &p["rayscope"]["nodes"][row["rayscope"].as_u64().unwrap() as usize];
    assert_eq!(rs["kind"], "refraction");
    // Rows above it agree: the camera ray pairs with rayscope's and has no verdict.
    let first = &p["alignment"]["rows"][0];
    assert_eq!(first["shape"], "both");
    assert_eq!(first["verdict"], "agrees");
    assert_eq!(p["yours"][first["yours"].as_u64().unwrap() as usize]["kind"], "camera");

    // The view draws the student's rays of that pixel (dashed lines the frame without them lacks).
    wait_for_render(addr);
    let view = |extra: &str| {
        let a = send(
            addr,
            "GET",
            &format!("/api/view?w=320&h=240&format=png&pixel={x},{y}&tree=1{extra}"),
            &[],
            b"",
        );
        assert_eq!(a.code, 200, "{}", a.text());
        image::load_from_memory(&a.body).unwrap().into_rgb8()
    };
    let plain = view("");
    let with = view("&student=1&verdicts=1");
    let changed = plain.pixels().zip(with.pixels()).filter(|(a, b)| a != b).count();
    assert!(
        changed > 200,
        "the student's rays and verdicts changed only {changed} pixels"
    );
    server.stop();
}

/// The correct tracer's log: every pixel agrees. A log of part of the image: the rest is not
/// logged. A settings change judges the kept log again (and it now disagrees everywhere).
#[test]
fn correct_log_agrees_everywhere_and_is_judged_again_after_a_change() {
    let (w, h) = (24, 18);
    let Some(log) = student_log(&whitted(), w, h, "none", None) else {
        return;
    };
    let server = start(&whitted(), w, h, Default::default());
    let addr = server.addr;
    let s = upload(addr, &log);
    let px = &s["judged"]["pixels"];
    assert_eq!(px["disagrees"], 0, "{s:#}");
    assert_eq!(px["not-logged"], 0);
    assert_eq!(
        px["agrees"].as_u64().unwrap() + px["tie"].as_u64().unwrap(),
        u64::from(w * h)
    );
    assert!(map(addr).2.iter().all(|s| *s == "agrees" || *s == "tie"));
    let p = get(addr, "/api/rays/pixel?x=12&y=9");
    assert!(p["divergence"].is_null() || p["divergence"]["code"].is_null(), "{p:#}");

    // Another field of view: the same log now fits no camera ray.
    let (code, body) = request(addr, "POST", "/api/settings", br#"{"fov": 50}"#);
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    let s = get(addr, "/api/rays/summary");
    assert!(
        s["state"] == "judging" || s["state"] == "done",
        "a kept upload is judged again: {s:#}"
    );
    let s = wait_state(addr, &["done", "error"]);
    assert_eq!(s["judged"]["settings"]["fov"], 50.0, "{s:#}");
    assert_eq!(s["judged"]["stale"], false);
    assert_eq!(s["judged"]["pixels"]["disagrees"], u64::from(w * h), "{s:#}");
    assert_eq!(s["judged"]["verdicts"][0]["code"], "camera.plane-distance", "{s:#}");

    // Part of the image only.
    let Some(part) = student_log(&whitted(), w, h, "none", Some([0, 0, 8, 6])) else {
        return;
    };
    let (code, _) = request(addr, "POST", "/api/settings", br#"{"fov": 60}"#);
    assert_eq!(code, 200);
    let s = upload(addr, &part);
    assert_eq!(
        s["judged"]["pixels"]["agrees"].as_u64().unwrap() + s["judged"]["pixels"]["tie"].as_u64().unwrap(),
        48
    );
    assert_eq!(s["judged"]["pixels"]["not-logged"], u64::from(w * h) - 48);
    let p = get(addr, "/api/rays/pixel?x=20&y=15");
    assert_eq!(p["status"], "not-logged");
    assert_eq!(p["yours"].as_array().unwrap().len(), 0);
    assert!(!p["rayscope"]["nodes"].as_array().unwrap().is_empty());
    server.stop();
}

/// `rayscope debug --rays LOG --image IMAGE`: judged at the start; their image with a readout.
#[test]
fn log_and_image_given_at_start() {
    let (w, h) = (16, 12);
    let Some(log) = student_log(&whitted(), w, h, "shadow-no-offset", None) else {
        return;
    };
    let dir = std::env::temp_dir().join(format!("rayscope-start-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("theirs.jsonl");
    std::fs::write(&path, &log).unwrap();
    let img = rayscope_debug::RgbImage {
        width: w,
        height: h,
        rgb: (0..w * h * 3).map(|i| (i % 251) as u8).collect(),
    };
    let server = start(
        &whitted(),
        w,
        h,
        rayscope_debug::student::StudentInput {
            rays: Some(path),
            image: Some(img),
            ..Default::default()
        },
    );
    let addr = server.addr;
    let s = wait_state(addr, &["done", "error"]);
    assert_eq!(s["state"], "done", "{s:#}");
    assert_eq!(s["source"]["kind"], "file");
    assert_eq!(s["judged"]["verdicts"][0]["code"], "shadow.acne", "{s:#}");
    // The cause names the catalogue's mistake, in the catalogue's words, for the panel to show.
    let cause = &s["judged"]["causes"][0];
    assert_eq!(cause["code"], "shadow.acne", "{s:#}");
    let entry = &cause["catalogue"][0];
    assert_eq!(entry["name"], "no-shadow-offset", "{s:#}");
    let info = rayscope_core::Mistake::NoShadowOffset.info();
    assert_eq!(entry["looks"], info.looks);
    assert_eq!(entry["wrong"], info.wrong);
    assert_eq!(s["image"]["matches"], true);
    let p = get(addr, "/api/rays/pixel?x=3&y=2");
    let i = ((2 * w + 3) * 3) as usize;
    assert_eq!(
        p["their_rgb8"],
        serde_json::json!([i % 251, (i + 1) % 251, (i + 2) % 251])
    );
    let a = send(addr, "GET", "/api/rays/image.png", &[], b"");
    assert_eq!(a.code, 200);
    assert_eq!(image::load_from_memory(&a.body).unwrap().width(), w);
    server.stop();
    let _ = std::fs::remove_dir_all(&dir);
}

/// Uploads follow the server's rules: only the page's own requests, the log's types, bounded.
#[test]
fn uploads_are_refused_across_sites_with_other_types_or_too_large() {
    let server = start(&whitted(), 8, 6, Default::default());
    let addr = server.addr;
    let line = br#"{"pixel":[0,0],"kind":"camera","origin":[0,0,0],"direction":[0,0,1]}"#;
    // A form post from another page.
    let a = send(addr, "POST", "/api/rays", &[("Content-Type", "text/plain")], line);
    assert_eq!(a.code, 415, "{}", a.text());
    assert!(a.error().contains("application/x-ndjson"));
    let a = send(
        addr,
        "POST",
        "/api/rays",
        &[
            ("Content-Type", "application/x-ndjson"),
            ("Origin", "http://evil.example"),
        ],
        line,
    );
    assert_eq!(a.code, 403, "{}", a.text());
    let a = send(
        addr,
        "POST",
        "/api/rays",
        &[
            ("Content-Type", "application/x-ndjson"),
            ("Sec-Fetch-Site", "cross-site"),
        ],
        line,
    );
    assert_eq!(a.code, 403, "{}", a.text());
    // A declared length over the limit is refused before any byte is read.
    let head = format!(
        "POST /api/rays HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/x-ndjson\r\nContent-Length: {}\r\nConnection: close\r\n\r\n",
        rayscope_debug::server::MAX_LOG_BYTES + 1
    );
    let a = send_raw(addr, head.as_bytes());
    assert_eq!(a.code, 413, "{}", a.text());
    // A malformed log names its line; nothing is judged.
    let a = send(
        addr,
        "POST",
        "/api/rays?name=bad.jsonl",
        &[("Content-Type", "application/x-ndjson")],
        b"{\"pixel\":[0,0],\"origin\":[0,0,0],\"direction\":[0,0,1]}\n{\"pixel\":[99,0],\"origin\":[0,0,0],\"direction\":[0,0,1]}\n",
    );
    assert_eq!(a.code, 400, "{}", a.text());
    assert!(a.error().contains("bad.jsonl:2:"), "{}", a.error());
    let s = get(addr, "/api/rays/summary");
    assert_eq!(s["state"], "error");
    let a = send(addr, "GET", "/api/rays/pixel?x=0&y=0", &[], b"");
    assert_eq!(a.code, 404);
    // A good one-line log.
    let s = upload(addr, line);
    assert_eq!(s["judged"]["rays"], 1);
    assert_eq!(s["judged"]["pixels"]["not-logged"], 47);
    // An image of another size is kept but not shown on the grid.
    let mut png = Vec::new();
    image::RgbImage::new(3, 2)
        .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    let a = send(addr, "POST", "/api/rays/image", &[("Content-Type", "image/png")], &png);
    assert_eq!(a.code, 200, "{}", a.text());
    assert_eq!(json(&a.body)["image"]["matches"], false);
    let a = send(addr, "POST", "/api/rays/image", &[("Content-Type", "text/plain")], &png);
    assert_eq!(a.code, 415);
    server.stop();
}

/// The student tracer's whole log and picture of `scene` at `w`×`h` with `bug`.
fn student_run(scene: &Path, w: u32, h: u32, bug: &str) -> Option<(String, rayscope_debug::RgbImage)> {
    let py = python()?;
    let dir = std::env::temp_dir().join(format!("rayscope-student-run-{}-{bug}-{w}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (log, ppm) = (dir.join("rays.jsonl"), dir.join("out.ppm"));
    let out = Command::new(py)
        .arg(rayscope_testkit::workspace().join("crates/rayscope_check/tests/student/tracer.py"))
        .arg("-f")
        .arg(scene)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "--bug", bug, "--log"])
        .arg(&log)
        .arg("--image")
        .arg(&ppm)
        .output()
        .expect("run the student tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let img = image::open(&ppm).expect("the tracer's PPM").into_rgb8();
    let img = rayscope_debug::RgbImage {
        width: img.width(),
        height: img.height(),
        rgb: img.into_raw(),
    };
    let text = std::fs::read_to_string(&log).expect("log");
    let _ = std::fs::remove_dir_all(&dir);
    Some((text, img))
}

/// A log of the top rows, where the tracer (a sphere test that compares with r, not r²) is right,
/// with the student's whole picture: the panel is handed the pixels to log next, all below those
/// rows where the picture differs from rayscope's render; without the picture, a grid.
#[test]
fn a_log_that_misses_the_mistake_gets_the_pixels_to_log_next() {
    let (w, h) = (48, 36);
    let Some((log, img)) = student_run(&whitted(), w, h, "radius-not-squared") else {
        return;
    };
    let top: String = log
        .lines()
        .filter(|l| json(l.as_bytes())["pixel"][1].as_u64().is_some_and(|y| y <= 3))
        .map(|l| format!("{l}\n"))
        .collect();
    let dir = std::env::temp_dir().join(format!("rayscope-top-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("top.jsonl");
    std::fs::write(&path, &top).unwrap();
    for with_image in [true, false] {
        let server = start(
            &whitted(),
            w,
            h,
            rayscope_debug::student::StudentInput {
                rays: Some(path.clone()),
                image: with_image.then(|| img.clone()),
                ..Default::default()
            },
        );
        let addr = server.addr;
        wait_for_render(addr);
        let s = wait_state(addr, &["done", "error"]);
        assert_eq!(s["state"], "done", "{s:#}");
        assert_eq!(s["judged"]["disagree"], 0, "{s:#}");
        let mut next = s["judged"]["next"].clone();
        for _ in 0..100 {
            if !next.is_null() {
                break;
            }
            std::thread::sleep(Duration::from_millis(100));
            next = get(addr, "/api/rays/summary")["judged"]["next"].clone();
        }
        if with_image {
            assert_eq!(next["kind"], "picture", "{next:#}");
            assert!(next["unlogged"].as_u64().unwrap_or(0) > 0, "{next:#}");
            let pixels = next["next"]["pixels"].as_array().expect("pixels");
            assert!(!pixels.is_empty() && pixels.len() <= 6, "{next:#}");
            assert!(pixels.iter().all(|p| p[1].as_u64().is_some_and(|y| y > 3)), "{next:#}");
            let env = next["next"]["log_env"].as_str().unwrap_or_default();
            assert!(
                env.starts_with("RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_PIXELS=\""),
                "{env}"
            );
            let check = next["next"]["check_command"].as_str().unwrap_or_default();
            assert!(check.contains("--rays rays.jsonl -w 48 -h 36 --stage 2"), "{check}");
        } else {
            assert_eq!(next["kind"], "sparse", "{next:#}");
            assert_eq!(next["camera_rays"], 4 * w, "{next:#}");
            assert_eq!(
                next["grid_env"], "RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_STEP=2",
                "{next:#}"
            );
        }
        server.stop();
    }
    // The same log sent from the page: the upload's own answer carries the advice, since the
    // page shows whichever answer arrives last and stops asking once the log is judged.
    let server = start(&whitted(), w, h, rayscope_debug::student::StudentInput::default());
    let s = upload(server.addr, top.as_bytes());
    assert_eq!(s["state"], "done", "{s:#}");
    assert_eq!(s["judged"]["next"]["kind"], "sparse", "{s:#}");
    server.stop();
    let _ = std::fs::remove_dir_all(&dir);
}
