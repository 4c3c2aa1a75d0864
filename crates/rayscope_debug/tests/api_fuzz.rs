//! A bounded random-request fuzz of the debugger's HTTP API on loopback: malformed JSON, wrong
//! types, huge numbers, path tricks and parallel clients. The server must answer every request
//! with a client error or a success (never a 5xx, never a dropped connection), keep serving
//! correctly afterwards, and not keep the memory it used.

mod common;

use common::{request, rss_kib, start_server};

use rayscope_core::rng::Rng;

/// Our room: planes, triangles, a mirror ball and a glass ball.
fn room() -> String {
    rayscope_testkit::scene("room.txt").to_str().unwrap().to_owned()
}

fn random_request(rng: &mut Rng) -> (&'static str, String, Vec<u8>) {
    let pick = |rng: &mut Rng, n: usize| (rng.next_u32() as usize) % n;
    let values = [
        "0",
        "-1",
        "1e309",
        "NaN",
        "abc",
        "99999999999999999999",
        "3",
        "%00",
        "..%2F..%2Fetc%2Fpasswd",
        "",
        "1,2",
        "0,0,0",
        "4294967296",
        "-0",
        "1.5",
        "%FF%FE",
    ];
    let keys = [
        "x",
        "y",
        "w",
        "h",
        "sample",
        "eye",
        "target",
        "fov",
        "rays",
        "channel",
        "pixel",
        "id",
        "intersector",
        "image",
        "format",
        "range",
    ];
    let paths = [
        "/api/view",
        "/api/trace",
        "/api/image.png",
        "/api/pick",
        "/api/render/status",
        "/api/scene",
        "/api/compare/heatmap.png",
        "/api/compare",
        "/api/compare/pixel",
        "/../../etc/passwd",
        "/api/%2e%2e/%2e%2e/etc/passwd",
        "/app.js",
        "/nope",
    ];
    match pick(rng, 4) {
        0 | 1 => {
            let mut q = String::new();
            for _ in 0..pick(rng, 6) {
                q.push_str(&format!(
                    "{}={}&",
                    keys[pick(rng, keys.len())],
                    values[pick(rng, values.len())]
                ));
            }
            ("GET", format!("{}?{q}", paths[pick(rng, paths.len())]), Vec::new())
        }
        2 => {
            let bodies: [&[u8]; 10] = [
                b"{",
                b"null",
                b"[]",
                b"{\"width\": \"wide\"}",
                b"{\"width\": 1e30}",
                b"{\"height\": -4}",
                b"{\"unknown\": 1}",
                b"{\"width\": 12, \"height\": 9, \"aa\": 2}",
                b"{\"fov\": 0}",
                b"\xff\xfe\x00garbage",
            ];
            ("POST", "/api/settings".into(), bodies[pick(rng, bodies.len())].to_vec())
        }
        _ => {
            let bodies: [&[u8]; 3] = [b"not a png", b"\x89PNG\r\n\x1a\n\x00\x00", b""];
            ("POST", "/api/compare".into(), bodies[pick(rng, bodies.len())].to_vec())
        }
    }
}

#[test]
fn random_requests_never_break_the_server() {
    let server = start_server(&room(), 40, 30);
    let addr = server.addr;
    // Warm up (first frames allocate caches), then measure.
    assert_eq!(request(addr, "GET", "/api/scene", b"").0, 200);
    assert_eq!(request(addr, "GET", "/api/view?w=320&h=200&rays=all", b"").0, 200);
    let before = rss_kib();

    // Four clients in parallel, 150 requests each.
    let threads: Vec<_> = (0..4u64)
        .map(|t| {
            std::thread::spawn(move || {
                let mut rng = Rng::for_sample(7, t, 0);
                let mut seen = Vec::new();
                for _ in 0..150 {
                    let (method, path, body) = random_request(&mut rng);
                    let (code, _) = request(addr, method, &path, &body);
                    assert!(
                        (200..500).contains(&code),
                        "{method} {path} with body {:?} answered {code}",
                        String::from_utf8_lossy(&body)
                    );
                    seen.push(code);
                }
                seen
            })
        })
        .collect();
    let codes: Vec<u16> = threads
        .into_iter()
        .flat_map(|t| t.join().expect("client thread"))
        .collect();
    assert!(codes.contains(&400), "malformed requests are refused with 400");
    assert!(codes.contains(&200), "valid requests still succeed");

    // Still correct afterwards: the scene lists its entities and a trace names what it hits.
    let (code, body) = request(addr, "GET", "/api/scene", b"");
    assert_eq!(code, 200);
    assert!(String::from_utf8_lossy(&body).contains("MirrorBall"));
    let (code, _) = request(addr, "POST", "/api/settings", b"{\"width\": 40, \"height\": 30}");
    assert_eq!(code, 200);
    let (code, body) = request(addr, "GET", "/api/trace?x=20&y=15", b"");
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
    // No path trick reads a file outside what the scene references.
    let (_, body) = request(addr, "GET", "/../../../../etc/passwd", b"");
    assert!(!String::from_utf8_lossy(&body).contains("root:"));

    let after = rss_kib();
    assert!(
        after < before + 200 * 1024,
        "memory grew from {before} KiB to {after} KiB"
    );
    server.stop();
}

#[test]
fn a_slow_client_does_not_stall_others() {
    use std::io::Write;
    let server = start_server(&room(), 40, 30);
    let addr = server.addr;
    // Three clients that send half a request (or half a body) and then go quiet.
    let mut slow = Vec::new();
    for partial in [
        &b"GET /api/scene HTTP/1.1\r\nHost: x"[..],
        b"POST /api/settings HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 1000\r\n\r\n{\"wid",
        b"G",
    ] {
        let mut s = std::net::TcpStream::connect(addr).unwrap();
        s.write_all(partial).unwrap();
        slow.push(s);
    }
    for _ in 0..5 {
        let t = std::time::Instant::now();
        assert_eq!(request(addr, "GET", "/api/scene", b"").0, 200);
        assert!(
            t.elapsed() < std::time::Duration::from_secs(2),
            "answered while slow clients hang"
        );
    }
    drop(slow);
    server.stop();
}
