//! `rayscope probe` against student-style intersectors: a correct one passes every course scene,
//! each realistic mistake is named, and programs that hang, crash or print garbage get a clear
//! error in time.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command as StdCommand;
use std::time::{Duration, Instant};

use common::{rayscope, scenes};
use serde_json::Value;

fn examples(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/probe")
        .join(rel)
}

fn student() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/probe/student_tracer.py")
}

fn python() -> &'static str {
    let ok = StdCommand::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(ok, "the probe tests need python3 (standard library only) on PATH");
    "python3"
}

/// Runs probe with the Python adapter on the student tracer with `mistakes`; (exit code, JSON report).
fn probe(scene: &Path, mistakes: &str) -> (i32, Value) {
    let out = rayscope()
        .arg("probe")
        .arg("-f")
        .arg(scene)
        .arg("--json")
        .env("PROBE_MISTAKES", mistakes)
        .arg("--")
        .arg(python())
        .arg(examples("python/probe_adapter.py"))
        .arg(student())
        .output()
        .unwrap();
    let code = out.status.code().unwrap_or(-1);
    let report: Value = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "no JSON report ({e}); exit {code}\nstdout: {}\nstderr: {}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (code, report)
}

/// (primitive, case, verdict, count, of) of every finding.
fn findings(report: &Value) -> Vec<(String, String, String, u64, u64)> {
    report["findings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["primitive"].as_str().unwrap().to_string(),
                f["case"].as_str().unwrap().to_string(),
                f["verdict"].as_str().unwrap().to_string(),
                f["count"].as_u64().unwrap(),
                f["of"].as_u64().unwrap(),
            )
        })
        .collect()
}

#[test]
fn a_correct_intersector_passes_every_course_scene_and_ours_in_double_and_single_precision() {
    let mut all = vec![scenes("obj.txt"), scenes("room.txt")];
    if let Some(course) = rayscope_testkit::course_part() {
        for name in ["sample_scene_1.txt", "sample_scene_2.txt", "sample_scene_obj.txt"] {
            all.push(course.scene(name));
        }
    }
    for scene in all {
        // "float32" rounds every operation to single precision, as a tracer in float does.
        for precision in ["", "float32"] {
            let (code, report) = probe(&scene, precision);
            assert_eq!(
                findings(&report),
                vec![],
                "{} {precision}: a correct intersector is blamed:\n{report:#}",
                scene.display()
            );
            assert_eq!(code, 0);
            assert!(report["rays"].as_u64().unwrap() > 200, "{}", report["rays"]);
        }
    }
}

#[test]
fn the_python_example_tracer_passes() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(course.scene("sample_scene_2.txt"))
        .arg("--")
        .arg(python())
        .arg(examples("python/probe_adapter.py"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        text.contains("Every answer is right: your intersector agrees with rayscope on all 1008 rays."),
        "{text}"
    );
}

/// Asserts that `mistakes` is reported as exactly the findings `allowed` (primitive, case,
/// verdict) and that each of `required` is among them, wrong on every one of its rays.
fn names(mistakes: &str, scene: &Path, required: &[(&str, &str, &str)], allowed: &[(&str, &str, &str)]) {
    let (code, report) = probe(scene, mistakes);
    assert_eq!(code, 1, "{mistakes}: exit code");
    let found = findings(&report);
    for (p, c, v, count, of) in &found {
        assert!(
            allowed.contains(&(p.as_str(), c.as_str(), v.as_str()))
                || required.contains(&(p.as_str(), c.as_str(), v.as_str())),
            "{mistakes}: unexpected finding {p} {c} {v} ({count} of {of}):\n{report:#}"
        );
    }
    for (p, c, v) in required {
        let f = found
            .iter()
            .find(|f| (f.0.as_str(), f.1.as_str(), f.2.as_str()) == (*p, *c, *v))
            .unwrap_or_else(|| panic!("{mistakes}: {p} {c} {v} not reported:\n{report:#}"));
        assert_eq!(f.3, f.4, "{mistakes}: {p} {c} {v} should be wrong on every ray");
    }
}

#[test]
fn names_a_sphere_returning_the_root_behind_the_origin() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    names(
        "sphere-inside",
        &course.scene("sample_scene_2.txt"),
        &[
            ("sphere", "inside", "behind-origin"),
            ("sphere", "centre", "behind-origin"),
        ],
        // A ray leaving the surface has one root at about 0 and one behind: the mistake returns
        // the one behind whenever rounding puts the other just above its epsilon.
        &[("sphere", "surface-leaving", "behind-origin")],
    );
}

