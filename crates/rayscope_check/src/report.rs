//! A check's result: counts, verdicts with their first examples, and the text and JSON forms
//! `rayscope check` prints.

use std::fmt::Write;
use std::time::Duration;

use serde::Serialize;

use crate::image::LogNext;

use crate::judge::{Cause, Finding, Tally, Tolerances};
use crate::log::printable;
use crate::verdict::Code;

/// Where a check spent its time.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Timing {
    /// Reading and parsing the log.
    pub reading: Duration,
    /// Grouping the rays into pixel samples and judging them, while the next batch is read.
    pub judging: Duration,
    /// Everything.
    pub total: Duration,
}

/// One verdict code's rays.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VerdictGroup {
    /// The code.
    pub code: Code,
    /// Rays with this verdict.
    pub count: u64,
    /// One line: what was found.
    pub summary: &'static str,
    /// The likely mistake and how to fix it.
    pub explanation: &'static str,
    /// The first rays with it, by line.
    pub examples: Vec<Finding>,
}

/// One root cause: the first wrong ray of a branch of a pixel sample's ray tree, with the
/// verdicts that follow from it below.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CauseGroup {
    /// The verdict.
    pub code: Code,
    /// A second verdict the same rays fit as well; both fixes apply.
    pub or: Option<Code>,
    /// Pixel samples in which it is the first wrong ray.
    pub samples: u64,
    /// Rays on which it is the first wrong verdict.
    pub rays: u64,
    /// One line: what was found.
    pub summary: String,
    /// What to change in the code.
    pub explanation: String,
    /// Verdicts that follow from it, most frequent first.
    pub consequences: Vec<Consequence>,
    /// The first rays it is the cause on, by line.
    pub examples: Vec<Finding>,
    /// Mistakes of rayscope's catalogue (`rayscope mistakes`) that show as this verdict.
    pub catalogue: Vec<&'static str>,
}

/// Verdicts of one code that follow from a cause.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Consequence {
    /// The verdict.
    pub code: Code,
    /// Rays with it below the cause (or beside it on the same ray).
    pub count: u64,
}

impl CauseGroup {
    fn new(c: Cause, n: crate::judge::CauseCount) -> Self {
        let (summary, explanation) = match c.or {
            None => (
                n.note.clone().unwrap_or_else(|| c.code.summary().to_string()),
                c.code.explanation().to_string(),
            ),
            Some(b) => (
                format!("{}, or {}", c.code.summary(), b.summary()),
                format!(
                    "These rays fit either mistake; check both. {} {}",
                    c.code.explanation(),
                    b.explanation()
                ),
            ),
        };
        let mut consequences: Vec<Consequence> = n
            .consequences
            .into_iter()
            .map(|(code, count)| Consequence { code, count })
            .collect();
        consequences.sort_by_key(|c| (std::cmp::Reverse(c.count), c.code));
        // A mistake whose verdict falls on some kinds of ray only is listed where the examples'
        // rays are of those kinds (or where no example was kept to tell).
        let on_its_rays = |m: rayscope_core::Mistake| {
            let kinds = m.check_ray_kinds();
            kinds.is_empty() || n.examples.is_empty() || n.examples.iter().any(|f| kinds.contains(&f.kind.as_str()))
        };
        let catalogue = rayscope_core::Mistake::ALL
            .into_iter()
            .filter(|&m| on_its_rays(m))
            .map(rayscope_core::Mistake::info)
            .filter(|i| i.check.iter().any(|k| c.codes().iter().any(|x| x.as_str() == *k)))
            .map(|i| i.name)
            .collect();
        CauseGroup {
            catalogue,
            code: c.code,
            or: c.or,
            samples: n.samples,
            rays: n.rays,
            summary,
            explanation,
            consequences,
            examples: n.examples,
        }
    }

    /// The cause's verdicts, the one it leads with first.
    #[must_use]
    pub fn codes(&self) -> Vec<Code> {
        std::iter::once(self.code).chain(self.or).collect()
    }

