//! `rayscope probe` against programs that misbehave on purpose: each is stopped in time, is
//! described truthfully, leaves nothing running, and cannot grow rayscope's memory. Each test
//! watches the real binary (its exit, its messages, its peak memory) and gives up on it after a
//! few seconds instead of hanging.

mod common;

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::thread;
use std::time::{Duration, Instant};

use common::{scenes, watch, Watched};

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

/// Runs rayscope with `args`, watching its peak memory; kills it and fails the test if it is
/// still running after `limit`.
fn watched(args: &[&str], limit: Duration) -> Watched {
    let mut cmd = Command::new(bin());
    cmd.args(args);
    watch(cmd, limit)
}

/// A one-sphere scene and a Python program `code` in a new folder.
fn setup(code: &str) -> (tempfile::TempDir, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("scene.txt");
    fs::write(
        &scene,
        "Material \"M\" Diffuse (1, 1, 1) 1\nSphere \"Ball\" (0, 0, 3) 0.5 \"M\"\n",
    )
    .unwrap();
    let prog = dir.path().join("prog.py");
    fs::write(&prog, code).unwrap();
    (dir, scene, prog)
}

fn probe(scene: &Path, prog: &Path, flags: &[&str]) -> Watched {
    let mut args = vec!["probe", "-f", scene.to_str().unwrap()];
    args.extend_from_slice(flags);
    args.extend(["--", "python3", prog.to_str().unwrap()]);
    watched(&args, Duration::from_secs(8))
}

/// Memory a probe run may reach: the binary, the scene and its pipes' buffers, far below what
/// the programs below would make it hold without its limits.
const PEAK_KIB: u64 = 96 * 1024;

const READY: &str = "import os, sys, time, subprocess\nsys.stdin.readline()\nprint('{\"ready\":true}', flush=True)\n";

/// Answers every request with a miss, reading each first, until its input closes.
const ANSWER_ALL: &str = "import json\nfor line in sys.stdin:\n    \
     print(json.dumps({'id': json.loads(line)['id'], 'hit': None}), flush=True)\n";