#[test]
fn names_a_sphere_taking_the_far_root() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let all = ["outside-hit", "grazing", "near", "far", "tiny", "huge"].map(|c| ("sphere", c, "wrong-root"));
    names(
        "sphere-far-root",
        &course.scene("sample_scene_2.txt"),
        &[("sphere", "outside-hit", "wrong-root"), ("sphere", "far", "wrong-root")],
        &all,
    );
}

#[test]
fn names_a_one_sided_triangle() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    names(
        "triangle-one-sided",
        &course.scene("sample_scene_2.txt"),
        &[("triangle", "back-hit", "missed")],
        &[],
    );
}

#[test]
fn names_a_plane_that_divides_by_zero_for_parallel_rays() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = course.scene("sample_scene_1.txt");
    names(
        "plane-parallel",
        &scene,
        &[
            ("plane", "parallel", "raised-error"),
            ("plane", "in-plane", "raised-error"),
        ],
        &[],
    );
    names(
        "plane-parallel-inf",
        &scene,
        &[],
        &[("plane", "parallel", "not-finite")],
    );
    let (_, report) = probe(&scene, "plane-parallel-inf");
    assert!(
        findings(&report)
            .iter()
            .any(|f| f.1 == "parallel" && f.2 == "not-finite"),
        "{report:#}"
    );
    let hint = report["findings"][0]["hint"].as_str().unwrap();
    assert!(hint.contains("divide by it"), "{hint}");
}

#[test]
fn names_a_strict_edge_test() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    names(
        "triangle-strict",
        &course.scene("sample_scene_2.txt"),
        &[("triangle", "edge", "missed"), ("triangle", "vertex", "missed")],
        &[],
    );
}

#[test]
fn names_normals_that_are_not_unit_length() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (code, report) = probe(&course.scene("sample_scene_2.txt"), "normal-unnormalised");
    assert_eq!(code, 1);
    // One finding per kind of primitive, on every hit, not one per case.
    let found = findings(&report);
    assert_eq!(found.len(), 2, "{report:#}");
    for p in ["sphere", "triangle"] {
        assert!(
            found
                .iter()
                .any(|f| f.0 == p && f.1 == "all" && f.2 == "normal-not-unit" && f.3 == f.4 && f.3 > 50),
            "{p}:\n{report:#}"
        );
    }
}

#[test]
fn the_text_report_explains_and_reproduces() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(course.scene("sample_scene_2.txt"))
        .env("PROBE_MISTAKES", "sphere-inside")
        .arg("--")
        .arg(python())
        .arg(examples("python/probe_adapter.py"))
        .arg(student())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("sphere: ray starting inside the sphere -- you return a hit behind the origin (t < 0) in"),
        "{text}"
    );
    assert!(text.contains("the hit is the larger root"), "{text}");
    assert!(text.contains("Reproduce"), "{text}");
    assert!(text.contains("request   {\"id\":"), "{text}");
    assert!(text.contains("expected  hit at t = "), "{text}");
    assert!(text.contains("yours     hit at t = -"), "{text}");
    assert!(
        text.contains("\"GlassSphere\" (line 12)") || text.contains("\"MirrorSphere\""),
        "{text}"
    );
}

/// Runs probe on a throw-away Python program; (exit code, stderr, seconds).
fn probe_program(code: &str, flags: &[&str]) -> (i32, String, f64) {
    let dir = tempfile::tempdir().unwrap();
    let script = dir.path().join("prog.py");
    std::fs::write(&script, code).unwrap();
    let start = Instant::now();
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(scenes("basic.txt"))
        .args(flags)
        .arg("--")
        .arg(python())
        .arg(&script)
        .timeout(Duration::from_secs(30))
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        start.elapsed().as_secs_f64(),
    )
}

const READY: &str = "import sys, time\nsys.stdin.readline()\nprint('{\"ready\":true}', flush=True)\n";

