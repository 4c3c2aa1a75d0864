//! A check kept per pixel, for the debugger: a verdict for every pixel of the image (agrees,
//! only ties, disagrees, not logged) and the rays each pixel's samples logged with their verdicts,
//! in bounded memory.
//!
//! The verdicts are [`crate::check`]'s, ray for ray: a pixel disagrees when any ray of any of its
//! samples has a verdict that is not a tie. Rays are kept for display up to
//! [`PixelOptions::detail_cap`] (the samples with a verdict up to twice that), so a log of any size
//! costs a few bytes per pixel plus the capped detail.

use std::collections::HashMap;
use std::sync::atomic::AtomicBool;

use glam::{DVec3, Vec3A};
use serde::Serialize;

use crate::judge::{Finding, Judge};
use crate::log::{Answer, Kind, LoggedRay, RaySource};
use crate::report::Report;
use crate::verdict::Code;
use crate::{CheckOptions, LogError};

/// A pixel's verdict on the map.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PixelStatus {
    /// The log has no ray for the pixel.
    NotLogged = 0,
    /// Every logged ray of the pixel agrees with rayscope.
    Agrees = 1,
    /// Some rays are genuine ties (not counted against the tracer), none disagrees.
    Tie = 2,
    /// Some ray of the pixel has a verdict.
    Disagrees = 3,
}

impl PixelStatus {
    /// The status stored in `byte` (its low two bits).
    #[must_use]
    pub fn from_byte(byte: u8) -> Self {
        match byte & 3 {
            1 => PixelStatus::Agrees,
            2 => PixelStatus::Tie,
            3 => PixelStatus::Disagrees,
            _ => PixelStatus::NotLogged,
        }
    }

    /// The stable name (`agrees`, `tie`, `disagrees`, `not-logged`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            PixelStatus::NotLogged => "not-logged",
            PixelStatus::Agrees => "agrees",
            PixelStatus::Tie => "tie",
            PixelStatus::Disagrees => "disagrees",
        }
    }
}

/// Bit of a pixel's byte set when some of its rays were not kept (the detail cap).
const DROPPED: u8 = 4;

/// One logged ray as the debugger shows it: what the tracer said, where it ends, its verdicts.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ShownRay {
    /// Line (or ray number) in the log.
    pub line: u64,
    /// Sample within the pixel, when logged.
    pub sample: Option<u32>,
    /// The ray's id, when logged.
    pub id: Option<i64>,
    /// Its parent's id, when logged.
    pub parent: Option<i64>,
    /// Its kind, as logged or inferred (`camera`, `shadow`, `reflection`, `refraction`, …).
    pub kind: String,
    /// Origin.
    pub origin: [f64; 3],
    /// Unit direction.
    pub direction: [f64; 3],
    /// Where the tracer says the ray ends: its hit point (logged, or origin + t · direction), the
    /// end of a `from`/`to` segment, or the light a shadow ray reaches.
    pub end: Option<[f64; 3]>,
    /// The entity the tracer says it hit (`None`: not logged or nothing).
    pub entity: Option<String>,
    /// What the tracer said, in words ("hit 'Sphere' at t = 2.5", "missed", "light 'Key' blocked
    /// by 'Wall'", "not logged").
    pub answer: String,
    /// Shadow rays: the light's index.
    pub light: Option<u32>,
    /// The ray's verdicts, ties included.
    pub findings: Vec<Finding>,
}

impl ShownRay {
    /// True when a verdict that is not a tie was given.
    #[must_use]
    pub fn disagrees(&self) -> bool {
        self.findings.iter().any(|f| !f.code.is_excused())
    }
}

fn a3(v: DVec3) -> [f64; 3] {
    v.to_array()
}

/// A ray distance as a person reads it: four decimals, and a distance too small for them in
/// scientific notation, so that a hit just behind the origin never reads "-0".
#[must_use]
pub fn fmt_t(t: f64) -> String {
    let r = (t * 1e4).round() / 1e4;
    if r == 0.0 && t != 0.0 {
        format!("{t:.1e}")
    } else {
        // `r + 0.0` turns -0 into 0.
        format!("{}", r + 0.0)
    }
}

