//! What the student-tracer tests share: where the repository is, the tools the tracers need
//! (failing in CI when one is missing, skipping loudly otherwise), and checking a tracer's log.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;

use rayscope_check::log::{open, IdRole};
use rayscope_check::{check, CheckOptions, Judge, LogContext, Report};
use rayscope_core::{RenderSettings, Scene};

/// The repository's root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// True when `tool --version` runs; otherwise fails under `CI=true` and says loudly that `what`
/// did not run.
pub fn have(tool: &str, what: &str) -> bool {
    let ok = Command::new(tool)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("CI").as_deref() != Ok("true"),
            "{tool} is required for {what} in CI"
        );
        eprintln!("SKIPPED: {tool} not found; {what} did not run");
    }
    ok
}

/// python3, or `None` (loudly) when it is missing outside CI.
pub fn python() -> Option<&'static str> {
    have("python3", "the student-tracer tests").then_some("python3")
}

/// The check of the log at `log`, written by a tracer rendering `scene` with `settings`, with
/// `examples` examples per verdict.
pub fn check_log(scene: &Path, settings: RenderSettings, log: &Path, examples: usize) -> Report {
    let file = rayscope_scene::load(scene).expect("scene");
    let scene = Scene::from_file(&file);
    let judge = Judge::new(&scene, &settings);
    let ctx = LogContext::new(
        &scene,
        settings.width,
        settings.height,
        judge.samples_per_pixel(),
        settings.aa,
    );
    let mut src = open(log, ctx, false, &[IdRole::X, IdRole::Y]).expect("open log");
    check(&judge, src.as_mut(), CheckOptions { examples }, &|_, _| {}).expect("check")
}

/// The report as a terminal shows it.
pub fn text(r: &Report) -> String {
    r.to_text(&|_| None)
}
