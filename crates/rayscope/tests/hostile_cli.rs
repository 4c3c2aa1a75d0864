//! The command line's other inputs against hostile values: verdicts that must survive a closed
//! standard output, camera axes too short for f32, outputs in formats a command cannot write,
//! and ray files that are devices, pipes or too large. Each test runs the real binary.

mod common;

use std::ffi::OsStr;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::Duration;

const SCENE: &str = "Material \"W\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     Material \"R\" Diffuse (0.9, 0.1, 0.1) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"W\"\n\
                     Sphere \"Ball\" (0.6, 0.2, 3) 0.8 \"R\"\n";

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("scene.txt");
    fs::write(&p, SCENE).unwrap();
    p
}

fn run<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(bin()).args(args).stdin(Stdio::null()).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs rayscope with `args` and its standard output a pipe whose reader is already gone;
/// returns the exit code and stderr.
fn with_closed_stdout<S: AsRef<OsStr>>(args: &[S]) -> (Option<i32>, String) {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(bin())
        .args(args)
        .stdin(Stdio::null())
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    (o.status.code(), stderr(&o))
}

/// Runs rayscope with `args`, killing it and failing the test if it runs past 20 s; returns the
/// exit code, stderr and its highest VmHWM seen, in KiB.
fn watched<S: AsRef<OsStr>>(args: &[S]) -> (Option<i32>, String, u64) {
    let mut cmd = Command::new(bin());
    cmd.args(args);
    let r = common::watch(cmd, Duration::from_secs(20));
    (r.code, r.stderr, r.peak_kib)
}

fn png(path: &Path, rgb: [u8; 3]) {
    image::RgbImage::from_pixel(16, 16, image::Rgb(rgb)).save(path).unwrap();
}

#[test]
fn a_closed_stdout_keeps_diffs_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    png(&a, [0, 0, 0]);
    png(&b, [200, 10, 10]);
    let (code, err) = with_closed_stdout(&[OsStr::new("diff"), a.as_os_str(), b.as_os_str()]);
    assert_eq!(code, Some(1), "images differ: {err}");
    let (code, err) = with_closed_stdout(&[OsStr::new("diff"), a.as_os_str(), a.as_os_str()]);
    assert_eq!(code, Some(0), "images equal: {err}");
    // With a tolerance the verdict is the tolerance's.
    let (code, _) = with_closed_stdout(&[
        OsStr::new("diff"),
        a.as_os_str(),
        b.as_os_str(),
        OsStr::new("--tol"),
        OsStr::new("1"),
    ]);
    assert_eq!(code, Some(0));
}

#[test]
fn a_closed_stdout_keeps_diagnoses_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let img = dir.path().join("yours.png");
    png(&img, [255, 0, 255]);
    let (code, err) = with_closed_stdout(&[
        OsStr::new("diagnose"),
        OsStr::new("-f"),
        s.as_os_str(),
        img.as_os_str(),
        OsStr::new("--no-pairs"),
        OsStr::new("--quiet"),
    ]);
    assert_eq!(code, Some(1), "a magenta image is not the scene: {err}");
}

#[test]
fn a_closed_stdout_keeps_checks_verdict() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rays.jsonl");
    // Three camera rays straight ahead: pixels (0..3, 0) of an 8×6 image look elsewhere.
    let text: String = (0..3)
        .map(|x| {
            format!("{{\"pixel\": [{x}, 0], \"id\": {x}, \"kind\": \"camera\", \"origin\": [0, 0, 0], \"direction\": [0, 0, 1]}}\n")
        })
        .collect();
    fs::write(&log, text).unwrap();
    let scene = rayscope_testkit::scene("basic.txt");
    for json in [false, true] {
        let mut args = vec![
            OsStr::new("check"),
            OsStr::new("-f"),
            scene.as_os_str(),
            OsStr::new("--rays"),
            log.as_os_str(),
            OsStr::new("-w"),
            OsStr::new("8"),
            OsStr::new("-h"),
            OsStr::new("6"),
            OsStr::new("--quiet"),
        ];
        if json {
            args.push(OsStr::new("--json"));
        }
        let (code, err) = with_closed_stdout(&args);
        assert_eq!(code, Some(1), "the rays disagree (json {json}): {err}");
    }
}

