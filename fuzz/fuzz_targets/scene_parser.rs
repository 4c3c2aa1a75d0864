//! Scene text → parser. Never panics; every error and warning formats.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    // An ObjModel line makes the parser read a file named by the input; keep the fuzzer off the
    // file system (ObjModel's argument parsing is covered by tests with paths that do not exist).
    if text.contains("ObjModel") {
        return;
    }
    match rayscope_scene::parse_str(&text, Path::new("fuzz.txt")) {
        Ok(scene) => {
            for w in &scene.warnings {
                let _ = w.to_string();
            }
            for e in &scene.entities {
                assert!(e.material < scene.materials.len());
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
