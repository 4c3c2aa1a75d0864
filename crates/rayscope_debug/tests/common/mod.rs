//! HTTP helpers shared by the debugger's API tests (plain HTTP/1.1 over loopback).
#![allow(dead_code)]

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

use rayscope_core::{RenderSettings, Scene};
use rayscope_debug::{RunningServer, ServeConfig};

/// Sends one request and returns the status code and body.
pub fn request(addr: SocketAddr, method: &str, path: &str, body: &[u8]) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).expect("server accepts connections");
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let head = format!(
        "{method} {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        body.len()
    );
    s.write_all(head.as_bytes()).unwrap();
    s.write_all(body).unwrap();
    let mut out = Vec::new();
    s.read_to_end(&mut out).expect("a complete response");
    let text = String::from_utf8_lossy(&out);
    let code = text.split_whitespace().nth(1).and_then(|c| c.parse().ok()).unwrap_or(0);
    let body_at = out
        .windows(4)
        .position(|w| w == b"\r\n\r\n")
        .map_or(out.len(), |i| i + 4);
    (code, out[body_at..].to_vec())
}

/// Resident memory of this process in KiB (0 where /proc is missing).
///
/// [`start_server`] runs the debugger inside the test process, so this is the server's memory
/// plus whatever the test itself holds: a test that reads it as the server's memory must keep
/// its own footprint constant while it runs (no per-request buffers kept).
pub fn rss_kib() -> u64 {
    proc_status("VmRSS")
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
    })
    .expect("debugger starts")
}
