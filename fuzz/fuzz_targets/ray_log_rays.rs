//! RayTracer.Debug `.rays` log → reader → judge. Never panics; every error formats.
//!
//! The first byte picks what the ids mean; the rest is the file.
#![no_main]

use std::io::Cursor;
use std::path::Path;

use libfuzzer_sys::fuzz_target;
use rayscope_check::log::{BinaryReader, IdRole};
use rayscope_check::{check, CheckOptions, Judge, LogContext};
use rayscope_core::{RenderSettings, Scene};

const SCENE: &str = "Material \"White\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"White\"\n\
                     Sphere \"Ball\" (0, 0, 3) 1 \"White\"\n";

/// The id lists a user may pass with `--ray-ids`.
const ROLES: [&[IdRole]; 4] = [
    &[IdRole::X, IdRole::Y],
    &[IdRole::X, IdRole::Y, IdRole::Sample, IdRole::Id, IdRole::Parent],
    &[],
    &[IdRole::Ignore, IdRole::Sample, IdRole::X, IdRole::Y],
];

fuzz_target!(|data: &[u8]| {
    let Some((&mode, file)) = data.split_first() else {
        return;
    };
    let parsed = rayscope_scene::parse_str(SCENE, Path::new("scene.txt")).expect("the fuzz scene parses");
    let scene = Scene::from_file(&parsed);
    let settings = RenderSettings {
        width: 4,
        height: 4,
        aa: 2,
        ..RenderSettings::default()
    };
    let judge = Judge::new(&scene, &settings);
    let ctx = LogContext::new(&scene, 4, 4, judge.samples_per_pixel(), settings.aa);
    let roles = ROLES[usize::from(mode & 3)];
    let mut reader = BinaryReader::new(Cursor::new(file), Path::new("fuzz.rays"), file.len() as u64, ctx, roles);
    match check(&judge, &mut reader, CheckOptions::default(), &|_, _| {}) {
        Ok(report) => {
            let _ = report.to_text(&|_| None);
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
