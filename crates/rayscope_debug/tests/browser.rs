//! The debugger in a real browser: headless Chromium driven through chromedriver (WebDriver)
//! with fantoccini. Needs the Debian packages `chromium` and `chromium-driver`.
//!
//! Without them the test fails when `CI=true`; otherwise it says on the terminal that it did
//! not run (see `rayscope_testkit::not_run`).
//! Screenshots go to `target/browser-screenshots/`.

#[path = "../../rayscope_core/tests/student/mod.rs"]
#[allow(dead_code)]
mod student;

use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use rayscope_core::{CameraSettings, FovAxis, RenderSettings, Scene};
use rayscope_debug::{RunningServer, ServeConfig, ServerLimits};
use serde_json::json;

fn find_exe(names: &[&str]) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    for dir in std::env::split_paths(&path) {
        for n in names {
            let p = dir.join(n);
            if p.is_file() {
                return Some(p);
            }
        }
    }
    None
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Kills chromedriver (and so its browser) when the test ends, pass or fail.
struct Driver(Child);

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Stops the debugger server when the test ends.
struct Server(Option<RunningServer>);

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(s) = self.0.take() {
            s.stop();
        }
    }
}

/// The debugger on `scene_path` at `w`×`h`, stage 2, on a free local port, and its URL.
fn serve_stage_two(scene_path: PathBuf, w: u32, h: u32) -> (Server, String) {
    let file = rayscope_scene::load(&scene_path).unwrap();
    let scene = Scene::from_file(&file);
    let server = rayscope_debug::start(ServeConfig {
        scene_path,
        scene_file: file,
        scene,
        settings: RenderSettings {
            width: w,
            height: h,
            stage: rayscope_core::Stage::Two,
            ..RenderSettings::default()
        },
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits: ServerLimits::default(),
        student: Default::default(),
    })
    .expect("debugger starts");
    let url = server.url.clone();
    (Server(Some(server)), url)
}

fn screenshots_dir() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/browser-screenshots");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

async fn shot(c: &Client, name: &str) {
    let png = c.screenshot().await.expect("screenshot");
    let path = screenshots_dir().join(name);
    std::fs::write(&path, png).unwrap();
    eprintln!("screenshot: {}", path.display());
}

