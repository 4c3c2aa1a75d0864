//! `rayscope probe`: runs a student's own intersector as a child process, sends it a battery of
//! rays against each of the scene's primitives, and reports the cases it gets wrong with a
//! reproduction for each. The protocol is in docs/probe.md ("Bring your own intersector" in the
//! README). The right answers are the [`crate::oracle`]'s, and a ray is a tie (either answer
//! right) by the log checker's rule, [`crate::tie`]. The command line's `rayscope probe` is a
//! thin wrapper around [`check_timeouts`], [`run`] and [`Outcome`].

pub mod battery;
pub mod child;
pub mod judge;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use glam::DVec3;
use rayscope_core::mistakes::{Mistake, MistakeInfo};
use rayscope_scene::SceneFile;

use battery::{cases_for, nice, Case, CaseKind, Expect, PrimKind, Shape};
use child::{ChildError, Probed};
use judge::{Answer, Verdict};

pub use child::kill_group;

/// Most requests one run sends (primitives × their cases × `--rays-per-case`). Each is kept
/// with its answer and verdicts until the report, about 450 bytes in all (84 MB at 190,000
/// requests), so a run stays under about 512 MiB whatever the flags.
pub const MAX_REQUESTS: u64 = 1_000_000;

/// Longest `--timeout` and `--startup-timeout` accepted, in seconds (a day).
pub const MAX_TIMEOUT_S: f64 = 86_400.0;

/// What one probe run is asked to do (the command line's flags).
#[derive(Debug, Clone)]
pub struct Options<'a> {
    /// The scene file's path, as given (for messages and the report).
    pub scene: &'a Path,
    /// The program to run and its arguments.
    pub command: &'a [String],
    /// Triangles of each mesh to test (`--mesh-triangles`).
    pub mesh_triangles: u32,
    /// Rays of each case (`--rays-per-case`, at least 1).
    pub rays_per_case: u32,
    /// Seed of the battery's rays (`--seed`).
    pub seed: u64,
    /// Seconds the program has for each answer (`--timeout`).
    pub timeout: f64,
    /// Seconds the program has for its first answer (`--startup-timeout`).
    pub startup_timeout: f64,
}

/// Refuses a `--timeout` or `--startup-timeout` outside (0, [`MAX_TIMEOUT_S`]]; the message
/// names the flag.
pub fn check_timeouts(timeout: f64, startup_timeout: f64) -> Result<(), String> {
    for (flag, secs) in [("--timeout", timeout), ("--startup-timeout", startup_timeout)] {
        if !(secs > 0.0 && secs <= MAX_TIMEOUT_S) {
            return Err(format!(
                "{flag} {} is out of range: give a number of seconds greater than 0 and at most {MAX_TIMEOUT_S} (a day)",
                if secs.abs() >= 1e9 { format!("{secs:e}") } else { format!("{secs}") }
            ));
        }
    }
    Ok(())
}

/// A finished probe run: the battery, the program's answers and their verdicts.
#[derive(Debug)]
pub struct Outcome {
    cases: Vec<Case>,
    answers: Vec<Answer>,
    judgements: Vec<judge::Judgement>,
    conventions: BTreeMap<PrimKind, bool>,
    sources: Vec<battery::Source>,
    shown: String,
}

impl Outcome {
    /// True when every answer is right (the exit status is 0).
    #[must_use]
    pub fn passed(&self) -> bool {
        self.judgements.iter().all(|j| j.verdicts.is_empty())
    }

    /// The verdict codes of the findings, one per finding in the report's order
    /// (primitive, case id or "all", verdict code).
    #[must_use]
    pub fn findings(&self) -> Vec<(&'static str, &'static str, &'static str)> {
        self.report()
            .findings
            .iter()
            .map(|f| (f.kind.name(), f.case.map_or("all", CaseKind::id), f.verdict.code()))
            .collect()
    }

