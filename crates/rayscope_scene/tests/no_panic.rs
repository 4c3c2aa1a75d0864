//! No input makes the parsers panic.

use std::path::Path;

use proptest::prelude::*;
use rayscope_scene::{parse_obj, parse_str, ObjOptions};

/// Lines built from the format's own vocabulary, to reach deep into the parser.
fn scene_like() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        Just("Material".to_string()),
        Just("PointLight".to_string()),
        Just("Plane".to_string()),
        Just("Sphere".to_string()),
        Just("Triangle".to_string()),
        Just("ObjModel".to_string()),
        Just("Diffuse".to_string()),
        Just("Refractive".to_string()),
        Just("\"M\"".to_string()),
        Just("\"A B\"".to_string()),
        Just("(".to_string()),
        Just(")".to_string()),
        Just(",".to_string()),
        Just("#".to_string()),
        Just("\t".to_string()),
        Just("\r\n".to_string()),
        Just("\n".to_string()),
        Just("é".to_string()),
        "-?[0-9]{0,3}(\\.[0-9]{0,3})?(e-?[0-9]{1,3})?",
        "[a-zA-Z]{1,6}",
    ];
    prop::collection::vec(token, 0..40).prop_map(|t| t.join(" "))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn arbitrary_text_does_not_panic(src in any::<String>()) {
        if let Err(e) = parse_str(&src, Path::new("scene.txt")) {
            let _ = e.to_string();
        }
    }

    #[test]
    fn ascii_text_does_not_panic(src in "[ -~\t\r\n]{0,200}") {
        if let Err(e) = parse_str(&src, Path::new("scene.txt")) {
            let _ = e.to_string();
        }
    }

    #[test]
    fn scene_like_text_does_not_panic(src in scene_like()) {
        match parse_str(&src, Path::new("scene.txt")) {
            Ok(scene) => {
                for w in &scene.warnings {
                    let _ = w.to_string();
                }
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }

    #[test]
    fn obj_text_does_not_panic(src in "((v|vn|vt|f|o|#)( (-?[0-9]{1,2}(\\.[0-9])?|/|//|x)){0,5}\n){0,30}") {
        if let Err(e) = parse_obj(&src, Path::new("m.obj"), &ObjOptions::default()) {
            let _ = e.to_string();
        }
    }

    #[test]
    fn arbitrary_obj_does_not_panic(src in any::<String>()) {
        if let Err(e) = parse_obj(&src, Path::new("m.obj"), &ObjOptions::default()) {
            let _ = e.to_string();
        }
    }
}