/// The display form of a logged ray.
#[must_use]
pub fn shown_ray(judge: &Judge<'_>, r: &LoggedRay, findings: Vec<Finding>) -> ShownRay {
    let scene = judge.scene();
    let ename = |e: u32| {
        scene
            .entities
            .get(e as usize)
            .map_or("?".to_string(), |x| x.name.clone())
    };
    let lname = |l: u32| scene.light_names.get(l as usize).map_or("?".to_string(), Clone::clone);
    let kind = judge.kind_of(r);
    let mut end = None;
    let mut entity = None;
    let answer = match r.hit {
        Answer::Found(h) => {
            let p = h
                .point
                .or_else(|| h.t.map(|t| r.origin + r.direction * (t * r.dir_len)));
            end = p.map(a3);
            entity = h.entity.map(ename);
            let t =
                h.t.map(|t| t * r.dir_len)
                    .or_else(|| h.point.map(|p| (p - r.origin).dot(r.direction)));
            match (&entity, t) {
                (Some(e), Some(t)) => format!("hit '{e}' at t = {}", fmt_t(t)),
                (Some(e), None) => format!("hit '{e}'"),
                (None, Some(t)) => format!("hit at t = {}", fmt_t(t)),
                (None, None) => "hit".to_string(),
            }
        }
        Answer::Nothing => "missed".to_string(),
        Answer::NotLogged => match r.end {
            Some(e) => {
                end = Some(a3(e));
                "segment".to_string()
            }
            None => String::new(),
        },
    };
    let mut answer = answer;
    if kind == Kind::Shadow {
        let light = r.light.map(lname).unwrap_or_else(|| "a light".into());
        let light_end = r
            .light
            .and_then(|l| scene.lights.get(l as usize))
            .map(|l| a3(crate::geom::d3(Vec3A::from(l.position))));
        let said = match r.blocked_by {
            Answer::Found(Some(e)) => format!("light {light} blocked by '{}'", ename(e)),
            Answer::Found(None) => format!("light {light} blocked"),
            Answer::Nothing => format!("light {light} reached"),
            Answer::NotLogged => String::new(),
        };
        if matches!(r.blocked_by, Answer::Nothing) && end.is_none() {
            end = light_end;
        }
        if !said.is_empty() {
            answer = if answer.is_empty() {
                said
            } else {
                format!("{said}; {answer}")
            };
        }
        if end.is_none() {
            end = light_end;
        }
    }
    if answer.is_empty() {
        answer = "not logged".into();
    }
    ShownRay {
        line: r.line,
        sample: r.sample,
        id: r.id,
        parent: r.parent,
        kind: kind.name().to_string(),
        origin: a3(r.origin),
        direction: a3(r.direction),
        end,
        entity,
        answer,
        light: r.light,
        findings,
    }
}

/// Options of a per-pixel check.
#[derive(Debug, Clone, Copy)]
pub struct PixelOptions {
    /// Examples kept per verdict code in the report.
    pub examples: usize,
    /// Rays kept for display; samples with a verdict are kept up to twice as many.
    pub detail_cap: usize,
}

impl Default for PixelOptions {
    /// 3 examples; 500,000 rays kept (about 100 MB at most).
    fn default() -> Self {
        Self {
            examples: 3,
            detail_cap: 500_000,
        }
    }
}

/// A check's verdicts per pixel and the rays kept for display.
#[derive(Debug, Clone)]
pub struct PixelLog {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Per pixel, row-major from the top-left: the [`PixelStatus`] in the low two bits, and bit 2
    /// set when some of the pixel's rays were not kept.
    pub status: Vec<u8>,
    /// Per pixel: 1 + the index in [`Code::ALL`] of the first verdict (by line) that is not a
    /// tie; 0 for none.
    pub first_code: Vec<u8>,
    /// The rays kept, per pixel, in log order.
    pub rays: HashMap<[u32; 2], Vec<ShownRay>>,
    /// Rays kept.
    pub kept: u64,
    /// Rays judged but not kept (over the cap).
    pub dropped: u64,
    /// Rays without a pixel (judged, not on the map).
    pub unplaced: u64,
    /// The whole log's report, as `rayscope check` prints it.
    pub report: Report,
}

