//! An OBJ model written with the liberties real students' files take renders as a user runs it:
//! exit 0, a warning on stderr naming the file and line of what was ignored, the same image as
//! the model written cleanly, and JSON outputs still JSON.

mod common;

use std::fs;
use std::path::Path;

use common::{rayscope, rgb};
use serde_json::Value;

/// A box (one corner pulled out, so that no two faces look alike) written as an exporter and a
/// student might: `\r\n` endings, `mtllib`/`o`/`g`/`s`/`usemtl` lines, trailing blanks and tabs,
/// comments at line ends, quads, negative indices, and faces naming texture coordinates and
/// normals that the file never defines (line 14 is the first face; its `/1` is at column 5, and
/// line 15's normal `/1` at column 8). Written here rather than as a file so that no checkout or
/// editor can normalise its line endings or blanks.
const LOOSE: &str = "# exported by hand\r\n\
mtllib box.mtl\r\n\
o Box   \r\n\
g sides\t\r\n\
s 1\r\n\
usemtl gold # the colour\r\n\
v -0.5 -0.5 -0.5\r\n\
v 0.5 -0.5 -0.5 # front\r\n\
v 0.5 0.5 -0.5\t\r\n\
v -0.5 0.5 -0.5 \r\n\
v -0.5 -0.5 0.5\r\n\
v 0.5 -0.5 0.5\r\n\
v 0.8 0.8 0.8 1.0\r\n\
f 1/1 2/2 3/3 4/4\r\n\
f -7/1/1 -6/2/2 -2/3/3 -3/4/4\r\n\
v -0.5 0.5 0.5\r\n\
f 5 6 7 8 # back\r\n\
f -8//1 -4//1 -1//1 -5//1\r\n\
f 2/1/ 3/2/ 7/3/ 6/4/\r\n\
\r\n\
g top\r\n\
f -5 -1 -2 -6\r\n";

/// The same box: the same vertices and the same triangles in the same order (each quad as the
/// fan from its first corner that the reader makes of it), nothing else.
const CLEAN: &str = "v -0.5 -0.5 -0.5
v 0.5 -0.5 -0.5
v 0.5 0.5 -0.5
v -0.5 0.5 -0.5
v -0.5 -0.5 0.5
v 0.5 -0.5 0.5
v 0.8 0.8 0.8
f 1 2 3
f 1 3 4
f 1 2 6
f 1 6 5
v -0.5 0.5 0.5
f 5 6 7
f 5 7 8
f 1 5 8
f 1 8 4
f 2 3 7
f 2 7 6
f 4 8 7
f 4 7 3
";

/// The box named `model` on a floor, lit, off to the side and below the camera so that three of
/// its faces show.
fn scene(model: &str) -> String {
    format!(
        "Material \"Gold\" Diffuse (0.9, 0.65, 0.2) 1\n\
         Material \"Floor\" Diffuse (0.7, 0.7, 0.75) 1\n\
         Plane \"Ground\" (0, -1, 0) (0, 1, 0) \"Floor\"\n\
         ObjModel \"Box\" \"{model}\" (0.25, -0.35, 3.2) 1 \"Gold\"\n\
         PointLight \"Key\" (-2, 3, 0) (1, 1, 1)\n"
    )
}

/// Writes both models and their scenes into `dir`: (loose scene, clean scene).
fn write_scenes(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    fs::write(dir.join("box.obj"), LOOSE).unwrap();
    fs::write(dir.join("clean.obj"), CLEAN).unwrap();
    let loose = dir.join("loose.txt");
    let clean = dir.join("clean.txt");
    fs::write(&loose, scene("box.obj")).unwrap();
    fs::write(&clean, scene("clean.obj")).unwrap();
    (loose, clean)
}

/// Renders `scene` to `out` as a user would (not quiet), returning the exit code and stderr.
fn render(scene: &Path, out: &Path) -> (Option<i32>, String) {
    let o = rayscope()
        .args(["-w", "64", "-h", "48", "-f"])
        .arg(scene)
        .arg("-o")
        .arg(out)
        .output()
        .unwrap();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
fn a_loosely_written_model_renders_as_the_clean_one_with_warnings_naming_its_lines() {
    let dir = tempfile::tempdir().unwrap();
    let (loose, clean) = write_scenes(dir.path());
    let obj = dir.path().join("box.obj");

    let (code, err) = render(&loose, &dir.path().join("loose.png"));
    assert_eq!(code, Some(0), "{err}");
    // One warning a kind, at the first line concerned, counting the others.
    assert!(
        err.contains("warning: face refers to texture coordinate 1 but no texture coordinates are defined so far"),
        "{err}"
    );
    assert!(err.contains(&format!("{}:14:5", obj.display())), "{err}");
    assert!(err.contains("ignored: texture coordinates are not used"), "{err}");
    assert!(err.contains("the same holds on 2 more lines: 15, 19"), "{err}");
    assert!(
        err.contains("warning: face refers to normal '1' but no normals ('vn' lines) are defined so far"),
        "{err}"
    );
    assert!(err.contains(&format!("{}:15:8", obj.display())), "{err}");
    assert!(err.contains("ignored: the face is shaded flat"), "{err}");
    assert!(err.contains("the same holds on 1 more line: 18"), "{err}");
    assert!(!err.contains("error"), "{err}");

    let (code, clean_err) = render(&clean, &dir.path().join("clean.png"));
    assert_eq!(code, Some(0), "{clean_err}");
    assert!(!clean_err.contains("warning"), "{clean_err}");

    let a = rgb(&dir.path().join("loose.png"));
    let b = rgb(&dir.path().join("clean.png"));
    assert!(
        a == b,
        "the loosely written model renders differently from the clean one"
    );
    // And the box is in the picture: its gold differs from the grey floor and the black sky.
    let gold = a.pixels().filter(|p| p[0] > p[2].saturating_add(40)).count();
    assert!(gold > 100, "only {gold} gold pixels");
}

#[test]
fn json_outputs_stay_json_with_the_warnings_on_stderr() {
    let dir = tempfile::tempdir().unwrap();
    let (loose, clean) = write_scenes(dir.path());
    let obj = dir.path().join("box.obj");
    // A pixel on the box.
    let trace = |scene: &Path| {
        rayscope()
            .args(["trace", "--json", "-w", "64", "-h", "48", "--pixel", "36,28", "-f"])
            .arg(scene)
            .output()
            .unwrap()
    };
    let out = trace(&loose);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{err}");
    let tree: Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("stdout is not JSON ({e}):\n{}", String::from_utf8_lossy(&out.stdout)));
    assert!(err.contains(&format!("{}:14:5", obj.display())), "{err}");
    assert!(err.contains(&format!("{}:15:8", obj.display())), "{err}");
    let clean_out = trace(&clean);
    assert_eq!(clean_out.status.code(), Some(0));
    let clean_tree: Value = serde_json::from_slice(&clean_out.stdout).unwrap();
    assert_eq!(tree, clean_tree, "the same ray tree as the clean model's");
    assert_eq!(
        tree["nodes"][0]["hit"]["entity_name"], "Box",
        "the pixel's ray hits the box: {tree:#}"
    );
}
