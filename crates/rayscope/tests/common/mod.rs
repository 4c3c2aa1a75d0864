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
