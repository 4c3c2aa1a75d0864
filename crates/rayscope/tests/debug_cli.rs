//! `rayscope trace --json`, `rayscope view` and `rayscope debug` through the binary.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Command, Stdio};

use assert_cmd::prelude::*;
use serde_json::Value;

/// One of our own scenes, as an argument.
fn scene(name: &str) -> String {
    rayscope_testkit::scene(name).to_str().unwrap().to_owned()
}

fn rayscope() -> Command {
    Command::cargo_bin("rayscope").unwrap()
}

fn trace_json(scene: &str, pixel: &str) -> Value {
    let out = rayscope()
        .args(["trace", "-f", scene, "--pixel", pixel, "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).expect("trace --json prints JSON")
}

#[test]
fn mirror_sphere_pixel_reflects_onto_a_named_wall() {
    // Our room at 400×400: pixel (142, 258) looks at the MirrorBall (centre (-0.4, -0.4, 2.4),
    // radius 0.55) near its middle, so its reflection comes back to the wall behind the camera.
    let walls = [
        "LeftA", "LeftB", "RightA", "RightB", "BackA", "BackB", "FrontA", "FrontB", "Floor", "Ceiling",
    ];
    let room = scene("room.txt");
    mirror_reflects_onto_a_wall(&room, "142,258", "MirrorBall", [-0.4, -0.4, 2.4], 0.55, &walls);
    // The course's scene 2: pixel (150, 150) looks at the MirrorSphere (centre (-0.15, 0.2, 2),
    // radius 0.35): its direction passes 0.09 from the centre.
    let Some(course) = rayscope_testkit::course_part() else {
        return;
    };
    let walls = [
        "LeftWallA",
        "LeftWallB",
        "RightWallA",
        "RightWallB",
        "RearWallA",
        "RearWallB",
        "FarWallA",
        "FarWallB",
        "Floor",
        "Roof",
    ];
    let scene_2 = course.scene("sample_scene_2.txt");
    let scene_2 = scene_2.to_str().unwrap();
    mirror_reflects_onto_a_wall(scene_2, "150,150", "MirrorSphere", [-0.15, 0.2, 2.0], 0.35, &walls);
}

/// `pixel` of `scene` sees the reflective sphere `mirror` (`centre`, `radius`), and its
/// reflection ray starts at the hit and hits one of `walls`.
fn mirror_reflects_onto_a_wall(scene: &str, pixel: &str, mirror: &str, centre: [f64; 3], radius: f64, walls: &[&str]) {
    let t = trace_json(scene, pixel);
    let nodes = t["nodes"].as_array().unwrap();
    let cam = &nodes[0];
    assert_eq!(cam["kind"], "camera");
    assert_eq!(cam["hit"]["entity_name"], mirror);
    assert_eq!(cam["hit"]["material_kind"], "Reflective");
    let refl = nodes
        .iter()
        .find(|n| n["kind"] == "reflection" && n["parent"] == 0)
        .expect("the mirror hit spawns a reflection ray");
    let wall = refl["hit"]["entity_name"]
        .as_str()
        .expect("the reflection hits something");
    assert!(walls.contains(&wall), "reflection hit {wall}");
    // The reflected ray starts on the sphere, at the camera ray's hit point.
    let p: Vec<f64> = cam["hit"]["point"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let o: Vec<f64> = refl["origin"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let d = p.iter().zip(&o).map(|(a, b)| (a - b).powi(2)).sum::<f64>().sqrt();
    assert!(d < 1e-3, "reflection starts {d} from the hit");
    let r = p.iter().zip(centre).map(|(a, c)| (a - c).powi(2)).sum::<f64>().sqrt();
    assert!((r - radius).abs() < 1e-4, "the hit lies on the sphere");
}

#[test]
fn shadow_ray_reports_its_blocker() {
    // Our basic scene at 400×400: pixel (95, 290) is the floor in the sphere's shadow, pixel
    // (200, 390) lit floor.
    shadow_rays_name_their_blocker(&scene("basic.txt"), "95,290", "200,390");
    // The course's scene 1: pixel (100, 300) is black in the course's image, (200, 390) lit.
    let Some(course) = rayscope_testkit::course_part() else {
        return;
    };
    let scene_1 = course.scene("sample_scene_1.txt");
    shadow_rays_name_their_blocker(scene_1.to_str().unwrap(), "100,300", "200,390");
}

/// In `scene` (a Plane, a Sphere and a Light), `shadowed` sees the plane in the sphere's
/// shadow: its shadow ray names the sphere; `lit` sees the plane lit: its shadow ray is clear.
fn shadow_rays_name_their_blocker(scene: &str, shadowed: &str, lit: &str) {
    let t = trace_json(scene, shadowed);
    let nodes = t["nodes"].as_array().unwrap();
    assert_eq!(nodes[0]["hit"]["entity_name"], "Plane");
    let shadow = nodes.iter().find(|n| n["kind"] == "shadow").expect("a shadow ray");
    assert_eq!(shadow["light"], "Light");
    assert_eq!(shadow["blocked_by"], "Sphere");
    let t = trace_json(scene, lit);
    assert_eq!(t["nodes"][0]["hit"]["entity_name"], "Plane");
    let shadow = t["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["kind"] == "shadow")
        .cloned()
        .unwrap();
    assert!(shadow["blocked_by"].is_null());
}

fn view_png(dir: &std::path::Path, name: &str, extra: &[&str]) -> image::RgbImage {
    let out = dir.join(name);
    let s = scene("basic.txt");
    let mut args = vec![
        "view",
        "-f",
        &s,
        "-o",
        out.to_str().unwrap(),
        "-w",
        "9",
        "-h",
        "9",
        "--fov-axis",
        "vertical",
        "--view-width",
        "480",
        "--view-height",
        "320",
        "--quiet",
    ];
    args.extend_from_slice(extra);
    rayscope().args(&args).assert().success();
    image::open(&out).unwrap().to_rgb8()
}

#[test]
fn view_reproduces_the_workshop_steps() {
    let dir = tempfile::tempdir().unwrap();
    let steps = [
        ("frustum.png", ["--rays", "frustum", "--image", "none"]),
        ("ray-0-0.png", ["--rays", "pixel:0,0", "--image", "none"]),
        ("all-rays.png", ["--rays", "all", "--image", "none"]),
        ("all-black.png", ["--rays", "all", "--image", "black"]),
        ("raytraced.png", ["--rays", "all", "--image", "traced"]),
    ];
    let imgs: Vec<image::RgbImage> = steps.iter().map(|(n, a)| view_png(dir.path(), n, a)).collect();
    for (img, (name, _)) in imgs.iter().zip(&steps) {
        assert_eq!(img.dimensions(), (480, 320), "{name}");
    }
    // Each step adds something: no two frames are the same.
    for i in 0..imgs.len() {
        for j in i + 1..imgs.len() {
            assert_ne!(imgs[i], imgs[j], "{} and {}", steps[i].0, steps[j].0);
        }
    }
    // Adding rays adds white; the black image adds near-black pixels.
    let white = |img: &image::RgbImage| img.pixels().filter(|p| p.0.iter().all(|&v| v > 235)).count();
    let black = |img: &image::RgbImage| img.pixels().filter(|p| p.0.iter().all(|&v| v < 12)).count();
    assert!(white(&imgs[1]) > white(&imgs[0]));
    assert!(white(&imgs[2]) > white(&imgs[1]) + 200);
    assert!(black(&imgs[3]) > black(&imgs[2]) + 1000);
}

#[test]
fn view_rejects_bad_flags_without_writing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("v.png");
    let s = scene("basic.txt");
    for bad in [
        vec!["--rays", "sideways"],
        vec!["--rays", "pixel:9,0"],
        vec!["--rays", "row:12"],
        vec!["--image", "sepia"],
        vec!["--eye", "0,0,0", "--target", "0,0,0"],
    ] {
        let mut args = vec!["view", "-f", &s, "-o", out.to_str().unwrap(), "-w", "9", "-h", "9"];
        args.extend(bad.iter().copied());
        let o = rayscope().args(&args).output().unwrap();
        assert_eq!(
            o.status.code(),
            Some(2),
            "{bad:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(!out.exists(), "{bad:?} wrote a file");
    }
    let jpg = dir.path().join("v.jpg");
    let o = rayscope()
        .args(["view", "-f", &s, "-o", jpg.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
}

fn http_get(port: u16, path: &str) -> (u16, String) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut buf = String::new();
    s.read_to_string(&mut buf).unwrap();
    let status = buf.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    let body = buf
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_string())
        .unwrap_or_default();
    (status, body)
}

/// Kills the server when the test ends.
struct Kill(std::process::Child);

impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn debug_serves_the_app_on_a_free_local_port() {
    let mut child = Command::cargo_bin("rayscope")
        .unwrap()
        .args(["debug", &scene("room.txt"), "-w", "40", "-h", "30", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let _kill = Kill(child);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let url = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .expect("prints its URL");
    let port: u16 = url
        .trim_start_matches("http://127.0.0.1:")
        .trim_end_matches('/')
        .parse()
        .unwrap();
    let (code, html) = http_get(port, "/");
    assert_eq!(code, 200);
    assert!(html.contains("rayscope") && html.contains("/app.js"));
    let (code, scene) = http_get(port, "/api/scene");
    assert_eq!(code, 200);
    let v: Value = serde_json::from_str(scene.trim()).unwrap_or_else(|e| panic!("{e}: {scene}"));
    let names: Vec<&str> = v["entities"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    assert!(names.contains(&"MirrorBall") && names.contains(&"BackB"));
    assert_eq!(v["settings"]["width"], 40);
    // Bad requests get a 400 with a message, and the server keeps serving.
    let (code, body) = http_get(port, "/api/trace?x=40&y=0");
    assert_eq!(code, 400, "{body}");
    assert!(body.contains("x must be"));
    let (code, _) = http_get(port, "/api/view?w=99999");
    assert_eq!(code, 400);
    let (code, _) = http_get(port, "/api/scene");
    assert_eq!(code, 200);
}

/// Sends a GET with this `Host` header to `port` on loopback; the status code.
fn get_with_host(port: u16, host: &str) -> u16 {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "GET /api/scene HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut buf = String::new();
    s.read_to_string(&mut buf).unwrap();
    buf.split(' ').nth(1).and_then(|c| c.parse().ok()).unwrap_or(0)
}

#[test]
fn debug_on_every_interface_warns_prints_its_address_and_keeps_the_host_check() {
    let mut child = Command::cargo_bin("rayscope")
        .unwrap()
        .args(["debug", &scene("basic.txt"), "-w", "8", "-h", "8", "--quiet"])
        .args(["--host", "0.0.0.0", "--allow-host", "Lab-PC.local"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let stderr = child.stderr.take().unwrap();
    let _kill = Kill(child);
    let mut out = BufReader::new(stdout);
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    // The real bound address, with its port, not 127.0.0.1.
    let bound = first
        .split_whitespace()
        .find(|w| w.starts_with("http://0.0.0.0:"))
        .unwrap_or_else(|| panic!("prints the bound address: {first}"));
    let port: u16 = bound
        .trim_start_matches("http://0.0.0.0:")
        .trim_end_matches('/')
        .parse()
        .unwrap();
    let mut rest = String::new();
    for _ in 0..4 {
        out.read_line(&mut rest).unwrap();
    }
    assert!(rest.contains(&format!("http://127.0.0.1:{port}/")), "{rest}");
    assert!(rest.contains(&format!("http://lab-pc.local:{port}/")), "{rest}");
    let mut warning = String::new();
    BufReader::new(stderr).read_line(&mut warning).unwrap();
    assert!(
        warning.starts_with("WARNING:") && warning.contains(&format!("0.0.0.0:{port}")),
        "{warning}"
    );
    // Any address of the machine and the listed name are answered; a name that could be
    // rebound to this machine is not.
    assert_eq!(get_with_host(port, &format!("127.0.0.1:{port}")), 200);
    assert_eq!(get_with_host(port, &format!("192.168.1.5:{port}")), 200);
    assert_eq!(get_with_host(port, &format!("lab-pc.local:{port}")), 200);
    assert_eq!(get_with_host(port, &format!("evil.example:{port}")), 403);
}

#[test]
fn debug_refuses_images_over_its_limit() {
    let o = rayscope()
        .args(["debug", &scene("basic.txt"), "-w", "4096", "-h", "16"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("2048"));
}

#[test]
fn view_shows_sub_pixel_and_lens_samples() {
    let dir = tempfile::tempdir().unwrap();
    // Orange marks the aperture ring and where lens samples leave it; cyan the sub-pixel samples.
    let orange = |img: &image::RgbImage| {
        img.pixels()
            .filter(|p| p[0] > 230 && (120..200).contains(&p[1]) && p[2] < 80)
            .count()
    };
    let cyan = |img: &image::RgbImage| img.pixels().filter(|p| p[0] < 110 && p[1] > 200 && p[2] > 230).count();
    let plain = view_png(dir.path(), "plain.png", &["--rays", "pixel:4,4"]);
    let grid = view_png(dir.path(), "grid.png", &["--rays", "pixel:4,4", "-x", "3", "--samples"]);
    let lens = view_png(
        dir.path(),
        "lens.png",
        &["--rays", "pixel:4,4", "-x", "3", "--samples", "-r", "0.2", "-t", "2"],
    );
    assert!(cyan(&grid) > cyan(&plain) + 20, "sub-pixel sample rays are drawn");
    assert!(
        orange(&lens) > orange(&grid) + 20,
        "the aperture ring and lens samples are drawn"
    );
    rayscope()
        .args([
            "view",
            "-f",
            &scene("basic.txt"),
            "-o",
            dir.path().join("x.png").to_str().unwrap(),
            "--samples",
        ])
        .assert()
        .code(2);
}

/// `rayscope view --rays-log`: the student's rays drawn dashed beside rayscope's, the first one
/// that disagrees over an orange halo, the verdict map tinting the grid.
#[test]
fn view_draws_a_students_ray_log() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("mine.jsonl");
    // Pixel (4, 4), the centre of the 9×9 image, whose camera ray points straight ahead: this
    // one points off to the upper right.
    std::fs::write(
        &log,
        concat!(
            r#"{"pixel":[4,4],"sample":0,"id":0,"kind":"camera","origin":[0,0,0],"direction":[0.35,0.2,1],"hit":null}"#,
            "\n",
            r#"{"pixel":[3,4],"sample":0,"id":0,"kind":"camera","origin":[0,0,0],"direction":[-0.0641,0,1]}"#,
            "\n"
        ),
    )
    .unwrap();
    let plain = view_png(dir.path(), "plain.png", &["--rays", "pixel:4,4", "--tree"]);
    let with = view_png(
        dir.path(),
        "with.png",
        &["--rays", "pixel:4,4", "--tree", "--rays-log", log.to_str().unwrap()],
    );
    let changed = plain.pixels().zip(with.pixels()).filter(|(a, b)| a != b).count();
    assert!(changed > 150, "the student's ray changed {changed} pixels");
    let orange = |img: &image::RgbImage| {
        img.pixels()
            .filter(|p| p.0[0] > 200 && (60..170).contains(&p.0[1]) && p.0[2] < 90)
            .count()
    };
    assert!(
        orange(&with) > orange(&plain) + 40,
        "no halo: {} vs {}",
        orange(&with),
        orange(&plain)
    );
    // Without a pixel: the log's rays over the image, and the grid's red cell.
    let all = view_png(dir.path(), "all.png", &["--rays-log", log.to_str().unwrap()]);
    let none = view_png(dir.path(), "none.png", &[]);
    assert!(all.pixels().zip(none.pixels()).filter(|(a, b)| a != b).count() > 150);
    // A log that does not fit the image is refused, naming the line.
    std::fs::write(&log, r#"{"pixel":[40,4],"origin":[0,0,0],"direction":[0,0,1]}"#).unwrap();
    let s = scene("basic.txt");
    let out = dir.path().join("bad.png");
    let o = rayscope()
        .args(["view", "-f", &s, "-o", out.to_str().unwrap(), "-w", "9", "-h", "9"])
        .args(["--rays-log", log.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("mine.jsonl:1:"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!out.exists());
}

/// `rayscope debug SCENE --rays LOG --image IMAGE`: judged at the start, served to the page.
#[test]
fn debug_judges_the_log_it_is_given() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("mine.jsonl");
    std::fs::write(
        &log,
        r#"{"pixel":[4,4],"sample":0,"id":0,"kind":"camera","origin":[0,0,0],"direction":[0.35,0.2,1]}"#,
    )
    .unwrap();
    let png = dir.path().join("mine.png");
    image::RgbImage::from_pixel(9, 9, image::Rgb([10, 20, 30]))
        .save(&png)
        .unwrap();
    let missing = dir.path().join("nope.jsonl");
    let o = rayscope()
        .args([
            "debug",
            &scene("basic.txt"),
            "-w",
            "9",
            "-h",
            "9",
            "--rays",
            missing.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let mut child = Command::cargo_bin("rayscope")
        .unwrap()
        .args([
            "debug",
            &scene("basic.txt"),
            "-w",
            "9",
            "-h",
            "9",
            "--fov-axis",
            "vertical",
            "--quiet",
        ])
        .args(["--rays", log.to_str().unwrap(), "--image", png.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let _kill = Kill(child);
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).unwrap();
    let port: u16 = line
        .split_whitespace()
        .find(|w| w.starts_with("http://127.0.0.1:"))
        .expect("prints its URL")
        .trim_start_matches("http://127.0.0.1:")
        .trim_end_matches('/')
        .parse()
        .unwrap();
    let mut v = Value::Null;
    for _ in 0..300 {
        let (code, body) = http_get(port, "/api/rays/summary");
        assert_eq!(code, 200, "{body}");
        v = serde_json::from_str(body.trim()).unwrap();
        if v["state"] != "judging" {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    assert_eq!(v["state"], "done", "{v:#}");
    assert_eq!(v["judged"]["pixels"]["disagrees"], 1);
    assert_eq!(v["judged"]["disagreeing"][0], serde_json::json!([4, 4]));
    assert_eq!(v["image"]["matches"], true);
    let (code, body) = http_get(port, "/api/rays/pixel?x=4&y=4");
    assert_eq!(code, 200);
    let p: Value = serde_json::from_str(body.trim()).unwrap();
    assert_eq!(p["divergence"]["code"], "camera.direction", "{p:#}");
    assert_eq!(p["their_rgb8"], serde_json::json!([10, 20, 30]));
    // The image is compared with the render too, and read pixel by pixel.
    let mut c = Value::Null;
    for _ in 0..300 {
        let (code, body) = http_get(port, "/api/compare");
        assert_eq!(code, 200, "{body}");
        c = serde_json::from_str(body.trim()).unwrap();
        if c["state"] != "rendering" {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    assert_eq!(c["state"], "done", "{c:#}");
    assert_eq!(c["image"]["width"], 9);
    assert!(c["psnr"].is_number(), "{c:#}");
    let (code, body) = http_get(port, "/api/compare/pixel?x=4&y=4");
    assert_eq!(code, 200, "{body}");
    let q: Value = serde_json::from_str(body.trim()).unwrap();
    assert_eq!(q["yours"], serde_json::json!([10, 20, 30]));
    assert_eq!(q["rayscope"], p["rayscope_rgb8"]);
}
