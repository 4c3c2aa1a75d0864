//! The logging kits (kits/) in students' own tracers: a C# tracer in the course template's shape
//! (Parallel.For), a Python one and a C++ one (std::threads), each with its kit added as a
//! student adds it (tests/student/kit/). With logging on, the correct tracers get no verdict and
//! each switchable mistake is named on the report's first line; with it off nothing is written;
//! the pixel filters log exactly the pixels asked for; and every kit line docs/check.md shows is
//! one the tracers compile and run.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use common::{check_log, have, root, text};

use rayscope_check::{Code, Report};
use rayscope_core::{RenderSettings, Stage};

#[derive(Clone, Copy, Debug, PartialEq)]
enum Lang {
    CSharp,
    Python,
    Cpp,
}

const LANGS: [Lang; 3] = [Lang::CSharp, Lang::Python, Lang::Cpp];

fn kit_dir() -> PathBuf {
    root().join("crates/rayscope_check/tests/student/kit")
}

/// The tracer's source, as the docs' kit lines are looked for in it.
fn source(lang: Lang) -> PathBuf {
    kit_dir().join(match lang {
        Lang::CSharp => "Tracer.cs",
        Lang::Python => "tracer.py",
        Lang::Cpp => "tracer.cpp",
    })
}

/// Compiles `what` once per test run into a kept temporary folder; `None` (loudly) when a tool
/// is missing outside CI.
fn built(cell: &'static OnceLock<Option<PathBuf>>, build: fn(&Path) -> Option<PathBuf>) -> Option<PathBuf> {
    cell.get_or_init(|| build(&tempfile::tempdir().expect("temp dir").keep()))
        .clone()
}

