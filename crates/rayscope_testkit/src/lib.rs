//! Test support shared by rayscope's crates: where the course's files are, where our own scenes
//! are, and how a test that needs something missing says loudly that it did not run.
//!
//! The course's files (its sample scenes and its reference images) are found through one
//! setting, the environment variable [`COURSE_DIR_VAR`]: a course template folder holding
//! `tests/` and `images/`. Unset, it is `../shared/reference` beside the workspace; a relative
//! value is taken from the workspace root (cargo runs each test in its own crate's folder, so
//! the folder `cargo test` was started in is not known to the test).
//!
//! Without the files a test that needs them passes as far as libtest is concerned, but first
//! writes `NOT RUN …` straight to the terminal's stderr (libtest captures only `print!` and
//! `eprint!`, so these lines show under plain `cargo test`), with a running count and, once per
//! test binary, how to enable them. With `CI=true` a missing prerequisite is a failure instead.

pub mod module_graph;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

/// The environment variable naming the course template folder.
pub const COURSE_DIR_VAR: &str = "RAYSCOPE_COURSE_DIR";

/// The course folder used when [`COURSE_DIR_VAR`] is unset, relative to the workspace root.
pub const DEFAULT_COURSE_DIR: &str = "../shared/reference";

/// The workspace root (the folder holding `Cargo.lock` and `scenes/`).
pub fn workspace() -> PathBuf {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    crate_dir
        .ancestors()
        .nth(2)
        .expect("crates/<name> lies two folders below the root")
        .to_path_buf()
}

/// Our own scenes (`scenes/<name>.txt`) on which the full renderer's engines must agree bit for
/// bit, with and without indirect light: emitters, point lights, mirrors, glass (absorbing too),
/// every reflection model, depth of field and OBJ meshes. A scene showing a new material joins
/// this list.
pub const ENGINE_SCENES: [&str; 11] = [
    "emissive", "glossy", "showcase", "dof", "ambient", "whitted", "beer", "camera", "obj", "room", "phong",
];

/// One of our own scenes: `scenes/<name>` in the workspace.
pub fn scene(name: &str) -> PathBuf {
    let p = workspace().join("scenes").join(name);
    assert!(p.is_file(), "missing our own scene {}", p.display());
    p
}

/// Where the course's files are looked for: [`COURSE_DIR_VAR`], else [`DEFAULT_COURSE_DIR`].
pub fn course_dir() -> PathBuf {
    let dir = course_dir_from(std::env::var_os(COURSE_DIR_VAR).as_deref());
    // Without `..` in it where it exists, for readable messages and paths in the debugger.
    dir.canonicalize().unwrap_or(dir)
}

/// [`course_dir`] for a given value of [`COURSE_DIR_VAR`] (an empty one counts as unset).
fn course_dir_from(var: Option<&std::ffi::OsStr>) -> PathBuf {
    match var {
        Some(v) if !v.is_empty() => workspace().join(v),
        _ => workspace().join(DEFAULT_COURSE_DIR),
    }
}

/// A course template folder that holds `tests/` and `images/`.
#[derive(Clone, Debug)]
pub struct Course {
    dir: PathBuf,
}

impl Course {
    /// The course folder if it holds `tests/` and `images/`, whatever `CI` says.
    pub fn find() -> Option<Course> {
        let dir = course_dir();
        (dir.join("tests").is_dir() && dir.join("images").is_dir()).then_some(Course { dir })
    }

    /// The folder itself.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// A file of the course, `rel` from its folder; a file missing from a folder that is
    /// there is a broken checkout, so it fails the test rather than skipping it.
    pub fn file(&self, rel: &str) -> PathBuf {
        let p = self.dir.join(rel);
        assert!(
            p.exists(),
            "{} is missing from the course folder {} ({COURSE_DIR_VAR}): is it a complete course template?",
            rel,
            self.dir.display()
        );
        p
    }

    /// One of the course's scenes, `tests/<name>`.
    pub fn scene(&self, name: &str) -> PathBuf {
        self.file(&format!("tests/{name}"))
    }

