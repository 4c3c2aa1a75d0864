//! Hostile ray-log uploads and per-pixel requests against a debugger running as a child process
//! (so that its peak memory, `VmHWM`, is its own): every answer arrives, readable, and the server
//! stays within its memory budget; slow uploads hold nothing that views need.
//!
//! The child is this test binary again, running [`child_server`] with the limits in
//! `RAYSCOPE_HOSTILE_CHILD`; it prints its address and serves until its stdin closes.

mod common;

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use common::{parse_answer, send, Answer};
use rayscope_core::{RenderSettings, Scene};
use rayscope_debug::student::PAGE_RAYS;
use rayscope_debug::{ServeConfig, ServerLimits};
use serde_json::Value;

const CHILD_VAR: &str = "RAYSCOPE_HOSTILE_CHILD";

fn scene() -> PathBuf {
    rayscope_testkit::scene("whitted.txt")
}

/// Limits as `body_timeout_ms,min_body_rate,body_budget,keep_log_bytes,ray_detail_cap`.
fn encode(l: &ServerLimits) -> String {
    format!(
        "{},{},{},{},{}",
        l.body_timeout.as_millis(),
        l.min_body_rate,
        l.body_budget,
        l.keep_log_bytes,
        l.ray_detail_cap
    )
}

fn decode(s: &str) -> ServerLimits {
    let v: Vec<u64> = s.split(',').map(|p| p.parse().unwrap()).collect();
    ServerLimits {
        body_timeout: Duration::from_millis(v[0]),
        min_body_rate: v[1],
        body_budget: v[2] as usize,
        keep_log_bytes: v[3] as usize,
        ray_detail_cap: v[4] as usize,
        ..ServerLimits::default()
    }
}

/// The child's side: serves until stdin closes. A no-op when run as a test of its own.
#[test]
fn child_server() {
    let Ok(spec) = std::env::var(CHILD_VAR) else {
        return;
    };
    let path = scene();
    let file = rayscope_scene::load(&path).expect("scene loads");
    let data = Scene::from_file(&file);
    let server = rayscope_debug::start(ServeConfig {
        scene_path: path,
        scene_file: file,
        scene: data,
        settings: RenderSettings {
            width: 16,
            height: 12,
            ..RenderSettings::default()
        },
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits: decode(&spec),
        student: Default::default(),
    })
    .expect("debugger starts");
    println!("LISTENING {}", server.addr);
    std::io::stdout().flush().unwrap();
    let _ = std::io::stdin().read_to_end(&mut Vec::new());
    server.stop();
}

/// A debugger in a child process.
struct Server {
    child: Child,
    addr: SocketAddr,
}

