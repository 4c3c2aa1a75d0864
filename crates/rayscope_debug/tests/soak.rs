//! Soak test of the debugger: several clients change settings, trace pixels and fetch frames
//! for a while. No request may fail, memory must stay flat, and the p99 latency is reported.
//!
//! The default run lasts 20 s; `RAYSCOPE_SOAK_SECS=300 cargo test -p rayscope_debug --test soak
//! -- --nocapture` runs it for five minutes.

mod common;

use std::time::{Duration, Instant};

use common::{request, rss_kib, start_server};
use rayscope_core::rng::Rng;

const SCENE: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/reference/tests/sample_scene_2.txt"
);

#[test]
fn several_clients_for_a_while() {
    let secs: u64 = std::env::var("RAYSCOPE_SOAK_SECS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(20);
    let server = start_server(SCENE, 60, 40);
    let addr = server.addr;
    assert_eq!(request(addr, "GET", "/api/view?w=480&h=320&rays=all", b"").0, 200);
    let start_rss = rss_kib();
    let deadline = Instant::now() + Duration::from_secs(secs);
    let clients: Vec<_> = (0..3u64)
        .map(|c| {
            std::thread::spawn(move || {
                let mut rng = Rng::for_sample(11, c, 0);
                let mut latencies = Vec::new();
                let mut peak_rss = 0;
                let mut n = 0u32;
                while Instant::now() < deadline {
                    n += 1;
                    let (w, h) = (20 + rng.next_u32() % 100, 20 + rng.next_u32() % 80);
                    let (method, path, body) = match n % 4 {
                        0 => (
                            "POST",
                            "/api/settings".to_string(),
                            format!("{{\"width\": {w}, \"height\": {h}, \"aa\": {}}}", 1 + n % 3),
                        ),
                        1 => (
                            "GET",
                            format!("/api/trace?x={}&y={}", rng.next_u32() % 20, rng.next_u32() % 20),
                            String::new(),
                        ),
                        2 => (
                            "GET",
                            "/api/view?w=320&h=200&rays=all&format=jpeg".to_string(),
                            String::new(),
                        ),
                        _ => ("GET", "/api/render/status".to_string(), String::new()),
                    };
                    let t = Instant::now();
                    let (code, resp) = request(addr, method, &path, body.as_bytes());
                    latencies.push(t.elapsed());
                    // A trace may ask for a pixel outside an image another client just shrank.
                    let ok = code == 200 || (code == 400 && path.starts_with("/api/trace"));
                    assert!(ok, "{method} {path} {body}: {code} {}", String::from_utf8_lossy(&resp));
                    if n.is_multiple_of(50) {
                        peak_rss = peak_rss.max(rss_kib());
                    }
                }
                (latencies, peak_rss)
            })
        })
        .collect();
    let mut all = Vec::new();
    let mut peak = 0;
    for c in clients {
        let (l, p) = c.join().expect("client");
        all.extend(l);
        peak = peak.max(p);
    }
    all.sort();
    let p = |q: f64| all[((all.len() as f64 - 1.0) * q) as usize];
    let end_rss = rss_kib();
    eprintln!(
        "soak: {} requests in {secs} s from 3 clients; p50 {:?}, p99 {:?}, max {:?}; RSS {start_rss} KiB → peak {peak} KiB → {end_rss} KiB",
        all.len(),
        p(0.5),
        p(0.99),
        all[all.len() - 1]
    );
    assert!(all.len() > 30, "the server kept answering");
    assert!(
        end_rss < start_rss + 150 * 1024,
        "memory grew from {start_rss} KiB to {end_rss} KiB"
    );
    server.stop();
}