    /// One of the course's reference images, `images/<name>`.
    pub fn image(&self, name: &str) -> PathBuf {
        self.file(&format!("images/{name}"))
    }
}

/// The course's files for a test that needs nothing else: `None` after reporting the calling
/// test as not run, or a panic when `CI=true`.
///
/// ```no_run
/// let Some(course) = rayscope_testkit::course() else { return };
/// let scene = course.scene("sample_scene_1.txt");
/// ```
pub fn course() -> Option<Course> {
    course_or("")
}

/// The course's files for a test that also runs on our own scenes: `None` after reporting its
/// course part as not run, or a panic when `CI=true`.
pub fn course_part() -> Option<Course> {
    course_or("its part on the course's scenes (the rest ran) ")
}

fn course_or(part: &str) -> Option<Course> {
    let found = Course::find();
    if found.is_none() {
        let source = if std::env::var_os(COURSE_DIR_VAR).is_some_and(|v| !v.is_empty()) {
            format!("from {COURSE_DIR_VAR}")
        } else {
            format!("the default: {COURSE_DIR_VAR} is unset")
        };
        not_run(
            &format!("{part}needs the course's files"),
            &format!(
                "No folder with tests/ and images/ at {} ({source}).",
                course_dir().display()
            ),
            &format!(
                "To run them, point {COURSE_DIR_VAR} at your course template checkout (the folder \
                 with tests/ and images/), e.g.\n  {COURSE_DIR_VAR}=$HOME/comp30019-project-1 cargo test --workspace"
            ),
        );
    }
    found
}

/// Whether this is a CI run (`CI` set to `true` or `1`), where a missing prerequisite fails.
pub fn ci() -> bool {
    std::env::var("CI").is_ok_and(|v| v.eq_ignore_ascii_case("true") || v == "1")
}

/// Tests of this process reported as not run so far.
static NOT_RUN: AtomicUsize = AtomicUsize::new(0);

/// Explanations already printed by this process (each once).
static EXPLAINED: Mutex<Vec<String>> = Mutex::new(Vec::new());

/// Reports the calling test as not run: it `needs` something (`"needs chromium"`), `missing`
/// says what was looked for and not found, `how_to` how to provide it; the last two are printed
/// once per test binary. Panics instead when `CI=true`, so that CI cannot pass without running
/// the test. The caller returns from the test after this.
pub fn not_run(needs: &str, missing: &str, how_to: &str) {
    let test = test_name();
    if ci() {
        panic!("{test} {needs}. {missing}\nCI=true, so this is a failure, not a skip.\n{how_to}");
    }
    let n = NOT_RUN.fetch_add(1, Ordering::SeqCst) + 1;
    let mut text = String::new();
    {
        let mut explained = EXPLAINED.lock().unwrap_or_else(|e| e.into_inner());
        let key = format!("{missing}{how_to}");
        if !explained.contains(&key) {
            explained.push(key);
            let rule = "=".repeat(78);
            let what = needs.rsplit("needs ").next().unwrap_or(needs);
            text += &format!(
                "\n{rule}\nNOT RUN: tests that need {what} pass here WITHOUT testing anything.\n\
                 {missing}\n{how_to}\n{rule}\n"
            );
        }
    }
    text += &format!("NOT RUN ({n} in {}): {test} {needs}\n", binary_name());
    // Straight to the file descriptor: libtest captures `eprint!`, not `io::stderr()`, so
    // this reaches the terminal under plain `cargo test`. One write keeps lines whole when
    // tests run in parallel.
    let _ = std::io::stderr().lock().write_all(text.as_bytes());
}

/// The running test's name (libtest names each test's thread after it).
fn test_name() -> String {
    let name = std::thread::current().name().unwrap_or("this test").to_owned();
    match name.as_str() {
        // `--test-threads=1` runs tests on the main thread.
        "main" => "this test".to_owned(),
        _ => format!("{}::{name}", binary_name()),
    }
}