    fn report(&self) -> Report<'_> {
        Report::new(&self.cases, &self.answers, &self.judgements, &self.conventions)
    }

    /// The text report, handed to `emit` a piece at a time (with `all_examples` it grows with
    /// the battery).
    pub fn text(&self, scene: &Path, all_examples: bool, emit: &mut dyn FnMut(&str)) {
        self.report()
            .text(&self.shown, scene, &self.sources, all_examples, emit);
    }

    /// The JSON report (`--json`).
    #[must_use]
    pub fn json(&self, scene: &Path, command: &[String]) -> String {
        self.report().json(scene, command)
    }
}

/// Runs the program of `opts` on the battery built from `file` and judges its answers.
/// `started` is told the program's process id as soon as it runs (to stop it on Ctrl-C, with
/// [`kill_group`]). `Err` is a message for the user: a battery too large, a scene without
/// primitives, a program that cannot start, does not answer or answers what cannot be read.
pub fn run(opts: &Options<'_>, file: &SceneFile, started: &mut dyn FnMut(u32)) -> Result<Outcome, String> {
    let scene = opts.scene;
    // Counted before anything is built: the battery is held whole until the report.
    let (requests, primitives) =
        battery::request_bound(file, opts.mesh_triangles as usize, opts.rays_per_case as usize);
    if requests > MAX_REQUESTS {
        // Every term of the count has --rays-per-case as a factor.
        let fitting = MAX_REQUESTS / (requests / u64::from(opts.rays_per_case)).max(1);
        return Err(format!(
            "{}: --mesh-triangles {} and --rays-per-case {} make up to {requests} requests ({primitives} primitives, each 11 to 15 cases of {} rays), more than the {MAX_REQUESTS} one run sends (every request is kept until the report).\n  Lower --rays-per-case{} or --mesh-triangles.",
            scene.display(),
            opts.mesh_triangles,
            opts.rays_per_case,
            opts.rays_per_case,
            if fitting >= 1 {
                format!(" (at most {fitting} here)")
            } else {
                String::new()
            }
        ));
    }
    let sources = battery::sources(file, opts.mesh_triangles as usize);
    if sources.is_empty() {
        return Err(format!("{} has no sphere, plane or triangle to test", scene.display()));
    }
    let cases: Vec<Case> = sources
        .iter()
        .enumerate()
        .flat_map(|(i, s)| battery::battery(s, i, opts.rays_per_case as usize, opts.seed))
        .collect();
    let shown = command_line(opts.command);
    let mut child = Probed::spawn(opts.command).map_err(|e| {
        format!(
            "cannot start `{shown}`: {e}{}",
            if e.kind() == std::io::ErrorKind::NotFound {
                " (is the program on PATH, and the command after `--`?)"
            } else {
                ""
            }
        )
    })?;
    // The program runs in a process group of its own, which Ctrl-C in the terminal does not
    // reach: the caller stops it on the way out.
    started(child.id());
    let startup = Duration::from_secs_f64(opts.startup_timeout);
    let timeout = Duration::from_secs_f64(opts.timeout);
    let hello = child
        .ask(judge::HELLO, startup)
        .map_err(|e| child_failure(&mut child, &shown, e, None))?;
    check_ready(&hello).map_err(|why| {
        child.kill();
        format!(
            "`{shown}` does not speak the probe protocol: {why}.\n  its first line: {}\n  expected: {{\"ready\":true}}, the answer to rayscope's hello {}\n  (print debugging output to stderr, never stdout; the README's \"Bring your own intersector\" has adapters for Python and C#)",
            quote(&hello),
            judge::HELLO
        )
    })?;
    let mut answers = Vec::with_capacity(cases.len());
    let mut judgements = Vec::with_capacity(cases.len());
    for (id, case) in cases.iter().enumerate() {
        let request = judge::request_json(id, case);
        let line = child
            .ask(&request, timeout)
            .map_err(|e| child_failure(&mut child, &shown, e, Some((case, &request))))?;
        let answer = judge::parse_answer(&line, id).map_err(|why| {
            child.kill();
            format!(
                "`{shown}` answered request {id} with a line rayscope cannot read: {why}.\n  request: {request}\n  answer:  {}\n  expected: {{\"id\":{id},\"hit\":null}} for a miss, or {{\"id\":{id},\"hit\":{{\"t\":…,\"point\":[x,y,z],\"normal\":[x,y,z]}}}}\n  (print debugging output to stderr, never stdout)",
                quote(&line)
            )
        })?;
        judgements.push(judge::judge(case, &answer));
        answers.push(answer);
    }
    child.finish(Duration::from_secs(2));

    // Normals: either convention is right, but one answer's must agree with the others'.
    let mut conventions = BTreeMap::new();
    for kind in [PrimKind::Sphere, PrimKind::Plane, PrimKind::Triangle] {
        let (idx, orient): (Vec<usize>, Vec<_>) = judgements
            .iter()
            .enumerate()
            .filter(|(i, _)| cases[*i].shape.kind() == kind)
            .filter_map(|(i, j)| j.orientation.map(|o| (i, o)))
            .unzip();
        let conv = judge::convention(&orient);
        for b in &conv.breaking {
            judgements[idx[*b]].verdicts.push(Verdict::NormalFlipped);
        }
        conventions.insert(kind, conv.outward);
    }
    Ok(Outcome {
        cases,
        answers,
        judgements,
        conventions,
        sources,
        shown,
    })
}

