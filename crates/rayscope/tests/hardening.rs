//! What a hostile local user, a closed pipe or an outsized request must not be able to do: make
//! rayscope write through a planted link, loop without end, grow without bound, ignore Ctrl-C,
//! block on a pipe, panic on its own output, or write an image that differs from run to run.
//! Each test runs the real binary the way a user's shell would.

use std::fs;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// A small lit scene path-traced with `-l`.
const SCENE: &str = "Material \"White\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     Material \"Lamp\" Emissive (4, 4, 4) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"White\"\n\
                     Sphere \"Ball\" (0, 0, 3) 1 \"White\"\n\
                     Sphere \"Bulb\" (1.5, 1.5, 3) 0.3 \"Lamp\"\n";

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("scene.txt");
    fs::write(&p, SCENE).unwrap();
    p
}

fn run(args: &[&str]) -> std::process::Output {
    Command::new(bin()).args(args).output().unwrap()
}

/// Renders `scene` into `out` with extra flags.
fn render(scene: &Path, out: &Path, flags: &[&str]) -> std::process::Output {
    Command::new(bin())
        .arg("-f")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .args(flags)
        .output()
        .unwrap()
}

fn stderr(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Waits up to `limit` for the child to exit; kills it and fails if it does not.
fn wait_within(child: &mut Child, limit: Duration, what: &str) -> std::process::ExitStatus {
    let start = Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{what}: still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success(), "kill {sig}");
}

