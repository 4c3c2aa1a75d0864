//! OBJ files take liberties that students' readers accept: those that change nothing drawn load
//! (with a warning naming the line when something is ignored), those that would change the
//! geometry stay errors with file:line:col.

use rayscope_scene::{parse_str, Diagnostic, Mesh, SceneError, Severity, Shape, Vec3};

/// A scene placing `model.obj` at the origin, unscaled, so a vertex (x, y, z) lands at (x, y, −z).
const SCENE: &str = "Material \"Red\" Diffuse (1, 0, 0) 1\nObjModel \"Model\" \"model.obj\" (0, 0, 0) 1 \"Red\"\n";

/// Writes `obj` as `model.obj` beside a scene that loads it, and parses the scene.
fn load(obj: &str) -> Result<(Mesh, Vec<Diagnostic>), Box<Diagnostic>> {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("model.obj"), obj).unwrap();
    match parse_str(SCENE, &dir.path().join("scene.txt")) {
        Ok(scene) => {
            let Shape::Mesh { mesh, .. } = &scene.entities[0].shape else {
                panic!("not a mesh: {:?}", scene.entities[0].shape);
            };
            Ok((mesh.clone(), scene.warnings))
        }
        Err(SceneError::Invalid(d)) => Err(d),
        Err(e) => panic!("expected a diagnostic, got {e}"),
    }
}

/// The mesh and warnings of `obj`, which must load.
fn loads(obj: &str) -> (Mesh, Vec<Diagnostic>) {
    load(obj).unwrap_or_else(|e| panic!("expected the OBJ file to load, got\n{e}"))
}

/// The error for `obj`, which must not load.
fn fails(obj: &str) -> Box<Diagnostic> {
    match load(obj) {
        Ok((mesh, _)) => panic!("expected an error, got {mesh:?}"),
        Err(d) => d,
    }
}

/// The one warning, checked to be a warning about `model.obj` at `line:column`, displayed.
fn one_warning(warnings: &[Diagnostic], line: usize, column: usize) -> String {
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    let w = &warnings[0];
    assert_eq!(w.severity, Severity::Warning);
    assert!(w.file.ends_with("model.obj"), "{}", w.file.display());
    assert_eq!((w.line, w.column), (line, column), "{w}");
    let text = w.to_string();
    assert!(text.contains(&format!("model.obj:{line}:{column}")), "{text}");
    text
}