/// What a catalogue entry's probe code (see [`MistakeInfo::probe`]) names: the primitive and
/// case it is narrowed to, if any, and the verdict. `None` for a code naming a primitive, case or
/// verdict the probe does not have, or a case the primitive does not get.
#[must_use]
pub fn parse_catalogue_code(code: &str) -> Option<(Option<PrimKind>, Option<CaseKind>, Verdict)> {
    let (scope, verdict) = match code.split_once(": ") {
        Some((scope, verdict)) => (Some(scope), verdict),
        None => (None, code),
    };
    let verdict = Verdict::parse(verdict)?;
    let Some(scope) = scope else {
        return Some((None, None, verdict));
    };
    let (kind, case) = match scope.split_once(' ') {
        Some((kind, case)) => (kind, Some(case)),
        None => (scope, None),
    };
    let kind = [PrimKind::Sphere, PrimKind::Plane, PrimKind::Triangle]
        .into_iter()
        .find(|k| k.name() == kind)?;
    let case = match case {
        Some(id) => Some(*cases_for(kind).iter().find(|c| c.id() == id)?),
        None => None,
    };
    Some((Some(kind), case, verdict))
}

/// The catalogue's mistakes that show as `verdict` in `case` (None: over all of a kind's
/// hits) of a `kind`, in catalogue order.
#[must_use]
pub fn catalogue_mistakes(kind: PrimKind, case: Option<CaseKind>, verdict: Verdict) -> Vec<MistakeInfo> {
    Mistake::ALL
        .into_iter()
        .map(Mistake::info)
        .filter(|i| {
            i.probe.iter().any(|code| {
                parse_catalogue_code(code)
                    .is_some_and(|(k, c, v)| v == verdict && k.is_none_or(|k| k == kind) && (c.is_none() || c == case))
            })
        })
        .collect()
}

