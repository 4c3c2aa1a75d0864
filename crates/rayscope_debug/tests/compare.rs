//! The debugger's comparison of a student's image over HTTP: a wrong picture (the student-style
//! tracer of rayscope_core's tests, with a realistic mistake) is compared with the render,
//! attributed to entities (through the chrome ball), diagnosed, shown as a heat map at a chosen
//! or automatic range, read pixel by pixel, and compared again, never stale, when the settings
//! change.

mod common;
#[path = "../../rayscope_core/tests/student/mod.rs"]
#[allow(dead_code)]
mod student;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use common::{request, send, wait_for_render};
use rayscope_core::{RenderSettings, Scene, Stage};
use rayscope_debug::{RunningServer, ServeConfig, ServerLimits};
use serde_json::Value;

const W: u32 = 80;
const H: u32 = 60;

fn whitted() -> PathBuf {
    rayscope_testkit::scene("whitted.txt")
}

/// The debugger on our Whitted still life at stage 2 (what the student's tracer renders).
fn start() -> RunningServer {
    let path = whitted();
    let file = rayscope_scene::load(&path).expect("scene loads");
    let scene = Scene::from_file(&file);
    rayscope_debug::start(ServeConfig {
        scene_path: path,
        scene_file: file,
        scene,
        settings: RenderSettings {
            width: W,
            height: H,
            stage: Stage::Two,
            ..RenderSettings::default()
        },
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits: ServerLimits::default(),
        student: Default::default(),
    })
    .expect("debugger starts")
}