/// Checks that an error is about `model.obj` at `line:column`.
fn error_at(e: &Diagnostic, line: usize, column: usize) {
    assert_eq!(e.severity, Severity::Error);
    assert!(e.file.ends_with("model.obj"), "{}", e.file.display());
    assert_eq!((e.line, e.column), (line, column), "{e}");
    assert!(e.to_string().contains(&format!("model.obj:{line}:{column}")), "{e}");
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";

fn triangle_positions() -> Vec<Vec3> {
    vec![Vec3::ZERO, Vec3::X, Vec3::Y]
}

#[test]
fn texture_coordinates_the_file_lacks_load_with_a_warning() {
    let (mesh, warnings) = loads(&format!("{TRIANGLE}f 1/1 2/2 3/3\nf 3/3 2/2 1/1\n"));
    assert_eq!(mesh.positions, triangle_positions());
    assert_eq!(mesh.triangles.len(), 2);
    assert_eq!(mesh.triangles[1].positions, [2, 1, 0]);
    let text = one_warning(&warnings, 4, 5);
    assert!(
        text.starts_with("warning: face refers to texture coordinate 1 but no texture coordinates are defined so far"),
        "{text}"
    );
    assert!(text.contains("ignored: texture coordinates are not used"), "{text}");
    assert!(text.contains("the same holds on 1 more line: 5"), "{text}");
}

#[test]
fn texture_coordinates_out_of_range_zero_or_malformed_load_with_a_warning() {
    for (face, column, what) in [
        ("f 1/1 2/2 3/1", 9, "texture coordinate 2"),
        ("f 1/1 2/-2 3/1", 9, "texture coordinate -2"),
        ("f 1/0 2/1 3/1", 5, "found 0"),
        ("f 1/1 2/1 3/x", 13, "found 'x'"),
        ("f 1/1/ 2/1/ 3/9/", 15, "texture coordinate 9"),
    ] {
        let (mesh, warnings) = loads(&format!("{TRIANGLE}vt 0 0\n{face}\n"));
        assert_eq!(mesh.positions, triangle_positions());
        assert_eq!(mesh.triangles.len(), 1, "{face}");
        let text = one_warning(&warnings, 5, column);
        assert!(text.contains(what), "{face}: {text}");
    }
}

#[test]
fn normals_in_a_file_without_normals_are_ignored_with_a_warning() {
    let (mesh, warnings) = loads(&format!(
        "{TRIANGLE}v 1 1 0\nf 1//1 2//2 3//3 4//4\nf 1/1/1 2/2/2 3/3/3\n"
    ));
    assert_eq!(mesh.triangles.len(), 3);
    assert!(mesh.normals.is_empty());
    assert!(mesh.triangles.iter().all(|t| t.normals.is_none()), "shaded flat");
    assert_eq!(mesh.triangles[1].positions, [0, 2, 3]);
    // One warning for both lines (the texture coordinates of the second are named at the
    // first face too, as a separate kind, so two in all).
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    let normals = warnings.iter().find(|w| w.message.contains("normal")).unwrap();
    assert_eq!((normals.line, normals.column), (5, 6));
    let text = normals.to_string();
    assert!(text.contains("no normals ('vn' lines) are defined so far"), "{text}");
    assert!(text.contains("ignored: the face is shaded flat"), "{text}");
    assert!(text.contains("the same holds on 1 more line: 6"), "{text}");
    let texcoords = warnings.iter().find(|w| w.message.contains("texture")).unwrap();
    assert_eq!((texcoords.line, texcoords.column), (6, 5));
}

#[test]
fn unreadable_normal_lines_are_ignored_with_a_warning() {
    let (mesh, warnings) = loads(&format!(
        "{TRIANGLE}vn 0 0 1\nvn 0 0\nf 1//1 2//1 3//1\nf 1//2 2//2 3//2\n"
    ));
    assert_eq!(mesh.positions, triangle_positions());
    assert_eq!(mesh.triangles.len(), 2);
    assert_eq!(mesh.normals, [Vec3::new(0.0, 0.0, -1.0)]);
    assert_eq!(mesh.triangles[0].normals, Some([0, 0, 0]));
    // The face using the unreadable normal is shaded flat.
    assert_eq!(mesh.triangles[1].normals, None);
    let text = one_warning(&warnings, 5, 7);
    assert!(
        text.contains("expected 3 coordinates (x y z) after 'vn' but found 2"),
        "{text}"
    );
    assert!(
        text.contains("ignored: faces using this normal are shaded flat"),
        "{text}"
    );
}

#[test]
fn other_liberties_load_silently() {
    let obj = "mtllib model.mtl\r\n# exported\r\no Thing  \r\ng part\ns off\nusemtl red # the colour\n\
               v 0 0 0 1\nv 1 0 0 0.5 0.5 0.5\nv 1 1 0\t \nv 0 1 -2 # back\nvt\nvt 0 0\nvn 0 0 1\n\
               f 1 2 3 4\nf -4//-1 -3//-1 -2//1\nf 1/2/1 2/1 3//1 # half a normal\n\nf 1/ 2/ 3/\nl 1 2\n";
    let (mesh, warnings) = loads(obj);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(
        mesh.positions,
        [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.0, 1.0, 2.0)]
    );
    // The quad makes two triangles, fanned from its first corner.
    assert_eq!(mesh.triangles.len(), 5);
    assert_eq!(mesh.triangles[0].positions, [0, 1, 2]);
    assert_eq!(mesh.triangles[1].positions, [0, 2, 3]);
    assert_eq!(mesh.triangles[2].positions, [0, 1, 2]);
    assert_eq!(mesh.triangles[2].normals, Some([0, 0, 0]));
    // A corner without a normal: the face is shaded flat.
    assert_eq!(mesh.triangles[3].normals, None);
    assert_eq!(mesh.triangles[4].positions, [0, 1, 2]);
}

