//! What a web page on another origin, or a hostile local client, can make the debugger do:
//! nothing that changes its state or starts work, no large allocation from a small upload, and
//! every refusal is the API's JSON error.

mod common;

use std::time::Instant;

use common::{peak_rss_kib, request, send, send_raw, start_server, wait_for_render};

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/room.txt");

fn width(addr: std::net::SocketAddr) -> u64 {
    let (code, body) = request(addr, "GET", "/api/settings", b"");
    assert_eq!(code, 200);
    let v: serde_json::Value = serde_json::from_slice(&body).unwrap();
    v["settings"]["width"].as_u64().unwrap()
}

#[test]
fn a_page_on_another_origin_cannot_change_the_settings() {
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    let own = format!("http://{addr}");
    let body = br#"{"width": 13}"#;
    // What an HTML form or a no-cors fetch can send without a preflight, from a modern browser
    // (Origin and Sec-Fetch-Site) and from one that sends neither.
    let forged: [&[(&str, &str)]; 7] = [
        &[("Origin", "http://evil.example"), ("Content-Type", "text/plain")],
        &[("Origin", "http://evil.example"), ("Content-Type", "application/json")],
        &[("Origin", "null"), ("Content-Type", "application/json")],
        &[("Sec-Fetch-Site", "cross-site"), ("Content-Type", "application/json")],
        &[("Sec-Fetch-Site", "same-site"), ("Content-Type", "application/json")],
        &[("Content-Type", "application/x-www-form-urlencoded")],
        &[("Content-Type", "text/plain; charset=utf-8")],
    ];
    for headers in forged {
        let a = send(addr, "POST", "/api/settings", headers, body);
        assert!(
            a.code == 403 || a.code == 415,
            "{headers:?} answered {}: {}",
            a.code,
            a.text()
        );
        assert!(!a.error().is_empty());
    }
    let a = send(
        addr,
        "POST",
        "/api/settings",
        &[("Content-Type", "multipart/form-data; boundary=x")],
        b"--x\r\nContent-Disposition: form-data; name=\"a\"\r\n\r\n{\"width\": 13}\r\n--x--\r\n",
    );
    assert_eq!(a.code, 415, "{}", a.text());
    assert_eq!(width(addr), 40, "no forged request changed the settings");

    // The debugger's own page (same origin, JSON) still can.
    let a = send(
        addr,
        "POST",
        "/api/settings",
        &[
            ("Origin", &own),
            ("Sec-Fetch-Site", "same-origin"),
            ("Content-Type", "application/json; charset=utf-8"),
        ],
        body,
    );
    assert_eq!(a.code, 200, "{}", a.text());
    assert_eq!(width(addr), 13);
    server.stop();
}

#[test]
fn a_page_on_another_site_cannot_start_work() {
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    // An <img> or a link on another site pointing at a heavy endpoint.
    for (path, headers) in [
        (
            "/api/view?w=2560&h=2560&rays=all",
            &[("Sec-Fetch-Site", "cross-site")][..],
        ),
        ("/api/image.png?channel=cost", &[("Sec-Fetch-Site", "same-site")][..]),
        ("/api/trace?x=1&y=1", &[("Origin", "http://evil.example")][..]),
        (
            "/api/check",
            &[("Sec-Fetch-Site", "cross-site"), ("Sec-Fetch-Mode", "navigate")][..],
        ),
    ] {
        let t = Instant::now();
        let a = send(addr, "GET", path, headers, b"");
        assert_eq!(a.code, 403, "{path} {headers:?}: {}", a.text());
        assert!(a.error().contains("another"), "{}", a.text());
        assert!(t.elapsed().as_secs() < 2, "{path} was refused before any work");
    }
    // The page itself may be opened from a link anywhere; the API from the page or the
    // address bar.
    assert_eq!(
        send(addr, "GET", "/", &[("Sec-Fetch-Site", "cross-site")], b"").code,
        200
    );
    for site in ["same-origin", "none"] {
        let a = send(addr, "GET", "/api/scene", &[("Sec-Fetch-Site", site)], b"");
        assert_eq!(a.code, 200, "{site}");
    }
    // Framing by another page is refused by the browser.
    let a = send(addr, "GET", "/", &[], b"");
    assert_eq!(a.header("x-frame-options"), Some("DENY"), "{}", a.head);
    server.stop();
}

#[test]
fn a_reference_image_must_be_sent_as_png() {
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    wait_for_render(addr);
    let (code, png) = request(addr, "GET", "/api/image.png", b"");
    assert_eq!(code, 200);
    // A form can post any bytes as text/plain: refused whatever they are.
    let a = send(addr, "POST", "/api/compare", &[("Content-Type", "text/plain")], &png);
    assert_eq!(a.code, 415, "{}", a.text());
    assert!(a.error().contains("image/png"), "{}", a.text());
    // The render compared with itself: identical.
    let a = send(addr, "POST", "/api/compare", &[("Content-Type", "image/png")], &png);
    assert_eq!(a.code, 200, "{}", a.text());
    let v: serde_json::Value = serde_json::from_slice(&a.body).unwrap();
    assert_eq!(v["psnr"], "inf");
    assert_eq!(v["differing"], 0);
    server.stop();
}

