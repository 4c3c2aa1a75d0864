//! The fuzz targets' checks (`fuzz/fuzz_targets/scene_parser.rs` and `obj_loader.rs`), run briefly
//! with proptest in the normal test suite, plus a replay of the fuzzers' seed corpus and of every
//! input that once crashed them (`fuzz/regressions/<target>/`).
//!
//! Beyond "never panics": a parsed scene only refers to materials that exist, a loaded mesh only
//! holds valid indices and finite numbers, and a message stays short however long its input line.

use std::path::{Path, PathBuf};

use proptest::prelude::*;
use rayscope_scene::{parse_obj, parse_str, ObjOptions, SceneError};

/// No diagnostic is longer than this, whatever the input (long lines are shown as a window).
const MAX_MESSAGE_BYTES: usize = 4096;

fn check_error(e: &SceneError) -> Result<(), TestCaseError> {
    let text = e.to_string();
    prop_assert!(text.len() < MAX_MESSAGE_BYTES, "a {}-byte message", text.len());
    Ok(())
}

/// What the `scene_parser` fuzz target checks.
fn scene_parser(data: &[u8]) -> Result<(), TestCaseError> {
    let text = String::from_utf8_lossy(data);
    if text.contains("ObjModel") {
        return Ok(()); // the parser would read files named by the input
    }
    match parse_str(&text, Path::new("fuzz.txt")) {
        Ok(scene) => {
            for w in &scene.warnings {
                let shown = w.to_string();
                prop_assert!(shown.len() < MAX_MESSAGE_BYTES, "a {}-byte warning", shown.len());
            }
            for e in &scene.entities {
                prop_assert!(e.material < scene.materials.len());
            }
        }
        Err(e) => check_error(&e)?,
    }
    Ok(())
}

/// What the `obj_loader` fuzz target checks.
fn obj_loader(data: &[u8]) -> Result<(), TestCaseError> {
    let text = String::from_utf8_lossy(data);
    match parse_obj(&text, Path::new("fuzz.obj"), &ObjOptions::default()) {
        Ok(mesh) => {
            prop_assert!(mesh.positions.iter().all(|p| p.is_finite()));
            prop_assert!(mesh.normals.iter().all(|n| n.is_finite()));
            for t in &mesh.triangles {
                prop_assert!(t.positions.iter().all(|&i| (i as usize) < mesh.positions.len()));
                if let Some(n) = t.normals {
                    prop_assert!(n.iter().all(|&i| (i as usize) < mesh.normals.len()));
                }
            }
        }
        Err(e) => check_error(&e)?,
    }
    Ok(())
}

/// Scene-like token soup: the format's words, separators and numbers in random order.
fn scene_soup() -> impl Strategy<Value = String> {
    let token = prop_oneof![
        4 => prop::sample::select(vec![
            "Material", "PointLight", "Plane", "Sphere", "Triangle", "Diffuse", "Reflective", "Refractive",
            "Emissive", "Glossy", "Phong", "\"M\"", "\"A B\"", "\"", "(", ")", ",", "\n", "\r\n", "\r", "\t", "#", "é",
            "\u{0}", "\u{feff}", "NaN", "inf",
        ])
        .prop_map(str::to_string),
        3 => "[-+]?[0-9]{0,3}(\\.[0-9]{0,3})?([eE][-+]?[0-9]{1,3})?",
        1 => "[a-zA-Z]{1,8}",
    ];
    prop::collection::vec(token, 0..60).prop_map(|t| t.join(" "))
}

/// Complete, mostly valid scenes with random numbers (so the parser gets past the first line).
fn scene_lines() -> impl Strategy<Value = String> {
    let num = prop_oneof![
        3 => -10.0f64..10.0,
        1 => prop::sample::select(vec![0.0, -0.0, 1e-300, 1e300, 3.5e38, 3.4e38, 1e39, -1.0]),
    ];
    let v = (num.clone(), num.clone(), num.clone()).prop_map(|(x, y, z)| format!("({x}, {y}, {z})"));
    let name = prop::sample::select(vec!["\"A\"", "\"B\"", "\"C\""]);
    let kind = prop::sample::select(vec![
        "Diffuse",
        "Reflective",
        "Refractive",
        "Emissive",
        "Glossy",
        "Phong",
        "Metal",
    ]);
    let line = prop_oneof![
        (name.clone(), kind, v.clone(), num.clone()).prop_map(|(n, k, c, x)| format!("Material {n} {k} {c} {x}")),
        (name.clone(), v.clone(), v.clone()).prop_map(|(n, p, c)| format!("PointLight {n} {p} {c}")),
        (name.clone(), v.clone(), v.clone(), name.clone()).prop_map(|(n, p, d, m)| format!("Plane {n} {p} {d} {m}")),
        (name.clone(), v.clone(), num, name.clone()).prop_map(|(n, c, r, m)| format!("Sphere {n} {c} {r} {m}")),
        (name.clone(), v.clone(), v.clone(), v, name)
            .prop_map(|(n, a, b, c, m)| format!("Triangle {n} {a} {b} {c} {m}")),
    ];
    prop::collection::vec(line, 0..12).prop_map(|l| l.join("\n"))
}