#[test]
fn a_hanging_program_is_stopped_after_the_timeout() {
    let (code, err, secs) = probe_program(
        &format!("{READY}sys.stdin.readline()\ntime.sleep(60)\n"),
        &["--timeout", "1"],
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("did not answer request 0") && err.contains("within 1 s"),
        "{err}"
    );
    assert!(err.contains("flush"), "{err}");
    assert!(secs < 10.0, "took {secs} s");
    // One that never says it is ready.
    let (code, err, secs) = probe_program("import time\ntime.sleep(60)\n", &["--startup-timeout", "1"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("did not answer rayscope's hello within 1 s"), "{err}");
    assert!(secs < 10.0, "took {secs} s");
}

#[test]
fn a_crashing_program_shows_its_exit_status_and_stderr() {
    let (code, err, _) = probe_program(
        &format!("{READY}sys.stdin.readline()\nraise ValueError('my tracer broke')\n"),
        &["--timeout", "5"],
    );
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("exited with status 1 before answering request 0"), "{err}");
    assert!(err.contains("ValueError: my tracer broke"), "{err}");
    assert!(err.contains("request: {\"id\":0"), "{err}");
}

#[test]
fn a_program_printing_garbage_is_quoted() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let (code, err, _) = probe_program(
        &format!("{READY}sys.stdin.readline()\nprint('Hit sphere at 0.5', flush=True)\ntime.sleep(60)\n"),
        &["--timeout", "5"],
    );
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("answered request 0 with a line rayscope cannot read: not JSON"),
        "{err}"
    );
    assert!(err.contains("answer:  Hit sphere at 0.5"), "{err}");
    assert!(err.contains("{\"id\":0,\"hit\":null}"), "{err}");
    assert!(err.contains("stderr"), "{err}");
    // Not speaking the protocol at all.
    let (code, err, _) = probe_program("print('Rendering scene...', flush=True)\n", &[]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("does not speak the probe protocol") && err.contains("Rendering scene..."),
        "{err}"
    );
    // A scene with an error is reported like anywhere else, before any program starts.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.txt");
    std::fs::write(&bad, "Sphere \"S\" (0, 0, 2) 0.5 \"Nope\"\n").unwrap();
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(&bad)
        .args(["--", "no-such-program-rayscope"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.txt:1:") && !err.contains("cannot start"), "{err}");
    // No command after `--`.
    let out = rayscope().args(["probe", "-f"]).arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    // A program that is not there.
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(course.scene("sample_scene_1.txt"))
        .args(["--", "no-such-program-rayscope"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot start `no-such-program-rayscope`"));
}

#[test]
fn the_csharp_adapter_compiles_and_passes() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let have = StdCommand::new("mcs")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
        && StdCommand::new("mono")
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success());
    if !have {
        rayscope_testkit::not_run(
            "needs mcs and mono",
            "No mcs (Mono's C# compiler) and mono found on PATH.",
            "To run it, install them (Debian: apt-get install mono-mcs).",
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let exe = dir.path().join("probe.exe");
    let built = StdCommand::new("mcs")
        .arg(format!("-out:{}", exe.display()))
        .arg(examples("csharp/ProbeAdapter.cs"))
        .arg(examples("csharp/ExampleTracer.cs"))
        .output()
        .unwrap();
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stdout));
    let out = rayscope()
        .args(["probe", "-f"])
        .arg(course.scene("sample_scene_2.txt"))
        .arg("--")
        .arg("mono")
        .arg(&exe)
        .arg("--probe")
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("Every answer is right"));
}

/// Whether Mono's compiler and runtime are on PATH; says loudly that the caller is not run
/// when they are not (and fails under CI=true).
fn have_mono() -> bool {
    let runs = |tool: &str| {
        StdCommand::new(tool)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    };
    let have = runs("mcs") && runs("mono");
    if !have {
        rayscope_testkit::not_run(
            "needs mcs and mono",
            "No mcs (Mono's C# compiler) and mono found on PATH.",
            "To run it, install them (Debian: apt-get install mono-mcs).",
        );
    }
    have
}

/// Compiles `sources` with mcs into `exe`.
fn mcs(exe: &Path, sources: &[&Path]) {
    let built = StdCommand::new("mcs")
        .arg(format!("-out:{}", exe.display()))
        .args(sources)
        .output()
        .unwrap();
    assert!(
        built.status.success(),
        "{}{}",
        String::from_utf8_lossy(&built.stdout),
        String::from_utf8_lossy(&built.stderr)
    );
}

