//! Farm renders against hostile inputs: part files whose headers lie about their sizes, parts
//! that are not files, `--frames` ranges past the bound, and the Slurm script given values that
//! are not what they should be. Each test runs the real binary (or the real script under bash,
//! without Slurm) and checks what a user would see: the exit code, the message naming the limit,
//! nothing written, and memory that stays small.

mod common;

use std::ffi::{OsStr, OsString};
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::{watch, Watched};
use serde_json::Value;

const SCENE: &str = "Material \"W\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"W\"\n\
                     Sphere \"Ball\" (0.3, 0, 3) 1 \"W\"\n";

/// The address-space cap every watched run gets: an allocation past it fails, so a run that
/// would grow without bound aborts at once instead of taking the machine.
const CAP_MIB: u64 = 1024;

/// The most resident memory a refusal may take.
const REFUSAL_KIB: u64 = 100 * 1024;

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

fn scene(dir: &Path) -> PathBuf {
    let p = dir.join("scene.txt");
    fs::write(&p, SCENE).unwrap();
    p
}

/// Runs rayscope with `args` under `ulimit -v` of [`CAP_MIB`], watching its peak resident
/// memory; fails the test if it is still running after 20 s.
fn watched<S: AsRef<OsStr>>(args: &[S]) -> Watched {
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg("ulimit -v \"$1\" && shift && exec \"$@\"")
        .arg("sh")
        .arg((CAP_MIB * 1024).to_string())
        .arg(bin())
        .args(args);
    watch(cmd, Duration::from_secs(20))
}

/// Asserts a refusal: exit 2, every one of `needles` in the message, small memory.
fn refused(run: &Watched, needles: &[&str]) {
    assert_eq!(run.code, Some(2), "{}", run.stderr);
    for n in needles {
        assert!(run.stderr.contains(n), "'{n}' not in:\n{}", run.stderr);
    }
    assert!(run.peak_kib < REFUSAL_KIB, "peak {} KiB:\n{}", run.peak_kib, run.stderr);
}