/// OBJ-like statements with valid, invalid, negative and huge indices.
fn obj_soup() -> impl Strategy<Value = String> {
    let index = prop_oneof![
        4 => 1i64..6,
        2 => -6i64..0,
        1 => Just(0i64),
        1 => prop::sample::select(vec![i64::MAX, i64::MIN, u32::MAX as i64 + 1, -(u32::MAX as i64) - 2]),
    ];
    let corner = prop_oneof![
        index.clone().prop_map(|v| v.to_string()),
        (index.clone(), index.clone()).prop_map(|(v, n)| format!("{v}//{n}")),
        (index.clone(), index.clone(), index.clone()).prop_map(|(v, t, n)| format!("{v}/{t}/{n}")),
        (index.clone(), index).prop_map(|(v, t)| format!("{v}/{t}")),
        Just("1//".to_string()),
        Just("/".to_string()),
    ];
    let num = prop_oneof![
        3 => "-?[0-9](\\.[0-9]{1,3})?",
        1 => prop::sample::select(vec!["0", "1e38", "1e39", "-1e300", "nan", "x"]).prop_map(str::to_string),
    ];
    let line = prop_oneof![
        3 => prop::collection::vec(num.clone(), 0..5).prop_map(|c| format!("v {}", c.join(" "))),
        2 => prop::collection::vec(num.clone(), 0..4).prop_map(|c| format!("vn {}", c.join(" "))),
        1 => prop::collection::vec(num, 0..3).prop_map(|c| format!("vt {}", c.join(" "))),
        4 => prop::collection::vec(corner, 0..6).prop_map(|c| format!("f {}", c.join(" "))),
        1 => prop::sample::select(vec!["o x", "g", "s off", "# f 1 2 3", "usemtl m", "l 1 2", ""]).prop_map(str::to_string),
    ];
    (
        prop::collection::vec(line, 0..30),
        prop::sample::select(vec!["\n", "\r\n", "\r"]),
    )
        .prop_map(|(lines, eol)| lines.join(eol))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 1000, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn scene_parser_random_bytes(data in prop::collection::vec(any::<u8>(), 0..1024)) {
        scene_parser(&data)?;
    }

    #[test]
    fn scene_parser_token_soup(text in scene_soup()) {
        scene_parser(text.as_bytes())?;
    }

    #[test]
    fn scene_parser_scene_lines(text in scene_lines()) {
        scene_parser(text.as_bytes())?;
    }

    #[test]
    fn obj_loader_random_bytes(data in prop::collection::vec(any::<u8>(), 0..1024)) {
        obj_loader(&data)?;
    }

    #[test]
    fn obj_loader_obj_soup(text in obj_soup()) {
        obj_loader(text.as_bytes())?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 16, failure_persistence: None, ..ProptestConfig::default() })]

    /// A long line (a token or a run of separators of up to 200 kB) anywhere in a scene: the
    /// message still fits on a screen.
    #[test]
    fn long_lines_give_short_messages(
        prefix in scene_lines(),
        filler in prop::sample::select(vec!["x", " ", "1 ", "(", "\t", "é"]),
        len in 1usize..200_000,
        suffix in prop::sample::select(vec!["", "x", " \"M\"", ")"]),
        command in prop::sample::select(vec!["", "Sphere \"Long\" (0, 0, 2) ", "Material \"Long\" "]),
    ) {
        let text = format!("{prefix}\n{command}{}{suffix}\n", filler.repeat(len));
        scene_parser(text.as_bytes())?;
        obj_loader(text.as_bytes())?;
    }
}

/// Files under `fuzz/<folder>/<target>/` (seed corpus or saved crashes).
fn fuzz_files(folder: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz")
        .join(folder)
        .join(target);
    let Ok(entries) = std::fs::read_dir(&dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            folder != "corpus" || name.starts_with("seed-")
        })
        .collect();
    files.sort();
    files
}

#[test]
fn fuzz_seeds_and_regressions_replay() {
    let mut replayed = 0;
    for (target, check) in [
        ("scene_parser", scene_parser as fn(&[u8]) -> Result<(), TestCaseError>),
        ("obj_loader", obj_loader),
    ] {
        for folder in ["corpus", "regressions"] {
            for file in fuzz_files(folder, target) {
                let data = std::fs::read(&file).unwrap();
                if let Err(e) = check(&data) {
                    panic!("{}: {e}", file.display());
                }
                replayed += 1;
            }
        }
    }
    assert!(
        replayed >= 6,
        "the seed corpus is in fuzz/corpus (found {replayed} files)"
    );
}