/// The student's picture with `bugs`, RGB8.
fn student_image(bugs: &[&'static str]) -> Vec<u8> {
    let file = rayscope_scene::load(&whitted()).unwrap();
    student::Student::new(&file, bugs, student::Options::new(W, H)).render()
}

fn png(rgb: &[u8], w: u32, h: u32) -> Vec<u8> {
    let img = image::RgbImage::from_raw(w, h, rgb.to_vec()).unwrap();
    let mut out = std::io::Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn decode(png: &[u8]) -> image::RgbImage {
    image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .expect("a PNG")
        .to_rgb8()
}

fn json(body: &[u8]) -> Value {
    serde_json::from_slice(body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(body)))
}

fn get(addr: SocketAddr, path: &str) -> Value {
    let (code, body) = request(addr, "GET", path, b"");
    assert_eq!(code, 200, "{path}: {}", String::from_utf8_lossy(&body));
    json(&body)
}

fn post_image(addr: SocketAddr, png: &[u8]) -> Value {
    let a = send(
        addr,
        "POST",
        "/api/compare?name=mine.png",
        &[("Content-Type", "image/png")],
        png,
    );
    assert_eq!(a.code, 200, "{}", a.text());
    json(&a.body)
}

fn post_settings(addr: SocketAddr, patch: &str) -> Value {
    let (code, body) = request(addr, "POST", "/api/settings", patch.as_bytes());
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    json(&body)
}

/// Polls `GET /api/compare` until the comparison and its diagnosis are done (up to 3 minutes).
fn diagnosed(addr: SocketAddr) -> Value {
    let end = Instant::now() + Duration::from_secs(180);
    loop {
        let v = get(addr, "/api/compare");
        if v["state"] == "done" && v["diagnosis"]["state"] != "running" && v["diagnosis"]["state"] != "waiting" {
            return v;
        }
        assert!(Instant::now() < end, "no diagnosis within 3 minutes: {v}");
        std::thread::sleep(Duration::from_millis(200));
    }
}

/// The current render job's id.
fn job(addr: SocketAddr) -> u64 {
    get(addr, "/api/render/status")["job"].as_u64().unwrap()
}

#[test]
fn a_wrong_picture_is_compared_attributed_and_diagnosed() {
    let server = start();
    let addr = server.addr;
    // Nothing to compare yet.
    assert_eq!(get(addr, "/api/compare")["state"], "none");
    let a = send(addr, "GET", "/api/compare/pixel?x=1&y=1", &[], b"");
    assert_eq!(a.code, 404, "{}", a.text());
    assert!(a.error().contains("no image of yours"), "{}", a.text());

    wait_for_render(addr);
    // The student's vertical field of view: the whole picture zoomed in.
    let theirs = student_image(&["fov-vertical"]);
    let v = post_image(addr, &png(&theirs, W, H));
    assert_eq!(v["state"], "done", "{v}");
    assert_eq!(v["image"]["name"], "mine.png");
    assert_eq!(v["render_job"].as_u64(), Some(job(addr)));
    let psnr = v["psnr"].as_f64().expect("a finite PSNR");
    assert!(psnr < 25.0, "{v}");
    assert!(v["differing"].as_u64().unwrap() > u64::from(W * H) / 2, "{v}");
    assert_eq!(v["heatmap_auto"], true);
    let range = v["heatmap_range"].as_u64().unwrap();
    assert!((1..=255).contains(&range), "{v}");

    // The attribution: shares of the differing pixels, largest first, some seen in the mirror.
    let shares = v["attribution"].as_array().expect("attribution");
    assert!(shares.len() >= 3, "{v}");
    let total: f64 = shares.iter().map(|s| s["percent"].as_f64().unwrap()).sum();
    assert!((total - 100.0).abs() < 1.0, "{total}");
    let pixels: Vec<u64> = shares.iter().map(|s| s["pixels"].as_u64().unwrap()).collect();
    assert!(pixels.windows(2).all(|p| p[0] >= p[1]), "{pixels:?}");
    assert!(
        shares.iter().any(|s| s["seen_in"] == serde_json::json!(["ChromeBall"])),
        "something is seen in the chrome ball: {shares:?}"
    );

    // The heat map: the render's size, each channel |a − b| scaled to the range.
    let (code, heat) = request(addr, "GET", v["heatmap"].as_str().unwrap(), b"");
    assert_eq!(code, 200);
    let heat = decode(&heat);
    let (code, ours) = request(addr, "GET", "/api/image.png", b"");
    assert_eq!(code, 200);
    let ours = decode(&ours).into_raw();
    assert_eq!(heat.dimensions(), (W, H));
    let scaled = |d: u8, r: u8| ((u32::from(d.min(r)) * 255 + u32::from(r) / 2) / u32::from(r)) as u8;
    for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        assert_eq!(heat.as_raw()[i], scaled(a.abs_diff(*b), range as u8), "byte {i}");
    }

    // The diagnosis finds the field of view's axis and says so in words.
    let v = diagnosed(addr);
    let d = &v["diagnosis"];
    assert_eq!(d["state"], "done", "{v}");
    assert_eq!(d["result"]["matches"], false);
    let first = &d["result"]["explanations"][0];
    assert_eq!(first["settings"], serde_json::json!(["--fov-axis vertical"]), "{d}");
    assert!((d["result"]["psnr_db"].as_f64().unwrap() - psnr).abs() < 0.01, "{d}");
    let text = d["text"].as_str().unwrap();
    // The cause on the first line, the figures after it.
    assert!(
        text.starts_with("Explained: your image is rayscope's render with the field of view on the vertical axis"),
        "{text}"
    );
    assert!(
        text.lines()
            .nth(1)
            .unwrap_or_default()
            .starts_with("Your image differs from rayscope's"),
        "{text}"
    );
    assert!(text.contains("--fov-axis vertical"), "{text}");
    server.stop();
}