impl Server {
    fn start(limits: ServerLimits) -> Self {
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "child_server", "--nocapture", "--test-threads=1"])
            .env(CHILD_VAR, encode(&limits))
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start the child server");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        // libtest prints "test child_server ... " before the test's own output, on that line.
        let addr = lines
            .by_ref()
            .map_while(Result::ok)
            .find_map(|l| Some(l.split_once("LISTENING ")?.1.trim().parse().unwrap()))
            .expect("the child server prints its address");
        // The rest of the child's output is read and dropped, so that it never writes to a
        // closed pipe.
        std::thread::spawn(move || lines.for_each(drop));
        Self { child, addr }
    }

    /// The child's peak resident memory in KiB.
    fn peak_kib(&self) -> u64 {
        self.status("VmHWM")
    }

    /// The child's resident memory now in KiB.
    fn rss_kib(&self) -> u64 {
        self.status("VmRSS")
    }

    fn status(&self, key: &str) -> u64 {
        let s = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap_or_default();
        s.lines()
            .find(|l| l.split(':').next() == Some(key))
            .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
            .unwrap_or(0)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        drop(self.child.stdin.take());
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn json(a: &Answer) -> Value {
    serde_json::from_slice(&a.body).unwrap_or_else(|e| panic!("{} answer is not JSON ({e}): {}", a.code, a.text()))
}

fn upload(addr: SocketAddr, query: &str, log: &[u8]) -> Answer {
    send(
        addr,
        "POST",
        &format!("/api/rays?name=rays.jsonl{query}"),
        &[("Content-Type", "application/x-ndjson")],
        log,
    )
}

/// A camera ray of pixel (`x`, `y`), sample `s`, towards the scene.
fn ray(x: u32, y: u32, s: u32) -> String {
    format!("{{\"pixel\":[{x},{y}],\"sample\":{s},\"kind\":\"camera\",\"origin\":[0,0,0],\"direction\":[0,0,1]}}\n")
}

fn quick() -> ServerLimits {
    ServerLimits {
        body_timeout: Duration::from_millis(1000),
        min_body_rate: 64 * 1024,
        ..ServerLimits::default()
    }
}

/// Issue 44 #2, scaled down: 20,000 rays of one pixel (the issue had 400,000). One comparison
/// shows a page of them, counts the rest and pages on; four at once stay within a few MiB.
#[test]
fn one_pixels_comparison_is_paged() {
    let server = Server::start(ServerLimits::default());
    let addr = server.addr;
    let n = 20_000usize;
    let log: String = (0..n).map(|_| ray(5, 5, 0)).collect();
    let a = upload(addr, "", log.as_bytes());
    assert_eq!(a.code, 200, "{}", a.text());
    let before = server.rss_kib();
    let answers: Vec<Answer> = (0..4)
        .map(|_| std::thread::spawn(move || send(addr, "GET", "/api/rays/pixel?x=5&y=5", &[], b"")))
        .collect::<Vec<_>>()
        .into_iter()
        .map(|t| t.join().unwrap())
        .collect();
    let mut served = 0;
    for a in &answers {
        if a.code == 503 {
            continue;
        }
        assert_eq!(a.code, 200, "{}", a.text());
        served += 1;
        assert!(a.body.len() < 4 << 20, "{} bytes for one pixel", a.body.len());
        let v = json(a);
        assert_eq!(v["yours"].as_array().unwrap().len(), PAGE_RAYS);
        assert_eq!(v["rays_total"], n);
        assert_eq!(v["offset"], 0);
        assert_eq!(v["more"], n - PAGE_RAYS);
        assert_eq!(v["page_rays"], PAGE_RAYS);
    }
    assert!(served >= 1);
    let grew = server.peak_kib().saturating_sub(before);
    assert!(grew < 64 * 1024, "four comparisons of one pixel took {grew} KiB");
    // The next pages, and the last, shorter one.
    let a = send(addr, "GET", "/api/rays/pixel?x=5&y=5&offset=19500", &[], b"");
    assert_eq!(a.code, 200, "{}", a.text());
    let v = json(&a);
    assert_eq!(v["yours"].as_array().unwrap().len(), 500);
    assert_eq!(v["yours"][0]["line"], 19_501);
    assert_eq!((v["offset"].as_u64(), v["more"].as_u64()), (Some(19_500), Some(0)));
    let a = send(addr, "GET", "/api/rays/pixel?x=5&y=5&offset=1000&limit=10", &[], b"");
    let v = json(&a);
    assert_eq!(v["yours"].as_array().unwrap().len(), 10);
    assert_eq!(v["more"], n - 1010);
    let a = send(addr, "GET", "/api/rays/pixel?x=5&y=5&limit=100000", &[], b"");
    assert_eq!(a.code, 400, "{}", a.text());
    assert!(json(&a)["error"].as_str().unwrap().contains("limit"));
}

/// Issue 44 #1 and #3 on the debugger's side: what an upload leaves in memory is bounded by the
/// server's limits (kept bytes, rays kept for display), whatever the upload holds: here 6 MB of
/// rays spread over every pixel and many samples, with a keep limit of 1 MiB and 2,000 rays.
#[test]
fn an_upload_is_held_within_the_servers_limits() {
    let limits = ServerLimits {
        keep_log_bytes: 1 << 20,
        ray_detail_cap: 2000,
        ..ServerLimits::default()
    };
    let server = Server::start(limits);
    let addr = server.addr;
    let mut log = String::new();
    let mut s = 0;
    while log.len() < 6 << 20 {
        for y in 0..12 {
            for x in 0..16 {
                log.push_str(&ray(x, y, s % 64));
            }
        }
        s += 1;
    }
    let before = server.peak_kib();
    let a = upload(addr, "", log.as_bytes());
    assert!(a.code == 200 || a.code == 400, "{}", a.text());
    let v = json(&a);
    if a.code == 200 {
        let j = &v["judged"];
        assert!(j["kept"].as_u64().unwrap() <= 4000, "{j}");
        assert_eq!(j["capped"], true);
        assert_eq!(j["detail_cap"], 2000);
        assert_eq!(v["source"]["kind"], "upload-not-kept");
        assert_eq!(v["keep_bytes"], 1 << 20);
    } else {
        assert!(!v["error"].as_str().unwrap().is_empty());
    }
    let grew = server.peak_kib().saturating_sub(before);
    // The 6 MB body itself is never held whole; the judge's batches and a few MiB of kept rays.
    assert!(grew < 96 * 1024, "a 6 MB upload took {grew} KiB");
    // A log within the keep limit is kept and judged again after a settings change.
    let small: String = (0..100).map(|i| ray(i % 16, 0, 0)).collect();
    let v = json(&upload(addr, "", small.as_bytes()));
    assert_eq!(v["source"]["kind"], "upload");
}

/// A connection that sends `head`, then drips `drip` bytes one at a time every `every`.
fn dripper(
    addr: SocketAddr,
    head: String,
    every: Duration,
    drip: usize,
) -> std::thread::JoinHandle<(Answer, Duration)> {
    std::thread::spawn(move || {
        let t = Instant::now();
        let mut s = TcpStream::connect(addr).unwrap();
        s.write_all(head.as_bytes()).unwrap();
        s.set_read_timeout(Some(every)).unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 4096];
        let mut sent = 0;
        loop {
            match s.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => got.extend_from_slice(&buf[..n]),
                Err(e) if matches!(e.kind(), std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut) => {
                    if sent < drip && s.write_all(b"{").is_ok() {
                        sent += 1;
                    }
                    if t.elapsed() > Duration::from_secs(20) {
                        break;
                    }
                }
                Err(_) => break,
            }
        }
        (parse_answer(&got), t.elapsed())
    })
}