    /// The cause's name: `code` or `code | other`.
    #[must_use]
    pub fn name(&self) -> String {
        Cause {
            code: self.code,
            or: self.or,
        }
        .name()
    }
}

fn plural(n: u64) -> &'static str {
    if n == 1 {
        ""
    } else {
        "s"
    }
}

/// The lines of [`Report::to_text`] that say what to log next.
fn next_text(s: &mut String, n: &LogNext, shaded_judged: u64) {
    match n {
        LogNext::Picture {
            differing,
            unlogged,
            next,
        } => {
            if *differing == 0 {
                let _ = writeln!(
                    s,
                    "\nyour picture against rayscope's render: no pixel differs by more than one level"
                );
                return;
            }
            let _ = writeln!(
                s,
                "\nyour picture against rayscope's render: {differing} pixel{} differ by two levels or more, {unlogged} of them with no camera ray in your log",
                plural(*differing)
            );
            if let Some(n) = next {
                let _ = writeln!(
                    s,
                    "log these pixels next (the logging kits read these variables: docs/check.md), then check again:"
                );
                let _ = writeln!(s, "  {} <run your tracer as before>", n.log_env);
                let _ = writeln!(s, "  {}", n.check_command);
                let _ = writeln!(s, "rayscope's own rays at the first of them: {}", n.trace_command);
            } else if *unlogged == 0 {
                let what = if shaded_judged == 0 {
                    "log \"color\" (docs/check.md) so their shading is judged too"
                } else {
                    "see the colours not judged above, or let `rayscope diagnose` compare the two pictures"
                };
                for l in wrap(
                    &format!("each of them is in your log and was judged above; where no verdict names one, its rays agree or tie and the difference is in the colours: {what}"),
                    96,
                ) {
                    let _ = writeln!(s, "  {l}");
                }
            }
        }
        LogNext::Sparse {
            camera_rays,
            all,
            grid_env,
            check_command,
        } => {
            for l in wrap(
                &format!(
                    "note: your log has {camera_rays} of the picture's {all} camera rays, so only those pixels were judged. Give check your picture (--image) and it finds the pixels where it differs from rayscope's render, or log an even grid of pixels:"
                ),
                96,
            ) {
                let _ = writeln!(s, "{l}");
            }
            let _ = writeln!(s, "  {grid_env} <run your tracer as before>");
            let _ = writeln!(s, "  {check_command}");
        }
    }
}

/// The result of checking a log.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// Rays judged.
    pub rays: u64,
    /// Rays without any verdict.
    pub agree: u64,
    /// Rays with a verdict that is not a tie.
    pub disagree: u64,
    /// Rays whose only verdicts are ties.
    pub ties: u64,
    /// Camera rays judged.
    pub camera_rays: u64,
    /// Camera rays with a `camera.*` verdict: placed or aimed otherwise than rayscope's.
    pub camera_disagree: u64,
    /// Rays naming a parent that was not among the rays of their pixel sample.
    pub orphans: u64,
    /// Surface decisions whose colour was judged.
    pub shaded_judged: u64,
    /// Rays that logged a colour.
    pub coloured_rays: u64,
    /// Surface decisions whose colour was not judged (no colour logged, a child missing, or a
    /// material the course's stage-2 rules do not cover).
    pub shaded_unjudged: u64,
    /// Malformed lines skipped under `--lenient`.
    pub skipped_lines: u64,
    /// The first skipped line's diagnostic.
    pub first_skipped: Option<String>,
    /// Root causes, the one the most pixel samples share first: the mistakes to fix.
    pub causes: Vec<CauseGroup>,
    /// Verdicts against the tracer, causes and consequences alike, most frequent first.
    pub verdicts: Vec<VerdictGroup>,
    /// Genuine ties, most frequent first.
    pub tie_verdicts: Vec<VerdictGroup>,
    /// Camera rays through another cell of their pixel's grid than their number's, where the log
    /// as a whole shows a numbering of the samples other than rayscope's (not a mistake).
    pub renumbered: Option<VerdictGroup>,
    /// Whether the log holds each sample of its pixels once, so that `renumbered` is surely a
    /// numbering (otherwise samples sharing a cell cannot be told from it).
    pub renumbered_whole: bool,
    /// The tracer's picture against its logged colours (`check --image`).
    pub image: Option<crate::image::ImageCheck>,
    /// What to log next when no ray disagrees but the log does not show the whole picture.
    pub next: Option<crate::image::LogNext>,
    /// The tolerances used.
    pub tolerances: Tolerances,
    /// Time spent.
    #[serde(skip)]
    pub timing: Timing,
}