/// CRC-32 of PNG chunks (bitwise: the test's chunks are small).
fn crc32(parts: &[&[u8]]) -> u32 {
    let mut c = !0u32;
    for b in parts.iter().flat_map(|p| p.iter()) {
        c ^= u32::from(*b);
        for _ in 0..8 {
            c = if c & 1 == 1 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}

/// Bits into bytes, least significant first (deflate's order).
struct Bits {
    out: Vec<u8>,
    acc: u64,
    n: u32,
}

impl Bits {
    /// Appends a Huffman code of `len` bits, most significant bit first.
    fn code(&mut self, code: u32, len: u32) {
        for i in (0..len).rev() {
            self.acc |= u64::from((code >> i) & 1) << self.n;
            self.n += 1;
        }
        while self.n >= 8 {
            self.out.push(self.acc as u8);
            self.acc >>= 8;
            self.n -= 8;
        }
    }

    fn finish(mut self) -> Vec<u8> {
        if self.n > 0 {
            self.out.push(self.acc as u8);
        }
        self.out
    }
}

/// A valid `w` × `h` RGB PNG of black pixels, deflated as far as fixed Huffman codes go
/// (about 2,000 : 1): small to send, `h` × (3`w` + 1) bytes once decoded.
fn png_bomb(w: u32, h: u32) -> Vec<u8> {
    let raw = u64::from(h) * (3 * u64::from(w) + 1);
    let mut bits = Bits {
        out: vec![0x78, 0x01],
        acc: 0,
        n: 0,
    };
    bits.code(0b110, 3); // BFINAL 1, then BTYPE 01 (fixed Huffman), each low bit first
    bits.code(0x30, 8); // literal 0
    let mut left = raw - 1;
    while left >= 258 {
        bits.code(0b1100_0101, 8); // length 258
        bits.code(0, 5); // distance 1
        left -= 258;
    }
    for _ in 0..left {
        bits.code(0x30, 8);
    }
    bits.code(0, 7); // end of block
    let mut z = bits.finish();
    let adler = ((raw % 65521) << 16 | 1) as u32;
    z.extend_from_slice(&adler.to_be_bytes());

    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        png.extend_from_slice(&(data.len() as u32).to_be_bytes());
        png.extend_from_slice(kind);
        png.extend_from_slice(data);
        png.extend_from_slice(&crc32(&[kind, data]).to_be_bytes());
    };
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    chunk(b"IHDR", &ihdr);
    chunk(b"IDAT", &z);
    chunk(b"IEND", &[]);
    png
}

#[test]
fn the_bomb_builder_makes_a_readable_png() {
    let png = png_bomb(300, 200);
    let img = image::load_from_memory_with_format(&png, image::ImageFormat::Png)
        .expect("the test's PNG decodes")
        .to_rgb8();
    assert_eq!(img.dimensions(), (300, 200));
    assert!(img.as_raw().iter().all(|&b| b == 0));
}

#[test]
fn a_png_bomb_is_refused_from_its_header() {
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    wait_for_render(addr);
    // 8192 × 8192: 1.3 MB to send, 201 MB once decoded.
    let bomb = png_bomb(8192, 8192);
    assert!(bomb.len() < 2 << 20);
    let before = peak_rss_kib();
    let a = send(addr, "POST", "/api/compare", &[("Content-Type", "image/png")], &bomb);
    let grew = peak_rss_kib().saturating_sub(before);
    assert_eq!(a.code, 400, "{}", a.text());
    let e = a.error();
    assert!(e.contains("8192×8192") && e.contains("40×30"), "{e}");
    // The request itself holds the 1.3 MB body and a copy; decoding would add 200 MB or more.
    assert!(grew < 48 * 1024, "peak memory grew by {grew} KiB");
    server.stop();
}

#[test]
fn every_refusal_is_a_json_error() {
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    let json = [("Content-Type", "application/json")];
    // 405: a method the route does not take.
    let a = send(addr, "POST", "/api/scene", &json, b"{}");
    assert_eq!(a.code, 405);
    assert!(a.error().contains("GET"), "{}\n{}", a.head, a.text());
    // 413: a settings body over its limit.
    let big = format!("{{\"seed\": 1{}}}", " ".repeat(64 * 1024));
    let a = send(addr, "POST", "/api/settings", &json, big.as_bytes());
    assert_eq!(a.code, 413, "{}", a.text());
    a.error();
    // 404.
    let a = send(addr, "GET", "/nope", &[], b"");
    assert_eq!(a.code, 404);
    a.error();
    // 414: a URL over the limit; 431 when it does not even fit in the head the server reads.
    let a = send(addr, "GET", &format!("/api/scene?x={}", "a".repeat(10_000)), &[], b"");
    assert_eq!(a.code, 414, "{}", a.head);
    assert!(a.error().contains("URL"), "{}", a.text());
    let a = send(addr, "GET", &format!("/api/scene?x={}", "a".repeat(70_000)), &[], b"");
    assert_eq!(a.code, 431, "{}", a.head);
    assert!(a.error().contains("URL"), "{}", a.text());
    // 431: headers larger than the server reads.
    let long = "b".repeat(100_000);
    let a = send(addr, "GET", "/api/scene", &[("X-Long", &long)], b"");
    assert_eq!(a.code, 431, "{}", a.head);
    assert!(a.error().contains("header"), "{}", a.text());
    // 400: not HTTP at all.
    let a = send_raw(addr, b"GET / HTTP/1.1\r\nHost: x\r\nBad Header\r\n\r\n");
    assert_eq!(a.code, 400, "{}", a.head);
    a.error();
    // The server still answers.
    assert_eq!(request(addr, "GET", "/api/scene", b"").0, 200);
    server.stop();
}

/// A value outside its range, sent to the settings API, is refused in the core's words: the
/// command line's words exactly where the bound is the command line's, and the debugger's own
/// bound named as the debugger's where it is narrower; the settings stay as they were.
#[test]
fn out_of_range_settings_are_refused_in_the_words_the_command_line_uses() {
    use rayscope_core::settings::{Ranges, Setting};
    let server = start_server(SCENE, 40, 30);
    let addr = server.addr;
    let cli = Ranges::COMMAND_LINE;
    let dbg = Ranges::DEBUGGER;
    // (request body, the core's words, the command line's words where the range is the command
    // line's; None where the debugger's range is narrower, so its message names its own range)
    let cases: Vec<(&str, String, Option<String>)> = vec![
        (r#"{"width": 0}"#, refused(dbg.whole(Setting::Width, 0)), None),
        (r#"{"width": 4096}"#, refused(dbg.whole(Setting::Width, 4096)), None),
        (r#"{"aa": 0}"#, refused(dbg.whole(Setting::Aa, 0)), None),
        (r#"{"aa": 17}"#, refused(dbg.whole(Setting::Aa, 17)), None),
        (
            r#"{"quality": 17}"#,
            refused(dbg.whole(Setting::Quality, 17)),
            Some(refused(cli.whole(Setting::Quality, 17))),
        ),
        (r#"{"max_depth": 65}"#, refused(dbg.whole(Setting::MaxDepth, 65)), None),
        (
            r#"{"fov": 180}"#,
            refused(dbg.real(Setting::Fov, 180.0)),
            Some(refused(cli.real(Setting::Fov, 180.0))),
        ),
        (
            r#"{"fov": 0}"#,
            refused(dbg.real(Setting::Fov, 0.0)),
            Some(refused(cli.real(Setting::Fov, 0.0))),
        ),
        (r#"{"aperture": -1}"#, refused(dbg.real(Setting::Aperture, -1.0)), None),
        (
            r#"{"aperture": 1000}"#,
            refused(dbg.real(Setting::Aperture, 1000.0)),
            None,
        ),
        (
            r#"{"focal_length": 0}"#,
            refused(dbg.real(Setting::FocalLength, 0.0)),
            None,
        ),
        (r#"{"cam_angle": 1e6}"#, refused(dbg.real(Setting::CamAngle, 1e6)), None),
        (
            r#"{"cam_pos": [2e6, 0, 0]}"#,
            refused(dbg.coordinates(Setting::CamPos, glam::Vec3::new(2e6, 0.0, 0.0))),
            None,
        ),
        (
            r#"{"cam_axis": [0, 0, 0], "cam_angle": 30}"#,
            refused(rayscope_core::settings::check_camera_axis(glam::Vec3::ZERO, 30.0)),
            Some(refused(rayscope_core::settings::check_camera_axis(
                glam::Vec3::ZERO,
                30.0,
            ))),
        ),
    ];
    for (body, core, command_line) in cases {
        let a = send(
            addr,
            "POST",
            "/api/settings",
            &[("Content-Type", "application/json")],
            body.as_bytes(),
        );
        assert_eq!(a.code, 400, "{body}: {}", a.text());
        assert_eq!(a.error(), core, "{body}: the API's words are the core's");
        match command_line {
            Some(words) => assert_eq!(a.error(), words, "{body}: the command line's words"),
            None => assert!(
                a.error().contains(" in the debugger, found "),
                "{body}: the debugger's own bound says it is the debugger's: {}",
                a.error()
            ),
        }
    }
    assert_eq!(width(addr), 40, "no refused request changed the settings");
    server.stop();
}

/// The message of a value the core refuses.
fn refused<T: std::fmt::Debug>(r: Result<T, String>) -> String {
    r.expect_err("out of range")
}