impl PixelLog {
    /// The pixel's status.
    #[must_use]
    pub fn status_at(&self, x: u32, y: u32) -> PixelStatus {
        if x >= self.width || y >= self.height {
            return PixelStatus::NotLogged;
        }
        PixelStatus::from_byte(self.status[(y * self.width + x) as usize])
    }

    /// True when some of the pixel's rays were judged but not kept.
    #[must_use]
    pub fn dropped_at(&self, x: u32, y: u32) -> bool {
        x < self.width && y < self.height && self.status[(y * self.width + x) as usize] & DROPPED != 0
    }

    /// The pixel's first verdict that is not a tie.
    #[must_use]
    pub fn code_at(&self, x: u32, y: u32) -> Option<Code> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let c = self.first_code[(y * self.width + x) as usize];
        (c > 0).then(|| Code::ALL.get(c as usize - 1).copied()).flatten()
    }

    /// Pixels per status: not logged, agrees, tie, disagrees.
    #[must_use]
    pub fn counts(&self) -> [u64; 4] {
        let mut n = [0u64; 4];
        for &b in &self.status {
            n[(b & 3) as usize] += 1;
        }
        n
    }
}

/// Reads every ray of `source`, judges it with `judge` like [`crate::check`], and keeps the
/// verdicts per pixel of the `judge`'s image. `None` when `cancel` was set.
pub fn check_pixels(
    judge: &Judge<'_>,
    source: &mut (dyn RaySource + Send),
    opts: PixelOptions,
    progress: &dyn Fn(u64, u64),
    cancel: &AtomicBool,
) -> Result<Option<PixelLog>, LogError> {
    let s = judge.settings();
    let (w, h) = (s.width, s.height);
    let n = w as usize * h as usize;
    let mut status = vec![0u8; n];
    let mut first: Vec<(u64, u8)> = vec![(u64::MAX, 0); n];
    // Per pixel, the first line of a camera ray numbered as another cell's sample (`u64::MAX`:
    // none).
    let mut first_order = vec![u64::MAX; n];
    let mut rays: HashMap<[u32; 2], Vec<ShownRay>> = HashMap::new();
    let (mut kept, mut dropped, mut unplaced) = (0u64, 0u64, 0u64);
    let cap = opts.detail_cap as u64;
    let mut sink = |group: Vec<LoggedRay>, findings: Vec<Vec<Finding>>| {
        let Some([x, y]) = group.first().and_then(|r| r.pixel) else {
            unplaced += group.len() as u64;
            return;
        };
        if x >= w || y >= h {
            unplaced += group.len() as u64;
            return;
        }
        let i = (y * w + x) as usize;
        let mut st = PixelStatus::Agrees;
        for (r, f) in group.iter().zip(&findings) {
            for v in f {
                if v.code == Code::CameraSampleOrder {
                    // A numbering or a mistake, as the whole log decides (below).
                    first_order[i] = first_order[i].min(r.line);
                } else if v.code.is_tie() {
                    st = st.max(PixelStatus::Tie);
                } else {
                    st = PixelStatus::Disagrees;
                    if r.line < first[i].0 {
                        let c = Code::ALL.iter().position(|&c| c == v.code).unwrap_or(0);
                        first[i] = (r.line, c as u8 + 1);
                    }
                }
            }
        }
        let old = status[i];
        status[i] = (old & DROPPED) | (old & 3).max(st as u8);
        let len = group.len() as u64;
        let limit = if st == PixelStatus::Disagrees { 2 * cap } else { cap };
        if kept + len <= limit {
            kept += len;
            let e = rays.entry([x, y]).or_default();
            for (r, f) in group.iter().zip(findings) {
                e.push(shown_ray(judge, r, f));
            }
        } else {
            dropped += len;
            status[i] |= DROPPED;
        }
    };
    let report = crate::run(
        judge,
        source,
        CheckOptions {
            examples: opts.examples,
        },
        progress,
        cancel,
        Some(&mut sink),
    )?;
    let Some(report) = report else {
        return Ok(None);
    };
    if report.renumbered.is_none() {
        // Not a numbering: those rays are the mistake the report names.
        let to = report
            .causes
            .iter()
            .map(|c| c.code)
            .find(|&c| matches!(c, Code::CameraSubpixelGrid | Code::CameraOnePoint))
            .unwrap_or(Code::CameraSubpixelGrid);
        let c = Code::ALL.iter().position(|&c| c == to).unwrap_or(0) as u8 + 1;
        for i in (0..n).filter(|&i| first_order[i] != u64::MAX) {
            status[i] = (status[i] & DROPPED) | PixelStatus::Disagrees as u8;
            if first_order[i] < first[i].0 {
                first[i] = (first_order[i], c);
            }
        }
    }
    for v in rays.values_mut() {
        v.sort_by_key(|r| r.line);
    }
    Ok(Some(PixelLog {
        width: w,
        height: h,
        spp: judge.samples_per_pixel(),
        status,
        first_code: first.into_iter().map(|(_, c)| c).collect(),
        rays,
        kept,
        dropped,
        unplaced,
        report,
    }))
}

