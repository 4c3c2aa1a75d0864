//! Every class of error and warning, snapshotted as students will see it.

use std::path::Path;

use insta::assert_snapshot;
use rayscope_scene::{load, parse_obj, parse_str, ObjOptions, SceneError, SceneFile, Severity};

const MATERIALS: &str = "Material \"Red\" Diffuse (1, .5, .5) 1\nMaterial \"Green\" Diffuse (.5, 1, .5) 1\n";

fn error_in(src: &str, path: &Path) -> String {
    match parse_str(src, path) {
        Ok(scene) => panic!("expected an error, got {scene:?}"),
        Err(SceneError::Invalid(d)) => {
            assert_eq!(d.severity, Severity::Error);
            d.to_string()
        }
        Err(e) => panic!("expected a diagnostic, got {e}"),
    }
}

/// The error for `src` parsed as `scene.txt`.
fn error(src: &str) -> String {
    error_in(src, Path::new("scene.txt"))
}

/// Same, with the two materials `Red` and `Green` defined on lines 1 and 2.
fn error_after_materials(line: &str) -> String {
    error(&format!("{MATERIALS}{line}\n"))
}

fn warnings(scene: &SceneFile) -> String {
    assert!(scene.warnings.iter().all(|w| w.severity == Severity::Warning));
    scene
        .warnings
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("\n\n")
}

fn warnings_for(src: &str) -> (SceneFile, String) {
    let scene = parse_str(src, Path::new("scene.txt")).unwrap();
    let text = warnings(&scene);
    (scene, text)
}

/// Replaces machine-specific paths with stable placeholders.
fn redact(text: &str, tmp: &Path) -> String {
    let cwd = std::env::current_dir().unwrap();
    let text = text
        .replace(&tmp.display().to_string(), "[TMP]")
        .replace(&cwd.display().to_string(), "[CWD]");
    // Ancestors of the temporary folder vary between machines: collapse them.
    let mut out: Vec<String> = Vec::new();
    for line in text.lines() {
        if line.trim_start().starts_with('/') {
            if out.last().is_some_and(|l| l.ends_with("[ANCESTORS OF TMP]")) {
                continue;
            }
            let indent = &line[..line.len() - line.trim_start().len()];
            out.push(format!("{indent}[ANCESTORS OF TMP]"));
        } else {
            out.push(line.to_string());
        }
    }
    out.join("\n")
}

// ---------------------------------------------------------------------------------------------
// Commands

#[test]
fn unknown_command() {
    assert_snapshot!(error("Camera (0, 0, 0) (0, 0, 1)\n"));
}

#[test]
fn near_miss_command() {
    assert_snapshot!(error_after_materials("sphere \"S\" (0, 0, 2) 1 \"Red\""));
}

#[test]
fn near_miss_command_case() {
    assert_snapshot!(error("pointlight \"L\" (0, 0, 0) (1, 1, 1)\n"));
}

#[test]
fn slash_comment() {
    assert_snapshot!(error("// my scene\n"));
}

#[test]
fn hash_comments_are_accepted() {
    let scene = parse_str(
        "# a comment\nMaterial \"Red\" Diffuse (1, 0, 0) 1 # trailing\n  # indented\n",
        Path::new("scene.txt"),
    )
    .unwrap();
    assert_eq!(scene.materials.len(), 1);
    assert!(scene.warnings.is_empty());
}

// ---------------------------------------------------------------------------------------------
// Numbers and vectors

#[test]
fn bad_number() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, abc, 2) 1 \"Red\""));
}

#[test]
fn bad_number_two_points() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) .5. \"Red\""));
}

#[test]
fn bad_number_in_colour() {
    assert_snapshot!(error("Material \"Red\" Diffuse (1, 0.5, x) 1\n"));
}

#[test]
fn nan() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) NaN \"Red\""));
}

#[test]
fn infinity() {
    assert_snapshot!(error("PointLight \"L\" (0, -Infinity, 0) (1, 1, 1)\n"));
}

#[test]
fn overflow() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (1e400, 0, 2) 1 \"Red\""));
}

#[test]
fn vector_with_two_numbers() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 2) 1 \"Red\""));
}

#[test]
fn vector_with_four_numbers() {
    assert_snapshot!(error("PointLight \"L\" (0, 1, 2) (1, 1, 1, 1)\n"));
}