impl Report {
    /// Keeps beside each cause only the catalogue's mistakes `keep` accepts (those that can show
    /// in the scene judged: no OBJ mistake for a scene without meshes).
    pub fn keep_catalogue(&mut self, keep: impl Fn(rayscope_core::Mistake) -> bool) {
        for c in &mut self.causes {
            c.catalogue.retain(|name| {
                rayscope_core::Mistake::ALL
                    .into_iter()
                    .find(|m| m.name() == *name)
                    .is_some_and(&keep)
            });
        }
    }

    /// The report of a finished tally.
    #[must_use]
    pub fn new(t: Tally, skipped: u64, first_skipped: Option<String>, tolerances: Tolerances, timing: Timing) -> Self {
        let mut verdicts = Vec::new();
        let mut ties = Vec::new();
        let mut renumbered = None;
        let order = t.order;
        for (code, (count, examples)) in t.codes {
            let g = VerdictGroup {
                code,
                count,
                summary: code.summary(),
                explanation: code.explanation(),
                examples,
            };
            if code.is_tie() {
                ties.push(g);
            } else if code == Code::CameraSampleOrder {
                renumbered = Some(g);
            } else {
                verdicts.push(g);
            }
        }
        verdicts.sort_by_key(|g| std::cmp::Reverse(g.count));
        let mut causes: Vec<CauseGroup> = t.causes.into_iter().map(|(c, n)| CauseGroup::new(c, n)).collect();
        // Most samples first; then most rays; then the order codes are listed in (camera, hit,
        // shadow, secondary), which is the order a tracer's rays are cast in.
        causes.sort_by_key(|g| (std::cmp::Reverse(g.samples), std::cmp::Reverse(g.rays), g.code, g.or));
        ties.sort_by_key(|g| std::cmp::Reverse(g.count));
        let disagree = t.disagree.min(t.rays);
        Report {
            rays: t.rays,
            agree: t.rays - disagree - t.tied.min(t.rays - disagree),
            disagree,
            ties: t.tied.min(t.rays - disagree),
            camera_rays: t.camera,
            camera_disagree: t.camera_disagree,
            orphans: t.orphans,
            shaded_judged: t.shaded_judged,
            coloured_rays: t.coloured,
            shaded_unjudged: t.shaded_unjudged,
            skipped_lines: skipped,
            first_skipped,
            causes,
            verdicts,
            tie_verdicts: ties,
            renumbered,
            renumbered_whole: order.whole(),
            image: None,
            next: None,
            tolerances,
            timing,
        }
    }

    /// True when no ray disagrees.
    #[must_use]
    pub fn passed(&self) -> bool {
        self.disagree == 0 && self.image.as_ref().is_none_or(|i| i.verdict.is_none())
    }

    /// The picture's verdict, when `--image` found one.
    fn image_verdict(&self) -> Option<(Code, &crate::image::ImageCheck)> {
        self.image.as_ref().and_then(|i| i.verdict.map(|c| (c, i)))
    }