#[test]
fn wrong_geometry_stays_an_error() {
    for (obj, line, column, what) in [
        // A vertex the file does not have, in every face form.
        (
            format!("{TRIANGLE}f 1/1 2/2 4/3\n"),
            4,
            11,
            "only 3 vertices are defined so far",
        ),
        (
            format!("{TRIANGLE}f 1//1 2//1 9//1\n"),
            4,
            13,
            "only 3 vertices are defined so far",
        ),
        (
            format!("{TRIANGLE}f -1/1 -2/1 -4/1\n"),
            4,
            13,
            "only 3 vertices are defined so far",
        ),
        (format!("{TRIANGLE}f 0/1 1/1 2/1\n"), 4, 3, "found 0"),
        (format!("{TRIANGLE}f 1/1 x/1 2/1\n"), 4, 7, "found 'x'"),
        // A vertex defined only after the face.
        (
            "v 0 0 0\nv 1 0 0\nf 1/1 2/1 3/1\nv 0 1 0\n".to_string(),
            3,
            11,
            "only 2 vertices",
        ),
        // A vertex that cannot be read, and a face that is not a polygon.
        (
            "v 0 0 0\nv 1 0\nv 0 1 0\nf 1 2 3\n".to_string(),
            2,
            6,
            "expected 3 coordinates",
        ),
        (format!("{TRIANGLE}f 1/1 2/1\n"), 4, 10, "at least 3 vertices"),
        // Normals that exist but are indexed wrongly would shade wrongly.
        (
            format!("{TRIANGLE}vn 0 0 1\nf 1//1 2//1 3//2\n"),
            5,
            16,
            "only 1 normal is defined",
        ),
        (format!("{TRIANGLE}f 1/2/3/4 2 3\n"), 4, 3, "face vertex"),
    ] {
        let e = fails(&obj);
        error_at(&e, line, column);
        assert!(e.message.contains(what), "{obj}: {e}");
    }
}

#[test]
fn a_line_continued_with_a_backslash_is_an_error_that_says_so() {
    let e = fails(&format!("{TRIANGLE}v 1 1 0\nf 1 2 \\\n  3 4\n"));
    error_at(&e, 5, 7);
    let text = e.to_string();
    assert!(
        text.contains("expected a vertex index (a whole number) but found '\\'"),
        "{text}"
    );
    assert!(
        text.contains("a '\\' at the end of a line does not continue it on the next here: join the lines"),
        "{text}"
    );
}

#[test]
fn many_such_lines_make_one_bounded_warning() {
    // Over 1 MiB, so that the file is parsed in stretches where there are several threads.
    let faces = 100_000;
    let obj = format!("{TRIANGLE}{}", "f 1/1 2/1 3/1\n".repeat(faces));
    assert!(obj.len() > 1 << 20);
    let (mesh, warnings) = loads(&obj);
    assert_eq!(mesh.triangles.len(), faces);
    let text = one_warning(&warnings, 4, 5);
    assert!(
        text.contains(&format!(
            "the same holds on {} more lines: 5, 6, 7, 8, 9 and {} more",
            faces - 1,
            faces - 6
        )),
        "{text}"
    );
    assert!(text.len() < 1000, "{text}");
}

#[test]
fn the_example_students_file_loads() {
    // As written by a student's exporter: faces with texture coordinates, and no `vt` lines.
    let (mesh, warnings) = loads(&format!(
        "# cube face\n{TRIANGLE}v 1 1 0\nf 1/1 2/2 3/3\nf 2/2 4/4 3/3\n"
    ));
    assert_eq!(mesh.triangles.len(), 2);
    assert_eq!(mesh.triangles[1].positions, [1, 3, 2]);
    one_warning(&warnings, 6, 5);
}