/// Which trees a row of an [`Alignment`] has a ray in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Shape {
    /// Both: the student's ray and rayscope's that corresponds to it.
    Both,
    /// Only the student's tracer cast this ray.
    OnlyYours,
    /// Only rayscope cast this ray.
    OnlyRayscope,
}

/// One row of two ray trees side by side.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AlignedRow {
    /// Depth in the tree (camera rays 0).
    pub depth: u32,
    /// The student's ray: index into the rays aligned.
    pub yours: Option<usize>,
    /// rayscope's ray: its id in the [`rayscope_core::RayTree`].
    pub rayscope: Option<u32>,
    /// Which side has a ray.
    pub shape: Shape,
    /// The student's ray's verdict: `agrees`, `tie` or `disagrees` (`None` without a ray).
    pub verdict: Option<PixelStatus>,
}

/// The student's rays of one pixel sample beside rayscope's ray tree for it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Alignment {
    /// Rows in rayscope's tree order (depth first), the student's extra rays under their parent.
    pub rows: Vec<AlignedRow>,
    /// The row where the trees first part: the shallowest ray with a verdict, else the shallowest
    /// ray only one side cast.
    pub divergence: Option<usize>,
}

fn angle3(a: [f64; 3], b: [f32; 3]) -> f64 {
    let a = DVec3::from(a).normalize_or_zero();
    let b = DVec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2])).normalize_or_zero();
    a.dot(b).clamp(-1.0, 1.0).acos()
}

fn dist3(a: [f64; 3], b: [f32; 3]) -> f64 {
    (DVec3::from(a) - DVec3::new(f64::from(b[0]), f64::from(b[1]), f64::from(b[2]))).length()
}