/// Renders part `k` of `n` of a 32×32 image (4 tiles) into `dir`.
fn part(dir: &Path, k: u32, n: u32) -> PathBuf {
    let out = dir.join(format!("part_{k}.exr"));
    let o = Command::new(bin())
        .arg("-f")
        .arg(scene(dir))
        .arg("-o")
        .arg(&out)
        .args(["-w", "32", "-h", "32", "--quiet", "--part", &format!("{k}/{n}")])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// The byte range of a part's JSON header in its EXR bytes (after the text attribute's length).
fn json_range(exr: &[u8]) -> (usize, usize) {
    let tag = b"rayscope.part\0string\0";
    let at = exr.windows(tag.len()).position(|w| w == tag).expect("a rayscope part") + tag.len();
    let len = i32::from_le_bytes(exr[at..at + 4].try_into().unwrap()) as usize;
    (at, at + 4 + len)
}

/// A copy of the part at `path` whose JSON header `edit` has changed, at `to`, followed by
/// `padding` zero bytes (which no reader of the header looks at).
fn forged(path: &Path, to: &Path, padding: usize, edit: impl FnOnce(&mut Value)) -> PathBuf {
    let exr = fs::read(path).unwrap();
    let (start, end) = json_range(&exr);
    let mut v: Value = serde_json::from_slice(&exr[start + 4..end]).unwrap();
    edit(&mut v);
    let json = serde_json::to_vec(&v).unwrap();
    let mut out = exr[..start].to_vec();
    out.extend((json.len() as i32).to_le_bytes());
    out.extend(&json);
    out.extend(&exr[end..]);
    out.resize(out.len() + padding, 0);
    fs::write(to, out).unwrap();
    to.to_path_buf()
}

/// A change to a part's JSON header.
type Edit = Box<dyn FnOnce(&mut Value)>;

fn merge_args(parts: &[&Path], out: &Path, extra: &[&str]) -> Vec<OsString> {
    let mut a: Vec<OsString> = vec!["merge".into()];
    a.extend(parts.iter().map(|p| p.as_os_str().to_owned()));
    a.extend(["-o".into(), out.as_os_str().to_owned()]);
    a.extend(extra.iter().map(OsString::from));
    a
}

#[test]
fn a_part_claiming_4294967295_parts_is_refused_in_bounded_memory() {
    let dir = tempfile::tempdir().unwrap();
    let p = part(dir.path(), 0, 2);
    // Part 0 of 4294967295 of a 4-tile image is dealt one tile: the bitmap agrees, so only the
    // part count itself can give the lie away (the merge listed every missing part: 16 GB).
    let bad = forged(&p, &dir.path().join("bad.exr"), 0, |v| {
        v["parts"] = 4_294_967_295u64.into();
        v["tiles"] = "01".into();
        v["tile_count"] = 1.into();
    });
    let out = dir.path().join("merged.png");
    let run = watched(&merge_args(&[&bad], &out, &["--allow-missing"]));
    refused(
        &run,
        &["bad.exr", "parts is 4294967295", "has 4 tiles", "from 1 to 4 parts"],
    );
    assert!(!out.exists());
    // Variants: one part more than tiles, and none.
    for parts in [5u32, 0] {
        let bad = forged(&p, &dir.path().join("bad.exr"), 0, |v| v["parts"] = parts.into());
        let run = watched(&merge_args(&[&bad], &out, &[]));
        refused(&run, &[&format!("parts is {parts}"), "from 1 to 4 parts"]);
    }
    let bad = forged(&p, &dir.path().join("bad.exr"), 0, |v| v["part"] = 7.into());
    refused(
        &watched(&merge_args(&[&bad], &out, &[])),
        &["part is 7 of 2", "from 0 to 1"],
    );
    assert!(!out.exists());
}

#[test]
fn a_part_claiming_a_huge_image_is_refused_before_allocating_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = part(dir.path(), 0, 1);
    let out = dir.path().join("merged.png");
    // 1048576 × 1048576 pixels (13 TB of film) in a 2 KB file: refused by the file's length,
    // with or without --allow-large.
    let bad = forged(&p, &dir.path().join("huge.exr"), 0, |v| {
        v["settings"]["width"] = 1_048_576.into();
        v["settings"]["height"] = 1_048_576.into();
    });
    for extra in [&[][..], &["--allow-large"][..]] {
        let run = watched(&merge_args(&[&bad], &out, extra));
        refused(
            &run,
            &[
                "huge.exr",
                "1048576×1048576 pixels",
                "compressed 2048:1",
                "but the file is",
            ],
        );
    }
    // Wider than tall, and past u32 tiles: the same.
    let bad = forged(&p, &dir.path().join("wide.exr"), 0, |v| {
        v["settings"]["width"] = 4_294_967_295u64.into();
    });
    refused(&watched(&merge_args(&[&bad], &out, &[])), &["4294967295×32 pixels"]);
    // 12000 × 12000 in a file long enough for it: over the 64-megapixel budget without
    // --allow-large; with it, the EXR's own size (32×32) gives the lie away.
    let bad = forged(&p, &dir.path().join("big.exr"), 900_000, |v| {
        v["settings"]["width"] = 12_000.into();
        v["settings"]["height"] = 12_000.into();
        // All 750 × 750 tiles, as part 0 of 1 holds them.
        v["tiles"] = format!("{}0f", "ff".repeat(562_500 / 8)).into();
        v["tile_count"] = 562_500.into();
    });
    let run = watched(&merge_args(&[&bad], &out, &[]));
    refused(
        &run,
        &[
            "big.exr",
            "width 12000, height 12000",
            "over the budget of 67108864",
            "pass --allow-large to merge",
        ],
    );
    let run = watched(&merge_args(&[&bad], &out, &["--allow-large"]));
    if !run.stderr.contains("memory available") {
        refused(&run, &["big.exr", "its pixels are 32×32", "say 12000×12000"]);
    }
    assert!(!out.exists());
}

#[test]
fn a_part_whose_tile_fields_disagree_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = part(dir.path(), 0, 1);
    let out = dir.path().join("merged.png");
    let cases: [(&str, Edit, &str); 5] = [
        (
            "count",
            Box::new(|v| v["tile_count"] = 3.into()),
            "tile_count is 3 but its tile bitmap holds 4",
        ),
        (
            "long",
            Box::new(|v| v["tiles"] = "0f00".into()),
            "has 4 hex digits; a 32×32 image of 4 tiles needs 2",
        ),
        (
            "huge",
            Box::new(|v| v["tiles"] = "ff".repeat(1 << 19).into()),
            "has 1048576 hex digits",
        ),
        ("hex", Box::new(|v| v["tiles"] = "zz".into()), "not hexadecimal"),
        (
            "size",
            Box::new(|v| v["tile_size"] = 8.into()),
            "tile_size is 8; rayscope's tiles are 16",
        ),
    ];
    for (name, edit, needle) in cases {
        let bad = forged(&p, &dir.path().join(format!("{name}.exr")), 0, edit);
        refused(
            &watched(&merge_args(&[&bad], &out, &[])),
            &[&format!("{name}.exr"), needle],
        );
    }
    assert!(!out.exists());
    // The part itself still merges.
    let run = watched(&merge_args(&[&p], &out, &[]));
    assert_eq!(run.code, Some(0), "{}", run.stderr);
}

