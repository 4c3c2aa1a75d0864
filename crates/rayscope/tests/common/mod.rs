//! Helpers shared by the binary's integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// Our own scenes folder.
pub fn scenes(rel: &str) -> PathBuf {
    rayscope_testkit::scene(rel)
}

/// The rayscope binary, quiet by default.
pub fn rayscope() -> Command {
    Command::cargo_bin("rayscope").expect("binary built")
}

/// Renders with extra flags into `out`, asserting success.
pub fn render_to(scene: &Path, out: &Path, flags: &[&str]) {
    rayscope()
        .arg("-f")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .arg("--quiet")
        .args(flags)
        .assert()
        .success();
}

/// Renders with extra flags into `out` and returns the image.
pub fn render(scene: &Path, out: &Path, flags: &[&str]) -> image::RgbImage {
    render_to(scene, out, flags);
    image::open(out).expect("output image").to_rgb8()
}

/// PSNR in dB and number of differing pixels between two images of equal size.
pub fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let c = rayscope_core::compare::compare_rgb8(a.as_raw(), b.as_raw());
    (c.psnr, c.differing)
}

/// An image file as RGB.
pub fn rgb(path: &Path) -> image::RgbImage {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
}

/// What one watched run of a process did.
pub struct Watched {
    /// Exit code (`None` when a signal ended it).
    pub code: Option<i32>,
    /// Everything it wrote to stdout.
    pub stdout: String,
    /// Everything it wrote to stderr.
    pub stderr: String,
    /// Highest VmHWM seen while it ran, in KiB.
    pub peak_kib: u64,
    /// Seconds it ran.
    pub secs: f64,
}

/// Peak resident memory (VmHWM) of a running process, in KiB; `None` once it has exited.
pub fn peak_rss_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// A watched process that passes this much memory is killed at once, so a regression fails its
/// test instead of taking the machine's memory.
const RUNAWAY_KIB: u64 = 4 << 20;

/// Runs `cmd` with no input and its output captured, polling its peak memory; kills it and
/// fails the test if it runs past `limit` or past [`RUNAWAY_KIB`].
pub fn watch(mut cmd: std::process::Command, limit: std::time::Duration) -> Watched {
    use std::io::Read;
    use std::process::Stdio;
    let start = std::time::Instant::now();
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the command starts");
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = Vec::new();
            let _ = r.read_to_end(&mut s);
            String::from_utf8_lossy(&s).into_owned()
        })
    };
    let out = drain(Box::new(child.stdout.take().unwrap()));
    let err = drain(Box::new(child.stderr.take().unwrap()));
    let mut peak_kib = 0;
    let status = loop {
        if let Some(kib) = peak_rss_kib(child.id()) {
            peak_kib = peak_kib.max(kib);
        }
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > limit || peak_kib > RUNAWAY_KIB {
            let _ = child.kill();
            let _ = child.wait();
            panic!(
                "{cmd:?} still running after {:?} at {peak_kib} KiB; stderr:\n{}",
                start.elapsed(),
                err.join().unwrap()
            );
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    };
    Watched {
        code: status.code(),
        stdout: out.join().unwrap(),
        stderr: err.join().unwrap(),
        peak_kib,
        secs: start.elapsed().as_secs_f64(),
    }
}