fn compile(mut cmd: Command, what: &str) {
    let out = cmd.output().unwrap_or_else(|e| panic!("run {what}: {e}"));
    assert!(
        out.status.success(),
        "{what} failed:\n{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The command that starts the tracer in `lang`, built from the kit files themselves.
fn tracer(lang: Lang) -> Option<Command> {
    static CS: OnceLock<Option<PathBuf>> = OnceLock::new();
    static CPP: OnceLock<Option<PathBuf>> = OnceLock::new();
    match lang {
        Lang::CSharp => {
            let exe = built(&CS, |dir| {
                if !have("mcs", "the C# kit tests") || !have("mono", "the C# kit tests") {
                    return None;
                }
                let exe = dir.join("tracer.exe");
                let mut cmd = Command::new("mcs");
                // The kit promises C# 7.0, which Mono's compiler checks.
                cmd.arg("-langversion:7")
                    .arg("-warnaserror+")
                    .arg(format!("-out:{}", exe.display()))
                    .arg(root().join("kits/csharp/RayLog.cs"))
                    .arg(source(Lang::CSharp));
                compile(cmd, "mcs");
                Some(exe)
            })?;
            let mut cmd = Command::new("mono");
            cmd.arg(exe);
            Some(cmd)
        }
        Lang::Python => {
            if !have("python3", "the Python kit tests") {
                return None;
            }
            let mut cmd = Command::new("python3");
            cmd.arg(source(Lang::Python))
                .env("PYTHONPATH", root().join("kits/python"));
            Some(cmd)
        }
        Lang::Cpp => {
            let exe = built(&CPP, |dir| {
                if !have("g++", "the C++ kit tests") {
                    return None;
                }
                let exe = dir.join("tracer");
                let mut cmd = Command::new("g++");
                cmd.args(["-O1", "-std=c++17", "-pthread", "-Wall", "-Wextra", "-Werror", "-I"])
                    .arg(root().join("kits/cpp"))
                    .arg("-o")
                    .arg(&exe)
                    .arg(source(Lang::Cpp));
                compile(cmd, "g++");
                Some(exe)
            })?;
            Some(Command::new(exe))
        }
    }
}

/// The pixel samples a log has records of: (x, y, sample).
type Logged = BTreeSet<(u32, u32, u32)>;

/// One render: the scene, the image size and `-x`, the mistake, and the kit's variables.
struct Run<'a> {
    lang: Lang,
    scene: PathBuf,
    w: u32,
    h: u32,
    aa: u32,
    bug: &'a str,
    env: Vec<(&'a str, &'a str)>,
}

impl<'a> Run<'a> {
    fn new(lang: Lang, scene: PathBuf) -> Self {
        Run {
            lang,
            scene,
            w: 40,
            h: 40,
            aa: 1,
            bug: "none",
            env: Vec::new(),
        }
    }

    /// Renders in an empty folder with every RAYSCOPE_ variable cleared but those of `env`, and
    /// `RAYSCOPE_LOG` set to `log` (relative to that folder) when given; returns the folder, or
    /// `None` when the tracer's tools are missing.
    fn render(&self, log: Option<&str>) -> Option<tempfile::TempDir> {
        let mut cmd = tracer(self.lang)?;
        let dir = tempfile::tempdir().expect("temp dir");
        cmd.current_dir(dir.path())
            .arg("-f")
            .arg(&self.scene)
            .args(["-w", &self.w.to_string(), "-h", &self.h.to_string()])
            .args(["-x", &self.aa.to_string(), "--bug", self.bug]);
        for (k, _) in std::env::vars() {
            if k.starts_with("RAYSCOPE_") {
                cmd.env_remove(k);
            }
        }
        if let Some(log) = log {
            cmd.env("RAYSCOPE_LOG", log);
        }
        cmd.envs(self.env.iter().copied());
        let out = cmd.output().expect("run the tracer");
        assert!(
            out.status.success(),
            "{:?} tracer failed:\n{}",
            self.lang,
            String::from_utf8_lossy(&out.stderr)
        );
        Some(dir)
    }

    /// Renders with logging on and checks the log; `None` when the tracer's tools are missing.
    fn check(&self) -> Option<Report> {
        let dir = self.render(Some("rays.jsonl"))?;
        let settings = RenderSettings {
            width: self.w,
            height: self.h,
            aa: self.aa,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        Some(check_log(&self.scene, settings, &dir.path().join("rays.jsonl"), 3))
    }

    /// The (x, y, sample) of every record of the log written with logging on.
    fn logged(&self) -> Option<Logged> {
        let dir = self.render(Some("rays.jsonl"))?;
        let log = std::fs::read_to_string(dir.path().join("rays.jsonl")).expect("the log");
        let mut seen = BTreeSet::new();
        for line in log.lines() {
            let v: serde_json::Value = serde_json::from_str(line).expect("a JSON line");
            let n = |x: &serde_json::Value| x.as_u64().expect("an integer") as u32;
            seen.insert((n(&v["pixel"][0]), n(&v["pixel"][1]), n(&v["sample"])));
        }
        Some(seen)
    }
}

fn course_scene(name: &str) -> Option<PathBuf> {
    rayscope_testkit::course().map(|c| c.scene(name))
}

#[test]
fn correct_tracers_get_no_verdict_on_course_scenes_1_and_2() {
    let (Some(s1), Some(s2)) = (course_scene("sample_scene_1.txt"), course_scene("sample_scene_2.txt")) else {
        return;
    };
    for lang in LANGS {
        for scene in [&s1, &s2] {
            let Some(r) = Run::new(lang, scene.clone()).check() else {
                continue;
            };
            assert!(r.rays > 1600, "{lang:?}: too few rays: {}", r.rays);
            assert_eq!(
                r.disagree,
                0,
                "{lang:?}: the correct tracer got verdicts:\n{}",
                text(&r)
            );
        }
    }
}

/// Parallel.For (C#) and std::threads (C++) interleave their samples; each sample is still
/// logged whole, once, with every ray and colour: no verdict, every sample present.
#[test]
fn threaded_renders_with_anti_aliasing_log_every_sample_whole() {
    let Some(s2) = course_scene("sample_scene_2.txt") else {
        return;
    };
    for lang in [Lang::CSharp, Lang::Cpp] {
        let run = Run {
            w: 30,
            h: 30,
            aa: 2,
            ..Run::new(lang, s2.clone())
        };
        let Some(r) = run.check() else {
            continue;
        };
        assert_eq!(r.disagree, 0, "{lang:?}: verdicts on a threaded render:\n{}", text(&r));
        let Some(seen) = run.logged() else {
            continue;
        };
        assert_eq!(seen.len(), 30 * 30 * 4, "{lang:?}: not every pixel sample was logged");
    }
}

#[test]
fn each_mistake_is_named_on_the_first_line() {
    let Some(s2) = course_scene("sample_scene_2.txt") else {
        return;
    };
    for lang in LANGS {
        for (bug, code) in [
            ("shadow-no-offset", Code::ShadowAcne),
            ("reflect-no-2", Code::ReflectionNotMirror),
            ("refraction-normal", Code::RefractionNormalNotFlipped),
        ] {
            let Some(r) = (Run {
                bug,
                ..Run::new(lang, s2.clone())
            })
            .check() else {
                continue;
            };
            let t = text(&r);
            eprintln!("{lang:?} {bug}: {}", t.lines().next().unwrap_or_default());
            assert!(
                t.lines().next().is_some_and(|l| l.contains(code.as_str())),
                "{lang:?} '{bug}': the first line does not name {}:\n{t}",
                code.as_str()
            );
            assert!(
                r.causes[0].code == code || r.causes[0].or == Some(code),
                "{lang:?} '{bug}':\n{t}"
            );
            assert_eq!(r.causes.len(), 1, "{lang:?} '{bug}' has more than one headline:\n{t}");
        }
    }
}

#[test]
fn logging_off_writes_nothing() {
    let Some(s1) = course_scene("sample_scene_1.txt") else {
        return;
    };
    for lang in LANGS {
        // Filters alone, or an empty RAYSCOPE_LOG, do not switch logging on.
        for log in [None, Some("")] {
            let run = Run {
                w: 10,
                h: 10,
                env: vec![("RAYSCOPE_LOG_PIXELS", "1,1"), ("RAYSCOPE_LOG_STEP", "2")],
                ..Run::new(lang, s1.clone())
            };
            let Some(dir) = run.render(log) else {
                continue;
            };
            let files: Vec<_> = std::fs::read_dir(dir.path()).expect("read dir").collect();
            assert!(files.is_empty(), "{lang:?} wrote {files:?} with RAYSCOPE_LOG {log:?}");
        }
    }
}

#[test]
fn filters_log_exactly_the_chosen_pixels_and_samples() {
    let Some(s1) = course_scene("sample_scene_1.txt") else {
        return;
    };
    let all = |x: u32, y: u32| (0..4).map(move |s| (x, y, s));
    let cases: Vec<(Vec<(&str, &str)>, Logged)> = vec![
        (
            vec![("RAYSCOPE_LOG_PIXELS", "3,4 10,12")],
            all(3, 4).chain(all(10, 12)).collect(),
        ),
        (
            vec![("RAYSCOPE_LOG_RECT", "2,3,4,5")],
            (2..=4).flat_map(|x| (3..=5).flat_map(move |y| all(x, y))).collect(),
        ),
        (
            vec![("RAYSCOPE_LOG_STEP", "5")],
            (0..4)
                .flat_map(|i| (0..4).flat_map(move |j| all(5 * i, 5 * j)))
                .collect(),
        ),
        (
            vec![("RAYSCOPE_LOG_RECT", "0,0,1,1"), ("RAYSCOPE_LOG_SAMPLES", "0,3")],
            [(0, 0), (1, 0), (0, 1), (1, 1)]
                .into_iter()
                .flat_map(|(x, y)| [(x, y, 0), (x, y, 3)])
                .collect(),
        ),
        (
            vec![("RAYSCOPE_LOG_PIXELS", "5,5 3,4 10,15"), ("RAYSCOPE_LOG_STEP", "5")],
            all(5, 5).chain(all(10, 15)).collect(),
        ),
    ];
    for lang in LANGS {
        for (env, want) in &cases {
            let run = Run {
                w: 20,
                h: 20,
                aa: 2,
                env: env.clone(),
                ..Run::new(lang, s1.clone())
            };
            let Some(seen) = run.logged() else {
                break;
            };
            assert_eq!(&seen, want, "{lang:?} with {env:?}");
        }
        // A sparse log is judged like a full one.
        let run = Run {
            env: vec![("RAYSCOPE_LOG_STEP", "7")],
            ..Run::new(lang, course_scene("sample_scene_2.txt").expect("scene 2"))
        };
        if let Some(r) = run.check() {
            assert!(r.rays > 30, "{lang:?}: {} rays", r.rays);
            assert_eq!(r.disagree, 0, "{lang:?}:\n{}", text(&r));
        }
    }
}

/// The kit's code blocks in docs/check.md (between "## Logging kits" and the next section),
/// by language: every line but comments and `...` is a line of that language's test tracer.
#[test]
fn the_docs_show_the_lines_the_tracers_run() {
    let doc = std::fs::read_to_string(root().join("docs/check.md")).expect("docs/check.md");
    let start = doc.find("\n## Logging kits").expect("a '## Logging kits' section");
    let section = &doc[start + 1..];
    let section = &section[..section[3..].find("\n## ").map_or(section.len(), |e| e + 3)];
    let mut blocks = 0;
    let mut lines = section.lines();
    while let Some(line) = lines.next() {
        let lang = match line.trim() {
            "```csharp" => Lang::CSharp,
            "```python" => Lang::Python,
            "```cpp" => Lang::Cpp,
            _ => continue,
        };
        blocks += 1;
        let src = std::fs::read_to_string(source(lang)).expect("tracer source");
        let have: BTreeSet<&str> = src.lines().map(str::trim).collect();
        for l in lines.by_ref().take_while(|l| l.trim() != "```") {
            let l = l.trim();
            if l.is_empty() || l == "..." || l.starts_with("//") || l.starts_with("# ") {
                continue;
            }
            assert!(
                have.contains(l),
                "docs/check.md shows `{l}` for {lang:?}, which {} does not have",
                source(lang).display()
            );
        }
    }
    assert!(blocks >= 3, "the kit section shows {blocks} code blocks");
    // The number of lines the docs say a student adds is the number the tracer has: the import,
    // and the calls that are statements of their own (not the wrapped returns).
    for (lang, calls, import, heading) in [
        (Lang::CSharp, "RayLog.", None, "**C#**"),
        (Lang::Python, "raylog.", Some("import raylog"), "**Python**"),
        (Lang::Cpp, "raylog::", Some("#include \"raylog.hpp\""), "**C++**"),
    ] {
        let src = std::fs::read_to_string(source(lang)).expect("tracer source");
        let added = src
            .lines()
            .map(str::trim)
            .filter(|l| l.starts_with(calls) || Some(*l) == import)
            .count();
        let from = section
            .find(heading)
            .unwrap_or_else(|| panic!("no {heading} paragraph"));
        let paragraph = &section[from..section[from..].find("\n\n").map_or(section.len(), |e| from + e)];
        assert!(
            paragraph.contains(&format!("**{added} lines**")),
            "{lang:?}: the tracer adds {added} lines, the docs say otherwise:\n{paragraph}"
        );
    }
}

/// Every number as an `f64`, so that `4.0` and `4` compare equal.
fn numbers_as_f64(v: serde_json::Value) -> serde_json::Value {
    use serde_json::Value;
    match v {
        Value::Number(n) => serde_json::json!(n.as_f64().expect("a number")),
        Value::Array(a) => Value::Array(a.into_iter().map(numbers_as_f64).collect()),
        Value::Object(o) => Value::Object(o.into_iter().map(|(k, v)| (k, numbers_as_f64(v))).collect()),
        v => v,
    }
}

/// The same calls in each kit (tests/student/kit/orders.py, Orders.cs, orders.cpp), in the orders
/// tracers use: a hit logged before its ray's kind, a hit logged for a shadow ray by a nearest-hit
/// search the shadow test shares, colours returned deepest first, a pixel the filter leaves out,
/// calls after Close. Each kit writes the same tree.
#[test]
fn the_kits_work_out_the_tree_whatever_the_call_order() {
    let want: Vec<serde_json::Value> = [
        r#"{"pixel":[1,2],"sample":3,"id":0,"parent":null,"kind":"camera","origin":[0,0,0],"direction":[0,0,1],"hit":{"point":[0,0,5],"normal":[0,0,-1]},"color":[0.25,0.25,0.25]}"#,
        r#"{"pixel":[1,2],"sample":3,"id":1,"parent":0,"kind":"reflection","origin":[0,0,4.99999],"direction":[0,1,0],"hit":{"point":[0,3,5],"normal":[0,-1,0]},"color":[0.5,0.5,0.5]}"#,
        r#"{"pixel":[1,2],"sample":3,"id":2,"parent":1,"kind":"shadow","origin":[0,2.99999,5],"direction":[1,0,0],"light":[4,3,5],"blocked_by":null}"#,
        r#"{"pixel":[1,2],"sample":3,"id":3,"parent":0,"kind":"refraction","origin":[0,0,5.00001],"direction":[0,0,1],"hit":null,"color":[0,0,0]}"#,
    ]
    .iter()
    .map(|l| numbers_as_f64(serde_json::from_str(l).expect("JSON")))
    .collect();
    let kit = kit_dir();
    let dir = tempfile::tempdir().expect("temp dir");
    for lang in LANGS {
        let mut cmd = match lang {
            Lang::Python => {
                if !have("python3", "the Python kit tests") {
                    continue;
                }
                let mut cmd = Command::new("python3");
                cmd.arg(kit.join("orders.py"))
                    .env("PYTHONPATH", root().join("kits/python"));
                cmd
            }
            Lang::CSharp => {
                if !have("mcs", "the C# kit tests") || !have("mono", "the C# kit tests") {
                    continue;
                }
                let exe = dir.path().join("orders.exe");
                let mut mcs = Command::new("mcs");
                mcs.args(["-langversion:7", "-warnaserror+", "-main:RayTracer.Orders"])
                    .arg(format!("-out:{}", exe.display()))
                    .arg(root().join("kits/csharp/RayLog.cs"))
                    .arg(kit.join("Tracer.cs"))
                    .arg(kit.join("Orders.cs"));
                compile(mcs, "mcs");
                let mut cmd = Command::new("mono");
                cmd.arg(exe);
                cmd
            }
            Lang::Cpp => {
                if !have("g++", "the C++ kit tests") {
                    continue;
                }
                let exe = dir.path().join("orders");
                let mut gpp = Command::new("g++");
                gpp.args(["-std=c++17", "-pthread", "-Wall", "-Wextra", "-Werror", "-I"])
                    .arg(root().join("kits/cpp"))
                    .arg("-o")
                    .arg(&exe)
                    .arg(kit.join("orders.cpp"));
                compile(gpp, "g++");
                Command::new(exe)
            }
        };
        let log = dir.path().join(format!("{lang:?}.jsonl"));
        for (k, _) in std::env::vars() {
            if k.starts_with("RAYSCOPE_") {
                cmd.env_remove(k);
            }
        }
        let out = cmd
            .env("RAYSCOPE_LOG", &log)
            .env("RAYSCOPE_LOG_PIXELS", "1,2")
            .output()
            .expect("run the calls");
        assert!(
            out.status.success(),
            "{lang:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&log).expect("the log");
        let got: Vec<serde_json::Value> = text
            .lines()
            .map(|l| numbers_as_f64(serde_json::from_str(l).expect("a JSON line")))
            .collect();
        assert_eq!(got, want, "{lang:?} wrote:\n{text}");
    }
}

/// Mistakes found in real students' tracers, made by the template-shaped C# tracer (its own code,
/// not theirs): `diagnose` names each from the picture alone, as the catalogue's mistake whose
/// render is that picture; the correct tracer's picture matches.
#[test]
fn diagnose_names_real_students_mistakes_in_a_template_shaped_tracer() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene2 = course.scene("sample_scene_2.txt");
    let pane = root().join("crates/rayscope_core/tests/scenes/thin_pane.txt");
    let (w, h) = (80u32, 60u32);
    // What the explanation must be (the catalogue's mistake, or the setting that is that mistake)
    // and what its first line says.
    for (scene, bug, named) in [
        (&scene2, "none", None),
        (&pane, "min-distance", Some(("min-hit-distance", "min-hit-distance"))),
        (
            &scene2,
            "first-in-list",
            Some(("first-hit-in-scene-order", "first-hit-in-scene-order")),
        ),
        (
            &scene2,
            "origin-distance",
            Some(("nearest-by-origin-distance", "nearest-by-origin-distance")),
        ),
        (
            &scene2,
            "reflect-along-ray",
            Some(("glass-reflection-along-ray", "glass-reflection-along-ray")),
        ),
        (
            &scene2,
            "reflect-outward",
            Some(("glass-reflection-outward", "glass-reflection-outward")),
        ),
        (
            &scene2,
            "accumulator",
            Some(("accumulator-not-reset", "accumulator-not-reset")),
        ),
        (&scene2, "schlick", Some(("schlick", "schlick"))),
        // 80 / 60 in integers is 1: a square image plane.
        (&scene2, "integer-aspect", Some(("aspect-ignored", "aspect-ignored"))),
        (&scene2, "fov-vertical", Some(("--fov-axis vertical", "fov-vertical"))),
        // Black from depth 3 for every material is the mirror-and-glass limit of 2 at stage 2.
        (
            &scene2,
            "depth-all-3",
            Some(("--max-depth 2", "every ray from depth 3 on")),
        ),
    ] {
        let Some((d, text)) = csharp_diagnosis(scene, bug, w, h) else {
            return;
        };
        match named {
            None => assert!(d.matches, "{bug}:\n{text}"),
            Some((name, said)) => {
                let first = d.explanations.first();
                let names = |e: &rayscope_core::diagnose::Explanation| -> Vec<String> {
                    e.mistakes.iter().chain(&e.settings).cloned().collect()
                };
                assert!(first.is_some_and(|e| e.matches && names(e) == [name]), "{bug}:\n{text}");
                assert!(text.lines().next().is_some_and(|l| l.contains(said)), "{bug}:\n{text}");
            }
        }
    }
}

/// The template-shaped C# tracer's stage-2 picture of `scene` with `bug`, `w`×`h`, diagnosed
/// from the picture alone, with the report; `None` where Mono is missing.
fn csharp_diagnosis(scene: &Path, bug: &str, w: u32, h: u32) -> Option<(rayscope_core::diagnose::Diagnosis, String)> {
    let mut cmd = tracer(Lang::CSharp)?;
    let dir = tempfile::tempdir().expect("temp dir");
    let ppm = dir.path().join("out.ppm");
    let out = cmd
        .arg("-f")
        .arg(scene)
        .args([
            "-w",
            &w.to_string(),
            "-h",
            &h.to_string(),
            "--bug",
            bug,
            "--serial",
            "-o",
        ])
        .arg(&ppm)
        .env_remove("RAYSCOPE_LOG")
        .output()
        .expect("run the tracer");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let rgb: Vec<u8> = std::fs::read_to_string(&ppm)
        .expect("the picture")
        .split_whitespace()
        .skip(4)
        .map(|t| t.parse().expect("a byte"))
        .collect();
    let file = rayscope_scene::load(scene).expect("scene");
    let flags = RenderSettings {
        width: w,
        height: h,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let image = rayscope_core::diagnose::Image {
        width: w,
        height: h,
        rgb: &rgb,
        alpha: None,
    };
    let opts = rayscope_core::diagnose::DiagnoseOptions {
        pairs: false,
        coarse_samples: 2_400,
        ..Default::default()
    };
    let d = rayscope_core::diagnose::diagnose(&file, &flags, image, &opts).expect("the sizes agree");
    let text = rayscope_core::diagnose::report_text(&d, &scene.display().to_string());
    Some((d, text))
}

/// Shadow rays that start on their surface in the template-shaped C# tracer (double precision,
/// no offset): the acne falls where the tracer's own rounding puts it, and `diagnose` names it
/// on the first line from how the picture looks.
#[test]
fn diagnose_recognises_the_template_tracer_s_shadow_acne() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = course.scene("sample_scene_2.txt");
    let Some((d, text)) = csharp_diagnosis(&scene, "shadow-no-offset", 160, 120) else {
        return;
    };
    let first = text.lines().next().unwrap_or_default();
    assert!(first.contains("shadow acne ('no-shadow-offset')"), "{text}");
    let r = d.recognised.first().expect("recognised");
    assert!(r.share > 0.8, "{r:?}");
    assert!(r.entities.iter().any(|e| e.contains("Wall")), "{r:?}");
}
