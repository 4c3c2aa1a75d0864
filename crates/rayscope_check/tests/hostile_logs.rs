//! Hostile and faulty ray logs at the library level: each is read in bounded memory and either
//! judged or refused with a message that names the place and the limit.

use std::io::{Cursor, Read};
use std::path::Path;

use rayscope_check::log::{open, printable, BinaryReader, IdRole, JsonlReader, Kind, BATCH, MAX_LINE};
use rayscope_check::{check, CheckOptions, Judge, LogContext, LogError, RaySource, Report, MAX_PENDING_RAYS};
use rayscope_core::{RenderSettings, Scene};

/// A lit sphere three units in front of the camera.
const SCENE: &str = "Material \"White\" Diffuse (0.8, 0.8, 0.8) 1\n\
                     PointLight \"L\" (0, 2, 1) (1, 1, 1)\n\
                     Sphere \"Ball\" (0, 0, 3) 1 \"White\"\n";

fn scene() -> Scene {
    Scene::from_file(&rayscope_scene::parse_str(SCENE, Path::new("scene.txt")).expect("scene"))
}

fn settings(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        ..RenderSettings::default()
    }
}

fn context(scene: &Scene, s: &RenderSettings) -> LogContext {
    let judge = Judge::new(scene, s);
    LogContext::new(scene, s.width, s.height, judge.samples_per_pixel(), s.aa)
}

/// Checks `src` as a JSON Lines log of an 8×6 render.
fn check_jsonl(src: impl Read + Send, lenient: bool) -> Result<Report, LogError> {
    check_jsonl_sized(src, lenient, 8, 6)
}

fn check_jsonl_sized(src: impl Read + Send, lenient: bool, w: u32, h: u32) -> Result<Report, LogError> {
    let scene = scene();
    let s = settings(w, h);
    let judge = Judge::new(&scene, &s);
    let mut r = JsonlReader::new(src, Path::new("rays.jsonl"), 0, context(&scene, &s), lenient);
    check(&judge, &mut r, CheckOptions::default(), &|_, _| {})
}

/// A reader that counts the bytes taken from it.
struct Counting<R> {
    inner: R,
    taken: std::sync::Arc<std::sync::atomic::AtomicU64>,
}

impl<R: Read> Read for Counting<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.taken.fetch_add(n as u64, std::sync::atomic::Ordering::Relaxed);
        Ok(n)
    }
}

/// A ray of pixel (0, 0) that hits the sphere where rayscope does, with `pad` spaces inside the object.
fn good_line(pad: usize) -> String {
    format!(
        "{{\"pixel\": [0, 0], \"kind\": \"probe\",{} \"origin\": [0, 0, 0], \"direction\": [0, 0, 1], \"hit\": {{\"t\": 2, \"entity\": \"Ball\"}}}}\n",
        " ".repeat(pad)
    )
}

#[test]
fn a_log_of_bad_lines_keeps_one_diagnostic_and_counts_the_rest() {
    let log = "x\n".repeat(300_000);
    let err = check_jsonl(Cursor::new(log.clone()), false).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("rays.jsonl:1:1") && msg.contains("expected a JSON ray record"),
        "{msg}"
    );

    let r = check_jsonl(Cursor::new(log), true).unwrap();
    assert_eq!((r.rays, r.skipped_lines), (0, 300_000));
    let first = r.first_skipped.as_deref().unwrap();
    assert!(first.contains("rays.jsonl:1:1"), "{first}");
    let text = r.to_text(&|_| None);
    assert!(
        text.contains("skipped 300000 malformed lines") && text.contains("no ray was judged"),
        "{text}"
    );
    assert!(!text.contains("every ray agrees"), "{text}");
}

#[test]
fn a_line_longer_than_the_cap_is_refused_without_reading_it_whole() {
    // A 64 MiB line: the reader gives up after a chunk, not at the end of the line.
    let taken = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let src = Counting {
        inner: std::io::repeat(b'a').take(64 << 20),
        taken: taken.clone(),
    };
    let msg = check_jsonl(src, false).unwrap_err().to_string();
    assert!(
        msg.contains("rays.jsonl:1:1") && msg.contains(&format!("longer than {MAX_LINE} bytes")),
        "{msg}"
    );
    let read = taken.load(std::sync::atomic::Ordering::Relaxed);
    assert!(read <= 9 << 20, "read {read} bytes of one line");

    // The same line after a good one, and a good line after it.
    let long = format!("{}\n", "a".repeat(5 << 20));
    let log = format!("{}{long}{}", good_line(0), good_line(0));
    let msg = check_jsonl(Cursor::new(log.clone()), false).unwrap_err().to_string();
    assert!(msg.contains("rays.jsonl:2:1") && msg.contains("65536 bytes"), "{msg}");
    // --lenient skips it, and its line is counted: the line after it is line 3.
    let r = check_jsonl(Cursor::new(log), true).unwrap();
    assert_eq!((r.rays, r.skipped_lines, r.disagree), (2, 1, 0));
    assert!(r.first_skipped.as_deref().unwrap().contains("rays.jsonl:2:1"));
    // A long last line without a newline, under --lenient.
    let log = format!("{}{}", good_line(0), "b".repeat(3 << 20));
    let r = check_jsonl(Cursor::new(log), true).unwrap();
    assert_eq!((r.rays, r.skipped_lines), (1, 1));
}