#[test]
fn plain_output_to_a_closed_stdout_still_ends_quietly() {
    let (code, err) = with_closed_stdout(&["mistakes"]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.is_empty(), "{err}");
}

/// Renders frame 0 of the scene with `flags` into `dir/name_0000.png` and returns its bytes.
fn frame(dir: &Path, name: &str, flags: &[&str]) -> Result<Vec<u8>, String> {
    let out = dir.join(format!("{name}.png"));
    let o = Command::new(bin())
        .arg("-f")
        .arg(scene(dir))
        .arg("-o")
        .arg(&out)
        .args(["-w", "24", "-h", "16", "--quiet"])
        .args(flags)
        .output()
        .unwrap();
    if !o.status.success() {
        return Err(stderr(&o));
    }
    let written = if flags.contains(&"--frames") {
        dir.join(format!("{name}_0000.png"))
    } else {
        out
    };
    Ok(fs::read(written).unwrap())
}

#[test]
fn a_tiny_key_axis_is_the_direction_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let unit = frame(d, "unit", &["--frames", "0", "--key-a", "0:1,0,0", "-n", "90"]).unwrap();
    let about_z = frame(d, "z", &["--frames", "0", "--key-a", "0:0,0,1", "-n", "90"]).unwrap();
    assert_ne!(unit, about_z, "the scene must show a turn about x from one about z");
    // Lengths whose square underflows in f32 (1e-23) or is a subnormal (1e-30, 1e-40): each is
    // the x axis, not dropped for the flags' axis (+z).
    for tiny in ["1e-23", "1e-30", "1e-40"] {
        let key = format!("0:{tiny},0,0");
        let got = frame(d, "tiny", &["--frames", "0", "--key-a", &key, "-n", "90"]).unwrap();
        assert!(got == unit, "--key-a {key} did not turn about x");
        // Between two tiny keyframes too.
        let got = frame(
            d,
            "tiny2",
            &[
                "--frames",
                "0",
                "--key-a",
                &key,
                "--key-a",
                &format!("10:{tiny},0,0"),
                "-n",
                "90",
            ],
        )
        .unwrap();
        assert!(got == unit, "--key-a {key} (two keys) did not turn about x");
    }
    // --cam-axis takes tiny axes the same way.
    let cam = frame(d, "cam", &["-a", "1e-30,0,0", "-n", "90"]).unwrap();
    let cam_unit = frame(d, "cam_unit", &["-a", "1,0,0", "-n", "90"]).unwrap();
    assert!(cam == cam_unit);
    // A zero axis has no direction: refused, naming the flag.
    let err = frame(d, "zero", &["--frames", "0", "--key-a", "3:0,0,0"]).unwrap_err();
    assert!(err.contains("--key-a") && err.contains("(0, 0, 0)"), "{err}");
}