/// Aligns the student's rays of one pixel sample (`yours`, in log order) with rayscope's tree of
/// the same sample. `light_names` are the scene's lights, to pair shadow rays by light.
///
/// Rays pair when they have the same kind (shadow rays the same light) and hang under paired
/// parents, the closest in origin and direction first; without `parent` links the student's rays
/// pair with rayscope's of the same kind that start within 5 % of the scene scale of them.
#[must_use]
pub fn align(yours: &[ShownRay], tree: &rayscope_core::RayTree, light_names: &[String]) -> Alignment {
    let nodes = &tree.nodes;
    let Trees {
        parent,
        kids,
        roots,
        rs_kids,
        rs_roots,
    } = trees(yours, nodes);
    let same = |s: &ShownRay, n: &rayscope_core::RayNode| {
        if s.kind != n.kind.name() {
            return false;
        }
        match (s.light, &n.light) {
            (Some(l), Some(name)) => light_names.get(l as usize).is_some_and(|x| x == name),
            _ => true,
        }
    };
    let score = |s: &ShownRay, n: &rayscope_core::RayNode| angle3(s.direction, n.direction) + dist3(s.origin, n.origin);
    let mut mine: Vec<Option<usize>> = vec![None; yours.len()];
    let mut theirs: Vec<Option<usize>> = vec![None; nodes.len()];
    // Greedy pairing of two sibling lists, best score first.
    let pair = |a: &[usize], b: &[usize], mine: &mut Vec<Option<usize>>, theirs: &mut Vec<Option<usize>>| {
        let mut c: Vec<(f64, usize, usize)> = Vec::new();
        for &i in a {
            for &j in b {
                if mine[i].is_none() && theirs[j].is_none() && same(&yours[i], &nodes[j]) {
                    c.push((score(&yours[i], &nodes[j]), i, j));
                }
            }
        }
        c.sort_by(|x, y| x.0.total_cmp(&y.0));
        let mut out = Vec::new();
        for (_, i, j) in c {
            if mine[i].is_none() && theirs[j].is_none() {
                mine[i] = Some(j);
                theirs[j] = Some(i);
                out.push((i, j));
            }
        }
        out
    };
    let mut stack = pair(&roots, &rs_roots, &mut mine, &mut theirs);
    while let Some((i, j)) = stack.pop() {
        let more = pair(&kids[i], &rs_kids[j], &mut mine, &mut theirs);
        stack.extend(more);
    }
    pair_by_origin(yours, nodes, &parent, &mut mine, &mut theirs, &same, &score);

    let verdict = |i: usize| {
        let f = &yours[i].findings;
        Some(if f.iter().any(|f| !f.code.is_tie()) {
            PixelStatus::Disagrees
        } else if f.is_empty() {
            PixelStatus::Agrees
        } else {
            PixelStatus::Tie
        })
    };
    let mut rows = Vec::new();
    let mut placed = vec![false; yours.len()];
    // Depth first over rayscope's tree.
    let mut todo: Vec<(usize, u32)> = rs_roots.iter().rev().map(|&j| (j, 0)).collect();
    while let Some((j, depth)) = todo.pop() {
        let i = theirs[j];
        if let Some(i) = i {
            placed[i] = true;
        }
        rows.push(AlignedRow {
            depth,
            yours: i,
            rayscope: Some(nodes[j].id),
            shape: if i.is_some() { Shape::Both } else { Shape::OnlyRayscope },
            verdict: i.and_then(verdict),
        });
        if let Some(i) = i {
            for &k in &kids[i] {
                if mine[k].is_none() {
                    only_yours(k, depth + 1, &kids, &mine, &mut placed, &mut rows, &verdict);
                }
            }
        }
        for &k in rs_kids[j].iter().rev() {
            todo.push((k, depth + 1));
        }
    }
    for i in 0..yours.len() {
        if !placed[i] && mine[i].is_none() && parent[i].is_none() {
            only_yours(i, 0, &kids, &mine, &mut placed, &mut rows, &verdict);
        }
    }
    for i in 0..yours.len() {
        if !placed[i] {
            only_yours(i, 0, &kids, &mine, &mut placed, &mut rows, &verdict);
        }
    }
    let first = |f: &dyn Fn(&AlignedRow) -> bool| {
        rows.iter()
            .enumerate()
            .filter(|(_, r)| f(r))
            .min_by_key(|(k, r)| (r.depth, *k))
            .map(|(k, _)| k)
    };
    let divergence =
        first(&|r| r.verdict == Some(PixelStatus::Disagrees)).or_else(|| first(&|r| r.shape != Shape::Both));
    Alignment { rows, divergence }
}