#[test]
fn vectors_without_parentheses_are_accepted() {
    let scene = parse_str(&format!("{MATERIALS}Sphere S 0 0 2 1 Red\n"), Path::new("scene.txt")).unwrap();
    assert_eq!(scene.entities.len(), 1);
}

#[test]
fn unbalanced_delimiters_are_separators() {
    let scene = parse_str(
        &format!("{MATERIALS}Sphere \"S (0, 0, 2 1 \"Red\"\nSphere \"T\" 0, 0, 2) 1 Red\n"),
        Path::new("scene.txt"),
    )
    .unwrap();
    assert_eq!(scene.entities.len(), 2);
}

// ---------------------------------------------------------------------------------------------
// Missing and extra tokens

#[test]
fn missing_radius() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2)"));
}

#[test]
fn missing_material() {
    assert_snapshot!(error_after_materials(
        "Triangle \"T\" (0, 0, 1) (1, 0, 1) (0, 1, 1)   # no material"
    ));
}

#[test]
fn missing_vector_component() {
    assert_snapshot!(error("PointLight \"L\" 0 1\n"));
}

#[test]
fn missing_material_number() {
    assert_snapshot!(error("Material \"Red\" Diffuse (1, 0, 0)\n"));
}

#[test]
fn missing_refractive_index() {
    assert_snapshot!(error("Material \"Glass\" Refractive (0, 0, 0)\n"));
}

#[test]
fn extra_tokens_warning() {
    let (scene, text) = warnings_for(&format!("{MATERIALS}Sphere \"S\" (0, 0, 2) 1 \"Red\" 7 \"x\"\n"));
    assert_eq!(scene.entities.len(), 1);
    assert_snapshot!(text);
}

// ---------------------------------------------------------------------------------------------
// Materials

#[test]
fn unknown_material_type() {
    assert_snapshot!(error_in(
        "# my scene\n\nMaterial \"Red\" Difuse (1, .5, .5) 1\n",
        Path::new("scenes/x.txt")
    ));
}

#[test]
fn unknown_material_type_far() {
    assert_snapshot!(error("Material \"Red\" Metal (1, .5, .5) 1\n"));
}

#[test]
fn name_with_a_space() {
    assert_snapshot!(error("Material \"Dark Red\" Diffuse (.5, 0, 0) 1\n"));
}

#[test]
fn non_positive_refractive_index() {
    assert_snapshot!(error("Material \"Glass\" Refractive (0, 0, 0) 0\n"));
}

#[test]
fn undefined_material_near_miss() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) 1 \"Gren\""));
}

#[test]
fn undefined_material_lists_defined() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) 1 \"Blue\""));
}

#[test]
fn undefined_material_none_defined() {
    assert_snapshot!(error("Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"Grey\"\n"));
}

#[test]
fn undefined_material_defined_later() {
    assert_snapshot!(error(
        "Sphere \"S\" (0, 0, 2) 1 \"Blue\"\nMaterial \"Blue\" Diffuse (0, 0, 1) 1\n"
    ));
}

// ---------------------------------------------------------------------------------------------
// Duplicates

#[test]
fn duplicate_material() {
    assert_snapshot!(error_after_materials("Material \"Red\" Reflective (0, 0, 0) 1"));
}

#[test]
fn duplicate_light() {
    assert_snapshot!(error(
        "PointLight \"L\" (0, 1, 0) (1, 1, 1)\nPointLight \"L\" (0, 2, 0) (1, 1, 1)\n"
    ));
}

#[test]
fn duplicate_entity() {
    assert_snapshot!(error_after_materials(
        "Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"Red\"\nSphere \"Floor\" (0, 0, 2) 1 \"Green\""
    ));
}

#[test]
fn namespaces_are_separate() {
    let scene = parse_str(
        "Material \"X\" Diffuse (1, 1, 1) 1\nPointLight \"X\" (0, 1, 0) (1, 1, 1)\nSphere \"X\" (0, 0, 2) 1 \"X\"\n",
        Path::new("scene.txt"),
    )
    .unwrap();
    assert_eq!(scene.entities.len(), 1);
}

// ---------------------------------------------------------------------------------------------
// Geometry

