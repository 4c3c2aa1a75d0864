//! Helpers shared by the binary's integration tests.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use assert_cmd::Command;

/// The course's reference folder, read in place (never copied into the repository).
pub fn reference(rel: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference")
        .join(rel);
    assert!(
        p.exists(),
        "missing {} — the tests need ../shared/reference beside the repository",
        p.display()
    );
    p
}

/// Our own scenes folder.
pub fn scenes(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes").join(rel)
}

/// The rayscope binary, quiet by default.
pub fn rayscope() -> Command {
    Command::cargo_bin("rayscope").expect("binary built")
}

/// Renders with extra flags into `out` and returns the image.
pub fn render(scene: &Path, out: &Path, flags: &[&str]) -> image::RgbImage {
    rayscope()
        .arg("-f")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .arg("--quiet")
        .args(flags)
        .assert()
        .success();
    image::open(out).expect("output image").to_rgb8()
}

/// PSNR in dB and number of differing pixels between two images of equal size.
pub fn psnr(a: &image::RgbImage, b: &image::RgbImage) -> (f64, u64) {
    assert_eq!(a.dimensions(), b.dimensions());
    let c = rayscope_core::compare::compare_rgb8(a.as_raw(), b.as_raw());
    (c.psnr, c.differing)
}

/// A reference image as RGB.
pub fn reference_image(rel: &str) -> image::RgbImage {
    image::open(reference(rel)).expect("reference image").to_rgb8()
}