/// The test binary's name without cargo's hash (`golden` for `golden-1a2b3c…`).
fn binary_name() -> String {
    let exe = std::env::current_exe().ok();
    let stem = exe
        .as_deref()
        .and_then(Path::file_stem)
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    match stem.rsplit_once('-') {
        Some((name, hash)) if hash.chars().all(|c| c.is_ascii_hexdigit()) => name.to_owned(),
        _ => stem,
    }
}

#[cfg(test)]
mod tests {
    use std::process::Command;

    use super::*;

    #[test]
    fn binary_names_lose_cargo_s_hash() {
        // This very binary is `rayscope_testkit-<hash>`.
        assert_eq!(binary_name(), "rayscope_testkit");
    }

    #[test]
    fn the_workspace_root_holds_our_scenes() {
        assert!(workspace().join("Cargo.lock").is_file());
        assert!(scene("whitted.txt").is_file());
    }

    #[test]
    fn the_course_folder_is_the_setting_or_the_default_beside_the_workspace() {
        let root = workspace();
        assert_eq!(course_dir_from(None), root.join("../shared/reference"));
        assert_eq!(course_dir_from(Some("".as_ref())), root.join("../shared/reference"));
        assert_eq!(course_dir_from(Some("/x/template".as_ref())), Path::new("/x/template"));
        assert_eq!(course_dir_from(Some("../t".as_ref())), root.join("../t"));
    }

    /// Set by [`run_probe`] for the child process it starts.
    const PROBE: &str = "RAYSCOPE_TESTKIT_PROBE";

    /// A course test as the other crates write one; it acts only inside [`run_probe`]'s child.
    #[test]
    fn probe_needs_the_course() {
        if std::env::var_os(PROBE).is_none() {
            return;
        }
        let Some(course) = course() else { return };
        assert!(course.dir().join("tests").is_dir());
        println!("PROBE RAN");
    }

    /// Runs [`probe_needs_the_course`] in a child test process, output captured as under a
    /// plain `cargo test`, with `dir` as the course folder and `ci` as `CI`; its exit status
    /// and stdout and stderr together.
    fn run_probe(dir: &Path, ci: Option<&str>) -> (bool, String) {
        let mut cmd = Command::new(std::env::current_exe().unwrap());
        cmd.args(["--exact", "tests::probe_needs_the_course", "--test-threads", "2"])
            .env(PROBE, "1")
            .env(COURSE_DIR_VAR, dir)
            .env_remove("CI");
        if let Some(v) = ci {
            cmd.env("CI", v);
        }
        let out = cmd.output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
        (out.status.success(), text)
    }

    #[test]
    fn without_the_course_a_test_says_it_did_not_run_and_fails_under_ci() {
        let empty = std::env::temp_dir().join(format!("rayscope-testkit-empty-{}", std::process::id()));
        std::fs::create_dir_all(&empty).unwrap();
        let (ok, text) = run_probe(&empty, None);
        assert!(ok, "{text}");
        // Printed although libtest captured the passing test's output.
        assert!(
            text.contains(
                "NOT RUN (1 in rayscope_testkit): rayscope_testkit::tests::probe_needs_the_course needs the course's files\n"
            ),
            "{text}"
        );
        assert!(text.contains(&format!("at {}", empty.display())), "{text}");
        assert!(
            text.contains("RAYSCOPE_COURSE_DIR=$HOME/"),
            "says how to enable it: {text}"
        );
        assert!(!text.contains("PROBE RAN"), "{text}");

        let (ok, text) = run_probe(&empty, Some("true"));
        assert!(!ok, "CI=true without the course must fail: {text}");
        assert!(text.contains("CI=true, so this is a failure, not a skip"), "{text}");
        std::fs::remove_dir_all(&empty).unwrap();
    }

    #[test]
    fn with_a_course_folder_the_test_runs() {
        // A course folder is one with tests/ and images/; nothing else is looked at here.
        let dir = std::env::temp_dir().join(format!("rayscope-testkit-course-{}", std::process::id()));
        for sub in ["tests", "images"] {
            std::fs::create_dir_all(dir.join(sub)).unwrap();
        }
        let (ok, text) = run_probe(&dir, Some("true"));
        assert!(ok, "{text}");
        assert!(!text.contains("NOT RUN"), "{text}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