#[test]
fn a_header_longer_than_the_bound_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = part(dir.path(), 0, 1);
    let bad = forged(&p, &dir.path().join("long.exr"), 0, |v| {
        v["flags"] = "x".repeat(21 << 20).into();
    });
    let out = dir.path().join("merged.png");
    refused(
        &watched(&merge_args(&[&bad], &out, &[])),
        &["long.exr", "longer than the 20 MiB"],
    );
    // Just within the bound: read, parsed and refused by its bitmap's length, in small memory.
    let bad = forged(&p, &dir.path().join("wide.exr"), 0, |v| {
        v["tiles"] = "00".repeat(19 << 19).into();
    });
    refused(
        &watched(&merge_args(&[&bad], &out, &[])),
        &["wide.exr", "has 19922944 hex digits"],
    );
    assert!(!out.exists());
}

#[test]
fn a_pipe_or_a_device_given_as_a_part_is_named_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("part.exr");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let out = dir.path().join("merged.png");
    refused(
        &watched(&merge_args(&[&fifo], &out, &[])),
        &["part.exr", "a named pipe (FIFO), not a file"],
    );
    let good = part(dir.path(), 0, 2);
    // After a good part too: every file is looked at before it is opened.
    for other in [Path::new("/dev/zero"), dir.path()] {
        let run = watched(&merge_args(&[&good, other], &out, &[]));
        refused(&run, &["not a file"]);
    }
    assert!(!out.exists());
}

#[test]
fn frames_past_the_bound_are_refused_before_anything_is_allocated() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path());
    let out = dir.path().join("f_####.png");
    let args = |frames: &str| -> Vec<OsString> {
        vec![
            "-f".into(),
            s.clone().into(),
            "-o".into(),
            out.clone().into(),
            "-w".into(),
            "8".into(),
            "-h".into(),
            "8".into(),
            "--frames".into(),
            frames.into(),
        ]
    };
    for (frames, count) in [("0..4294967295", "4294967296"), ("5..100005", "100001")] {
        refused(
            &watched(&args(frames)),
            &[&format!("--frames {frames} is {count} frames"), "at most 100000"],
        );
    }
    // 100000 frames are accepted: they are rendered one after another, nothing is kept per
    // frame (here the output folder is missing, which stops it before the first).
    let mut a = args("0..99999");
    a[3] = dir.path().join("missing/f_####.png").into();
    let run = watched(&a);
    assert_eq!(run.code, Some(2), "{}", run.stderr);
    assert!(run.stderr.contains("f_0000.png"), "{}", run.stderr);
    assert!(run.peak_kib < REFUSAL_KIB, "{}", run.peak_kib);
    assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
}

// ---- the Slurm script, run under bash with a stub rayscope, without Slurm ----

/// Runs deploy/slurm/render.sbatch in `dir` with `env` (and nothing else of the caller's
/// environment but PATH), rayscope replaced by a stub that records its arguments, one a line,
/// each call ended by `---`. Returns the exit code, stderr, and the recorded calls.
fn sbatch(dir: &Path, env: &[(&str, &str)]) -> (Option<i32>, String, Vec<Vec<String>>) {
    let stub = dir.join("stub-rayscope");
    let log = dir.join("calls.txt");
    fs::write(
        &stub,
        "#!/bin/sh\nprintf '%s\\n' \"$@\" >> \"$CALLS\"\necho --- >> \"$CALLS\"\n",
    )
    .unwrap();
    fs::set_permissions(&stub, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let _ = fs::remove_file(&log);
    let script = rayscope_testkit::workspace().join("deploy/slurm/render.sbatch");
    let o = Command::new("bash")
        .arg(script)
        .current_dir(dir)
        .env_clear()
        .env("PATH", std::env::var_os("PATH").unwrap_or_default())
        .env("CALLS", &log)
        .env("RAYSCOPE", &stub)
        .envs(env.iter().copied())
        .output()
        .unwrap();
    let calls = fs::read_to_string(&log).unwrap_or_default();
    let calls = calls
        .split("---\n")
        .filter(|c| !c.is_empty())
        .map(|c| c.lines().map(str::to_owned).collect())
        .collect();
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned(), calls)
}