#[test]
fn zero_radius() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) 0 \"Red\""));
}

#[test]
fn negative_radius() {
    assert_snapshot!(error_after_materials("Sphere \"S\" (0, 0, 2) -0.5 \"Red\""));
}

#[test]
fn zero_normal() {
    assert_snapshot!(error_after_materials("Plane \"P\" (0, -1, 0) (0, 0, -0) \"Red\""));
}

#[test]
fn plane_normal_is_normalised() {
    let scene = parse_str(
        &format!(
            "{MATERIALS}Plane \"P\" (0, 0, 0) (0, 3, 4) \"Red\"\nPlane \"Q\" (0, 0, 0) (1e300, 1e300, 0) \"Red\"\n"
        ),
        Path::new("scene.txt"),
    )
    .unwrap();
    let rayscope_scene::Shape::Plane { normal, .. } = scene.entities[0].shape else {
        panic!()
    };
    assert!((normal - rayscope_scene::DVec3::new(0.0, 0.6, 0.8)).length() < 1e-15);
    let rayscope_scene::Shape::Plane { normal, .. } = scene.entities[1].shape else {
        panic!()
    };
    assert!((normal.length() - 1.0).abs() < 1e-15);
}

#[test]
fn degenerate_triangle_warning() {
    let (scene, text) = warnings_for(&format!(
        "{MATERIALS}Triangle \"T\" (0, 0, 1) (1, 1, 1) (2, 2, 1) \"Red\"\nTriangle \"U\" (0, 0, 1) (0, 0, 1) (2, 2, 1) \"Red\"\n"
    ));
    assert_eq!(scene.entities.len(), 2);
    assert_snapshot!(text);
}

#[test]
fn tabs_line_up() {
    assert_snapshot!(error_after_materials("Sphere\t\"S\"\t(0, 0, 2)\t0\t\"Red\""));
}

// ---------------------------------------------------------------------------------------------
// Files

#[test]
fn crlf_and_empty_file() {
    let scene = parse_str(
        &format!(
            "{}\r\nSphere \"S\" (0, 0, 2) 1 \"Red\"\r\n",
            MATERIALS.replace('\n', "\r\n")
        ),
        Path::new("scene.txt"),
    )
    .unwrap();
    assert_eq!(scene.entities[0].line, 4);
    assert!(scene.warnings.is_empty());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.txt");
    std::fs::write(&path, "").unwrap();
    let scene = load(&path).unwrap();
    assert_eq!(scene.path, path);
    assert!(scene.entities.is_empty() && scene.warnings.is_empty());
}

#[test]
fn non_utf8_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("latin1.txt");
    std::fs::write(
        &path,
        b"Material \"Red\" Diffuse (1, 0, 0) 1\r\nMaterial \"Caf\xE9\" Diffuse (1, 1, 1) 1\r\n",
    )
    .unwrap();
    let Err(SceneError::Invalid(d)) = load(&path) else {
        panic!("expected a diagnostic");
    };
    assert_eq!((d.line, d.column), (2, 14));
    assert_snapshot!(redact(&d.to_string(), dir.path()));
}

#[test]
fn missing_scene_file() {
    let err = load(Path::new("does/not/exist.txt")).unwrap_err();
    assert!(matches!(err, SceneError::Io { .. }));
    assert!(err.to_string().starts_with("cannot read does/not/exist.txt: "), "{err}");
}

// ---------------------------------------------------------------------------------------------
// OBJ models

/// Writes `obj` as `model.obj` beside a scene that references it, and returns the error.
fn obj_error(obj: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("model.obj"), obj).unwrap();
    let scene = dir.path().join("scene.txt");
    let src = format!("{MATERIALS}ObjModel \"Model\" \"model.obj\" (0, 0, 2) 0.5 \"Red\"\n");
    redact(&error_in(&src, &scene), dir.path())
}

#[test]
fn obj_missing_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scenes/scene.txt");
    let src = format!("{MATERIALS}ObjModel \"Model\" \"models/missing.obj\" (0, 0, 2) 1 \"Red\"\n");
    assert_snapshot!(redact(&error_in(&src, &scene), dir.path()));
}

#[test]
fn obj_missing_absolute() {
    assert_snapshot!(error_after_materials(
        "ObjModel \"Model\" \"/nonexistent/rayscope/missing.obj\" (0, 0, 2) 1 \"Red\""
    ));
}