#[test]
fn the_heat_map_range_is_chosen_or_automatic() {
    let server = start();
    let addr = server.addr;
    wait_for_render(addr);
    let theirs = student_image(&["light-falloff"]);
    let auto = post_image(addr, &png(&theirs, W, H));
    assert_eq!(auto["heatmap_auto"], true);
    // Small differences are not saturated by the automatic range: it is that of all but 1 %
    // of the differing pixels, so at most 1 % of them clip.
    let differing = auto["differing"].as_u64().unwrap();
    assert!(auto["heatmap_clipped"].as_u64().unwrap() <= differing / 100, "{auto}");

    let v = get(addr, "/api/compare?range=8");
    assert_eq!(
        (v["heatmap_range"].as_u64(), v["heatmap_auto"].as_bool()),
        (Some(8), Some(false))
    );
    let (_, ours) = request(addr, "GET", "/api/image.png", b"");
    let ours = decode(&ours).into_raw();
    let clipped = ours
        .chunks_exact(3)
        .zip(theirs.chunks_exact(3))
        .filter(|(a, b)| a.iter().zip(b.iter()).any(|(x, y)| x.abs_diff(*y) > 8))
        .count() as u64;
    assert_eq!(v["heatmap_clipped"].as_u64(), Some(clipped), "{v}");
    let (_, heat) = request(addr, "GET", v["heatmap"].as_str().unwrap(), b"");
    let heat = decode(&heat);
    for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        let d = u32::from(a.abs_diff(*b).min(8));
        assert_eq!(u32::from(heat.as_raw()[i]), (d * 255 + 4) / 8, "byte {i}");
    }
    // The same comparison is not made twice: the heat map's URL stays.
    assert_eq!(get(addr, "/api/compare?range=8")["heatmap"], v["heatmap"]);
    for bad in ["0", "256", "-1", "x", "1.5"] {
        let a = send(addr, "GET", &format!("/api/compare?range={bad}"), &[], b"");
        assert_eq!(a.code, 400, "{bad}: {}", a.text());
        assert!(a.error().contains("range must be auto"), "{}", a.text());
    }
    server.stop();
}

#[test]
fn hovering_a_pixel_reads_both_values_and_the_entity() {
    let server = start();
    let addr = server.addr;
    wait_for_render(addr);
    let theirs = student_image(&["no-shadow-offset"]);
    post_image(addr, &png(&theirs, W, H));
    let (_, ours) = request(addr, "GET", "/api/image.png", b"");
    let ours = decode(&ours).into_raw();
    // A row through the chrome ball: its pixels show what the ball reflects.
    let y = 36;
    let mut in_mirror = 0;
    for x in 0..W {
        let p = get(addr, &format!("/api/compare/pixel?x={x}&y={y}"));
        let i = ((y * W + x) * 3) as usize;
        assert_eq!(p["yours"], serde_json::json!(&theirs[i..i + 3]), "({x}, {y})");
        assert_eq!(p["rayscope"], serde_json::json!(&ours[i..i + 3]), "({x}, {y})");
        let diff: Vec<i64> = (0..3)
            .map(|c| i64::from(theirs[i + c]) - i64::from(ours[i + c]))
            .collect();
        assert_eq!(p["difference"], serde_json::json!(diff));
        let t = get(addr, &format!("/api/trace?x={x}&y={y}"));
        let hit = t["tree"]["nodes"][0]["hit"]["entity_name"]
            .as_str()
            .unwrap_or("(background)");
        if hit == "ChromeBall" {
            in_mirror += 1;
            assert_eq!(p["seen_in"], serde_json::json!(["ChromeBall"]), "({x}, {y}): {p}");
            assert_ne!(p["entity"], "ChromeBall");
        } else {
            assert_eq!(p["entity"], hit, "({x}, {y}): {p}");
            assert_eq!(p["seen_in"], serde_json::json!([]));
        }
    }
    assert!(in_mirror >= 3, "row {y} crosses the chrome ball");
    for (q, want) in [
        ("x=80&y=0", "x must be a pixel column from 0 to 79"),
        ("x=0&y=60", "y must be a pixel row from 0 to 59"),
        ("x=3", "x and y are required"),
        ("x=a&y=1", "x must be"),
    ] {
        let a = send(addr, "GET", &format!("/api/compare/pixel?{q}"), &[], b"");
        assert_eq!(a.code, 400, "{q}: {}", a.text());
        assert!(a.error().contains(want), "{q}: {}", a.text());
    }
    server.stop();
}