/// Pairs the rays the tree walk left unpaired (a log without parent links) by kind and origin,
/// closest first.
fn pair_by_origin(
    yours: &[ShownRay],
    nodes: &[rayscope_core::RayNode],
    parent: &[Option<usize>],
    mine: &mut [Option<usize>],
    theirs: &mut [Option<usize>],
    same: &dyn Fn(&ShownRay, &rayscope_core::RayNode) -> bool,
    score: &dyn Fn(&ShownRay, &rayscope_core::RayNode) -> f64,
) {
    let scale = nodes
        .iter()
        .map(|n| n.origin.iter().fold(1.0f64, |m, v| m.max(f64::from(v.abs()))))
        .fold(1.0, f64::max);
    let mut c: Vec<(f64, usize, usize)> = Vec::new();
    for (i, s) in yours.iter().enumerate() {
        if mine[i].is_some() || parent[i].is_some_and(|p| mine[p].is_some()) {
            continue;
        }
        for (j, n) in nodes.iter().enumerate() {
            if theirs[j].is_none() && same(s, n) && dist3(s.origin, n.origin) <= 0.05 * scale {
                c.push((score(s, n), i, j));
            }
        }
    }
    c.sort_by(|x, y| x.0.total_cmp(&y.0));
    for (_, i, j) in c {
        if mine[i].is_none() && theirs[j].is_none() {
            mine[i] = Some(j);
            theirs[j] = Some(i);
        }
    }
}

/// The parent links of both trees, as child lists and roots.
struct Trees {
    parent: Vec<Option<usize>>,
    kids: Vec<Vec<usize>>,
    roots: Vec<usize>,
    rs_kids: Vec<Vec<usize>>,
    rs_roots: Vec<usize>,
}

/// The student's rays `yours` and rayscope's `nodes` as trees; a link to a missing ray or to
/// itself makes a root.
fn trees(yours: &[ShownRay], nodes: &[rayscope_core::RayNode]) -> Trees {
    let ids: HashMap<i64, usize> = yours
        .iter()
        .enumerate()
        .filter_map(|(i, r)| r.id.map(|id| (id, i)))
        .collect();
    let parent: Vec<Option<usize>> = yours
        .iter()
        .enumerate()
        .map(|(i, r)| r.parent.and_then(|p| ids.get(&p).copied()).filter(|&p| p != i))
        .collect();
    let mut kids: Vec<Vec<usize>> = vec![Vec::new(); yours.len()];
    let mut roots = Vec::new();
    for (i, p) in parent.iter().enumerate() {
        match p {
            Some(p) => kids[*p].push(i),
            None => roots.push(i),
        }
    }
    let mut rs_kids: Vec<Vec<usize>> = vec![Vec::new(); nodes.len()];
    let mut rs_roots = Vec::new();
    for (i, n) in nodes.iter().enumerate() {
        match n.parent.map(|p| p as usize).filter(|&p| p < nodes.len() && p != i) {
            Some(p) => rs_kids[p].push(i),
            None => rs_roots.push(i),
        }
    }
    Trees {
        parent,
        kids,
        roots,
        rs_kids,
        rs_roots,
    }
}

/// Adds the student's own subtree under ray `i`, none of it paired, to `rows`.
fn only_yours(
    i: usize,
    depth: u32,
    kids: &[Vec<usize>],
    mine: &[Option<usize>],
    placed: &mut [bool],
    rows: &mut Vec<AlignedRow>,
    verdict: &dyn Fn(usize) -> Option<PixelStatus>,
) {
    if placed[i] || depth > 64 {
        return;
    }
    placed[i] = true;
    rows.push(AlignedRow {
        depth,
        yours: Some(i),
        rayscope: None,
        shape: Shape::OnlyYours,
        verdict: verdict(i),
    });
    for &k in &kids[i] {
        if mine[k].is_none() {
            only_yours(k, depth + 1, kids, mine, placed, rows, verdict);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances_read_as_a_person_reads_them() {
        assert_eq!(fmt_t(2.5), "2.5");
        assert_eq!(fmt_t(1.234_56), "1.2346");
        assert_eq!(fmt_t(0.0), "0");
        assert_eq!(fmt_t(-0.0), "0");
        // Behind the origin, however little: the sign shows.
        assert_eq!(fmt_t(-0.000_012), "-1.2e-5");
        assert_eq!(fmt_t(0.000_03), "3.0e-5");
        assert_eq!(fmt_t(-0.25), "-0.25");
    }
}
