//! `rayscope check` on hostile and faulty ray logs: whatever the log, the check's peak memory
//! stays within its budget, and a log it cannot judge is refused with exit 2 and a message that
//! names the place and the limit. Each test runs the real binary and reads its peak resident
//! memory (VmHWM) while it runs.

mod common;

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use common::{watch, Watched};

/// The most memory `rayscope check` may use on a small scene, whatever the log (docs/security.md):
/// the rays of unfinished pixel samples it holds (`rayscope_check::MAX_PENDING_RAYS`), two
/// batches of parsed rays and a chunk of the log.
const BUDGET_KIB: u64 = 320 * 1024;

/// A lit sphere three units in front of the camera.
const SCENE: &str = "Material \"White\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Sphere \"Ball\" (0, 0, 3) 1 \"White\"\n";

fn bin() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_rayscope"))
}

/// Runs `rayscope check` on `log` against the test scene in `dir`, watching its peak memory
/// (the high-water mark only grows, so polling it misses at most the last moments' growth).
fn check(dir: &Path, log: &Path, flags: &[&str]) -> Watched {
    let scene = dir.join("scene.txt");
    fs::write(&scene, SCENE).unwrap();
    let mut cmd = Command::new(bin());
    cmd.arg("check")
        .arg("-f")
        .arg(&scene)
        .arg("--rays")
        .arg(log)
        .arg("--quiet")
        .args(flags);
    watch(cmd, Duration::from_secs(60))
}

/// Asserts the run stayed within the budget.
fn within_budget(r: &Watched, what: &str) {
    eprintln!("{what}: peak resident memory {} KiB", r.peak_kib);
    assert!(
        r.peak_kib < BUDGET_KIB,
        "{what}: peak resident memory {} KiB, over the budget of {BUDGET_KIB} KiB\n{}",
        r.peak_kib,
        r.stderr
    );
}

/// Writes `lines` copies of `line` to `path`, in large writes.
fn write_repeated(path: &Path, line: &str, lines: usize) {
    let mut f = std::io::BufWriter::with_capacity(1 << 20, fs::File::create(path).unwrap());
    for _ in 0..lines {
        f.write_all(line.as_bytes()).unwrap();
    }
    f.flush().unwrap();
}

fn ray_line(x: u32, y: u32) -> String {
    format!("{{\"pixel\":[{x},{y}],\"origin\":[0,0,0],\"direction\":[0,0.1,1]}}\n")
}

#[test]
fn a_log_of_bad_lines_is_refused_at_its_first_line_within_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("x.jsonl");
    // The reproduction, scaled down: 500,000 lines `x`.
    write_repeated(&log, "x\n", 500_000);
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6"]);
    within_budget(&r, "500,000 lines x");
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("x.jsonl:1:1") && r.stderr.contains("expected a JSON ray record"),
        "{}",
        r.stderr
    );
    assert!(r.stdout.is_empty());

    // Under --lenient every line is skipped and counted, with the first one's diagnostic, and a
    // log of nothing but skipped lines judged nothing.
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6", "--lenient"]);
    within_budget(&r, "500,000 lines x, --lenient");
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("has no ray to judge")
            && r.stderr.contains("500000 non-blank lines are all malformed")
            && r.stderr.contains("x.jsonl:1:1"),
        "{}",
        r.stderr
    );

    // Lines that are JSON but not rays, and good rays between bad lines.
    let log = dir.path().join("objects.jsonl");
    let mut text = String::new();
    for i in 0..400_000u32 {
        if i % 1000 == 0 {
            text.push_str(&ray_line(0, 0));
        } else {
            text.push_str("{\"pixel\":[0,0],\"kind\":\"camera\"}\n");
        }
    }
    fs::write(&log, text).unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6", "--lenient"]);
    within_budget(&r, "400,000 records without a ray, --lenient");
    assert!(matches!(r.code, Some(0 | 1)), "{}", r.stderr);
    assert!(
        r.stdout.contains("checked 400 rays") && r.stdout.contains("skipped 399600 malformed lines"),
        "{}",
        r.stdout
    );
}