    /// The report as JSON, each example with the command that shows rayscope's ray tree.
    #[must_use]
    pub fn to_json(&self, trace_command: &dyn Fn(&Finding) -> Option<String>) -> serde_json::Value {
        let mut v = serde_json::to_value(self).unwrap_or_default();
        let examples: [(&str, Vec<&[Finding]>); 3] = [
            ("causes", self.causes.iter().map(|g| g.examples.as_slice()).collect()),
            (
                "verdicts",
                self.verdicts.iter().map(|g| g.examples.as_slice()).collect(),
            ),
            (
                "tie_verdicts",
                self.tie_verdicts.iter().map(|g| g.examples.as_slice()).collect(),
            ),
        ];
        for (list, src) in examples {
            let Some(groups) = v.get_mut(list).and_then(|g| g.as_array_mut()) else {
                continue;
            };
            for (g, sg) in groups.iter_mut().zip(src) {
                let Some(ex) = g.get_mut("examples").and_then(|e| e.as_array_mut()) else {
                    continue;
                };
                for (e, f) in ex.iter_mut().zip(sg) {
                    if let Some(obj) = e.as_object_mut() {
                        obj.insert("trace_command".into(), trace_command(f).into());
                    }
                }
            }
        }
        if let Some(obj) = v.as_object_mut() {
            obj.insert("headline".into(), self.headline().into());
        }
        v
    }

    /// The report's first line: the cause the most pixel samples share, or that none was found.
    #[must_use]
    pub fn headline(&self) -> String {
        if let (None, Some((code, i))) = (self.causes.first(), self.image_verdict()) {
            return format!("mistake: {} [{}]: {}", code.summary(), code.as_str(), i.detail);
        }
        if let Some(c) = self.causes.first() {
            let more = match self.causes.len() - 1 + usize::from(self.image_verdict().is_some()) {
                0 => String::new(),
                1 => "; 1 other cause below".to_string(),
                n => format!("; {n} other causes below"),
            };
            format!(
                "mistake: {} [{}]: the first wrong ray in {} pixel sample{}{more}",
                c.summary,
                c.name(),
                c.samples,
                if c.samples == 1 { "" } else { "s" }
            )
        } else if self.rays == 0 {
            "no ray was judged: the log has none".to_string()
        } else if let Some(LogNext::Picture {
            differing, unlogged, ..
        }) = self
            .next
            .as_ref()
            .filter(|n| self.disagree == 0 && matches!(n, LogNext::Picture { unlogged, .. } if *unlogged > 0))
        {
            format!(
                "no mistake found in the log, but your picture differs from rayscope's at {differing} pixel{}, {unlogged} of them not in your log: log some of those next (below)",
                plural(*differing)
            )
        } else if self.shaded_judged == 0 && self.coloured_rays > 0 {
            "no mistake found in the rays: every ray agrees with rayscope; colours were logged, but no surface's colour could be judged: the shadow, reflected or refracted rays it is made from are not in the log (or its material is not one stage 2 covers)".to_string()
        } else if self.shaded_judged == 0 {
            "no mistake found in the rays: every ray agrees with rayscope; no colour was logged, so shading (diffuse sums, Fresnel, mirrors) was not judged: log \"color\" to have it judged".to_string()
        } else if self.shaded_unjudged > self.shaded_judged / 10 {
            format!(
                "no mistake found: every ray agrees with rayscope; {} of {} surface colours could not be judged (see below)",
                self.shaded_unjudged,
                self.shaded_judged + self.shaded_unjudged
            )
        } else {
            "no mistake found: every ray and every logged colour agrees with rayscope".to_string()
        }
    }

