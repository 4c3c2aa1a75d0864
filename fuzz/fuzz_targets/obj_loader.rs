//! OBJ text → loader. Never panics; a loaded mesh only holds valid indices and finite values.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use rayscope_scene::{parse_obj, ObjOptions};

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    match parse_obj(&text, Path::new("fuzz.obj"), &ObjOptions::default()) {
        Ok(mesh) => {
            assert!(mesh.positions.iter().all(|p| p.is_finite()));
            assert!(mesh.normals.iter().all(|n| n.is_finite()));
            for t in &mesh.triangles {
                assert!(t.positions.iter().all(|&i| (i as usize) < mesh.positions.len()));
                if let Some(n) = t.normals {
                    assert!(n.iter().all(|&i| (i as usize) < mesh.normals.len()));
                }
            }
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