#[test]
fn a_line_longer_than_the_cap_is_refused_within_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("long.jsonl");
    // One 50 MB line.
    fs::write(&log, format!("{{\"kind\":\"{}\"}}\n", "a".repeat(50 << 20))).unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6"]);
    within_budget(&r, "one 50 MB line");
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("long.jsonl:1:1") && r.stderr.contains("longer than 65536 bytes"),
        "{}",
        r.stderr
    );

    // Under --lenient a 50 MB line of spaces between two rays is skipped, and the rays judged.
    let mut text = ray_line(1, 1);
    text.push_str(&" ".repeat(50 << 20));
    text.push('\n');
    text.push_str(&ray_line(2, 2));
    fs::write(&log, text).unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6", "--lenient"]);
    within_budget(&r, "a 50 MB line of spaces, --lenient");
    assert!(matches!(r.code, Some(0 | 1)), "{}", r.stderr);
    assert!(
        r.stdout.contains("checked 2 rays") && r.stdout.contains("long.jsonl:2:1"),
        "{}",
        r.stdout
    );
}

#[test]
fn an_interleaved_log_is_refused_within_the_budget_with_how_to_write_it() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("interleaved.jsonl");
    // 4,096 pixel samples whose rays alternate, 250 rays each: a million rays, every sample
    // unfinished until the log ends.
    let round: String = (0..64).flat_map(|y| (0..64).map(move |x| ray_line(x, y))).collect();
    write_repeated(&log, &round, 250);
    let r = check(dir.path(), &log, &["-w", "64", "-h", "64"]);
    within_budget(&r, "a million interleaved rays");
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("interleaves the rays of too many pixel samples")
            && r.stderr.contains("4096 unfinished pixel samples")
            && r.stderr.contains("more than the 262144 rays")
            && r.stderr.contains("interleaved.jsonl:")
            && r.stderr.contains("write each pixel sample's rays together"),
        "{}",
        r.stderr
    );
    assert!(r.stdout.is_empty());

    // The same rays as a parallel tracer writes them, 64 threads at once, each sample's rays
    // one after another on its thread: judged.
    let mut text = String::new();
    for step in 0..4000u32 {
        for t in 0..64u32 {
            text.push_str(&ray_line(t, step / 500));
        }
    }
    fs::write(&log, text).unwrap();
    let r = check(dir.path(), &log, &["-w", "64", "-h", "64"]);
    within_budget(&r, "64 threads' interleaving");
    assert!(matches!(r.code, Some(0 | 1)), "{}", r.stderr);
    assert!(r.stdout.contains("checked 256000 rays"), "{}", r.stdout);
}

#[test]
fn a_log_that_is_not_a_regular_file_is_named_and_not_read() {
    let dir = tempfile::tempdir().unwrap();
    let r = check(dir.path(), Path::new("/dev/zero"), &["-w", "8", "-h", "6"]);
    within_budget(&r, "/dev/zero");
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(
        r.stderr.contains("/dev/zero: it is a device, not a file"),
        "{}",
        r.stderr
    );
    let r = check(dir.path(), dir.path(), &["-w", "8", "-h", "6"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(r.stderr.contains("it is a folder, not a file"), "{}", r.stderr);
    let fifo = dir.path().join("rays.jsonl");
    if Command::new("mkfifo").arg(&fifo).status().is_ok_and(|s| s.success()) {
        // Without a writer, opening it would block for ever.
        let r = check(dir.path(), &fifo, &["-w", "8", "-h", "6"]);
        assert_eq!(r.code, Some(2), "{}", r.stderr);
        assert!(
            r.stderr.contains("it is a named pipe (FIFO), not a file"),
            "{}",
            r.stderr
        );
    }
}

#[test]
fn an_empty_log_judges_nothing_and_exits_2() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [
        ("empty.jsonl", ""),
        ("blank.jsonl", "\n \n\r\n"),
        ("empty.rays", "\0\0\0\0"),
    ] {
        let log = dir.path().join(name);
        fs::write(&log, text).unwrap();
        let r = check(dir.path(), &log, &["-w", "8", "-h", "6"]);
        assert_eq!(r.code, Some(2), "{name}: {}", r.stderr);
        assert!(
            r.stderr
                .contains(&format!("{name} has no ray to judge, so nothing was checked")),
            "{name}: {}",
            r.stderr
        );
        assert!(!r.stdout.contains("every ray agrees"), "{}", r.stdout);
    }
}

#[test]
fn terminal_escape_sequences_in_the_log_are_printed_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("rays.jsonl");
    // A ray that claims t = 5 where the sphere is at t = 2, so the report shows it, kind and all;
    // and an unknown entity name in a second log, shown in the error.
    fs::write(
        &log,
        "{\"pixel\":[0,0],\"kind\":\"\\u001b[31mred\\u001b]0;title\\u0007\",\"origin\":[0,0,0],\"direction\":[0,0,1],\"hit\":{\"t\":5,\"entity\":\"Ball\"}}\n",
    )
    .unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6"]);
    assert_eq!(r.code, Some(1), "{}", r.stderr);
    assert!(
        !r.stdout.contains('\u{1b}') && !r.stdout.contains('\u{7}'),
        "{:?}",
        r.stdout
    );
    assert!(
        r.stdout.contains("\\u{1b}[31mred\\u{1b}]0;title\\u{7} ray"),
        "{}",
        r.stdout
    );

    fs::write(
        &log,
        "{\"origin\":[0,0,0],\"direction\":[0,0,1],\"hit\":{\"t\":2,\"entity\":\"\\u001b[2JBall\"}}\n",
    )
    .unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    assert!(!r.stderr.contains('\u{1b}'), "{:?}", r.stderr);
    assert!(r.stderr.contains("no entity named '\\u{1b}[2JBall'"), "{}", r.stderr);
}