#[test]
fn view_names_only_the_format_it_writes() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    for name in ["x.jpg", "x.exr", "x"] {
        let out = dir.path().join(name);
        let o = run(&[
            OsStr::new("view"),
            OsStr::new("-f"),
            s.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
        ]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("PNG") && err.contains(".png"), "{err}");
        assert!(!err.contains("ppm") && !err.contains("exr,"), "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn bench_rays_reads_only_regular_files_of_bounded_size() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let fifo = dir.path().join("rays.bin");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let sparse = dir.path().join("big.bin");
    // 400 MiB without a byte written (a sparse file): over the bound, refused by its length.
    fs::File::create(&sparse).unwrap().set_len(400 << 20).unwrap();
    for (file, needle) in [
        (Path::new("/dev/zero"), "a device, not a file"),
        (fifo.as_path(), "a named pipe (FIFO), not a file"),
        (dir.path(), "a folder, not a file"),
        (sparse.as_path(), "more than the 384 MiB"),
    ] {
        let (code, err, peak) = watched(&[
            OsStr::new("bench"),
            OsStr::new("rays"),
            OsStr::new("-f"),
            s.as_os_str(),
            OsStr::new("--rays-file"),
            file.as_os_str(),
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
        assert!(peak < 100 * 1024, "{peak} KiB");
    }
    let (_, err, _) = watched(&[
        OsStr::new("bench"),
        OsStr::new("rays"),
        OsStr::new("-f"),
        s.as_os_str(),
        OsStr::new("--rays-file"),
        sparse.as_os_str(),
    ]);
    assert!(err.contains("at most 16777216 rays"), "{err}");
}

#[test]
fn view_and_debug_read_ray_logs_only_from_regular_files() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let fifo = dir.path().join("rays.jsonl");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let out = dir.path().join("view.png");
    for (log, needle) in [
        (Path::new("/dev/zero"), "a device, not a file"),
        (fifo.as_path(), "a named pipe (FIFO), not a file"),
    ] {
        let (code, err, peak) = watched(&[
            OsStr::new("view"),
            OsStr::new("-f"),
            s.as_os_str(),
            OsStr::new("-o"),
            out.as_os_str(),
            OsStr::new("-w"),
            OsStr::new("8"),
            OsStr::new("-h"),
            OsStr::new("8"),
            OsStr::new("--view-width"),
            OsStr::new("32"),
            OsStr::new("--view-height"),
            OsStr::new("32"),
            OsStr::new("--rays-log"),
            log.as_os_str(),
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
        assert!(peak < 200 * 1024, "{peak} KiB");
        assert!(!out.exists());
        let (code, err, _) = watched(&[
            OsStr::new("debug"),
            s.as_os_str(),
            OsStr::new("--rays"),
            log.as_os_str(),
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(err.contains(needle), "{err}");
    }
}

#[test]
fn a_closed_stdout_keeps_probes_verdict() {
    // The probe tests' student tracer, made to return the sphere's far root: probe finds
    // mistakes, so its verdict is 1 whether or not its report could be printed.
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(bin())
        .arg("probe")
        .arg("-f")
        .arg(rayscope_testkit::scene("basic.txt"))
        .arg("--")
        .arg("python3")
        .arg(manifest.join("../../examples/probe/python/probe_adapter.py"))
        .arg(manifest.join("tests/probe/student_tracer.py"))
        .env("PROBE_MISTAKES", "sphere-far-root")
        .stdin(Stdio::null())
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

/// A PNG that is a header claiming `w`×`h` RGB pixels and almost no data: a reader that decodes before it
/// checks the size would allocate `3·w·h` bytes.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let mut ihdr = b"IHDR".to_vec();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 2, 0, 0, 0]);
    let crc = |data: &[u8]| {
        let mut c = 0xffff_ffffu32;
        for &b in data {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    };
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&ihdr);
    png.extend_from_slice(&crc(&ihdr).to_be_bytes());
    // A few bytes of image data (an empty zlib stream): readers look for it before they answer.
    let mut idat = b"IDAT".to_vec();
    idat.extend_from_slice(&[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    png.extend_from_slice(&8u32.to_be_bytes());
    png.extend_from_slice(&idat);
    png.extend_from_slice(&crc(&idat).to_be_bytes());
    png.extend_from_slice(&0u32.to_be_bytes());
    png.extend_from_slice(b"IEND");
    png.extend_from_slice(&crc(b"IEND").to_be_bytes());
    png
}

#[test]
fn diff_and_diagnose_check_an_images_size_before_decoding_it() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.png");
    fs::write(&huge, png_header_only(100_000, 100_000)).unwrap();
    let scene = rayscope_testkit::scene("basic.txt");
    let cases: [Vec<&OsStr>; 2] = [
        vec![OsStr::new("diff"), huge.as_os_str(), huge.as_os_str()],
        vec![
            OsStr::new("diagnose"),
            OsStr::new("-f"),
            scene.as_os_str(),
            huge.as_os_str(),
        ],
    ];
    for args in cases {
        let (code, err, peak) = watched(&args);
        assert_eq!(code, Some(2), "{args:?}: {err}");
        assert!(
            err.contains("100000×100000") && err.contains("over the limit of 67108864"),
            "{args:?}: {err}"
        );
        assert!(peak < 64 * 1024, "{args:?}: peak {peak} KiB");
    }
}

#[test]
fn diff_reads_images_only_from_regular_files() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("pipe.png");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let (code, err, _) = watched(&[OsStr::new("diff"), fifo.as_os_str(), fifo.as_os_str()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("it is a named pipe (FIFO), not a file"), "{err}");
}
