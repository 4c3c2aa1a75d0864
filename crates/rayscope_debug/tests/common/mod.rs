//! HTTP helpers shared by the debugger's API tests (plain HTTP/1.1 over loopback).
#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

use rayscope_core::{RenderSettings, Scene};
use rayscope_debug::{RunningServer, ServeConfig, ServerLimits};

/// Sends one request (`Content-Type: application/json`, no `Origin`) and returns the status
/// code and body.
pub fn request(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
    let a = send(addr, method, path, &[("Content-Type", "application/json")], body);
    (a.code, a.body)
}

/// A response as received.
pub struct Answer {
    /// The status code (0 when none arrived).
    pub code: u16,
    /// The header lines, as sent.
    pub head: String,
    /// The body bytes.
    pub body: Vec<u8>,
}

impl Answer {
    /// The value of header `name` (case-insensitive).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.head.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            k.trim().eq_ignore_ascii_case(name).then(|| v.trim())
        })
    }

    /// The body as text.
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.body).into_owned()
    }

    /// The body's `{"error": …}` message; panics, naming the answer, when the body is not one.
    pub fn error(&self) -> String {
        let v: serde_json::Value = serde_json::from_slice(&self.body).unwrap_or_else(|e| {
            panic!(
                "{} answer is not JSON ({e}): {}\n{:?}",
                self.code,
                self.head,
                self.text()
            )
        });
        assert!(
            self.header("content-type")
                .is_some_and(|t| t.starts_with("application/json")),
            "{} answer's type: {}",
            self.code,
            self.head
        );
        v["error"]
            .as_str()
            .unwrap_or_else(|| panic!("no error message in {}", self.text()))
            .to_string()
    }
}

/// Sends `method path` with `headers` (a `Host` among them replaces the default
/// `Host: <addr>`), `Connection: close` and `Content-Length`, then `body`; reads the whole answer.
pub fn send(addr: SocketAddr, method: &str, path: &str, headers: &[(&str, &str)], body: &[u8]) -> Answer {
    let mut head = format!("{method} {path} HTTP/1.1\r\n");
    if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
        head.push_str(&format!("Host: {addr}\r\n"));
    }
    for (k, v) in headers {
        head.push_str(&format!("{k}: {v}\r\n"));
    }
    head.push_str(&format!("Connection: close\r\nContent-Length: {}\r\n\r\n", body.len()));
    let mut raw = head.into_bytes();
    raw.extend_from_slice(body);
    send_raw(addr, &raw)
}

/// Writes `raw` to a fresh connection and reads until the server closes it.
pub fn send_raw(addr: SocketAddr, raw: &[u8]) -> Answer {
    let mut s = TcpStream::connect(addr).expect("server accepts connections");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    // The server may answer (and close) before it has read everything, as for a head that is
    // too large: a failed write is then expected, and the answer is still there to read.
    let _ = s.write_all(raw);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    parse_answer(&out)
}

/// Splits a raw HTTP/1.1 response into status, head and body (no chunked decoding: the
/// debugger sends lengths).
pub fn parse_answer(out: &[u8]) -> Answer {
    let text = String::from_utf8_lossy(out);
    let code = text.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    let head_end = out.windows(4).position(|w| w == b"\r\n\r\n").unwrap_or(out.len());
    let body_at = (head_end + 4).min(out.len());
    Answer {
        code,
        head: String::from_utf8_lossy(&out[..head_end]).into_owned(),
        body: out[body_at..].to_vec(),
    }
}

/// Waits (up to a minute) until the server's current render has finished.
pub fn wait_for_render(addr: SocketAddr) {
    for _ in 0..600 {
        let (_, body) = request(addr, "GET", "/api/render/status", b"");
        let v: serde_json::Value = serde_json::from_slice(&body).expect("status JSON");
        if v["state"] == "done" {
            return;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    panic!("the render did not finish within a minute");
}

/// Resident memory of this process in KiB (0 where /proc is missing).
///
/// [`start_server`] runs the debugger inside the test process, so this is the server's memory
/// plus whatever the test itself holds: a test that reads it as the server's memory must keep
/// its own footprint constant while it runs (no per-request buffers kept).
pub fn rss_kib() -> u64 {
    proc_status("VmRSS")
}

/// Peak resident memory of this process so far in KiB (0 where /proc is missing).
pub fn peak_rss_kib() -> u64 {
    proc_status("VmHWM")
}

/// Open file descriptors of this process (0 where /proc is missing).
pub fn open_fds() -> u64 {
    std::fs::read_dir("/proc/self/fd").map_or(0, |d| d.count() as u64)
}

/// Threads of this process (0 where /proc is missing): the server's runtime, render and
/// blocking-pool threads plus the test's own.
pub fn thread_count() -> u64 {
    proc_status("Threads")
}

/// The first number of the `name:` line of `/proc/self/status` (0 where missing).
fn proc_status(name: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.split(':').next() == Some(name))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .unwrap_or(0)
}

/// Starts the debugger in-process on a free loopback port for `scene` at `width` × `height`.
pub fn start_server(scene: &str, width: u32, height: u32) -> RunningServer {
    start_server_with(scene, width, height, ServerLimits::default())
}

/// [`start_server`] with other limits.
pub fn start_server_with(scene: &str, width: u32, height: u32, limits: ServerLimits) -> RunningServer {
    let file = rayscope_scene::load(Path::new(scene)).expect("scene loads");
    let scene_data = Scene::from_file(&file);
    rayscope_debug::start(ServeConfig {
        scene_path: PathBuf::from(scene),
        scene_file: file,
        scene: scene_data,
        settings: RenderSettings {
            width,
            height,
            ..RenderSettings::default()
        },
        host: "127.0.0.1".into(),
        port: 0,
        allow_hosts: Vec::new(),
        limits,
        student: Default::default(),
    })
    .expect("debugger starts")
}