/// Peak resident memory of a running process, in KiB.
fn peak_rss_kib(pid: u32) -> u64 {
    let status = fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    let line = status.lines().find(|l| l.starts_with("VmHWM:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse().unwrap()
}

#[test]
fn a_link_planted_at_the_temporary_name_is_never_followed() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let precious = dir.path().join("precious.txt");
    fs::write(&precious, "the user's work").unwrap();
    let out = dir.path().join("out.png");
    let mut child = Command::new(bin())
        .arg("-f")
        .arg(&s)
        .arg("-o")
        .arg(&out)
        .args(["-w", "96", "-h", "96", "-x", "3", "--quiet"])
        .spawn()
        .unwrap();
    // Links at every name derived from the output's name and the process id: what an attacker
    // who can write to the folder would plant.
    for name in [
        format!(".out.png.rayscope-{}.tmp", child.id()),
        format!(".rayscope-{}.tmp", child.id()),
        format!("out.png.{}.tmp", child.id()),
    ] {
        std::os::unix::fs::symlink(&precious, dir.path().join(name)).unwrap();
    }
    assert!(wait_within(&mut child, Duration::from_secs(60), "render").success());
    assert_eq!(fs::read_to_string(&precious).unwrap(), "the user's work");
    assert_eq!(image::open(&out).unwrap().width(), 96);
}

#[test]
fn a_replaced_file_keeps_its_permissions_and_long_names_work() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = dir.path().join("private.png");
    fs::write(&out, "old").unwrap();
    fs::set_permissions(&out, fs::Permissions::from_mode(0o600)).unwrap();
    let o = render(&s, &out, &["-w", "8", "-h", "8", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(fs::metadata(&out).unwrap().permissions().mode() & 0o777, 0o600);
    assert!(image::open(&out).is_ok());

    // 250 bytes is a valid name on every common file system; the temporary name must not be longer.
    let long = dir.path().join(format!("{}.png", "a".repeat(246)));
    let o = render(&s, &long, &["-w", "8", "-h", "8", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(image::open(&long).is_ok());
    let names: Vec<_> = fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 3, "no temporary file left: {names:?}");
}

#[test]
fn an_output_path_ending_in_a_slash_fails_before_rendering() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = format!("{}/new.png/", dir.path().display());
    let start = Instant::now();
    let o = run(&[
        "-f",
        s.to_str().unwrap(),
        "-o",
        &out,
        "-w",
        "64",
        "-h",
        "64",
        "-x",
        "16",
        "-q",
        "6",
        "-l",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("it is a folder"), "{}", stderr(&o));
    assert!(start.elapsed() < Duration::from_secs(10), "refused before rendering");
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn ctrl_c_stops_a_render_of_any_sample_count_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = dir.path().join("never.png");
    // 256 pixels × 2^24 samples: the tile's sample count is 2^32, which wrapped to 0 in 32 bits
    // and looped for ever; each pixel alone takes hours.
    for sig in ["-INT", "-TERM"] {
        let mut child = Command::new(bin())
            .arg("-f")
            .arg(&s)
            .arg("-o")
            .arg(&out)
            .args(["-x", "16", "-q", "16", "-l", "-w", "16", "-h", "16", "--quiet"])
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(1500));
        assert!(child.try_wait().unwrap().is_none(), "the render is still running");
        // Samples stream through bounded batches: memory does not grow with -x and -q.
        let rss = peak_rss_kib(child.id());
        assert!(
            rss < 200 * 1024,
            "peak resident memory {rss} KiB at 2^24 samples a pixel"
        );
        signal(&child, sig);
        let status = wait_within(&mut child, Duration::from_secs(5), "after the signal");
        assert_eq!(status.code(), Some(130), "{sig}");
        assert!(!out.exists());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1, "no temporary file left");
    }
}

#[test]
fn samples_past_single_precision_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = dir.path().join("x.png");
    let o = render(&s, &out, &["-x", "64", "-q", "16", "-l"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("268435456 samples per pixel"), "{}", stderr(&o));
    let o = render(&s, &out, &["-w", "65536", "-h", "65536", "--allow-large"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("even with --allow-large"), "{}", stderr(&o));
    assert!(!out.exists());
}

#[test]
fn devices_pipes_folders_and_huge_lines_are_named_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let o = run(&["-f", "/dev/zero", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("it is a device, not a file"), "{}", stderr(&o));

    let fifo = dir.path().join("pipe.txt");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let mut child = Command::new(bin())
        .arg("-f")
        .arg(&fifo)
        .arg("-o")
        .arg(&out)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status = wait_within(&mut child, Duration::from_secs(10), "a FIFO as the scene");
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert_eq!(status.code(), Some(2));
    assert!(err.contains("named pipe"), "{err}");

    // Four million words on one line: counted as extra words, not held as tokens.
    let long = dir.path().join("long.txt");
    let scene = format!(
        "{SCENE}Sphere \"Extra\" (0, 0, 9) 1 \"White\" {}\n",
        "7 ".repeat(1 << 22)
    );
    fs::write(&long, scene).unwrap();
    let o = render(&long, &out, &["-w", "8", "-h", "8"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("long.txt:7:"), "{}", stderr(&o));
    assert!(stderr(&o).contains("4194304 extra tokens ignored"), "{}", stderr(&o));
    fs::remove_file(&out).unwrap();

    // A folder where the OBJ file should be is a folder, not "not found".
    fs::create_dir(dir.path().join("bunny.obj")).unwrap();
    let s = dir.path().join("obj.txt");
    fs::write(
        &s,
        "Material \"M\" Diffuse (1, 1, 1) 1\nObjModel \"B\" \"bunny.obj\" (0, 0, 3) 1 \"M\"\n",
    )
    .unwrap();
    let o = run(&["-f", s.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("it is a folder, not a file"), "{}", stderr(&o));
    assert!(stderr(&o).contains("obj.txt:2:"), "{}", stderr(&o));
    assert!(!out.exists());
}

#[test]
fn a_closed_pipe_or_full_disk_never_panics() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    // `rayscope trace --json | head -c 0`: the reader is gone before anything is written.
    let mut child = Command::new(bin())
        .args([
            "trace",
            "-f",
            s.to_str().unwrap(),
            "--pixel",
            "8,8",
            "--json",
            "-w",
            "16",
            "-h",
            "16",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let status = wait_within(&mut child, Duration::from_secs(30), "trace into a closed pipe");
    let mut err = String::new();
    child.stderr.take().unwrap().read_to_string(&mut err).unwrap();
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    // Standard output on a full disk: an error, not a panic.
    let full = fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = Command::new(bin())
        .args([
            "trace",
            "-f",
            s.to_str().unwrap(),
            "--pixel",
            "8,8",
            "-w",
            "16",
            "-h",
            "16",
        ])
        .stdout(full)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("cannot write to standard output"), "{}", stderr(&o));

    // A bad scene with standard error closed still exits 2.
    let bad = dir.path().join("bad.txt");
    fs::write(&bad, "Sphere \"S\" (0, 0, 2) 0.5 \"Nope\"\n").unwrap();
    let mut child = Command::new(bin())
        .arg("-f")
        .arg(&bad)
        .arg("-o")
        .arg(dir.path().join("x.png"))
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stderr.take());
    let status = wait_within(&mut child, Duration::from_secs(30), "closed stderr");
    assert_eq!(status.code(), Some(2));
}

#[test]
fn exr_files_are_the_same_bytes_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let mut files = Vec::new();
    for threads in ["1", "2", "2"] {
        let out = dir.path().join(format!("img-{}.exr", files.len()));
        let o = render(&s, &out, &["-w", "160", "-h", "120", "--threads", threads, "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        files.push(fs::read(&out).unwrap());
    }
    assert!(files.windows(2).all(|w| w[0] == w[1]), "EXR bytes differ between runs");
}

#[test]
fn unbalanced_quotes_and_parentheses_render_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let s = dir.path().join("typos.txt");
    fs::write(
        &s,
        "Material \"M\" Diffuse (1, 1, 1) 1\nPointLight \"L\" (0, 2, 0) (1, 1, 1)\n\
         Sphere \"S (0, 0, 2) 0.5 \"M\"\nSphere \"T\" (1, 0, 2 0.5 \"M\"\nSphere \"U\" (-1, 0, 2)) 0.5 \"M\"\n",
    )
    .unwrap();
    let out = dir.path().join("x.png");
    let o = render(&s, &out, &["-w", "8", "-h", "8"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("unbalanced quote") && err.contains("typos.txt:3:27"),
        "{err}"
    );
    assert!(
        err.contains("this '(' is never closed") && err.contains("typos.txt:4:12"),
        "{err}"
    );
    assert!(
        err.contains("this ')' closes nothing") && err.contains("typos.txt:5:22"),
        "{err}"
    );
    assert!(image::open(&out).is_ok());
}
