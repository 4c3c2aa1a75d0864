//! `rayscope debug`'s launcher with hostile surroundings: a closed standard output (issue 44 #16,
//! `rayscope debug … | true`) neither panics nor stops the debugger.

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

fn scene() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/room.txt")
}

/// A port free a moment ago.
fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The status code of `GET path`, or `None` when nothing answers.
fn get(port: u16, path: &str) -> Option<u16> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(10))).ok()?;
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nConnection: close\r\n\r\n"
    )
    .ok()?;
    let mut out = String::new();
    let _ = s.read_to_string(&mut out);
    out.split_whitespace().nth(1)?.parse().ok()
}

#[test]
fn a_closed_stdout_neither_panics_nor_stops_the_debugger() {
    let port = free_port();
    let mut child = Command::new(bin())
        .args(["debug", "-w", "16", "-h", "12", "--port", &port.to_string()])
        .arg(scene())
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // What `| true` leaves: a pipe nobody reads, closed before the URL is printed.
    drop(child.stdout.take());
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut answered = None;
    while Instant::now() < deadline {
        if let Ok(Some(status)) = child.try_wait() {
            let mut err = String::new();
            let _ = child.stderr.take().unwrap().read_to_string(&mut err);
            panic!("the debugger exited ({status}) with a closed stdout:\n{err}");
        }
        answered = get(port, "/api/render/status");
        if answered.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // It has printed its URL to the closed pipe by the time it answers; it still serves.
    std::thread::sleep(Duration::from_millis(300));
    let still = child.try_wait().unwrap();
    let _ = child.kill();
    let _ = child.wait();
    let mut err = String::new();
    let _ = child.stderr.take().unwrap().read_to_string(&mut err);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(answered, Some(200), "the debugger did not answer: {err}");
    assert!(still.is_none(), "the debugger stopped: {err}");
}