#[test]
fn the_slurm_script_refuses_values_it_would_have_evaluated() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // Each would run `touch pwned` if bash arithmetic ever saw it.
    let evil = "HOME[$(touch pwned)]";
    let cases: [(&[(&str, &str)], &str); 6] = [
        (
            &[("PARTS", evil), ("SLURM_ARRAY_TASK_ID", "0")],
            "PARTS must be a whole number",
        ),
        (&[("PARTS", evil)], "PARTS must be a whole number"),
        (
            &[("PARTS", "4"), ("SLURM_ARRAY_TASK_ID", evil)],
            "SLURM_ARRAY_TASK_ID must be a whole number",
        ),
        (
            &[
                ("PARTS", "4"),
                ("SLURM_ARRAY_TASK_ID", "1"),
                ("SLURM_ARRAY_TASK_MAX", evil),
            ],
            "SLURM_ARRAY_TASK_MAX must be a whole number",
        ),
        (
            &[("PARTS", "4"), ("FRAMES", "1..$(touch pwned)")],
            "FRAMES must be A..B",
        ),
        (
            &[("PARTS", "1+1"), ("SLURM_ARRAY_TASK_ID", "0")],
            "PARTS must be a whole number",
        ),
    ];
    for (env, needle) in cases {
        let (code, err, calls) = sbatch(d, env);
        assert_eq!(code, Some(2), "{env:?}: {err}");
        assert!(err.contains(needle), "{env:?}: {err}");
        assert!(calls.is_empty(), "{env:?}: rayscope ran: {calls:?}");
        assert!(!d.join("pwned").exists(), "{env:?}: the command substitution ran");
    }
    for (env, needle) in [
        (&[("PARTS", "0")][..], "PARTS must be at least 1"),
        (&[("PARTS", "1234567890")][..], "at most 9 digits"),
        (&[("PARTS", "2"), ("SLURM_ARRAY_TASK_ID", "2")][..], "--array=0-1"),
        (&[("FRAMES", "0..100000")][..], "at most 100000"),
        (&[("FRAMES", "0..3"), ("OUTPUT", "turn.png")][..], "needs a run of #"),
    ] {
        let (code, err, calls) = sbatch(d, env);
        assert_eq!(code, Some(2), "{env:?}: {err}");
        assert!(err.contains(needle), "{env:?}: {err}");
        assert!(calls.is_empty(), "{env:?}: {calls:?}");
    }
}

#[test]
fn the_slurm_script_reads_numbers_in_base_10_and_never_globs_flags() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fs::write(d.join("a-file-a-glob-would-find"), "").unwrap();
    // Frame 010 is frame 10 (octal would make it 8); task 09 is task 9 (octal: an error).
    let (code, err, calls) = sbatch(
        d,
        &[
            ("PARTS", "04"),
            ("FRAMES", "010..012"),
            ("OUTPUT", "fr/t_####.png"),
            ("SLURM_ARRAY_TASK_ID", "09"),
            ("FLAGS", "-w 32 * [a]* -h 16"),
        ],
    );
    assert_eq!(code, Some(0), "{err}");
    let call = &calls[0];
    let at = |flag: &str| call[call.iter().position(|a| a == flag).unwrap() + 1].clone();
    assert_eq!(at("--frames"), "12");
    assert_eq!(at("--part"), "1/4");
    assert_eq!(at("-o"), "fr/rayscope-parts/f####_part_1.exr");
    assert!(
        call.ends_with(&["-w", "32", "*", "[a]*", "-h", "16"].map(String::from)),
        "{call:?}"
    );
}

#[test]
fn the_slurm_merge_names_frames_by_any_run_of_hashes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (output, names) in [
        ("fr/t_##.png", ["fr/t_10.png", "fr/t_11.png"]),
        ("fr/t_#####.png", ["fr/t_00010.png", "fr/t_00011.png"]),
        ("fr/#_x##.png", ["fr/10_x##.png", "fr/11_x##.png"]),
    ] {
        let (code, err, calls) = sbatch(d, &[("PARTS", "2"), ("FRAMES", "010..011"), ("OUTPUT", output)]);
        assert_eq!(code, Some(0), "{err}");
        assert_eq!(calls.len(), 2, "{calls:?}");
        for (call, name) in calls.iter().zip(names) {
            assert_eq!(call[0], "merge");
            assert_eq!(call[call.len() - 2..], ["-o".to_string(), name.to_string()], "{call:?}");
        }
        assert_eq!(calls[0][1], "fr/rayscope-parts/f0010_part_0.exr");
    }
}

#[test]
fn the_slurm_script_keeps_outputs_that_start_with_a_dash_where_they_belong() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (code, err, calls) = sbatch(d, &[("PARTS", "2"), ("OUTPUT", "-x.png"), ("SLURM_ARRAY_TASK_ID", "1")]);
    assert_eq!(code, Some(0), "{err}");
    assert!(
        calls[0].contains(&"./rayscope-parts/part_1.exr".to_string()),
        "{calls:?}"
    );
    assert!(d.join("rayscope-parts").is_dir());
    let (code, err, calls) = sbatch(d, &[("PARTS", "2"), ("OUTPUT", "-x.png"), ("SCENE", "-s.txt")]);
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(
        calls[0],
        [
            "merge",
            "./rayscope-parts/part_0.exr",
            "./rayscope-parts/part_1.exr",
            "-o",
            "./-x.png"
        ]
        .map(String::from)
    );
}