#[test]
fn a_negative_sample_id_in_a_rays_file_is_refused_with_its_place() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("log.rays");
    let mut b = 2i32.to_le_bytes().to_vec();
    for sample in [0i32, -1] {
        b.push(3);
        for id in [1, 2, sample] {
            b.extend(id.to_le_bytes());
        }
        for v in [0.0f64, 0.0, 0.0, 0.0, 0.0, 1.0] {
            b.extend(v.to_le_bytes());
        }
    }
    fs::write(&log, b).unwrap();
    let r = check(dir.path(), &log, &["-w", "8", "-h", "6", "--ray-ids", "x,y,sample"]);
    assert_eq!(r.code, Some(2), "{}", r.stderr);
    // Ray 2 starts at byte 4 + 61; its sample id is the third, 9 bytes in.
    assert!(
        r.stderr.contains("ray 2 is sample -1") && r.stderr.contains("log.rays: ray 2, byte 74"),
        "{}",
        r.stderr
    );
}

#[test]
fn a_large_log_written_sample_by_sample_is_judged_within_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("ordered.jsonl");
    // 300,000 rays, 20 a pixel, one pixel after another.
    let mut f = std::io::BufWriter::new(fs::File::create(&log).unwrap());
    for i in 0..300_000u32 {
        let p = i / 20;
        f.write_all(ray_line(p % 64, p / 64 % 64).as_bytes()).unwrap();
    }
    f.flush().unwrap();
    drop(f);
    let r = check(dir.path(), &log, &["-w", "64", "-h", "64"]);
    within_budget(&r, "300,000 ordered rays");
    assert!(matches!(r.code, Some(0 | 1)), "{}", r.stderr);
    assert!(r.stdout.contains("checked 300000 rays"), "{}", r.stdout);
}

#[test]
fn one_sample_of_400000_rays_is_judged_within_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("one.jsonl");
    // The debugger issue's reproduction: 400,000 rays of one pixel, all of one sample (a real
    // sample has at most a few thousand). They are judged in groups, never held whole.
    let mut f = std::io::BufWriter::with_capacity(1 << 20, fs::File::create(&log).unwrap());
    for i in 0..400_000u32 {
        let (parent, kind) = if i == 0 { ("null", "camera") } else { ("0", "shadow") };
        writeln!(
            f,
            "{{\"pixel\":[5,5],\"sample\":0,\"id\":{i},\"parent\":{parent},\"kind\":\"{kind}\",\
             \"origin\":[0,0,0],\"direction\":[0,0,1],\"hit\":null}}"
        )
        .unwrap();
    }
    f.flush().unwrap();
    drop(f);
    let r = check(dir.path(), &log, &["-w", "8", "-h", "8"]);
    within_budget(&r, "400,000 rays of one sample");
    assert_eq!(r.code, Some(1), "the rays disagree with rayscope's: {}", r.stderr);
}