    /// The report as text for a terminal.
    #[must_use]
    pub fn to_text(&self, trace_command: &dyn Fn(&Finding) -> Option<String>) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "{}", self.headline());
        let _ = writeln!(
            s,
            "checked {} rays ({} camera rays): {} agree, {} disagree, {} ties (not counted against you)",
            self.rays, self.camera_rays, self.agree, self.disagree, self.ties
        );
        if self.shaded_judged + self.shaded_unjudged > 0 {
            let _ = writeln!(
                s,
                "colours: {} surface decisions judged; {} not judged (no colour logged, a ray missing, or a material stage 2 does not cover)",
                self.shaded_judged, self.shaded_unjudged
            );
        }
        if self.skipped_lines > 0 {
            let _ = writeln!(
                s,
                "skipped {} malformed line{} (--lenient); the first:",
                self.skipped_lines,
                if self.skipped_lines == 1 { "" } else { "s" }
            );
            if let Some(d) = &self.first_skipped {
                for l in d.lines() {
                    let _ = writeln!(s, "  {}", printable(l));
                }
            }
        }
        if let Some(g) = &self.renumbered {
            let conclusion = if self.renumbered_whole {
                "your samples are rayscope's grid positions, numbered in another order, which changes nothing in the picture and is not counted against you (each was judged as the sample whose cell it crosses)"
            } else {
                "the log does not hold every sample of each of its pixels once, so rayscope cannot tell whether that is only another numbering (no mistake) or several samples through the same cell (a mistake); it is not counted against you: log every sample of a few pixels (with the logging kit, leave RAYSCOPE_LOG_SAMPLES unset) to find out"
            };
            let _ = writeln!(
                s,
                "note: {} camera ray{} go{} through the centre of another cell of {} pixel's sub-pixel grid than rayscope's sample of {} number: {conclusion}; the first:",
                g.count,
                plural(g.count),
                if g.count == 1 { "es" } else { "" },
                if g.count == 1 { "its" } else { "their" },
                if g.count == 1 { "its" } else { "their" },
            );
            if let Some(f) = g.examples.first() {
                let _ = writeln!(s, "{}", example(f, trace_command(f)));
            }
            let _ = writeln!(
                s,
                "  rayscope numbers sample s as cell (s mod N, s div N), left to right, then top to bottom; number yours the same way to have the debugger pair your trees with rayscope's sample by sample"
            );
        }
        if self.camera_rays > 0 && self.camera_disagree * 2 > self.camera_rays {
            let _ = writeln!(
                s,
                "note: most camera rays disagree; make sure check gets the same -w, -h, -x, --fov and camera flags your tracer rendered with"
            );
        }
        if self.orphans > 0 {
            let _ = writeln!(
                s,
                "note: {} rays name a parent id not found among the rays of their pixel sample, so how they leave their parent was not judged (write each sample's rays together, ids unique within it)",
                self.orphans
            );
        }
        if self.causes.len() > 1 {
            let _ = writeln!(s, "\n{:>9}  {:>9}  cause (fix the first one first)", "samples", "rays");
            for c in &self.causes {
                let _ = writeln!(s, "{:>9}  {:>9}  {}", c.samples, c.rays, c.name());
            }
        }
        for c in &self.causes {
            cause_text(&mut s, c, trace_command);
        }
        if let Some(i) = &self.image {
            image_text(&mut s, i);
        }
        if let Some(n) = self.next.as_ref().filter(|_| self.disagree == 0) {
            next_text(&mut s, n, self.shaded_judged);
        }
        if !self.tie_verdicts.is_empty() {
            let _ = writeln!(s, "\nties (either answer is right; not counted against you):");
        }
        for g in &self.tie_verdicts {
            let _ = writeln!(
                s,
                "\n{} — {} ray{}",
                g.code.as_str(),
                g.count,
                if g.count == 1 { "" } else { "s" }
            );
            for l in wrap(g.explanation, 96) {
                let _ = writeln!(s, "  {l}");
            }
            for f in &g.examples {
                let _ = writeln!(s, "{}", example(f, trace_command(f)));
            }
            if g.count > g.examples.len() as u64 {
                let _ = writeln!(s, "  … and {} more", g.count - g.examples.len() as u64);
            }
        }
        s
    }
}