#[test]
fn a_line_of_exactly_the_cap_is_read() {
    let pad = MAX_LINE - good_line(0).len() + 1;
    let line = good_line(pad);
    assert_eq!(line.len(), MAX_LINE + 1, "the cap counts the bytes before the newline");
    let r = check_jsonl(Cursor::new(format!("{line}{line}")), false).unwrap();
    assert_eq!((r.rays, r.disagree), (2, 0));
    let longer = good_line(pad + 1);
    let msg = check_jsonl(Cursor::new(longer), false).unwrap_err().to_string();
    assert!(msg.contains("longer than 65536 bytes"), "{msg}");
}

#[test]
fn an_empty_log_judges_nothing_and_does_not_say_every_ray_agrees() {
    for log in ["", "\n\n  \n", "\u{feff}\n"] {
        let r = check_jsonl(Cursor::new(log), false).unwrap();
        assert_eq!(r.rays, 0);
        let text = r.to_text(&|_| None);
        assert!(
            text.contains("no ray was judged") && !text.contains("every ray agrees"),
            "{text}"
        );
    }
}

#[test]
fn escape_sequences_in_a_kind_word_are_printed_escaped() {
    // The tracer claims t = 5 where the sphere is at t = 2: the ray gets a verdict, and its
    // example line prints the kind word.
    let log = "{\"pixel\": [0, 0], \"kind\": \"\\u001b]0;owned\\u0007\\u001b[2J\\u009b31m\\u202eevil\", \"origin\": [0, 0, 0], \"direction\": [0, 0, 1], \"hit\": {\"t\": 5, \"entity\": \"Ball\"}}\n";
    let r = check_jsonl(Cursor::new(log), false).unwrap();
    assert_eq!(r.disagree, 1);
    let text = r.to_text(&|_| None);
    assert!(
        !text.chars().any(|c| c.is_control() && c != '\n') && !text.contains('\u{202e}'),
        "{text:?}"
    );
    assert!(
        text.contains("\\u{1b}]0;owned\\u{7}\\u{1b}[2J\\u{9b}31m\\u{202e}evil ray"),
        "{text}"
    );
    // A kind word is kept to a word's length.
    let long = "k".repeat(10_000);
    assert_eq!(Kind::from_word(&long).name().chars().count(), 65);
    assert_eq!(printable("plain"), "plain");
    assert_eq!(printable("a\tb\u{7f}"), "a\\u{9}b\\u{7f}");
}

#[test]
fn interleaving_more_samples_than_the_cap_is_refused_and_64_threads_are_not() {
    // 4,096 pixels' rays round-robin, 80 rounds: every sample is open until the log ends.
    let line = |x: u32, y: u32| format!("{{\"pixel\":[{x},{y}],\"origin\":[0,0,0],\"direction\":[0,0.1,1]}}\n");
    let mut log = String::new();
    for _ in 0..80 {
        for y in 0..64 {
            for x in 0..64 {
                log.push_str(&line(x, y));
            }
        }
    }
    let err = check_jsonl_sized(Cursor::new(log), false, 64, 64).unwrap_err();
    let LogError::Interleaved {
        rays, samples, limit, ..
    } = &err
    else {
        panic!("{err}");
    };
    assert_eq!((*samples, *limit), (4096, MAX_PENDING_RAYS as u64));
    assert!(*rays > *limit);
    let msg = err.to_string();
    assert!(
        msg.contains(&format!("more than the {MAX_PENDING_RAYS} rays"))
            && msg.contains("rays.jsonl:")
            && msg.contains("write each pixel sample's rays together"),
        "{msg}"
    );

    // 64 threads, each writing its 400-ray samples' rays as it traces them: judged.
    let mut log = String::new();
    for step in 0..1200u32 {
        for t in 0..64u32 {
            log.push_str(&line(t, step / 400));
        }
    }
    let r = check_jsonl_sized(Cursor::new(log), false, 64, 64).unwrap();
    assert_eq!(r.rays, 64 * 1200);
}

/// A `.rays` file of one ray whose three ids are `ids`.
fn rays_file(ids: [i32; 3]) -> Vec<u8> {
    let mut b = 1i32.to_le_bytes().to_vec();
    b.push(3);
    for id in ids {
        b.extend(id.to_le_bytes());
    }
    for v in [0.0f64, 0.0, 0.0, 0.0, 0.0, 1.0] {
        b.extend(v.to_le_bytes());
    }
    b
}