/// Polls `f` until it returns `Some`, for up to `secs` seconds.
async fn wait_for<T, F, Fut>(what: &str, secs: u64, mut f: F) -> T
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = Option<T>>,
{
    let end = Instant::now() + Duration::from_secs(secs);
    loop {
        if let Some(v) = f().await {
            return v;
        }
        assert!(Instant::now() < end, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn attr(c: &Client, css: &str, name: &str) -> Option<String> {
    let e = c.find(Locator::Css(css)).await.ok()?;
    e.attr(name).await.ok().flatten()
}

/// Chromium and chromedriver, or `None` after reporting the test as not run (a failure under
/// CI=true).
fn chromium_and_driver() -> Option<(PathBuf, PathBuf)> {
    let chromium = find_exe(&["chromium", "chromium-browser", "google-chrome"]);
    let driver = find_exe(&["chromedriver"]);
    let (Some(chromium), Some(driver)) = (chromium, driver) else {
        rayscope_testkit::not_run(
            "needs chromium and chromedriver",
            "No chromium (or chromium-browser, google-chrome) and chromedriver found on PATH.",
            "To run it, install them (Debian: apt-get install chromium chromium-driver).",
        );
        return None;
    };
    Some((chromium, driver))
}

/// Starts chromedriver, connects a headless Chromium to it and runs `drive` against `url`;
/// takes `failure.png` and panics when `drive` fails.
fn in_chromium<F, Fut>(chromium: &Path, driver: &Path, url: &str, failure: &str, drive: F)
where
    F: FnOnce(Client, String) -> Fut,
    Fut: std::future::Future<Output = (Client, Result<(), String>)>,
{
    let port = free_port();
    let _driver = Driver(
        Command::new(driver)
            .arg(format!("--port={port}"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("chromedriver starts"),
    );
    let profile = tempfile_dir();
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async move {
        let mut caps = serde_json::Map::new();
        caps.insert(
            "goog:chromeOptions".into(),
            json!({
                "binary": chromium.to_string_lossy(),
                "args": [
                    "--headless", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                    "--disable-background-networking", "--disable-component-update", "--disable-sync",
                    "--no-first-run", "--window-size=1500,950",
                    format!("--user-data-dir={}", profile.display()),
                ],
            }),
        );
        let webdriver = format!("http://127.0.0.1:{port}");
        let c = wait_for("chromedriver", 20, || {
            let caps = caps.clone();
            let webdriver = webdriver.clone();
            async move {
                ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
                    .capabilities(caps)
                    .connect(&webdriver)
                    .await
                    .ok()
            }
        })
        .await;
        let (c, result) = drive(c, url.to_string()).await;
        if result.is_err() {
            shot(&c, failure).await;
        }
        let _ = c.close().await;
        if let Err(e) = result {
            panic!("{e}");
        }
    });
    let _ = std::fs::remove_dir_all(tempfile_dir());
}

#[test]
fn debugger_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };

    // The debugger, in process, on a free port: our basic scene as in the workshop (9×9,
    // vertical FOV).
    let scene_path = rayscope_testkit::scene("basic.txt");
    let file = rayscope_scene::load(&scene_path).unwrap();
    let scene = Scene::from_file(&file);
    let settings = RenderSettings {
        width: 9,
        height: 9,
        camera: CameraSettings {
            fov_axis: FovAxis::Vertical,
            ..CameraSettings::default()
        },
        ..RenderSettings::default()
    };
    let server = rayscope_debug::start(ServeConfig {
        scene_path,
        scene_file: file,
        scene,
        settings,
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits: ServerLimits::default(),
        student: Default::default(),
    })
    .expect("debugger starts");
    let url = server.url.clone();
    let _server = Server(Some(server));

    in_chromium(&chromium, &driver, &url, "failure.png", |c, url| async move {
        let r = drive(&c, &url).await;
        (c, r)
    });
}

fn tempfile_dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "rayscope-chromium-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::create_dir_all(&d).unwrap();
    d
}

async fn drive(c: &Client, url: &str) -> Result<(), String> {
    c.goto(url).await.map_err(|e| e.to_string())?;
    wait_for("the page to load the scene", 20, || async {
        attr(c, "body", "data-ready").await.filter(|v| v == "1")
    })
    .await;

    // The hierarchy lists the scene's entities by name.
    let names: Vec<String> = {
        let mut v = Vec::new();
        for e in c
            .find_all(Locator::Css("#hierarchy li.entity .name"))
            .await
            .map_err(|e| e.to_string())?
        {
            v.push(e.text().await.map_err(|e| e.to_string())?);
        }
        v
    };
    assert_eq!(names, ["Plane", "Sphere", "Triangle"], "hierarchy entities");
    let lights = c
        .find(Locator::Css("#hierarchy li.light .name"))
        .await
        .map_err(|e| e.to_string())?;
    assert_eq!(lights.text().await.map_err(|e| e.to_string())?, "Light");

    // The view arrives with a 9×9 grid: 10 × 10 lines.
    wait_for("the first view frame", 20, || async {
        attr(c, "#view", "data-grid-x").await.filter(|v| v == "10")
    })
    .await;
    wait_for("the rendered image", 20, || async {
        attr(c, "#image", "data-loaded").await.filter(|v| v == "9x9")
    })
    .await;
    shot(c, "01-loaded.png").await;

    // Change the width like a user: type into the inspector's field and leave it.
    let width = c.find(Locator::Css("#set-width")).await.map_err(|e| e.to_string())?;
    width.clear().await.map_err(|e| e.to_string())?;
    width.send_keys("12\u{e004}").await.map_err(|e| e.to_string())?;
    wait_for("the grid to follow the width", 20, || async {
        let x = attr(c, "#view", "data-grid-x").await?;
        let y = attr(c, "#view", "data-grid-y").await?;
        (x == "13" && y == "10").then_some(())
    })
    .await;
    wait_for("the 12×9 render", 20, || async {
        attr(c, "#image", "data-loaded").await.filter(|v| v == "12x9")
    })
    .await;
    shot(c, "02-width-12.png").await;

    // Click the image's centre pixel: its ray tree names the sphere.
    let image = c.find(Locator::Css("#image")).await.map_err(|e| e.to_string())?;
    image.click().await.map_err(|e| e.to_string())?;
    let entity = wait_for("the ray tree", 20, || async {
        let cell = c
            .find(Locator::Css("#tree tbody tr:first-child td.entity"))
            .await
            .ok()?;
        cell.text().await.ok().filter(|t| !t.is_empty())
    })
    .await;
    assert_eq!(entity, "Sphere", "the centre pixel's camera ray hits the sphere");
    let head = c.find(Locator::Css("#tree-head")).await.map_err(|e| e.to_string())?;
    let head = head.text().await.map_err(|e| e.to_string())?;
    // WebDriver clicks the middle of the element's visible part: a pixel near the centre.
    let near_centre = ["(5, 3)", "(5, 4)", "(6, 3)", "(6, 4)"]
        .iter()
        .any(|p| head.starts_with(&format!("pixel {p}")));
    assert!(near_centre, "{head}");
    // A shadow ray towards the light is listed too.
    let kinds = c
        .find_all(Locator::Css("#tree tbody td.k"))
        .await
        .map_err(|e| e.to_string())?;
    let mut ks = Vec::new();
    for k in kinds {
        ks.push(k.text().await.map_err(|e| e.to_string())?);
    }
    assert!(
        ks.contains(&"camera".to_string()) && ks.contains(&"shadow".to_string()),
        "{ks:?}"
    );
    // Give the view a moment to show the tree.
    tokio::time::sleep(Duration::from_millis(600)).await;
    shot(c, "03-ray-tree.png").await;

    // rayscope's own self-test is out of a student's way: offered only with ?selftest=1.
    let offered = c
        .find(Locator::Css("#check-btn"))
        .await
        .map_err(|e| e.to_string())?
        .is_displayed()
        .await
        .map_err(|e| e.to_string())?;
    assert!(!offered, "the self-test button shows on a student's page");
    let self_test = format!("{url}?selftest=1");
    c.goto(&self_test).await.map_err(|e| e.to_string())?;
    wait_for("the page with the self-test", 20, || async {
        attr(c, "body", "data-ready").await.filter(|v| v == "1")
    })
    .await;
    // Check the intersector: both agree on this scene.
    c.find(Locator::Css("#check-btn"))
        .await
        .map_err(|e| e.to_string())?
        .click()
        .await
        .map_err(|e| e.to_string())?;
    let summary = wait_for("the intersector check", 30, || async {
        let e = c.find(Locator::Css("#check-summary")).await.ok()?;
        e.text().await.ok().filter(|t| t.contains("disagree"))
    })
    .await;
    assert!(summary.starts_with("0 of 108 pixels disagree"), "{summary}");
    shot(c, "04-check.png").await;

    // The same page under another origin (localhost and 127.0.0.1 are different origins and
    // sites) works against its own server, but cannot change the settings at 127.0.0.1 the
    // ways a page can without a preflight, nor with one.
    let other = url.replace("127.0.0.1", "localhost");
    c.goto(&other).await.map_err(|e| e.to_string())?;
    wait_for("the page under localhost", 20, || async {
        attr(c, "body", "data-ready").await.filter(|v| v == "1")
    })
    .await;
    let outcomes = c
        .execute_async(
            r#"const [target, done] = arguments;
            const body = JSON.stringify({ width: 5 });
            const form = new URLSearchParams({ width: "5" });
            Promise.allSettled([
              fetch(target + "api/settings", { method: "POST", mode: "no-cors", headers: { "content-type": "text/plain" }, body }),
              fetch(target + "api/settings", { method: "POST", mode: "no-cors", body: form }),
              fetch(target + "api/settings", { method: "POST", headers: { "content-type": "application/json" }, body }),
            ]).then((rs) => done(rs.map((r) => r.status === "fulfilled" ? r.value.type : "refused")));"#,
            vec![json!(url)],
        )
        .await
        .map_err(|e| e.to_string())?;
    // The page reads none of the answers: the no-cors posts get an opaque answer or none (the
    // server's Cross-Origin-Resource-Policy), the JSON one needs a preflight, never granted.
    let outcomes: Vec<&str> = outcomes
        .as_array()
        .ok_or("outcomes")?
        .iter()
        .map(|v| v.as_str().unwrap_or("?"))
        .collect();
    assert!(
        outcomes[..2].iter().all(|o| *o == "opaque" || *o == "refused") && outcomes[2] == "refused",
        "cross-origin fetches: {outcomes:?}"
    );
    let width = c
        .execute_async(
            r#"const [done] = arguments;
            fetch("/api/settings").then((r) => r.json()).then((v) => done(v.settings.width));"#,
            vec![],
        )
        .await
        .map_err(|e| e.to_string())?;
    assert_eq!(width, json!(12), "no forged request changed the settings");
    Ok(())
}

/// A student's ray log in the page: loaded through the file picker, the verdict map over the
/// image and the grid, a red pixel clicked, the two trees side by side and the divergence
/// explained. The log is the student-style Python tracer's with its refraction mistake.
#[test]
fn student_log_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    if !python3() {
        return;
    }
    let (w, h) = (32u32, 24u32);
    let scene_path = rayscope_testkit::scene("whitted.txt");
    let dir = std::env::temp_dir().join(format!("rayscope-chromium-log-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("my_rays.jsonl");
    std::fs::write(
        &log,
        student_tracer_log(&scene_path, w, h, &["--bug", "refraction-normal"]),
    )
    .unwrap();
    // The fixed tracer's log of the top-left corner, dropped on the page afterwards.
    let fixed = student_tracer_log(&scene_path, w, h, &["--region", "0,0,8,6"]);

    let (_server, url) = serve_stage_two(scene_path, w, h);
    let log2 = log.clone();
    in_chromium(&chromium, &driver, &url, "student-failure.png", |c, url| async move {
        let r = drive_student_log(&c, &url, &log2, fixed).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// Whether python3 runs, after reporting the test as not run (a failure under CI=true) where it
/// does not: the student-style tracer that writes the logs is a Python script.
fn python3() -> bool {
    let python = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !python {
        rayscope_testkit::not_run(
            "needs python3",
            "No python3 found on PATH: the student-style tracer that writes the log is a Python script.",
            "To run it, install Python 3 (Debian: apt-get install python3).",
        );
    }
    python
}

/// The ray log of rayscope_check's student-style tracer on `scene` at `w`×`h`, run with `args`.
fn student_tracer_log(scene: &Path, w: u32, h: u32, args: &[&str]) -> String {
    let out = Command::new("python3")
        .arg(rayscope_testkit::workspace().join("crates/rayscope_check/tests/student/tracer.py"))
        .arg("-f")
        .arg(scene)
        .args(["-w", &w.to_string(), "-h", &h.to_string(), "--log", "-"])
        .args(args)
        .output()
        .expect("run the student tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("the log is text")
}

/// Opens the page at `url` and waits for the scene, then for rayscope's render of `size`
/// ("WxH") for at most `secs` seconds.
async fn open_page(c: &Client, url: &str, size: &str, secs: u64) -> Result<(), String> {
    c.goto(url).await.map_err(|e| e.to_string())?;
    wait_for("the page to load the scene", 20, || async {
        attr(c, "body", "data-ready").await.filter(|v| v == "1")
    })
    .await;
    wait_for("the rendered image", secs, || async {
        attr(c, "#image", "data-loaded").await.filter(|v| v == size)
    })
    .await;
    Ok(())
}

/// A mouse click on the image at (dx, dy) from its in-view centre, as WebDriver measures it.
async fn click_image(c: &Client, dx: f64, dy: f64) -> Result<(), String> {
    use fantoccini::actions::{InputSource, MouseActions, PointerAction, MOUSE_BUTTON_LEFT};
    let e = |e: fantoccini::error::CmdError| e.to_string();
    let image = c.find(Locator::Css("#image")).await.map_err(e)?;
    let click = MouseActions::new("mouse".into())
        .then(PointerAction::MoveToElement {
            element: image,
            duration: None,
            x: dx,
            y: dy,
        })
        .then(PointerAction::Down {
            button: MOUSE_BUTTON_LEFT,
        })
        .then(PointerAction::Up {
            button: MOUSE_BUTTON_LEFT,
        });
    c.perform_actions(click).await.map_err(e)
}

async fn drive_student_log(c: &Client, url: &str, log: &Path, fixed: String) -> Result<(), String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    open_page(c, url, "32x24", 30).await?;

    // Load the log through the file picker, as a student would.
    let input = c.find(Locator::Css("#rays-file")).await.map_err(e)?;
    input.send_keys(&log.to_string_lossy()).await.map_err(e)?;
    let state = wait_for("the log to be judged", 60, || async {
        attr(c, "#rays-summary", "data-state")
            .await
            .filter(|v| v == "done" || v == "error")
    })
    .await;
    let summary = c
        .find(Locator::Css("#rays-summary"))
        .await
        .map_err(e)?
        .text()
        .await
        .map_err(e)?;
    assert_eq!(state, "done", "{summary}");
    assert!(summary.starts_with("my_rays.jsonl: "), "{summary}");
    let red: u32 = attr(c, "#rays-summary", "data-disagree")
        .await
        .and_then(|v| v.parse().ok())
        .ok_or("no count of red pixels")?;
    assert!(red > 10, "{summary}");
    let codes = c
        .find(Locator::Css("#rays-codes"))
        .await
        .map_err(e)?
        .text()
        .await
        .map_err(e)?;
    assert!(codes.contains("refraction.normal-not-flipped"), "{codes}");
    // Under the headline, the catalogue's entry for the mistake, with the render that shows it.
    let name = rayscope_core::Mistake::RefractionNoNormalFlip.info().name;
    assert!(
        codes.contains(&format!("rayscope's catalogue: {name}")) && codes.contains(&format!("--mistake {name}")),
        "{codes}"
    );

    // The verdict map over the image, and the student's rays in the view.
    wait_for("the verdict map on the image", 20, || async {
        attr(c, "#image-overlay", "data-verdicts")
            .await
            .filter(|v| *v == red.to_string())
    })
    .await;
    let legend = c.find(Locator::Css("#legend-yours")).await.map_err(e)?;
    assert!(
        legend.is_displayed().await.map_err(e)?,
        "the legend shows the student's dashed rays"
    );
    shot(c, "05-student-log-loaded.png").await;

    // Click a red pixel (one from the middle of the list the page got).
    let v = c
        .execute_async(
            r#"const [done] = arguments;
            fetch("/api/rays/summary").then((r) => r.json()).then((s) => {
              const list = s.judged.disagreeing;
              const p = list[Math.floor(list.length / 2)];
              const img = document.getElementById("image");
              const r = img.getBoundingClientRect();
              // WebDriver offsets count from the element's in-view centre: the centre of the part
              // of its box inside the viewport.
              const left = Math.max(r.left, 0), right = Math.min(r.right, window.innerWidth);
              const top = Math.max(r.top, 0), bottom = Math.min(r.bottom, window.innerHeight);
              const tx = r.left + (p[0] + 0.5) / 32 * r.width, ty = r.top + (p[1] + 0.5) / 24 * r.height;
              done({ x: p[0], y: p[1], dx: Math.round(tx - (left + right) / 2), dy: Math.round(ty - (top + bottom) / 2), w: r.width, h: r.height });
            });"#,
            vec![],
        )
        .await
        .map_err(e)?;
    let (x, y) = (v["x"].as_u64().ok_or("x")?, v["y"].as_u64().ok_or("y")?);
    let (iw, ih) = (v["w"].as_f64().ok_or("w")?, v["h"].as_f64().ok_or("h")?);
    let (dx, dy) = (v["dx"].as_f64().ok_or("dx")?, v["dy"].as_f64().ok_or("dy")?);
    click_image(c, dx, dy).await?;
    let code = wait_for("the divergence to be explained", 30, || async {
        attr(c, "#rays-divergence-box", "data-code").await
    })
    .await;
    let head = c
        .find(Locator::Css("#rays-pixel-head"))
        .await
        .map_err(e)?
        .text()
        .await
        .map_err(e)?;
    assert!(
        head.starts_with(&format!("pixel ({x}, {y}): disagrees")),
        "clicked ({x}, {y}) at offset ({dx}, {dy}) of a {iw}×{ih} image: {head}"
    );
    assert_eq!(code, "refraction.normal-not-flipped", "{head}");
    let text = c
        .find(Locator::Css("#rays-divergence-box"))
        .await
        .map_err(e)?
        .text()
        .await
        .map_err(e)?;
    assert!(
        text.contains("refraction leaving glass used the outward normal") && text.contains("flipped to face the ray"),
        "{text}"
    );
    // The two trees pair by pair, the divergent pair marked, a refraction on both sides.
    let cells = c
        .find_all(Locator::Css("#rays-table tr.diverge td.k"))
        .await
        .map_err(e)?;
    let mut kinds = Vec::new();
    for k in cells {
        let t = k.prop("textContent").await.map_err(e)?.unwrap_or_default();
        kinds.push(t.trim().to_string());
    }
    assert_eq!(kinds, ["refraction", "refraction"], "{kinds:?}");
    // In a 1400×900 window the explanation and the aligned rays fit the panel's width: nothing
    // to scroll sideways.
    c.set_window_size(1400, 900).await.map_err(e)?;
    tokio::time::sleep(Duration::from_millis(500)).await;
    let widths = c
        .execute(
            r#"const t = document.getElementById("rays-tab");
            return [t.scrollWidth, t.clientWidth, window.innerWidth];"#,
            vec![],
        )
        .await
        .map_err(e)?;
    let w: Vec<u64> = serde_json::from_value(widths).map_err(|x| x.to_string())?;
    assert!(
        w[2] <= 1400 && w[0] <= w[1],
        "the rays panel scrolls sideways at 1400×900: {w:?}"
    );
    shot(c, "06c-student-divergence-1400x900.png").await;
    c.set_window_size(1500, 950).await.map_err(e)?;
    // The view draws the student's rays of the pixel.
    wait_for("a view with the student's rays", 20, || async {
        attr(c, "#view", "data-student").await.filter(|v| v == "1")
    })
    .await;
    tokio::time::sleep(Duration::from_millis(800)).await;
    shot(c, "06-student-divergence.png").await;

    // The fixed tracer's log dropped on the page: the drop hint shows while a file is dragged
    // over, and the new log replaces the old one.
    let hint = c
        .execute(
            r#"const [text] = arguments;
            const dt = new DataTransfer();
            dt.items.add(new File([text], "fixed_rays.jsonl", { type: "application/x-ndjson" }));
            document.body.dispatchEvent(new DragEvent("dragenter", { dataTransfer: dt, bubbles: true }));
            const shown = !document.getElementById("drop-hint").classList.contains("hidden");
            document.body.dispatchEvent(new DragEvent("drop", { dataTransfer: dt, bubbles: true, cancelable: true }));
            return shown;"#,
            vec![serde_json::Value::String(fixed)],
        )
        .await
        .map_err(e)?;
    assert_eq!(
        hint,
        serde_json::Value::Bool(true),
        "the drop hint did not show during the drag"
    );
    let summary = wait_for("the dropped log to be judged", 60, || async {
        let t = c.find(Locator::Css("#rays-summary")).await.ok()?.text().await.ok()?;
        let done = attr(c, "#rays-summary", "data-state")
            .await
            .filter(|v| v == "done" || v == "error");
        (t.starts_with("fixed_rays.jsonl: ") && done.is_some()).then_some(t)
    })
    .await;
    let red = attr(c, "#rays-summary", "data-disagree").await;
    assert_eq!(red.as_deref(), Some("0"), "{summary}");
    let hidden = attr(c, "#drop-hint", "class").await.unwrap_or_default();
    assert!(
        hidden.contains("hidden"),
        "the drop hint stays after the drop: {hidden}"
    );
    // A log of 48 of the 768 pixels: each logged pixel is marked, whatever the zoom.
    wait_for("a marker on each logged pixel", 20, || async {
        attr(c, "#image-overlay", "data-markers").await.filter(|v| v == "48")
    })
    .await;
    // The same 48 pixels listed with their verdicts; filtered to those that disagree, none; a row
    // selects its pixel.
    let rows = wait_for("the list of logged pixels", 20, || async {
        attr(c, "#rays-logged", "data-rows").await.filter(|v| v == "48")
    })
    .await;
    assert_eq!(rows, "48");
    choose(c, "#rays-logged-filter", "disagrees").await?;
    assert_eq!(attr(c, "#rays-logged", "data-rows").await.as_deref(), Some("0"));
    choose(c, "#rays-logged-filter", "").await?;
    c.find(Locator::Css("#rays-logged-list tbody tr:nth-child(2)"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    wait_for("the listed pixel's rays", 30, || async {
        let t = c.find(Locator::Css("#rays-pixel-head")).await.ok()?.text().await.ok()?;
        t.starts_with("pixel (1, 0)").then_some(t)
    })
    .await;
    shot(c, "06b-student-log-dropped.png").await;

    // That log has rays only for pixels x < 8, y < 6: a click three pixels right of them selects
    // the nearest logged pixel, (7, 3).
    let v = c
        .execute(
            r#"const img = document.getElementById("image");
            const r = img.getBoundingClientRect();
            const left = Math.max(r.left, 0), right = Math.min(r.right, window.innerWidth);
            const top = Math.max(r.top, 0), bottom = Math.min(r.bottom, window.innerHeight);
            const tx = r.left + 10.5 / 32 * r.width, ty = r.top + 3.5 / 24 * r.height;
            return { dx: Math.round(tx - (left + right) / 2), dy: Math.round(ty - (top + bottom) / 2) };"#,
            vec![],
        )
        .await
        .map_err(e)?;
    let (dx, dy) = (v["dx"].as_f64().ok_or("dx")?, v["dy"].as_f64().ok_or("dy")?);
    click_image(c, dx, dy).await?;
    let head = wait_for("the snapped pixel's rays", 30, || async {
        let t = c.find(Locator::Css("#rays-pixel-head")).await.ok()?.text().await.ok()?;
        t.starts_with("pixel (7, 3)").then_some(t)
    })
    .await;
    assert!(head.contains("agrees"), "{head}");

    // No mistake in those 48 pixels and no picture loaded: the page says how to log an even grid.
    let next = wait_for("the advice on what to log next", 20, || async {
        let t = c.find(Locator::Css("#rays-next")).await.ok()?.text().await.ok()?;
        t.contains("RAYSCOPE_LOG=").then_some(t)
    })
    .await;
    assert!(next.contains("RAYSCOPE_LOG_STEP="), "{next}");
    // The student's picture, wrong in the glass ball, loaded beside that log: the pixels where it
    // differs that the log lacks, as the kits' variables, and the check command to run after.
    let (_, dir, png) = student_png("next", &["refraction-no-normal-flip"], 32, 24, "mine.png");
    let input = c.find(Locator::Css("#rays-image-file")).await.map_err(e)?;
    input.send_keys(&png.to_string_lossy()).await.map_err(e)?;
    // Loading a picture shows the comparison; the advice is on the "your rays" tab.
    c.find(Locator::Css(".tab[data-tab='rays-tab']"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    let headline = wait_for("the pixels to log next", 60, || async {
        let t = c
            .find(Locator::Css("#rays-next-headline"))
            .await
            .ok()?
            .text()
            .await
            .ok()?;
        t.starts_with("No mistake in your log, but your image differs")
            .then_some(t)
    })
    .await;
    let next = c
        .find(Locator::Css("#rays-next"))
        .await
        .map_err(e)?
        .text()
        .await
        .map_err(e)?;
    let _ = std::fs::remove_dir_all(&dir);
    assert!(
        next.contains("RAYSCOPE_LOG=") && next.contains("RAYSCOPE_LOG_PIXELS=") && next.contains("rayscope check"),
        "{headline}\n{next}"
    );
    assert!(next.contains("--image mine.png"), "{next}");
    shot(c, "06d-student-log-next.png").await;
    Ok(())
}

/// The student-style tracer's picture of our whitted scene with `mistakes`, saved as `name` in a
/// folder of its own: the scene, the folder (to remove afterwards) and the picture.
fn student_png(test: &str, mistakes: &[&'static str], w: u32, h: u32, name: &str) -> (PathBuf, PathBuf, PathBuf) {
    let scene_path = rayscope_testkit::scene("whitted.txt");
    let file = rayscope_scene::load(&scene_path).unwrap();
    let theirs = student::Student::new(&file, mistakes, student::Options::new(w, h)).render();
    let dir = std::env::temp_dir().join(format!("rayscope-chromium-{test}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join(name);
    image::RgbImage::from_raw(w, h, theirs).unwrap().save(&png).unwrap();
    (scene_path, dir, png)
}

/// A student's wrong picture in the page, at the course's 400×400: it fits the panel below 1×,
/// is loaded through the file picker, compared and diagnosed (the mistake named, the
/// differences attributed to the glass ball), shown as a heat map with its scale, flickered
/// against rayscope's render and side by side; hovering a pixel reads both values and the
/// entity; their image goes on the grid in the view; a settings change compares again. The
/// picture is the student-style tracer's of rayscope_core's tests, with its refraction mistake.
#[test]
fn compare_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    let (w, h) = (400u32, 400u32);
    let (scene_path, dir, png) = student_png("compare", &["refraction-no-normal-flip"], w, h, "my_render.png");

    let (_server, url) = serve_stage_two(scene_path, w, h);
    let png2 = png.clone();
    in_chromium(&chromium, &driver, &url, "compare-failure.png", |c, url| async move {
        let r = drive_compare(&c, &url, &png2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// A student's upside-down picture in the page: the diagnosis says so on its first line, before
/// the verdict and the catalogue's 'image-flipped'.
#[test]
fn compare_says_the_obvious_first_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    let (w, h) = (64u32, 48u32);
    let (scene_path, dir, png) = student_png("obvious", &["image-flipped"], w, h, "upside_down.png");

    let (_server, url) = serve_stage_two(scene_path, w, h);
    let png2 = png.clone();
    in_chromium(&chromium, &driver, &url, "obvious-failure.png", |c, url| async move {
        let r = drive_obvious(&c, &url, &png2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// Opens the 64×48 page at `url`, loads the student's `png` through the compare panel's file
/// picker and waits up to `secs` seconds for the diagnosis, which must finish; its text.
async fn diagnosed_in_page(c: &Client, url: &str, png: &Path, secs: u64) -> Result<String, String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    open_page(c, url, "64x48", 60).await?;
    let input = c.find(Locator::Css("#compare-file")).await.map_err(e)?;
    input.send_keys(&png.to_string_lossy()).await.map_err(e)?;
    let state = wait_for("the diagnosis", secs, || async {
        attr(c, "#diagnosis", "data-state")
            .await
            .filter(|v| v == "done" || v == "error")
    })
    .await;
    let diagnosis = text(c, "#diagnosis").await?;
    assert_eq!(state, "done", "{diagnosis}");
    Ok(diagnosis)
}

async fn drive_obvious(c: &Client, url: &str, png: &Path) -> Result<(), String> {
    let diagnosis = diagnosed_in_page(c, url, png, 120).await?;
    assert!(
        diagnosis.starts_with("Your image is upside down: flipped vertically it is "),
        "{diagnosis}"
    );
    assert_eq!(
        attr(c, "#diagnosis p.obvious", "data-code").await.as_deref(),
        Some("upside-down"),
        "{diagnosis}"
    );
    let named = attr(c, "#explanations li:first-child", "data-mistakes").await;
    assert_eq!(named.as_deref(), Some("image-flipped"), "{diagnosis}");
    shot(c, "08b-compare-obvious.png").await;
    Ok(())
}

/// Glass whose refracted ray goes along its surface (a refraction formula without its square
/// root, a mistake the catalogue does not hold) shows only its reflection: the panel says that
/// this is one way to get the picture, names no cause, and lists the render as one way.
#[test]
fn compare_says_glass_that_only_reflects_is_one_way_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    let (w, h) = (64u32, 48u32);
    let (scene_path, dir, png) = student_png("oneway", &["refraction-no-root"], w, h, "no_root.png");
    let (_server, url) = serve_stage_two(scene_path, w, h);
    let png2 = png.clone();
    in_chromium(&chromium, &driver, &url, "oneway-failure.png", |c, url| async move {
        let r = drive_one_way(&c, &url, &png2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

async fn drive_one_way(c: &Client, url: &str, png: &Path) -> Result<(), String> {
    let diagnosis = diagnosed_in_page(c, url, png, 180).await?;
    assert!(
        diagnosis.starts_with("One way to get your picture, not necessarily yours: your "),
        "{diagnosis}"
    );
    assert!(
        diagnosis.contains("only its reflection") || diagnosis.contains("only their reflection"),
        "{diagnosis}"
    );
    let first = text(c, "#explanations li:first-child").await?;
    assert!(
        first.contains("one way to get it, as is losing the refracted light of"),
        "{first}"
    );
    shot(c, "08c-compare-one-way.png").await;
    Ok(())
}

/// Two catalogued mistakes that give the student's picture (a refracted ray started on the
/// incoming side, and a sphere test taking the root behind a ray from inside, on glass spheres):
/// the panel says both, neither as the cause, and gives the pixels to log.
#[test]
fn compare_says_mistakes_with_the_same_picture_together_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    let (w, h) = (64u32, 48u32);
    let (scene_path, dir, png) = student_png("twins", &["refraction-offset-outside"], w, h, "twins.png");
    let (_server, url) = serve_stage_two(scene_path, w, h);
    let png2 = png.clone();
    in_chromium(&chromium, &driver, &url, "twins-failure.png", |c, url| async move {
        let r = drive_twins(&c, &url, &png2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

async fn drive_twins(c: &Client, url: &str, png: &Path) -> Result<(), String> {
    let diagnosis = diagnosed_in_page(c, url, png, 180).await?;
    assert!(
        diagnosis
            .starts_with("One way to get your picture, not necessarily yours: your image is rayscope's render with ")
            && diagnosis.contains("'refraction-offset-outside'")
            && diagnosis.contains("'sphere-near-root-behind'"),
        "{diagnosis}"
    );
    let first = text(c, "#explanations li:first-child").await?;
    assert!(
        first.contains("one way to get this picture, as is")
            && first.contains("the picture alone cannot tell which is yours"),
        "{first}"
    );
    if !c
        .find_all(Locator::Css("#diagnosis-log-env"))
        .await
        .map_err(|e| e.to_string())?
        .is_empty()
    {
        shot(c, "08d-compare-same-picture.png").await;
        return Ok(());
    }
    Err("no pixels to log".into())
}

/// A field of view the student took whole instead of halved, a mistake the catalogue does not
/// hold: the panel says the fitted angle in the core's words and offers to render with it; the
/// button applies `--fov 120` to the debugger's settings, and the picture then matches.
#[test]
fn compare_fits_the_field_of_view_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    let (w, h) = (64u32, 48u32);
    let (scene_path, dir, png) = student_png("fov", &["fov-not-halved"], w, h, "wide.png");

    let (_server, url) = serve_stage_two(scene_path, w, h);
    let png2 = png.clone();
    in_chromium(&chromium, &driver, &url, "fov-failure.png", |c, url| async move {
        let r = drive_fov(&c, &url, &png2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

async fn drive_fov(c: &Client, url: &str, png: &Path) -> Result<(), String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    let diagnosis = diagnosed_in_page(c, url, png, 120).await?;
    assert!(
        diagnosis.starts_with(
            "Explained: your image is rayscope's render with a field of view of 120° (horizontal) instead of 60°"
        ),
        "{diagnosis}"
    );
    assert_eq!(
        attr(c, "#explanations li:first-child", "data-settings")
            .await
            .as_deref(),
        Some("--fov 120"),
        "{diagnosis}"
    );
    shot(c, "08c-compare-fov.png").await;
    c.find(Locator::Css("#explanations li:first-child button"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    let matched = wait_for("the comparison with the fitted angle", 120, || async {
        let status: serde_json::Value = c
            .execute_async(
                r#"const [done] = arguments; fetch("/api/render/status").then((r) => r.json()).then(done);"#,
                vec![],
            )
            .await
            .ok()?;
        if status["settings"]["fov"] != 120.0 {
            return None;
        }
        let state = attr(c, "#diagnosis", "data-state").await?;
        (state == "done").then_some(())?;
        text(c, "#diagnosis").await.ok()
    })
    .await;
    assert!(matched.starts_with("Your image matches rayscope's render"), "{matched}");
    shot(c, "08d-compare-fov-applied.png").await;
    Ok(())
}

async fn text(c: &Client, css: &str) -> Result<String, String> {
    c.find(Locator::Css(css))
        .await
        .map_err(|e| format!("{css}: {e}"))?
        .text()
        .await
        .map_err(|e| e.to_string())
}

async fn choose(c: &Client, css: &str, value: &str) -> Result<(), String> {
    c.find(Locator::Css(css))
        .await
        .map_err(|e| format!("{css}: {e}"))?
        .select_by_value(value)
        .await
        .map_err(|e| e.to_string())
}

/// Whether the element's box lies inside the image panel's scrolling box (nothing to scroll).
async fn fits_panel(c: &Client, css: &str) -> Result<serde_json::Value, String> {
    c.execute(
        r#"const r = document.querySelector(arguments[0]).getBoundingClientRect();
        const b = document.getElementById("image-scroll").getBoundingClientRect();
        return { fits: r.left >= b.left && r.right <= b.right && r.top >= b.top && r.bottom <= b.bottom,
                 image: [r.left, r.top, r.width, r.height], panel: [b.left, b.top, b.width, b.height] };"#,
        vec![json!(css)],
    )
    .await
    .map_err(|e| e.to_string())
}

async fn drive_compare(c: &Client, url: &str, png: &Path) -> Result<(), String> {
    use fantoccini::actions::{InputSource, MouseActions, PointerAction};
    let e = |e: fantoccini::error::CmdError| e.to_string();
    open_page(c, url, "400x400", 60).await?;
    shot(c, "07-compare-400-fits.png").await;
    // The default window: 400×400 fits the panel at a zoom below 1×.
    let zoom: f64 = attr(c, "#image", "data-zoom")
        .await
        .and_then(|z| z.parse().ok())
        .ok_or("no zoom")?;
    assert!(zoom < 1.0 && zoom > 0.3, "zoom {zoom}");
    let fit = fits_panel(c, "#image").await?;
    assert_eq!(fit["fits"], true, "{fit}");

    // Load the picture through the file picker: compared, then diagnosed.
    let input = c.find(Locator::Css("#compare-file")).await.map_err(e)?;
    input.send_keys(&png.to_string_lossy()).await.map_err(e)?;
    wait_for("the comparison", 60, || async {
        attr(c, "#compare-result", "data-state").await.filter(|v| v == "done")
    })
    .await;
    let result = text(c, "#compare-result").await?;
    assert!(result.starts_with("my_render.png vs rayscope: PSNR "), "{result}");
    let first_job = attr(c, "#compare-result", "data-job").await.ok_or("no job")?;
    let attribution = text(c, "#attribution").await?;
    assert!(attribution.contains("GlassBall"), "{attribution}");
    let state = wait_for("the diagnosis", 300, || async {
        attr(c, "#diagnosis", "data-state")
            .await
            .filter(|v| v == "done" || v == "error")
    })
    .await;
    let diagnosis = text(c, "#diagnosis").await?;
    assert_eq!(state, "done", "{diagnosis}");
    assert!(
        diagnosis.starts_with("Explained: your image is rayscope's render with 'refraction-no-normal-flip'"),
        "{diagnosis}"
    );
    let named = attr(c, "#explanations li:first-child", "data-mistakes").await;
    assert_eq!(named.as_deref(), Some("refraction-no-normal-flip"), "{diagnosis}");
    assert!(
        diagnosis.contains("see it: rayscope -f ") && diagnosis.contains("--mistake refraction-no-normal-flip"),
        "{diagnosis}"
    );
    let fit = fits_panel(c, "#image").await?;
    assert_eq!(fit["fits"], true, "comparing: {fit}");
    shot(c, "08-compare-diagnosis.png").await;

    // The heat map and its scale.
    choose(c, "#compare-mode", "heat").await?;
    wait_for("the heat map", 20, || async {
        attr(c, "#image", "data-showing").await.filter(|v| v == "heat")
    })
    .await;
    let scale = c.find(Locator::Css("#heat-scale")).await.map_err(e)?;
    assert!(scale.is_displayed().await.map_err(e)?, "the scale is shown");
    let scale = text(c, "#heat-scale").await?;
    assert!(scale.contains("levels or more (auto)"), "{scale}");
    tokio::time::sleep(Duration::from_millis(400)).await;
    shot(c, "09-compare-heatmap.png").await;
    // A chosen range: small differences at full brightness, the scale says so.
    choose(c, "#heat-range", "8").await?;
    let scale = wait_for("the heat map at range 8", 30, || async {
        let t = text(c, "#heat-scale").await.ok()?;
        t.contains("8 levels or more").then_some(t)
    })
    .await;
    assert!(
        !scale.contains("(auto)") && scale.contains("pixels differ by more"),
        "{scale}"
    );
    tokio::time::sleep(Duration::from_millis(400)).await;
    shot(c, "09b-compare-heatmap-range-8.png").await;

    // Flicker: the two images alternate.
    choose(c, "#compare-mode", "flicker").await?;
    let mut seen = std::collections::BTreeSet::new();
    let end = Instant::now() + Duration::from_secs(5);
    while seen.len() < 2 && Instant::now() < end {
        if let Some(s) = attr(c, "#image", "data-showing").await {
            seen.insert(s);
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    assert_eq!(seen.into_iter().collect::<Vec<_>>(), ["rayscope", "yours"], "flicker");
    shot(c, "10-compare-flicker.png").await;

    // Hover a pixel where the pictures differ, and so do the pixels four around it: below 1× a
    // screen pixel spans two or more image pixels, and the pointer lands within a screen pixel
    // or two of the asked point (WebDriver offsets are whole pixels from the element's centre),
    // so it may land beside the pixel. The readout has both values and the entity.
    let v = c
        .execute_async(
            r#"const [done] = arguments;
            const pixels = async (path) => {
              const b = await createImageBitmap(await (await fetch(path)).blob());
              const cv = document.createElement("canvas"); cv.width = b.width; cv.height = b.height;
              const g = cv.getContext("2d"); g.drawImage(b, 0, 0);
              return g.getImageData(0, 0, b.width, b.height).data;
            };
            Promise.all([pixels("/api/image.png"), pixels("/api/rays/image.png")]).then(([a, b]) => {
              const W = 400, diff = (x, y) => { const i = (y * W + x) * 4; return Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) + Math.abs(a[i + 2] - b[i + 2]); };
              let best = null;
              for (let y = 4; y < 396; y++) for (let x = 4; x < 396; x++) {
                let m = Infinity;
                for (let dy = -4; dy <= 4; dy++) for (let dx = -4; dx <= 4; dx++) m = Math.min(m, diff(x + dx, y + dy));
                if (!best || m > best.m) best = { x, y, m };
              }
              const img = document.getElementById("image");
              const r = img.getBoundingClientRect();
              const tx = r.left + (best.x + 0.5) / W * r.width, ty = r.top + (best.y + 0.5) / W * r.height;
              const at = (x, y) => { const i = (y * W + x) * 4; return [[b[i], b[i + 1], b[i + 2]].join(","), [a[i], a[i + 1], a[i + 2]].join(",")]; };
              const values = {};
              for (let dy = -4; dy <= 4; dy++) for (let dx = -4; dx <= 4; dx++) values[`${best.x + dx},${best.y + dy}`] = at(best.x + dx, best.y + dy);
              done({ x: best.x, y: best.y, m: best.m, dx: Math.round(tx - (r.left + r.width / 2)), dy: Math.round(ty - (r.top + r.height / 2)), values });
            });"#,
            vec![],
        )
        .await
        .map_err(e)?;
    assert!(v["m"].as_f64().ok_or("m")? > 30.0, "{v}");
    let image = c.find(Locator::Css("#image")).await.map_err(e)?;
    let hover = MouseActions::new("mouse".into()).then(PointerAction::MoveToElement {
        element: image,
        duration: None,
        x: v["dx"].as_f64().ok_or("dx")?,
        y: v["dy"].as_f64().ok_or("dy")?,
    });
    c.perform_actions(hover).await.map_err(e)?;
    let end = Instant::now() + Duration::from_secs(20);
    let pixel = loop {
        let p = attr(c, "#pixel-readout", "data-pixel").await.unwrap_or_default();
        if v["values"].get(&p).is_some() {
            break p;
        }
        if Instant::now() > end {
            let readout = text(c, "#pixel-readout").await?;
            return Err(format!(
                "no hover readout for the pixels around ({}, {}): {readout}",
                v["x"], v["y"]
            ));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let (yours, ours) = (
        attr(c, "#pixel-readout", "data-yours").await.ok_or("yours")?,
        attr(c, "#pixel-readout", "data-rayscope").await.ok_or("rayscope")?,
    );
    assert_eq!(json!([yours, ours]), v["values"][&pixel], "pixel {pixel}");
    assert_ne!(yours, ours);
    let readout = text(c, "#pixel-readout").await?;
    let entity = attr(c, "#pixel-readout", "data-entity").await.ok_or("entity")?;
    assert!(
        readout.starts_with(&format!("pixel ({})", pixel.replace(',', ", ")))
            && readout.contains(&format!("yours rgb({})", yours.replace(',', ", ")))
            && readout.contains(&format!("rayscope rgb({})", ours.replace(',', ", ")))
            && readout.ends_with(&entity),
        "{readout}"
    );
    assert!(entity.starts_with("GlassBall"), "{readout}");
    shot(c, "11-compare-hover.png").await;

    // Side by side: both fit the panel.
    choose(c, "#compare-mode", "side").await?;
    wait_for("their image on the right", 20, || async {
        let b = c.find(Locator::Css("#image-b")).await.ok()?;
        let loaded = c
            .execute(r#"return document.getElementById("image-b").naturalWidth;"#, vec![])
            .await
            .ok()?;
        (loaded == json!(400) && b.is_displayed().await.ok()?).then_some(())
    })
    .await;
    for css in ["#image", "#image-b"] {
        let fit = fits_panel(c, css).await?;
        assert_eq!(fit["fits"], true, "{css}: {fit}");
    }
    tokio::time::sleep(Duration::from_millis(300)).await;
    shot(c, "12-compare-side-by-side.png").await;

    // Their image on the pixel grid in the view.
    choose(c, "#image-mode", "theirs").await?;
    wait_for("their image on the grid", 30, || async {
        attr(c, "#view", "data-plane").await.filter(|v| v == "yours")
    })
    .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    shot(c, "13-compare-grid-yours.png").await;

    // A settings change: the comparison is blanked, then made again with the new render.
    c.find(Locator::Css("#hierarchy li.camera"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    let aa = c.find(Locator::Css("#set-aa")).await.map_err(e)?;
    aa.clear().await.map_err(e)?;
    aa.send_keys("2\u{e004}").await.map_err(e)?;
    let stale_seen = std::cell::Cell::new(false);
    let job = wait_for("the comparison with the -x 2 render", 120, || {
        let (stale_seen, first_job) = (&stale_seen, &first_job);
        async move {
            let state = attr(c, "#compare-result", "data-state").await?;
            if state != "done" {
                stale_seen.set(true);
                return None;
            }
            attr(c, "#compare-result", "data-job").await.filter(|j| j != first_job)
        }
    })
    .await;
    assert!(
        stale_seen.get(),
        "the old comparison stayed on screen while the new render ran"
    );
    let status: serde_json::Value = c
        .execute_async(
            r#"const [done] = arguments; fetch("/api/render/status").then((r) => r.json()).then(done);"#,
            vec![],
        )
        .await
        .map_err(e)?;
    assert_eq!(status["settings"]["aa"], 2);
    assert_eq!(job, status["job"].to_string(), "compared with the current render");
    let after = text(c, "#compare-result").await?;
    assert!(after.contains("PSNR"), "{after}");
    // The hover readout of the old render went with it.
    assert_eq!(attr(c, "#pixel-readout", "data-pixel").await, None);
    let fit = fits_panel(c, "#image-b").await?;
    assert_eq!(fit["fits"], true, "{fit}");
    shot(c, "14-compare-after-settings.png").await;
    Ok(())
}

/// A picture no catalogued mistake explains (the student-style tracer's sphere test compares
/// |o − c|² with r, not r²), diagnosed in the page: "Show these pixels" rings the pixels the
/// diagnosis says to log next on the picture and traces the first; "copy" puts the logging
/// variables on the clipboard, or selects them where the clipboard refuses. The student's log of
/// those pixels and of the top rows, loaded afterwards, is shown only at those pixels, on the
/// verdict map and in the list of logged pixels, until "show all".
#[test]
fn diagnosis_next_pixels_in_chromium() {
    let Some((chromium, driver)) = chromium_and_driver() else {
        return;
    };
    if !python3() {
        return;
    }
    let (w, h) = (32u32, 24u32);
    let scene_path = rayscope_testkit::scene("whitted.txt");
    let dir = std::env::temp_dir().join(format!("rayscope-chromium-next-pixels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let ppm = dir.join("mine.ppm");
    let log = student_tracer_log(
        &scene_path,
        w,
        h,
        &["--bug", "radius-not-squared", "--image", &ppm.to_string_lossy()],
    );
    let png = dir.join("mine.png");
    image::open(&ppm).unwrap().to_rgb8().save(&png).unwrap();

    let (_server, url) = serve_stage_two(scene_path, w, h);
    let (png2, dir2) = (png.clone(), dir.clone());
    in_chromium(&chromium, &driver, &url, "next-failure.png", |c, url| async move {
        let r = drive_next_pixels(&c, &url, &png2, &log, &dir2).await;
        (c, r)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// The lines of a JSON Lines ray log whose pixel `keep` accepts.
fn log_of_pixels(log: &str, keep: impl Fn(u64, u64) -> bool) -> String {
    let mut out = String::new();
    for line in log.lines() {
        let ray: serde_json::Value = serde_json::from_str(line).expect("a JSON line");
        let (x, y) = (ray["pixel"][0].as_u64().unwrap(), ray["pixel"][1].as_u64().unwrap());
        if keep(x, y) {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

/// The pixels of the rows of the list of logged pixels, as "x,y", and how many say "disagrees".
async fn logged_rows(c: &Client) -> Result<(Vec<String>, usize), String> {
    let v = c
        .execute(
            r##"return [...document.querySelectorAll("#rays-logged-list tbody tr")].map((tr) => [tr.cells[0].textContent, tr.cells[1].textContent]);"##,
            vec![],
        )
        .await
        .map_err(|e| e.to_string())?;
    let rows: Vec<[String; 2]> = serde_json::from_value(v).map_err(|e| e.to_string())?;
    let red = rows.iter().filter(|r| r[1] == "disagrees").count();
    let pixels = rows
        .iter()
        .map(|r| r[0].trim_matches(['(', ')']).replace(", ", ","))
        .collect();
    Ok((pixels, red))
}

/// The picture at `png` diagnosed, its next step's buttons used, then the log of `log`'s rays
/// at the chosen pixels and the top rows (written to `dir`) loaded.
async fn drive_next_pixels(c: &Client, url: &str, png: &Path, log: &str, dir: &Path) -> Result<(), String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    open_page(c, url, "32x24", 30).await?;
    let input = c.find(Locator::Css("#compare-file")).await.map_err(e)?;
    input.send_keys(&png.to_string_lossy()).await.map_err(e)?;
    let state = wait_for("the diagnosis", 120, || async {
        attr(c, "#diagnosis", "data-state")
            .await
            .filter(|v| v == "done" || v == "error")
    })
    .await;
    let diagnosis = text(c, "#diagnosis").await?;
    assert_eq!(state, "done", "{diagnosis}");
    assert!(diagnosis.starts_with("No known mistake explains"), "{diagnosis}");
    // The pixels to log next and their variables, as the server's diagnosis has them.
    let next = c
        .execute_async(
            r#"const [done] = arguments;
            fetch("/api/compare").then((r) => r.json()).then((v) => done(v.diagnosis.result.next));"#,
            vec![],
        )
        .await
        .map_err(e)?;
    let pixels: Vec<[u32; 2]> = serde_json::from_value(next["pixels"].clone()).map_err(|x| x.to_string())?;
    let env = next["log_env"].as_str().ok_or("no log_env")?.to_string();
    assert!(pixels.len() >= 2, "{next}");
    assert_eq!(
        text(c, "#diagnosis-log-pixels").await?,
        format!("Show these {} pixels", pixels.len())
    );

    check_copy(c, &env).await?;

    // "Show these pixels": ringed on the picture in their own colour, the first traced.
    c.find(Locator::Css("#diagnosis-log-pixels"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    let rings = pixels.len().to_string();
    wait_for("the rings of the chosen pixels", 20, || async {
        attr(c, "#image-overlay", "data-chosen").await.filter(|v| *v == rings)
    })
    .await;
    let ringed = c
        .execute(
            r#"const ov = document.getElementById("image-overlay");
            const d = ov.getContext("2d").getImageData(0, 0, ov.width, ov.height).data;
            let n = 0;
            for (let i = 0; i < d.length; i += 4) if (d[i + 3] > 200 && Math.abs(d[i] - 199) < 24 && Math.abs(d[i + 1] - 125) < 24 && d[i + 2] > 230) n++;
            return n;"#,
            vec![],
        )
        .await
        .map_err(e)?;
    assert!(
        ringed.as_u64().is_some_and(|n| n > 20 * pixels.len() as u64),
        "{ringed}"
    );
    let [x0, y0] = pixels[0];
    let head = wait_for("the first chosen pixel's ray tree", 30, || async {
        let t = text(c, "#tree-head").await.ok()?;
        t.starts_with(&format!("pixel ({x0}, {y0}),")).then_some(t)
    })
    .await;
    let bar = text(c, "#rays-only").await?;
    assert_eq!(
        bar,
        format!("showing {} chosen pixels — show all", pixels.len()),
        "{bar}\n{head}"
    );
    tokio::time::sleep(Duration::from_millis(500)).await;
    shot(c, "15-next-pixels-ringed.png").await;

    check_chosen_in_log(c, log, dir, &pixels).await
}

/// "copy" puts `env` on the clipboard; where the clipboard refuses, it selects `env`.
async fn check_copy(c: &Client, env: &str) -> Result<(), String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    let copied = c
        .execute_async(
            r#"const [done] = arguments;
            Object.defineProperty(navigator, "clipboard", { configurable: true,
              value: { writeText: (t) => { window.copiedText = t; return Promise.resolve(); } } });
            document.getElementById("diagnosis-copy-env").click();
            setTimeout(() => done([document.getElementById("diagnosis-copy-env").dataset.copied, window.copiedText]), 300);"#,
            vec![],
        )
        .await
        .map_err(e)?;
    assert_eq!(copied, json!(["clipboard", env]));
    let selected = c
        .execute_async(
            r#"const [done] = arguments;
            Object.defineProperty(navigator, "clipboard", { configurable: true,
              value: { writeText: () => Promise.reject(new Error("not allowed")) } });
            window.getSelection().removeAllRanges();
            document.getElementById("diagnosis-copy-env").click();
            setTimeout(() => done([document.getElementById("diagnosis-copy-env").dataset.copied, window.getSelection().toString()]), 300);"#,
            vec![],
        )
        .await
        .map_err(e)?;
    assert!(
        (selected[0] == "copied" || selected[0] == "selected") && selected[1] == env,
        "{selected}"
    );

    Ok(())
}

/// The student's log of the chosen `pixels` (the first selected) and of the top four rows,
/// loaded: the verdict map and the list show only the chosen pixels until "show all".
async fn check_chosen_in_log(c: &Client, log: &str, dir: &Path, pixels: &[[u32; 2]]) -> Result<(), String> {
    let e = |e: fantoccini::error::CmdError| e.to_string();
    let chosen: std::collections::BTreeSet<String> = pixels.iter().map(|[x, y]| format!("{x},{y}")).collect();
    let rings = pixels.len().to_string();
    let [x0, y0] = pixels[0];
    // The student's log of those pixels and of the top four rows: the verdict map and the list
    // show only the chosen pixels.
    let sparse = log_of_pixels(log, |x, y| y < 4 || chosen.contains(&format!("{x},{y}")));
    let logged = (0..4)
        .flat_map(|y| (0..32).map(move |x| format!("{x},{y}")))
        .chain(chosen.iter().cloned())
        .collect::<std::collections::BTreeSet<_>>()
        .len();
    let path = dir.join("my_rays.jsonl");
    std::fs::write(&path, sparse).unwrap();
    let input = c.find(Locator::Css("#rays-file")).await.map_err(e)?;
    input.send_keys(&path.to_string_lossy()).await.map_err(e)?;
    let state = wait_for("the log to be judged", 60, || async {
        attr(c, "#rays-summary", "data-state")
            .await
            .filter(|v| v == "done" || v == "error")
    })
    .await;
    let summary = text(c, "#rays-summary").await?;
    assert_eq!(state, "done", "{summary}");
    wait_for("the list of the chosen pixels", 30, || async {
        attr(c, "#rays-logged", "data-rows").await.filter(|v| *v == rings)
    })
    .await;
    let (listed, red) = logged_rows(c).await?;
    assert_eq!(
        listed.iter().cloned().collect::<std::collections::BTreeSet<_>>(),
        chosen
    );
    assert_eq!(attr(c, "#image-overlay", "data-markers").await, Some(rings.clone()));
    assert_eq!(attr(c, "#image-overlay", "data-verdicts").await, Some(red.to_string()));
    assert!(red > 0, "none of the chosen pixels disagrees: {summary}");
    let head = wait_for("the first chosen pixel's rays", 30, || async {
        let t = text(c, "#rays-pixel-head").await.ok()?;
        t.starts_with(&format!("pixel ({x0}, {y0}):")).then_some(t)
    })
    .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    shot(c, "16-next-pixels-log-filtered.png").await;

    // "show all": every logged pixel again, no rings of chosen pixels.
    c.find(Locator::Css("#rays-only-clear"))
        .await
        .map_err(e)?
        .click()
        .await
        .map_err(e)?;
    let all = logged.to_string();
    wait_for("the list of every logged pixel", 20, || async {
        attr(c, "#rays-logged", "data-rows").await.filter(|v| *v == all)
    })
    .await;
    assert_eq!(
        attr(c, "#image-overlay", "data-markers").await,
        Some(all.clone()),
        "{head}"
    );
    assert_eq!(attr(c, "#image-overlay", "data-chosen").await, None);
    let disagree = attr(c, "#rays-summary", "data-disagree").await;
    assert_eq!(attr(c, "#image-overlay", "data-verdicts").await, disagree);
    assert!(
        !c.find(Locator::Css("#rays-only"))
            .await
            .map_err(e)?
            .is_displayed()
            .await
            .map_err(e)?,
        "the chosen pixels' bar stays after 'show all'"
    );
    shot(c, "17-next-pixels-show-all.png").await;
    Ok(())
}