fn command_line(cmd: &[String]) -> String {
    cmd.iter()
        .map(|s| {
            if s.is_empty() || s.contains(char::is_whitespace) {
                format!("'{s}'")
            } else {
                s.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// A line of the program's output, shortened for a message.
fn quote(line: &str) -> String {
    let mut s: String = line.chars().take(200).collect();
    if s.len() < line.len() {
        s.push_str(" …");
    }
    if s.trim().is_empty() {
        "(an empty line)".into()
    } else {
        s
    }
}

fn check_ready(line: &str) -> Result<(), String> {
    let v: serde_json::Value =
        serde_json::from_str(line.trim()).map_err(|_| "its first line is not JSON".to_string())?;
    match v.get("ready") {
        Some(serde_json::Value::Bool(true)) => Ok(()),
        _ => Err("its first line is not {\"ready\":true}".into()),
    }
}

/// The error for a program that did not answer, with its stderr's last lines.
fn child_failure(child: &mut Probed, shown: &str, e: ChildError, at: Option<(&Case, &str)>) -> String {
    let what = match at {
        Some((c, _)) => format!(
            "request {} ({}: {})",
            request_id(at),
            c.shape.kind().name(),
            c.case.describe(c.shape.kind())
        ),
        None => "rayscope's hello".to_string(),
    };
    let mut msg = match e {
        ChildError::Timeout(d) => {
            child.kill();
            format!(
                "`{shown}` did not answer {what} within {} s, so rayscope stopped it.\n  Does it write a newline and flush its output after each answer (Python: print(..., flush=True); C#: Console.Out.Flush())? Does the intersector loop forever on this ray?{}",
                d.as_secs_f64(),
                if at.is_none() {
                    " A program that compiles first may need a longer --startup-timeout."
                } else {
                    ""
                }
            )
        }
        ChildError::NotReading(d) => {
            child.kill();
            format!(
                "`{shown}` did not read {what} from its input (stdin) within {} s, so rayscope stopped it.\n  It stopped reading what rayscope sends: read each request line, then answer it.",
                d.as_secs_f64()
            )
        }
        ChildError::Exited(Some(status)) => format!("`{shown}` {} before answering {what}.", describe_status(status)),
        ChildError::Exited(None) => {
            child.kill();
            format!(
                "`{shown}` closed its output (stdout) without exiting before answering {what}, so rayscope stopped it."
            )
        }
        ChildError::InputClosed => {
            child.kill();
            format!(
                "`{shown}` closed its input (stdin) without exiting before reading {what}, so rayscope stopped it.\n  Keep reading requests until rayscope closes the input, then exit."
            )
        }
        ChildError::TooLong => {
            child.kill();
            format!(
                "`{shown}` wrote a line of more than {} KiB instead of answering {what}; that is not an answer.",
                child::MAX_LINE / 1024
            )
        }
        ChildError::Io(err) => {
            child.kill();
            format!("talking to `{shown}` failed while waiting for {what}: {err}")
        }
    };
    if let Some((_, request)) = at {
        msg.push_str(&format!("\n  request: {request}"));
    }
    let err = child.stderr();
    if err.total == 0 {
        msg.push_str("\n  (it wrote nothing to stderr)");
    } else if err.lines.is_empty() {
        msg.push_str(&format!(
            "\n  (it wrote {} of blank lines to stderr)",
            amount(err.total)
        ));
    } else {
        msg.push_str("\n  the last lines it wrote to stderr");
        if err.dropped > 0 {
            msg.push_str(&format!(
                " (it wrote {} in all; only the last {} KiB were kept)",
                amount(err.total),
                child::STDERR_KEPT / 1024
            ));
        }
        msg.push(':');
        for l in err.lines {
            msg.push_str(&format!("\n    | {l}"));
        }
    }
    msg
}

/// A number of bytes, for reading.
fn amount(bytes: u64) -> String {
    const KIB: f64 = 1024.0;
    let b = bytes as f64;
    if bytes < 1024 {
        format!("{bytes} bytes")
    } else if b < KIB * KIB {
        format!("{:.1} KiB", b / KIB)
    } else if b < KIB * KIB * KIB {
        format!("{:.1} MiB", b / (KIB * KIB))
    } else {
        format!("{:.2} GiB", b / (KIB * KIB * KIB))
    }
}

fn request_id(at: Option<(&Case, &str)>) -> String {
    at.and_then(|(_, r)| serde_json::from_str::<serde_json::Value>(r).ok())
        .and_then(|v| v.get("id").and_then(serde_json::Value::as_u64))
        .map_or_else(|| "?".into(), |id| id.to_string())
}

fn describe_status(s: std::process::ExitStatus) -> String {
    if let Some(code) = s.code() {
        return format!("exited with status {code}");
    }
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        if let Some(sig) = s.signal() {
            return format!("was killed by signal {sig}");
        }
    }
    "exited".to_string()
}

/// Short decimal of a number for reading (7 significant digits).
fn short(x: f64) -> String {
    let n = nice(x);
    if n == 0.0 {
        "0".into()
    } else {
        format!("{n}")
    }
}

fn vec3(v: DVec3) -> String {
    format!("({}, {}, {})", short(v.x), short(v.y), short(v.z))
}

fn describe_expect(e: &Expect, kind: PrimKind) -> String {
    let origin_too = if e.at_origin_ok {
        " (a hit at t = 0, where the ray starts, is right too)"
    } else {
        ""
    };
    match e.hit {
        Some(h) if !e.miss_ok => format!(
            "hit at t = {}, point {}, normal {} or its opposite{origin_too}",
            short(h.t),
            vec3(h.point),
            vec3(h.normal)
        ),
        Some(h) => format!(
            "a miss, or a hit at t = {} (the ray passes within rounding of the {}: either is right){origin_too}",
            short(h.t),
            if kind == PrimKind::Sphere { "rim" } else { "boundary" }
        ),
        None if e.any_hit_ok => "a miss (a finite hit with t >= 0 is accepted too)".into(),
        None => format!("miss{origin_too}"),
    }
}

fn describe_answer(a: &Answer, c: &Case) -> String {
    match a {
        Answer::Miss => "miss".into(),
        Answer::Error(m) => format!("error: {m}"),
        Answer::Hit { t, point, normal } => {
            let mut parts = Vec::new();
            match (t, point) {
                (Some(t), _) => parts.push(format!("t = {}", short(*t))),
                (None, Some(p)) => parts.push(format!(
                    "t = {} (from the point)",
                    short((*p - c.origin).dot(c.dir) / c.dir.length_squared())
                )),
                (None, None) => {}
            }
            if let Some(p) = point {
                parts.push(format!("point {}", vec3(*p)));
            }
            if let Some(n) = normal {
                parts.push(format!("normal {} (length {})", vec3(*n), short(n.length())));
            }
            format!("hit at {}", parts.join(", "))
        }
    }
}

/// A vector with every digit sent (the numbers have 7 significant digits at most).
fn exact(v: DVec3) -> String {
    let n = |x: f64| if x == 0.0 { "0".to_string() } else { format!("{x}") };
    format!("({}, {}, {})", n(v.x), n(v.y), n(v.z))
}

fn describe_shape(s: &Shape) -> String {
    let f = exact;
    match *s {
        Shape::Sphere { center, radius } => format!("sphere    center = {}, radius = {radius}", f(center)),
        Shape::Plane { point, normal } => format!("plane     point = {}, normal = {}", f(point), f(normal)),
        Shape::Triangle { v } => format!("triangle  v0 = {}, v1 = {}, v2 = {}", f(v[0]), f(v[1]), f(v[2])),
    }
}

/// One wrong behaviour: a verdict in a case, with the rays it happened on.
struct Finding {
    kind: PrimKind,
    /// None for a verdict judged over all of a kind's hits (a normal that is never unit length).
    case: Option<CaseKind>,
    verdict: Verdict,
    /// Indices of the requests.
    requests: Vec<usize>,
    /// Rays of this case and kind in all (hits with a normal, for a kind-wide finding).
    of: usize,
}

/// The judged battery.
struct Report<'a> {
    cases: &'a [Case],
    answers: &'a [Answer],
    /// (kind, case) → (rays, rays with any verdict).
    rows: BTreeMap<(PrimKind, CaseKind), (usize, usize)>,
    findings: Vec<Finding>,
    conventions: &'a BTreeMap<PrimKind, bool>,
}

impl<'a> Report<'a> {
    fn new(
        cases: &'a [Case],
        answers: &'a [Answer],
        judgements: &[judge::Judgement],
        conventions: &'a BTreeMap<PrimKind, bool>,
    ) -> Self {
        let mut rows: BTreeMap<(PrimKind, CaseKind), (usize, usize)> = BTreeMap::new();
        let mut groups: BTreeMap<(PrimKind, Option<CaseKind>, Verdict), Vec<usize>> = BTreeMap::new();
        let mut with_normal: BTreeMap<PrimKind, usize> = BTreeMap::new();
        for (i, (c, j)) in cases.iter().zip(judgements).enumerate() {
            let key = (c.shape.kind(), c.case);
            let row = rows.entry(key).or_default();
            row.0 += 1;
            if !j.verdicts.is_empty() {
                row.1 += 1;
            }
            if matches!(answers[i], Answer::Hit { normal: Some(_), .. }) {
                *with_normal.entry(key.0).or_default() += 1;
            }
            let mut seen = Vec::new();
            for v in &j.verdicts {
                if !seen.contains(v) {
                    seen.push(*v);
                    // A normal of the wrong length is one mistake wherever the ray comes from.
                    let case = (*v != Verdict::NormalNotUnit).then_some(key.1);
                    groups.entry((key.0, case, *v)).or_default().push(i);
                }
            }
        }
        let findings = groups
            .into_iter()
            .map(|((kind, case, verdict), requests)| Finding {
                kind,
                case,
                verdict,
                of: match case {
                    Some(c) => rows[&(kind, c)].0,
                    None => with_normal.get(&kind).copied().unwrap_or(requests.len()),
                },
                requests,
            })
            .collect();
        Self {
            cases,
            answers,
            rows,
            findings,
            conventions,
        }
    }

    fn headline(&self, f: &Finding) -> String {
        match f.case {
            Some(case) => format!(
                "{}: {} -- {} in {} of {} rays.",
                f.kind.name(),
                case.describe(f.kind),
                judge::phrase(f.verdict),
                f.requests.len(),
                f.of
            ),
            None => format!(
                "{}: {} in {} of {} hits, whatever the ray.",
                f.kind.name(),
                judge::phrase(f.verdict),
                f.requests.len(),
                f.of
            ),
        }
    }

    fn hint(&self, f: &Finding) -> Option<String> {
        judge::hint(
            f.kind,
            f.case,
            f.verdict,
            self.conventions.get(&f.kind).copied().unwrap_or(true),
        )
    }

    /// The text report, handed to `emit` a piece at a time.
    fn text(
        &self,
        shown: &str,
        scene: &std::path::Path,
        sources: &[battery::Source],
        all: bool,
        emit: &mut dyn FnMut(&str),
    ) {
        let count = |k: PrimKind| sources.iter().filter(|s| s.shape.kind() == k).count();
        let mut out = format!(
            "probe: {} rays sent to `{shown}`, built from {} ({} spheres, {} planes, {} triangles)\n\n",
            self.cases.len(),
            scene.display(),
            count(PrimKind::Sphere),
            count(PrimKind::Plane),
            count(PrimKind::Triangle)
        );
        for kind in [PrimKind::Sphere, PrimKind::Plane, PrimKind::Triangle] {
            for case in cases_for(kind) {
                if let Some((n, bad)) = self.rows.get(&(kind, *case)) {
                    out.push_str(&format!(
                        "  {:<9} {:<72} {:>4}/{:<4} right{}\n",
                        kind.name(),
                        case.describe(kind),
                        n - bad,
                        n,
                        if *bad > 0 { "   WRONG" } else { "" }
                    ));
                }
            }
        }
        let wrong: usize = self.rows.values().map(|r| r.1).sum();
        if self.findings.is_empty() {
            out.push_str(&format!(
                "\nEvery answer is right: your intersector agrees with rayscope on all {} rays.\n",
                self.cases.len()
            ));
            emit(&out);
            return;
        }
        out.push_str(&format!(
            "\n{wrong} of {} rays answered wrongly; {} finding{}:\n",
            self.cases.len(),
            self.findings.len(),
            if self.findings.len() == 1 { "" } else { "s" }
        ));
        for (n, f) in self.findings.iter().enumerate() {
            out.push_str(&format!("\n{}. {}\n", n + 1, self.headline(f)));
            if let Some(h) = self.hint(f) {
                out.push_str(&format!("   {h}\n"));
            }
            let named = catalogue_mistakes(f.kind, f.case, f.verdict);
            if !named.is_empty() {
                let names: Vec<String> = named
                    .iter()
                    .map(|i| format!("'{}', a tracer that {}", i.name, i.wrong))
                    .collect();
                out.push_str(&format!(
                    "   rayscope's catalogue (`rayscope mistakes`): {}.\n",
                    names.join("; ")
                ));
            }
            let shown_examples = if all { f.requests.len() } else { 1 };
            for (k, &i) in f.requests.iter().take(shown_examples).enumerate() {
                let c = &self.cases[i];
                out.push_str(&format!(
                    "   {} (paste into a unit test; values exactly as sent, from {}):\n",
                    if k == 0 { "Reproduce" } else { "Also" },
                    c.source
                ));
                out.push_str(&format!("     {}\n", describe_shape(&c.shape)));
                out.push_str(&format!(
                    "     ray       origin = {}, direction = {}\n",
                    exact(c.origin),
                    exact(c.dir)
                ));
                out.push_str(&format!("     expected  {}\n", describe_expect(&c.expect, f.kind)));
                out.push_str(&format!("     yours     {}\n", describe_answer(&self.answers[i], c)));
                out.push_str(&format!("     request   {}\n", judge::request_json(i, c)));
                emit(&out);
                out.clear();
            }
        }
        emit(&out);
    }

    fn json(&self, scene: &std::path::Path, command: &[String]) -> String {
        use serde_json::json;
        let cases: Vec<_> = self
            .rows
            .iter()
            .map(|((kind, case), (n, bad))| {
                json!({
                    "primitive": kind.name(),
                    "case": case.id(),
                    "description": case.describe(*kind),
                    "rays": n,
                    "wrong": bad,
                })
            })
            .collect();
        let findings: Vec<_> = self
            .findings
            .iter()
            .map(|f| {
                let examples: Vec<_> = f
                    .requests
                    .iter()
                    .take(10)
                    .map(|&i| {
                        let c = &self.cases[i];
                        let request: serde_json::Value =
                            serde_json::from_str(&judge::request_json(i, c)).unwrap_or(serde_json::Value::Null);
                        json!({
                            "request": request,
                            "source": &*c.source,
                            "expected": describe_expect(&c.expect, f.kind),
                            "answer": describe_answer(&self.answers[i], c),
                        })
                    })
                    .collect();
                json!({
                    "primitive": f.kind.name(),
                    "case": f.case.map_or("all", CaseKind::id),
                    "verdict": f.verdict.code(),
                    "count": f.requests.len(),
                    "of": f.of,
                    "summary": self.headline(f),
                    "hint": self.hint(f),
                    "mistakes": catalogue_mistakes(f.kind, f.case, f.verdict)
                        .iter()
                        .map(|i| i.name)
                        .collect::<Vec<_>>(),
                    "examples": examples,
                })
            })
            .collect();
        let v = json!({
            "version": 1,
            "scene": scene.display().to_string(),
            "command": command,
            "rays": self.cases.len(),
            "wrong": self.rows.values().map(|r| r.1).sum::<usize>(),
            "cases": cases,
            "findings": findings,
        });
        serde_json::to_string_pretty(&v).unwrap_or_default()
    }
}