#[test]
fn obj_zero_scale() {
    assert_snapshot!(error_after_materials(
        "ObjModel \"Model\" \"model.obj\" (0, 0, 2) 0 \"Red\""
    ));
}

#[test]
fn obj_index_past_the_end() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 4\n"));
}

#[test]
fn obj_zero_index() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"));
}

#[test]
fn obj_negative_index_too_far() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -4\n"));
}

#[test]
fn obj_normal_index() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//2\n"));
}

#[test]
fn obj_malformed_vertex() {
    assert_snapshot!(obj_error(b"# cube\nv 0 0 0\nv 1 0,5 0\n"));
}

#[test]
fn obj_short_vertex() {
    assert_snapshot!(obj_error(b"v 0 0\n"));
}

#[test]
fn obj_malformed_face() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n"));
}

#[test]
fn obj_face_too_small() {
    assert_snapshot!(obj_error(b"v 0 0 0\nv 1 0 0\nf 1 2\n"));
}

#[test]
fn obj_non_finite() {
    assert_snapshot!(obj_error(b"v 0 0 nan\n"));
}

#[test]
fn obj_not_utf8() {
    assert_snapshot!(obj_error(b"v 0 0 0\n\xFF\xFE\n"));
}

#[test]
fn obj_empty_warning() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("model.obj"), "# nothing here\n").unwrap();
    let scene = dir.path().join("scene.txt");
    let src = format!("{MATERIALS}ObjModel \"Model\" \"model.obj\" (0, 0, 2) 0.5 \"Red\"\n");
    let scene = parse_str(&src, &scene).unwrap();
    assert_eq!(scene.entities.len(), 1);
    assert_snapshot!(redact(&warnings(&scene), dir.path()));
}

#[test]
fn obj_direct_parse_error() {
    let err = parse_obj(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 9\n",
        Path::new("model.obj"),
        &ObjOptions::default(),
    )
    .unwrap_err();
    assert_snapshot!(err.to_string());
}

#[test]
fn obj_ignores_other_statements() {
    let mesh = parse_obj(
        "mtllib a.mtl\no thing\ng group\ns 1\nusemtl m\nv 0 0 0 1\nv 1 0 0\nv 0 1 0\nvt 0 0\nl 1 2\np 1\nf 1/1 2/1 3/1\ncurv 0 1 1 2\n",
        Path::new("model.obj"),
        &ObjOptions::default(),
    )
    .unwrap();
    assert_eq!(mesh.triangles.len(), 1);
}

/// The error a Phong material with exponent `n` gets, as (line, column, message, whole text).
fn phong_error(n: &str) -> (usize, usize, String, String) {
    let src = format!("{MATERIALS}Material \"Shiny\" Phong (0.8, 0.2, 0.2) {n}\n");
    match parse_str(&src, Path::new("scene.txt")) {
        Err(SceneError::Invalid(d)) => (d.line, d.column, d.message.clone(), d.to_string()),
        other => panic!("Phong {n}: expected a diagnostic, got {other:?}"),
    }
}

#[test]
fn phong_exponent_out_of_range() {
    for (n, label) in [
        ("-1", "must not be negative"),
        ("10001", "too large"),
        ("250000.5", "too large"),
    ] {
        let (line, column, message, text) = phong_error(n);
        assert_eq!((line, column), (3, 40), "Phong {n}: {text}");
        assert_eq!(
            message,
            format!("expected a Phong exponent from 0 to 10000 but found '{n}'"),
            "{text}"
        );
        assert!(text.contains("--> scene.txt:3:40") && text.contains(label), "{text}");
    }
    let (_, _, message, _) = phong_error("x");
    assert!(message.contains("the material's Phong exponent"), "{message}");
    for n in ["0", "32", "10000"] {
        let src = format!("Material \"Shiny\" Phong (0.8, 0.2, 0.2) {n}\n");
        let scene = parse_str(&src, Path::new("scene.txt")).expect("a Phong exponent in range parses");
        assert_eq!(scene.materials[0].kind, rayscope_scene::MaterialKind::Phong);
        assert_eq!(scene.materials[0].value, n.parse::<f64>().unwrap());
    }
}