fn upload_head(addr: SocketAddr, path: &str, mime: &str, len: usize) -> String {
    format!("POST {path} HTTP/1.1\r\nHost: {addr}\r\nContent-Type: {mime}\r\nContent-Length: {len}\r\nConnection: close\r\n\r\n")
}

/// Issue 44 #5, scaled down: four ray-log uploads and an image upload dripping a byte every
/// 200 ms. Views, traces and a new upload are answered meanwhile (not 503), and every dripper
/// gets a readable answer within a few seconds: 409 (replaced by the newer upload) or 408 (too
/// slow).
#[test]
fn dripping_uploads_hold_nothing_other_requests_need() {
    let server = Server::start(quick());
    let addr = server.addr;
    let every = Duration::from_millis(200);
    let mut drippers: Vec<_> = (0..4)
        .map(|_| {
            dripper(
                addr,
                upload_head(addr, "/api/rays", "application/x-ndjson", 1 << 20),
                every,
                1000,
            )
        })
        .collect();
    drippers.push(dripper(
        addr,
        upload_head(addr, "/api/rays/image", "image/png", 1 << 20),
        every,
        1000,
    ));
    std::thread::sleep(Duration::from_millis(300));
    for path in [
        "/api/view?w=64&h=48",
        "/api/trace?x=3&y=3",
        "/api/image.png?channel=normal",
    ] {
        let a = send(addr, "GET", path, &[], b"");
        assert_eq!(a.code, 200, "{path} while uploads drip: {}", a.text());
    }
    let a = upload(addr, "", ray(1, 1, 0).as_bytes());
    assert_eq!(a.code, 200, "an upload while others drip: {}", a.text());
    for d in drippers {
        let (a, took) = d.join().unwrap();
        assert!(
            a.code == 408 || a.code == 409,
            "a dripping upload got {}: {}",
            a.code,
            a.text()
        );
        let e = json(&a)["error"].as_str().unwrap().to_string();
        assert!(
            e.contains("replaced") || e.contains("too slowly") || e.contains("did not arrive"),
            "{e}"
        );
        assert!(took < Duration::from_secs(5), "answered after {took:?}");
    }
}