/// `rayscope probe --json` of `scene` against the program `command`: (exit code, report).
fn probe_report(scene: &Path, command: &[&std::ffi::OsStr]) -> (i32, Value) {
    let out = rayscope()
        .args(["probe", "--json", "-f"])
        .arg(scene)
        .arg("--")
        .args(command)
        .output()
        .unwrap();
    let code = out.status.code().unwrap_or(-1);
    let report = serde_json::from_slice(&out.stdout).unwrap_or_else(|e| {
        panic!(
            "no JSON report ({e}); exit {code}\nstdout: {}\nstderr: {}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        )
    });
    (code, report)
}

/// `probe_report` against `mono exe --probe`.
fn probe_mono(scene: &Path, exe: &Path) -> (i32, Value) {
    probe_report(scene, &["mono".as_ref(), exe.as_os_str(), "--probe".as_ref()])
}

#[test]
fn the_csharp_adapter_gives_entities_a_material_their_intersect_may_read() {
    if !have_mono() {
        return;
    }
    // ExampleTracer.cs is in the template's shape, and its hits read the entity's material, as
    // many students' tracers do: `new RayHit(p, n, ray.Direction, this.Material)` taking its
    // type and colour.
    let tracer = examples("csharp/ExampleTracer.cs");
    let adapter = examples("csharp/ProbeAdapter.cs");
    let dir = tempfile::tempdir().unwrap();
    let exe = dir.path().join("probe.exe");
    mcs(&exe, &[&adapter, &tracer]);
    // The same adapter handing the constructors a null material, which this tracer must not
    // survive: otherwise the test would pass whatever material the adapter gave.
    let source = std::fs::read_to_string(&adapter).unwrap();
    let real = "static readonly Material Probe = new Material(Material.MaterialType.Diffuse, new Color(1, 1, 1));";
    assert!(
        source.contains(real),
        "the adapter's material line changed; update this test"
    );
    let null_adapter = dir.path().join("NullMaterialAdapter.cs");
    std::fs::write(
        &null_adapter,
        source.replace(real, "static readonly Material Probe = null;"),
    )
    .unwrap();
    let null_exe = dir.path().join("null.exe");
    mcs(&null_exe, &[&null_adapter, &tracer]);

    let mut all = vec![scenes("room.txt"), scenes("obj.txt")];
    if let Some(course) = rayscope_testkit::course_part() {
        all.push(course.scene("sample_scene_2.txt"));
    }
    for scene in all {
        let (code, report) = probe_mono(&scene, &exe);
        assert_eq!(
            findings(&report),
            vec![],
            "{}: the C# example tracer is blamed:\n{report:#}",
            scene.display()
        );
        assert_eq!(code, 0);
        // Without a material every hit throws: each is reported as an error the tracer raised.
        let (code, report) = probe_mono(&scene, &null_exe);
        assert_eq!(code, 1, "{}: a null material went unnoticed", scene.display());
        let raised: u64 = report["findings"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|f| f["verdict"] == "raised-error")
            .map(|f| f["count"].as_u64().unwrap())
            .sum();
        assert!(raised > 100, "{}: {raised} raised errors\n{report:#}", scene.display());
    }
}

/// `probe_report` against `python3 adapter example_tracer.py`.
fn probe_python_example(scene: &Path, adapter: &Path) -> (i32, Value) {
    let tracer = examples("python/example_tracer.py");
    probe_report(scene, &[python().as_ref(), adapter.as_os_str(), tracer.as_os_str()])
}

#[test]
fn the_python_adapter_gives_primitives_a_material_their_intersect_may_read() {
    // example_tracer.py's constructors take a material after the geometry, as the template's
    // do, and its hits read the material's type and colour (student_tracer.py's take none, and
    // the other tests run it through the same adapter).
    let adapter = examples("python/probe_adapter.py");
    let source = std::fs::read_to_string(&adapter).unwrap();
    let real = "MATERIAL = make_material()\n";
    assert!(
        source.contains(real),
        "the adapter's material line changed; update this test"
    );
    let dir = tempfile::tempdir().unwrap();
    let null_adapter = dir.path().join("probe_adapter.py");
    std::fs::write(&null_adapter, source.replace(real, "MATERIAL = None\n")).unwrap();
    for scene in [scenes("room.txt"), scenes("obj.txt")] {
        let (code, report) = probe_python_example(&scene, &adapter);
        assert_eq!(
            findings(&report),
            vec![],
            "{}: the Python example tracer is blamed:\n{report:#}",
            scene.display()
        );
        assert_eq!(code, 0);
        let (code, report) = probe_python_example(&scene, &null_adapter);
        assert_eq!(code, 1, "{}: a missing material went unnoticed", scene.display());
        assert!(
            findings(&report).iter().any(|f| f.2 == "raised-error"),
            "{}:\n{report:#}",
            scene.display()
        );
    }
}