#[test]
fn a_settings_change_compares_again_and_never_shows_a_stale_psnr() {
    let server = start();
    let addr = server.addr;
    wait_for_render(addr);
    let theirs = student_image(&["fov-vertical"]);
    let first = post_image(addr, &png(&theirs, W, H));
    let before = first["psnr"].as_f64().unwrap();

    // The diagnosis names the setting as data in the settings API's own keys: what the panel's
    // "render with this here" button sends back.
    let d = diagnosed(addr);
    let patch = &d["diagnosis"]["result"]["explanations"][0]["patch"];
    assert_eq!(*patch, serde_json::json!({"fov_axis": "vertical"}), "{d}");

    // The field of view's axis set as the student's: a new render, and the comparison is only
    // ever made against it.
    let new_job = post_settings(addr, &patch.to_string())["job"].as_u64().unwrap();
    let end = Instant::now() + Duration::from_secs(60);
    let after = loop {
        let v = get(addr, "/api/compare");
        match v["state"].as_str() {
            Some("rendering") => assert!(v.get("psnr").is_none(), "{v}"),
            Some("done") => {
                assert_eq!(
                    v["render_job"].as_u64(),
                    Some(new_job),
                    "compared with a stale render: {v}"
                );
                break v;
            }
            _ => panic!("{v}"),
        }
        assert!(Instant::now() < end, "the new render did not finish");
        std::thread::sleep(Duration::from_millis(20));
    };
    assert_eq!(after["settings"]["fov_axis"], "vertical");
    let psnr = after["psnr"].as_f64().unwrap_or(f64::INFINITY);
    assert!(
        psnr > before + 20.0,
        "the student's own settings explain it: {before} → {psnr}"
    );
    // The diagnosis is the new settings' (the picture now matches), not the old one's.
    let v = diagnosed(addr);
    let d = &v["diagnosis"];
    assert_eq!(d["state"], "done", "{v}");
    assert_eq!(d["result"]["matches"], true, "{d}");
    assert!(d["text"].as_str().unwrap().starts_with("Your image matches"), "{d}");

    // Another size: nothing to compare until the size is the image's again.
    post_settings(addr, r#"{"width": 40}"#);
    let v = get(addr, "/api/compare");
    assert_eq!(v["state"], "size", "{v}");
    assert!(v.get("psnr").is_none(), "{v}");
    let m = v["message"].as_str().unwrap();
    assert!(m.contains("80×60") && m.contains("40×60"), "{m}");
    let a = send(addr, "GET", "/api/compare/pixel?x=1&y=1", &[], b"");
    assert_eq!(a.code, 409, "{}", a.text());
    assert!(a.error().contains("80×60"), "{}", a.text());
    // Uploading at the wrong size is refused and keeps the image there was.
    let a = send(
        addr,
        "POST",
        "/api/compare",
        &[("Content-Type", "image/png")],
        &png(&theirs, W, H),
    );
    assert_eq!(a.code, 400, "{}", a.text());
    assert!(
        a.error().contains("80×60") && a.error().contains("40×60"),
        "{}",
        a.text()
    );
    post_settings(addr, r#"{"width": 80}"#);
    wait_for_render(addr);
    assert_eq!(diagnosed(addr)["diagnosis"]["result"]["matches"], true);
    server.stop();
}

#[test]
fn only_the_debuggers_own_page_may_compare() {
    let server = start();
    let addr = server.addr;
    wait_for_render(addr);
    let body = png(&student_image(&[]), W, H);
    let other = [("Content-Type", "image/png"), ("Origin", "http://evil.example")];
    let a = send(addr, "POST", "/api/compare", &other, &body);
    assert_eq!(a.code, 403, "{}", a.text());
    let a = send(addr, "GET", "/api/compare", &[("Sec-Fetch-Site", "cross-site")], b"");
    assert_eq!(a.code, 403, "{}", a.text());
    let a = send(addr, "POST", "/api/compare", &[("Content-Type", "text/plain")], &body);
    assert_eq!(a.code, 415, "{}", a.text());
    // Nothing was kept.
    assert_eq!(get(addr, "/api/compare")["state"], "none");
    let a = send(
        addr,
        "POST",
        "/api/compare",
        &[("Content-Type", "image/png")],
        b"not a png",
    );
    assert_eq!(a.code, 400, "{}", a.text());
    assert!(a.error().contains("not a readable PNG"), "{}", a.text());
    server.stop();
}