#[test]
fn stderr_without_newlines_is_kept_bounded_and_reported() {
    // 256 MiB on stderr with no newline, then an exit without answering.
    let (_dir, scene, prog) = setup(
        "import sys\nsys.stdin.readline()\nchunk = b'x' * (1 << 20)\nfor _ in range(256):\n    \
         sys.stderr.buffer.write(chunk)\nsys.stderr.buffer.write(b'the end')\nsys.stderr.flush()\nsys.exit(3)\n",
    );
    let r = probe(&scene, &prog, &["--timeout", "5"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("exited with status 3 before answering rayscope's hello"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("wrote nothing"), "{}", r.stderr);
    assert!(r.stderr.contains("it wrote 256.0 MiB in all"), "{}", r.stderr);
    assert!(r.stderr.contains("only the last 64 KiB were kept"), "{}", r.stderr);
    // One line shown, cut.
    let shown: Vec<_> = r.stderr.lines().filter(|l| l.starts_with("    | ")).collect();
    assert_eq!(shown.len(), 1, "{}", r.stderr);
    assert!(shown[0].starts_with("    | xxxx") && shown[0].ends_with(" …") && shown[0].len() < 400);
    assert!(r.peak_kib < PEAK_KIB, "peak {} KiB", r.peak_kib);
}

#[test]
fn stderr_lines_show_their_end_and_nothing_written_is_said() {
    // Many lines: the last ones are shown, with how much was written.
    let (_dir, scene, prog) = setup(
        "import sys\nsys.stdin.readline()\nfor i in range(200000):\n    print('line', i, file=sys.stderr)\n\
         print('\\x1b[2Jlast', file=sys.stderr)\nsys.exit(1)\n",
    );
    let r = probe(&scene, &prog, &[]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("| line 199999\n"), "{}", r.stderr);
    assert!(
        r.stderr.contains("| \u{fffd}[2Jlast"),
        "escape sequences are not passed on: {}",
        r.stderr
    );
    assert!(r.stderr.contains("only the last 64 KiB were kept"), "{}", r.stderr);
    assert!(r.peak_kib < PEAK_KIB, "peak {} KiB", r.peak_kib);
    // Nothing at all.
    let (_dir, scene, prog) = setup("import sys\nsys.stdin.readline()\nsys.exit(4)\n");
    let r = probe(&scene, &prog, &[]);
    assert_eq!(r.code, Some(2));
    assert!(r.stderr.contains("exited with status 4") && r.stderr.contains("(it wrote nothing to stderr)"));
}

#[test]
fn a_program_that_answers_without_reading_is_stopped_at_the_timeout() {
    // It answers every id in turn but never reads a request: rayscope's writes fill the pipe.
    let (_dir, scene, prog) = setup(
        "import sys\nprint('{\"ready\":true}', flush=True)\ni = 0\nwhile True:\n    \
         print('{\"id\":%d,\"hit\":null}' % i, flush=True)\n    i += 1\n",
    );
    let r = probe(&scene, &prog, &["--timeout", "1", "--rays-per-case", "200"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("did not read request") && r.stderr.contains("from its input (stdin) within 1 s"),
        "{}",
        r.stderr
    );
    assert!(r.secs < 5.0, "took {} s", r.secs);
    assert!(r.peak_kib < PEAK_KIB, "peak {} KiB", r.peak_kib);
    // One that never reads even the hello: the hello fits in the pipe, so the answer times out.
    let (_dir, scene, prog) = setup("import sys, time\ntime.sleep(30)\n");
    let r = probe(&scene, &prog, &["--startup-timeout", "1"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("did not answer rayscope's hello within 1 s"),
        "{}",
        r.stderr
    );
}

/// True while `pid` is a live process (a zombie, exited but not yet reaped, is not).
fn alive(pid: u32) -> bool {
    fs::read_to_string(format!("/proc/{pid}/status"))
        .is_ok_and(|s| !s.lines().any(|l| l.starts_with("State:") && l.contains("Z")))
}

fn grandchild_pid(file: &Path) -> u32 {
    let start = Instant::now();
    loop {
        if let Some(pid) = fs::read_to_string(file).ok().and_then(|s| s.trim().parse().ok()) {
            return pid;
        }
        assert!(start.elapsed() < Duration::from_secs(3), "the program wrote no pid");
        thread::sleep(Duration::from_millis(10));
    }
}

fn assert_gone(pid: u32) {
    let start = Instant::now();
    while alive(pid) {
        if start.elapsed() > Duration::from_secs(2) {
            let _ = Command::new("kill").args(["-KILL", &pid.to_string()]).status();
            panic!("the program's own child {pid} is still running after probe ended");
        }
        thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn what_the_program_started_is_stopped_when_it_exits() {
    for (end, code) in [(ANSWER_ALL, 1), ("sys.stdin.readline()\nsys.exit(5)\n", 2)] {
        let dir = tempfile::tempdir().unwrap();
        let pid_file = dir.path().join("grandchild.pid");
        let (_d, scene, prog) = setup(&format!(
            "{READY}g = subprocess.Popen(['sleep', '30'], stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, \
             stderr=subprocess.DEVNULL)\nopen({:?}, 'w').write(str(g.pid))\n{end}",
            pid_file.to_str().unwrap()
        ));
        let r = probe(&scene, &prog, &[]);
        assert_eq!(r.code, Some(code), "{}{}", r.stdout, r.stderr);
        assert_gone(grandchild_pid(&pid_file));
    }
}

#[test]
fn out_of_range_timeouts_are_refused() {
    let s = scenes("basic.txt");
    let s = s.to_str().unwrap();
    for (flag, value, shown) in [
        ("--timeout", "1e300", "--timeout 1e300 is out of range"),
        ("--startup-timeout", "1e19", "--startup-timeout 1e19 is out of range"),
        ("--timeout", "86401", "--timeout 86401 is out of range"),
    ] {
        let r = watched(
            &["probe", "-f", s, flag, value, "--", "python3", "-c", "pass"],
            Duration::from_secs(5),
        );
        assert_eq!(r.code, Some(2), "{flag} {value}: {}", r.stderr);
        assert!(
            r.stderr.contains(shown) && r.stderr.contains("at most 86400 (a day)"),
            "{}",
            r.stderr
        );
    }
    for bad in ["inf", "nan", "0", "-1"] {
        let r = watched(
            &["probe", "-f", s, "--timeout", bad, "--", "python3", "-c", "pass"],
            Duration::from_secs(5),
        );
        assert_eq!(r.code, Some(2), "{bad}: {}", r.stderr);
    }
    // The largest accepted reaches the program.
    let r = watched(
        &["probe", "-f", s, "--timeout", "86400", "--", "no-such-program-rayscope"],
        Duration::from_secs(5),
    );
    assert_eq!(r.code, Some(2));
    assert!(r.stderr.contains("cannot start"), "{}", r.stderr);
}

#[test]
fn a_program_that_closes_its_input_or_output_is_described_as_such() {
    // Closed before it says it is ready, so that request 0 finds the pipe closed.
    let (_dir, scene, prog) = setup(
        "import os, sys, time\nsys.stdin.readline()\nos.close(0)\nprint('{\"ready\":true}', flush=True)\ntime.sleep(30)\n",
    );
    let r = probe(&scene, &prog, &[]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("closed its input (stdin) without exiting before reading request 0"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("closed its output"), "{}", r.stderr);
    assert!(r.secs < 5.0, "took {} s", r.secs);
    // Its output.
    let (_dir, scene, prog) = setup(&format!("{READY}sys.stdout.close()\nos.close(1)\ntime.sleep(30)\n"));
    let r = probe(&scene, &prog, &[]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("closed its output (stdout) without exiting before answering request 0"),
        "{}",
        r.stderr
    );
    assert!(r.secs < 5.0, "took {} s", r.secs);
    // Both, by exiting: its exit status is what it did.
    let (_dir, scene, prog) = setup(
        "import os, sys, time\nsys.stdin.readline()\nos.close(0)\nprint('{\"ready\":true}', flush=True)\nsys.exit(6)\n",
    );
    let r = probe(&scene, &prog, &[]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("exited with status 6 before answering request 0"),
        "{}",
        r.stderr
    );
}

#[test]
fn batteries_past_the_request_limit_are_refused_before_they_are_built() {
    // Two meshes of 576 triangles, a plane and a sphere.
    let s = scenes("obj.txt");
    let s = s.to_str().unwrap();
    let r = watched(
        &[
            "probe",
            "-f",
            s,
            "--mesh-triangles",
            "100000",
            "--rays-per-case",
            "1000",
            "--",
            "python3",
            "-c",
            "pass",
        ],
        Duration::from_secs(5),
    );
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("make up to 17304000 requests")
            && r.stderr.contains("more than the 1000000 one run sends")
            && r.stderr
                .contains("Lower --rays-per-case (at most 57 here) or --mesh-triangles"),
        "{}",
        r.stderr
    );
    assert!(r.peak_kib < PEAK_KIB, "peak {} KiB", r.peak_kib);
    // Just past the limit.
    let r = watched(
        &[
            "probe",
            "-f",
            s,
            "--mesh-triangles",
            "576",
            "--rays-per-case",
            "58",
            "--",
            "true",
        ],
        Duration::from_secs(5),
    );
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("make up to 1003632 requests"), "{}", r.stderr);
}

#[test]
fn the_csharp_adapter_gives_entities_a_material_they_may_read() {
    // ExampleTracer.cs has the template's shape: its hits read their entity's material, as many
    // students' do, so an entity built with a null material throws on every hit.
    let have = |tool: &str| {
        Command::new(tool)
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
    };
    if !(have("mcs") && have("mono")) {
        rayscope_testkit::not_run(
            "needs mcs and mono",
            "No mcs (Mono's C# compiler) and mono found on PATH.",
            "To run it, install them (Debian: apt-get install mono-mcs).",
        );
        return;
    }
    let csharp = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/probe/csharp");
    let dir = tempfile::tempdir().unwrap();
    let exe = dir.path().join("probe.exe");
    let built = Command::new("mcs")
        .arg(format!("-out:{}", exe.display()))
        .arg(csharp.join("ProbeAdapter.cs"))
        .arg(csharp.join("ExampleTracer.cs"))
        .output()
        .unwrap();
    assert!(built.status.success(), "{}", String::from_utf8_lossy(&built.stdout));
    let s = scenes("basic.txt");
    let r = watched(
        &[
            "probe",
            "-f",
            s.to_str().unwrap(),
            "--",
            "mono",
            exe.to_str().unwrap(),
            "--probe",
        ],
        Duration::from_secs(20),
    );
    assert_eq!(r.code, Some(0), "{}\n{}", r.stdout, r.stderr);
    assert!(r.stdout.contains("Every answer is right"), "{}", r.stdout);
}