/// Writes one cause of a report: its name, explanation, examples, catalogue entries and
/// consequences.
fn cause_text(s: &mut String, c: &CauseGroup, trace_command: &dyn Fn(&Finding) -> Option<String>) {
    let _ = writeln!(
        s,
        "\n{} — the first wrong ray in {} pixel sample{} ({} ray{})",
        c.name(),
        c.samples,
        if c.samples == 1 { "" } else { "s" },
        c.rays,
        if c.rays == 1 { "" } else { "s" }
    );
    let _ = writeln!(s, "  {}", c.summary);
    for l in wrap(&c.explanation, 96) {
        let _ = writeln!(s, "  {l}");
    }
    for f in &c.examples {
        let _ = writeln!(s, "{}", example(f, trace_command(f)));
    }
    if c.rays > c.examples.len() as u64 {
        let _ = writeln!(s, "  … and {} more", c.rays - c.examples.len() as u64);
    }
    if !c.catalogue.is_empty() {
        let names: Vec<String> = c.catalogue.iter().map(|n| format!("'{n}'")).collect();
        for l in wrap(
            &format!(
                "rayscope's catalogue of common mistakes has {} that show{} this way: see what {} does to the picture with `rayscope -f SCENE -o out.png --mistake {}` (rayscope mistakes describes {})",
                names.join(", "),
                if names.len() == 1 { "s" } else { "" },
                if names.len() == 1 { "it" } else { "each" },
                c.catalogue[0],
                if names.len() == 1 { "it" } else { "them" },
            ),
            96,
        ) {
            let _ = writeln!(s, "  {l}");
        }
    }
    if !c.consequences.is_empty() {
        let list: Vec<String> = c
            .consequences
            .iter()
            .map(|k| format!("{} {}", k.count, k.code.as_str()))
            .collect();
        for l in wrap(
            &format!(
                "follows from it (rays below it, or beside it on the same ray; fix the cause first): {}",
                list.join(", ")
            ),
            96,
        ) {
            let _ = writeln!(s, "  {l}");
        }
    }
}

/// Writes the verdict on the student's picture.
fn image_text(s: &mut String, i: &crate::image::ImageCheck) {
    let _ = writeln!(s, "\nyour picture: {}", i.detail);
    if let Some(code) = i.verdict {
        let _ = writeln!(s, "\n{} — {}", code.as_str(), code.summary());
        for l in wrap(code.explanation(), 96) {
            let _ = writeln!(s, "  {l}");
        }
    }
    for e in &i.examples {
        let _ = writeln!(
            s,
            "  pixel ({}, {}): your bytes {:?}, the course's conversion of your logged colour ({:.6}, {:.6}, {:.6}) is {:?}",
            e.pixel[0], e.pixel[1], e.yours, e.colour[0], e.colour[1], e.colour[2], e.expected
        );
    }
}

fn example(f: &Finding, cmd: Option<String>) -> String {
    let mut s = String::new();
    let mut head = format!("  line {}:", f.line);
    if let Some([x, y]) = f.pixel {
        let _ = write!(head, " pixel ({x}, {y})");
    }
    if let Some(sm) = f.sample {
        let _ = write!(head, " sample {sm}");
    }
    // The kind and the details may quote the log: what is printed is made safe for a terminal.
    let _ = write!(head, ", {} ray", printable(&f.kind));
    if let Some(id) = f.id {
        let _ = write!(head, " {id}");
    }
    let _ = writeln!(s, "{head}");
    let _ = writeln!(s, "    {}", printable(&f.detail));
    if !f.values.is_empty() {
        let w = f
            .values
            .iter()
            .map(|v| v.what.chars().count())
            .max()
            .unwrap_or(0)
            .max(4);
        let cells: Vec<(String, String)> = f.values.iter().map(|v| (show(&v.yours), show(&v.rayscope))).collect();
        let yw = cells.iter().map(|c| c.0.chars().count()).max().unwrap_or(0).max(5);
        let _ = writeln!(s, "    {:w$}  {:yw$}  rayscope", "", "yours");
        for (v, (y, r)) in f.values.iter().zip(cells) {
            let _ = writeln!(s, "    {:w$}  {:yw$}  {}", v.what, y, r);
        }
    }
    if let Some(c) = cmd {
        let _ = writeln!(s, "    rayscope's ray tree: {c}");
    }
    s.trim_end().to_string()
}

/// A JSON value as a compact text cell.
fn show(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::String(s) => printable(s).into_owned(),
        serde_json::Value::Array(a) => format!("({})", a.iter().map(show).collect::<Vec<_>>().join(", ")),
        serde_json::Value::Null => "—".into(),
        other => other.to_string(),
    }
}

fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut cur = String::new();
    for w in text.split_whitespace() {
        if !cur.is_empty() && cur.chars().count() + 1 + w.chars().count() > width {
            lines.push(std::mem::take(&mut cur));
        }
        if !cur.is_empty() {
            cur.push(' ');
        }
        cur.push_str(w);
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}