#[test]
fn a_negative_sample_id_in_a_rays_file_is_refused_with_its_place() {
    let scene = scene();
    let s = settings(8, 6);
    let judge = Judge::new(&scene, &s);
    let roles = [IdRole::X, IdRole::Y, IdRole::Sample];
    let mut r = BinaryReader::new(
        Cursor::new(rays_file([1, 2, -3])),
        Path::new("log.rays"),
        0,
        context(&scene, &s),
        &roles,
    );
    let msg = check(&judge, &mut r, CheckOptions::default(), &|_, _| {})
        .unwrap_err()
        .to_string();
    // The count (4 bytes), the id count (1) and two ids (8) come before the sample id.
    assert!(
        msg.contains("ray 1 is sample -3") && msg.contains("log.rays: ray 1, byte 13"),
        "{msg}"
    );
    let mut r = BinaryReader::new(
        Cursor::new(rays_file([1, 2, 0])),
        Path::new("log.rays"),
        0,
        context(&scene, &s),
        &roles,
    );
    let mut out = Vec::new();
    assert!(r.next_batch(&mut out).unwrap());
    assert_eq!((out[0].pixel, out[0].sample), (Some([1, 2]), Some(0)));
}

#[test]
fn only_regular_files_are_opened_as_logs() {
    let scene = scene();
    let s = settings(8, 6);
    let dir = tempfile::tempdir().unwrap();
    let open_err = |p: &Path| match open(p, context(&scene, &s), false, &[]) {
        Ok(_) => panic!("{} was opened", p.display()),
        Err(e) => e.to_string(),
    };
    let msg = open_err(dir.path());
    assert!(msg.contains("it is a folder, not a file"), "{msg}");
    #[cfg(unix)]
    {
        let msg = open_err(Path::new("/dev/zero"));
        assert!(msg.contains("cannot read ray log /dev/zero: it is a device"), "{msg}");
        let fifo = dir.path().join("rays.rays");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            // Opening a FIFO without a writer would block: it is named before it is opened.
            let msg = open_err(&fifo);
            assert!(msg.contains("named pipe"), "{msg}");
        }
    }
    let msg = open_err(&dir.path().join("missing.jsonl"));
    assert!(msg.contains("missing.jsonl"), "{msg}");
}

#[test]
fn every_batch_but_the_last_is_whole_where_a_read_ends_inside_one() {
    // About 11 MB of records: reads of the log end inside batches, and every record is handed
    // on once, in order.
    let line = good_line(0);
    let lines = (11 << 20) / line.len();
    let scene = scene();
    let s = settings(8, 6);
    let mut r = JsonlReader::new(
        Cursor::new(line.repeat(lines)),
        Path::new("rays.jsonl"),
        0,
        context(&scene, &s),
        false,
    );
    let mut sizes = Vec::new();
    let mut next = 1;
    let mut batch = Vec::new();
    while r.next_batch(&mut batch).unwrap() {
        sizes.push(batch.len());
        for ray in batch.drain(..) {
            assert_eq!(ray.line, next);
            next += 1;
        }
    }
    assert_eq!(next - 1, lines as u64);
    let (last, whole) = sizes.split_last().unwrap();
    assert!(whole.iter().all(|&n| n == BATCH), "{sizes:?}");
    assert!(*last > 0 && *last <= BATCH);
}

#[test]
fn keyed_batches_hold_each_rays_sample_whatever_the_lines() {
    let scene = scene();
    let s = settings(8, 6);
    let line = |x: u32, y: u32, k: u32| {
        format!(
            "{{\"pixel\":[{x},{y}],\"sample\":0,\"id\":{k},\"parent\":null,\"kind\":\"camera\",\"origin\":[0,0,0],\"direction\":[0,0,1]}}\n"
        )
    };
    // Clean lines of rayscope's shape; then the same with blank and malformed lines among them
    // (read under --lenient), and a record of another shape.
    let clean: String = (0..3 * BATCH as u32).map(|k| line(k % 8, k / 8 % 6, k)).collect();
    let mut odd = String::new();
    for k in 0..3 * BATCH as u32 {
        odd.push_str(&line(k % 8, k / 8 % 6, k));
        match k % 1000 {
            0 => odd.push('\n'),
            1 => odd.push_str("not a ray\n"),
            2 => odd.push_str(&good_line(1)),
            _ => {}
        }
    }
    for (log, lenient) in [(clean, false), (odd, true)] {
        for prefilled in [false, true] {
            let mut r = JsonlReader::new(
                Cursor::new(log.clone()),
                Path::new("rays.jsonl"),
                0,
                context(&scene, &s),
                lenient,
            );
            let (mut rays, mut keys, mut total) = (Vec::new(), Vec::new(), 0);
            if prefilled {
                assert!(r.next_batch(&mut rays).unwrap());
                keys.extend(rays.iter().map(|x: &rayscope_check::LoggedRay| x.sample_key()));
            }
            while r.next_batch_keyed(&mut rays, &mut keys).unwrap() {
                assert_eq!(keys, rays.iter().map(|x| x.sample_key()).collect::<Vec<_>>());
                total += rays.len();
                rays.clear();
                keys.clear();
            }
            assert!(total >= 2 * BATCH, "{total}");
        }
    }
}
