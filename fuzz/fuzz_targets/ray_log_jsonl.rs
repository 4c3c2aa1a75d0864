//! JSON Lines ray log → reader → judge, strict or `--lenient`. Never panics; every error
//! formats, and the report's text carries no control character but line ends.
//!
//! The first byte picks `--lenient` and the image size; the rest is the log.
#![no_main]

use std::io::Cursor;
use std::path::Path;

use libfuzzer_sys::fuzz_target;
use rayscope_check::log::JsonlReader;
use rayscope_check::{check, CheckOptions, Judge, LogContext};
use rayscope_core::{RenderSettings, Scene};

/// A lit sphere on a plane: the names a log may use are "Ball", "Floor" and "L".
const SCENE: &str = "Material \"White\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     Material \"Glass\" Refractive (1, 1, 1) 1.5\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"White\"\n\
                     Sphere \"Ball\" (0, 0, 3) 1 \"Glass\"\n";

fuzz_target!(|data: &[u8]| {
    let Some((&mode, log)) = data.split_first() else {
        return;
    };
    let file = rayscope_scene::parse_str(SCENE, Path::new("scene.txt")).expect("the fuzz scene parses");
    let scene = Scene::from_file(&file);
    let side = 1 + u32::from(mode >> 4);
    let settings = RenderSettings {
        width: side,
        height: side,
        aa: 1 + u32::from(mode >> 1 & 1),
        ..RenderSettings::default()
    };
    let judge = Judge::new(&scene, &settings);
    let ctx = LogContext::new(&scene, side, side, judge.samples_per_pixel(), settings.aa);
    let lenient = mode & 1 != 0;
    let mut reader = JsonlReader::new(
        Cursor::new(log),
        Path::new("fuzz.jsonl"),
        log.len() as u64,
        ctx,
        lenient,
    );
    match check(&judge, &mut reader, CheckOptions::default(), &|_, _| {}) {
        Ok(report) => {
            let lines = log.split(|&b| b == b'\n').count() as u64;
            assert!(report.rays + report.skipped_lines <= lines);
            let text = report.to_text(&|_| None);
            assert!(
                !text.chars().any(|c| c.is_control() && c != '\n'),
                "a control character reached the report: {text:?}"
            );
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