/// A ray log arriving slower than the minimum rate is refused with a message naming the rate.
#[test]
fn a_slow_upload_is_answered_408_naming_the_rate() {
    let server = Server::start(quick());
    let addr = server.addr;
    let mut s = TcpStream::connect(addr).unwrap();
    s.write_all(upload_head(addr, "/api/rays", "application/x-ndjson", 1 << 20).as_bytes())
        .unwrap();
    // Steady, never pausing long, but far below 64 KiB/s.
    let line = ray(0, 0, 0);
    let t = Instant::now();
    s.set_nonblocking(true).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    while t.elapsed() < Duration::from_secs(10) {
        let _ = s.write_all(line.as_bytes());
        match s.read(&mut buf) {
            Ok(0) => break,
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(_) => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    let a = parse_answer(&got);
    assert_eq!(a.code, 408, "{}", a.text());
    let e = json(&a)["error"].as_str().unwrap().to_string();
    assert!(e.contains("too slowly") && e.contains("65536 bytes a second"), "{e}");
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
}

/// Writes the whole request (head and body) as a plain client does, then reads the answer.
fn client(addr: SocketAddr, head: &str, body: &[u8]) -> Answer {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    s.write_all(head.as_bytes()).unwrap();
    let wrote = s.write_all(body);
    let mut out = Vec::new();
    let read = s.read_to_end(&mut out);
    let a = parse_answer(&out);
    assert!(
        a.code != 0,
        "no answer (writing the body: {wrote:?}; reading: {read:?}, {} bytes)",
        out.len()
    );
    a
}

/// Issue 44 #21: refusals of bodies over 1 MiB reach a client that sends its whole body before
/// reading: a 503 while the body budget is taken, a 415 and a 413, each before the body is read.
#[test]
fn refusals_of_large_bodies_reach_the_client() {
    let limits = ServerLimits {
        body_budget: 4 << 20,
        body_timeout: Duration::from_secs(2),
        ..ServerLimits::default()
    };
    let server = Server::start(limits);
    let addr = server.addr;
    // Takes the whole body budget for a few seconds.
    let holder = dripper(
        addr,
        upload_head(addr, "/api/rays/image", "image/png", 4 << 20),
        Duration::from_millis(100),
        20,
    );
    std::thread::sleep(Duration::from_millis(300));
    let body = vec![7u8; 3 << 20];
    let a = client(
        addr,
        &upload_head(addr, "/api/rays/image", "image/png", body.len()),
        &body,
    );
    assert_eq!(a.code, 503, "{}", a.text());
    assert!(
        json(&a)["error"].as_str().unwrap().contains("at most 4 MiB"),
        "{}",
        a.text()
    );
    assert_eq!(a.header("connection"), Some("close"));
    assert!(a.header("retry-after").is_some());
    let a = client(
        addr,
        &upload_head(addr, "/api/rays/image", "text/plain", body.len()),
        &body,
    );
    assert_eq!(a.code, 415, "{}", a.text());
    let big = vec![7u8; 33 << 20];
    let a = client(addr, &upload_head(addr, "/api/compare", "image/png", big.len()), &big);
    assert_eq!(a.code, 413, "{}", a.text());
    assert!(
        json(&a)["error"].as_str().unwrap().contains("too large"),
        "{}",
        a.text()
    );
    let (a, _) = holder.join().unwrap();
    assert_eq!(a.code, 408, "{}", a.text());
}
