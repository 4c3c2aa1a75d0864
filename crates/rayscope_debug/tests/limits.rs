//! The debugger's bounds on concurrent heavy work, connections and time: a flood of heavy
//! requests, idle or half-sent connections and stalled bodies cost a bounded amount and are
//! answered or dropped within the configured times.

mod common;

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::{Duration, Instant};

use common::{open_fds, parse_answer, request, send, start_server_with};
use rayscope_debug::ServerLimits;

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/room.txt");

/// One-second timeouts, so the tests take seconds.
fn quick() -> ServerLimits {
    ServerLimits {
        header_timeout: Duration::from_secs(1),
        body_timeout: Duration::from_secs(1),
        write_timeout: Duration::from_secs(1),
        ..ServerLimits::default()
    }
}

/// Reads until the server closes the connection; the time that took, or `None` when it was
/// still open after `patience`.
fn closed_within(s: &mut TcpStream, patience: Duration) -> Option<(Duration, Vec<u8>)> {
    let t = Instant::now();
    s.set_read_timeout(Some(patience)).unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return Some((t.elapsed(), got)),
            Ok(n) => got.extend_from_slice(&buf[..n]),
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => return Some((t.elapsed(), got)),
            Err(_) => return None,
        }
    }
}

#[test]
fn heavy_requests_beyond_the_pool_are_answered_503() {
    let limits = ServerLimits {
        heavy_slots: 1,
        ..ServerLimits::default()
    };
    let server = start_server_with(SCENE, 64, 48, limits);
    let addr = server.addr;
    // Four large frames at once with one slot: one is drawn, the others are turned away at
    // once instead of each holding a 2560 × 2560 frame in memory.
    let mut busy = None;
    for _ in 0..5 {
        let clients: Vec<_> = (0..4)
            .map(|_| std::thread::spawn(move || send(addr, "GET", "/api/view?w=2560&h=2560&rays=all", &[], b"")))
            .collect();
        let answers: Vec<_> = clients.into_iter().map(|c| c.join().unwrap()).collect();
        for a in &answers {
            assert!(a.code == 200 || a.code == 503, "{} {}", a.code, a.head);
        }
        assert!(answers.iter().any(|a| a.code == 200), "one frame is drawn");
        if let Some(a) = answers.into_iter().find(|a| a.code == 503) {
            busy = Some(a);
            break;
        }
    }
    let a = busy.expect("a heavy request beyond the one slot is refused");
    assert_eq!(a.header("retry-after"), Some("1"), "{}", a.head);
    assert!(a.error().contains("busy"), "{}", a.text());
    // Light requests are not limited, and the slot is free again afterwards.
    assert_eq!(request(addr, "GET", "/api/scene", b"").0, 200);
    assert_eq!(request(addr, "GET", "/api/trace?x=3&y=3", b"").0, 200);
    server.stop();
}

#[test]
fn a_half_sent_head_is_dropped_after_the_header_timeout() {
    let server = start_server_with(SCENE, 40, 30, quick());
    let addr = server.addr;
    let start = Instant::now();
    let mut silent = TcpStream::connect(addr).unwrap();
    let mut partial = TcpStream::connect(addr).unwrap();
    partial
        .write_all(b"GET /api/scene HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
        .unwrap();
    for s in [&mut silent, &mut partial] {
        closed_within(s, Duration::from_secs(5)).expect("the server closes the connection");
        let took = start.elapsed();
        assert!(took >= Duration::from_millis(800), "closed after {took:?}");
    }
    server.stop();
}

#[test]
fn an_idle_keep_alive_connection_is_closed() {
    let server = start_server_with(SCENE, 40, 30, quick());
    let addr = server.addr;
    let mut s = TcpStream::connect(addr).unwrap();
    write!(s, "GET /api/render/status HTTP/1.1\r\nHost: {addr}\r\n\r\n").unwrap();
    // The answer arrives, then the connection stays open until the idle timeout.
    let (took, got) = closed_within(&mut s, Duration::from_secs(5)).expect("closed when idle");
    assert_eq!(parse_answer(&got).code, 200);
    assert!(took >= Duration::from_millis(800), "closed after {took:?}");
    server.stop();
}

#[test]
fn a_stalled_body_is_answered_408() {
    let server = start_server_with(SCENE, 40, 30, quick());
    let addr = server.addr;
    let mut s = TcpStream::connect(addr).unwrap();
    write!(
        s,
        "POST /api/settings HTTP/1.1\r\nHost: {addr}\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{{\"wid"
    )
    .unwrap();
    let (took, got) = closed_within(&mut s, Duration::from_secs(5)).expect("answered and closed");
    let a = parse_answer(&got);
    assert_eq!(a.code, 408, "{}", a.head);
    assert!(a.error().contains("did not arrive"), "{}", a.text());
    assert!(took < Duration::from_secs(3), "{took:?}");
    server.stop();
}

/// Opens `n` connections that never send anything.
fn idle_connections(addr: SocketAddr, n: usize) -> Vec<TcpStream> {
    (0..n).map(|_| TcpStream::connect(addr).unwrap()).collect()
}

#[test]
fn idle_connections_beyond_the_cap_take_no_file_descriptors() {
    let limits = ServerLimits {
        max_connections: 8,
        ..quick()
    };
    let server = start_server_with(SCENE, 40, 30, limits);
    let addr = server.addr;
    let before = open_fds();
    // 20 silent clients: the test holds 20 sockets, the server accepts only 8 of them (the
    // rest wait in the listen backlog).
    let idle = idle_connections(addr, 20);
    std::thread::sleep(Duration::from_millis(300));
    let grew = open_fds().saturating_sub(before);
    assert!(grew <= 20 + 8 + 4, "{grew} more open files with 20 idle clients");
    // A real request still gets through once header timeouts have dropped the clients ahead of
    // it in the backlog (three rounds of 8).
    let t = Instant::now();
    assert_eq!(request(addr, "GET", "/api/scene", b"").0, 200);
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    drop(idle);
    server.stop();
}
