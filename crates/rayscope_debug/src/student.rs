//! A student's own ray log and image in the debugger and in `rayscope view`.
//!
//! The log is judged once with rayscope_check's verdict engine ([`rayscope_check::check_pixels`]),
//! which keeps a verdict per pixel and the rays of each pixel (up to a cap). From that this module
//! makes what the views show: the verdict map (an image and a tint for the image plane's grid),
//! the student's rays of a pixel as dashed lines beside rayscope's ray tree, and the two trees
//! aligned row by row with the first divergence explained.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use glam::Vec3;
use rayscope_check::log::{BinaryReader, IdRole, JsonlReader};
use rayscope_check::{
    align, Alignment, Judge, LogContext, LogError, PixelLog, PixelOptions, PixelStatus, Shape, ShownRay,
};
use rayscope_core::{RayTree, RenderSettings, Scene};
use serde::Serialize;
use serde_json::{json, Value};

use crate::view::{kind_color_named, ForeignRay, RgbImage};

/// What `rayscope debug` loads besides the scene: the student's ray log and image.
#[derive(Debug, Clone, Default)]
pub struct StudentInput {
    /// The ray log (JSON Lines, or RayTracer.Debug's `.rays`), judged when the debugger starts.
    pub rays: Option<PathBuf>,
    /// The student's rendered image.
    pub image: Option<RgbImage>,
    /// What a `.rays` file's ids mean (default x, y).
    pub ray_ids: Vec<IdRole>,
    /// Skip malformed lines instead of refusing the log.
    pub lenient: bool,
}

/// The default roles of a `.rays` file's ids, as `rayscope check --ray-ids` has them.
#[must_use]
pub fn default_ray_ids() -> Vec<IdRole> {
    vec![IdRole::X, IdRole::Y]
}

/// Judges a log read from `src` (`name` in messages, `total` bytes when known) for `scene`
/// rendered with `settings`; `binary` for a `.rays` file. `None` when `cancel` was set.
///
/// # Errors
/// A malformed log (the message names the line), or an unreadable one.
#[allow(clippy::too_many_arguments)]
pub fn judge_reader<R: Read + Send>(
    scene: &Scene,
    settings: &RenderSettings,
    src: R,
    name: &Path,
    total: u64,
    binary: bool,
    roles: &[IdRole],
    lenient: bool,
    opts: PixelOptions,
    progress: &dyn Fn(u64, u64),
    cancel: &AtomicBool,
) -> Result<Option<PixelLog>, LogError> {
    let judge = Judge::new(scene, settings);
    let ctx = LogContext::new(
        scene,
        settings.width,
        settings.height,
        judge.samples_per_pixel(),
        settings.aa,
    );
    if binary {
        let mut s = BinaryReader::new(src, name, total, ctx, roles);
        rayscope_check::check_pixels(&judge, &mut s, opts, progress, cancel)
    } else {
        let mut s = JsonlReader::new(src, name, total, ctx, lenient);
        rayscope_check::check_pixels(&judge, &mut s, opts, progress, cancel)
    }
}

/// True when `path` names a RayTracer.Debug `.rays` file (else JSON Lines), as `rayscope check`
/// decides.
#[must_use]
pub fn is_binary_log(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rays"))
}

/// Judges the log file at `path`.
///
/// # Errors
/// See [`judge_reader`].
pub fn judge_file(
    scene: &Scene,
    settings: &RenderSettings,
    path: &Path,
    roles: &[IdRole],
    lenient: bool,
    progress: &dyn Fn(u64, u64),
    cancel: &AtomicBool,
) -> Result<Option<PixelLog>, LogError> {
    // Only a regular file: a device or a pipe would never end.
    let (file, total) = rayscope_check::log::open_file(path)?;
    judge_reader(
        scene,
        settings,
        std::io::BufReader::with_capacity(1 << 20, file),
        path,
        total,
        is_binary_log(path),
        roles,
        lenient,
        // The debugger's cap on rays kept for display, so `view --rays-log` has its budget.
        PixelOptions {
            detail_cap: crate::server::RAY_DETAIL_CAP,
            ..PixelOptions::default()
        },
        progress,
        cancel,
    )
}

/// A verdict's colour on the map and the grid.
#[must_use]
pub fn status_color(s: PixelStatus) -> [u8; 3] {
    match s {
        PixelStatus::NotLogged => [70, 70, 76],
        PixelStatus::Agrees => [46, 204, 113],
        PixelStatus::Tie => [241, 196, 15],
        PixelStatus::Disagrees => [255, 38, 38],
    }
}

/// The verdict map as an image: a pixel per image pixel in [`status_color`].
#[must_use]
pub fn verdict_map(log: &PixelLog) -> RgbImage {
    let mut rgb = Vec::with_capacity(log.status.len() * 3);
    for &b in &log.status {
        rgb.extend_from_slice(&status_color(PixelStatus::from_byte(b)));
    }
    RgbImage {
        width: log.width,
        height: log.height,
        rgb,
    }
}

/// The verdict map as a tint of the image plane's grid cells: red over the cells that disagree,
/// amber over ties, a light green over those that agree, nothing where nothing was logged.
#[must_use]
pub fn verdict_tint(log: &PixelLog) -> Vec<[u8; 4]> {
    log.status
        .iter()
        .map(|&b| {
            let s = PixelStatus::from_byte(b);
            let [r, g, bl] = status_color(s);
            let a = match s {
                PixelStatus::NotLogged => 0,
                PixelStatus::Agrees => 70,
                PixelStatus::Tie => 140,
                PixelStatus::Disagrees => 190,
            };
            [r, g, bl, a]
        })
        .collect()
}

/// The samples the log has rays for at pixel (`x`, `y`), in order (`None`: rays without a sample).
#[must_use]
pub fn samples_at(log: &PixelLog, x: u32, y: u32) -> Vec<Option<u32>> {
    let mut v: Vec<Option<u32>> = log
        .rays
        .get(&[x, y])
        .map(|r| r.iter().map(|r| r.sample).collect())
        .unwrap_or_default();
    v.sort_unstable();
    v.dedup();
    v
}

/// The sample to show at a pixel: `want` when logged, else the first sample with a verdict, else
/// the first logged.
#[must_use]
pub fn pick_sample(log: &PixelLog, x: u32, y: u32, want: Option<u32>) -> Option<Option<u32>> {
    let samples = samples_at(log, x, y);
    if let Some(w) = want {
        if samples.contains(&Some(w)) {
            return Some(Some(w));
        }
        if samples == [None] {
            return Some(None);
        }
    }
    let rays = log.rays.get(&[x, y])?;
    rays.iter()
        .find(|r| r.disagrees())
        .map(|r| r.sample)
        .or_else(|| samples.first().copied())
}

/// The rays of one sample of a pixel, in log order.
#[must_use]
pub fn sample_rays(log: &PixelLog, x: u32, y: u32, sample: Option<u32>) -> Vec<ShownRay> {
    log.rays
        .get(&[x, y])
        .map(|r| r.iter().filter(|r| r.sample == sample).cloned().collect())
        .unwrap_or_default()
}

/// Most of a sample's rays one comparison shows: a pixel's tree rarely has more than a few
/// hundred, and a log with hundreds of thousands in one pixel must not turn one request into
/// hundreds of megabytes (the rest are paged with [`RayPage::offset`]).
pub const PAGE_RAYS: usize = 1000;
/// Most samples a comparison lists (all are counted).
pub const LISTED_SAMPLES: usize = 1024;

/// Which of a sample's rays a comparison shows: `limit` of them from `offset`, in log order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RayPage {
    /// Rays of the sample skipped before the first shown.
    pub offset: usize,
    /// Most rays shown (at most [`PAGE_RAYS`]).
    pub limit: usize,
}

impl Default for RayPage {
    /// The first [`PAGE_RAYS`] rays.
    fn default() -> Self {
        Self {
            offset: 0,
            limit: PAGE_RAYS,
        }
    }
}

/// One page of the rays of one sample of a pixel, in log order, and how many rays the sample
/// has in all; only the page is copied.
#[must_use]
pub fn sample_rays_page(log: &PixelLog, x: u32, y: u32, sample: Option<u32>, page: RayPage) -> (Vec<ShownRay>, usize) {
    let Some(rays) = log.rays.get(&[x, y]) else {
        return (Vec::new(), 0);
    };
    let limit = page.limit.min(PAGE_RAYS);
    let mut shown = Vec::with_capacity(limit.min(rays.len()));
    let mut total = 0;
    for r in rays.iter().filter(|r| r.sample == sample) {
        if total >= page.offset && shown.len() < limit {
            shown.push(r.clone());
        }
        total += 1;
    }
    (shown, total)
}

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0] as f32, a[1] as f32, a[2] as f32)
}

/// The student's rays as dashed view lines in their kinds' colours; `highlight` (an index into
/// `rays`) is the first divergent ray.
#[must_use]
pub fn foreign_rays(rays: &[ShownRay], highlight: Option<usize>) -> Vec<ForeignRay> {
    rays.iter()
        .enumerate()
        .map(|(i, r)| ForeignRay {
            origin: v3(r.origin),
            direction: v3(r.direction),
            end: r.end.map(v3),
            color: kind_color_named(&r.kind),
            highlight: Some(i) == highlight,
        })
        .collect()
}

/// At most `max` of the log's camera rays, from pixels spread evenly over the image (those that
/// disagree first), with their secondary rays: what `rayscope view --rays-log` draws without a
/// pixel.
#[must_use]
pub fn overview_rays(log: &PixelLog, max: usize) -> Vec<ForeignRay> {
    let mut pixels: Vec<&[u32; 2]> = log.rays.keys().collect();
    pixels.sort_by_key(|p| (p[1], p[0]));
    let (bad, good): (Vec<&[u32; 2]>, Vec<&[u32; 2]>) = pixels
        .into_iter()
        .partition(|p| log.status_at(p[0], p[1]) == PixelStatus::Disagrees);
    let mut out = Vec::new();
    for list in [bad, good] {
        if out.len() >= max || list.is_empty() {
            continue;
        }
        let per = log.rays.get(list[0]).map_or(1, Vec::len).max(1);
        let room = (max - out.len()) / per;
        let stride = list.len().div_ceil(room.max(1)).max(1);
        for p in list.iter().step_by(stride) {
            if let Some(rays) = log.rays.get(*p) {
                let hl = rays.iter().position(ShownRay::disagrees);
                out.extend(foreign_rays(rays, hl));
            }
            if out.len() >= max {
                break;
            }
        }
    }
    out
}

/// What a ray of rayscope's tree did, in words, like [`ShownRay::answer`].
fn rs_answer(n: &rayscope_core::RayNode) -> String {
    match (&n.hit, &n.light, &n.blocked_by) {
        (_, Some(l), Some(b)) => format!("light '{l}' blocked by '{b}'"),
        (_, Some(l), None) => format!("light '{l}' reached"),
        (Some(h), _, _) => format!(
            "hit '{}' at t = {}",
            h.entity_name,
            rayscope_check::pixels::fmt_t(f64::from(h.t))
        ),
        (None, _, _) => "missed".into(),
    }
}

/// The first divergence of an [`Alignment`], explained for a student.
#[derive(Debug, Clone, Serialize)]
pub struct Divergence {
    /// Row of the alignment.
    pub row: usize,
    /// The verdict code (`None`: the trees differ in shape only, which is no verdict).
    pub code: Option<&'static str>,
    /// One line: what was found.
    pub summary: String,
    /// The likely mistake and its fix (a verdict's explanation).
    pub explanation: String,
    /// What exactly is wrong with this ray.
    pub detail: String,
    /// The tracer's numbers beside rayscope's.
    pub values: Vec<rayscope_check::Value>,
}

/// The student's rays of one pixel sample beside rayscope's tree for it.
#[derive(Debug, Clone, Serialize)]
pub struct PixelComparison {
    /// Pixel column.
    pub x: u32,
    /// Pixel row.
    pub y: u32,
    /// The pixel's verdict.
    pub status: PixelStatus,
    /// The pixel's first verdict code.
    pub code: Option<&'static str>,
    /// Samples logged at the pixel (`null`: without a sample).
    pub samples: Vec<Option<u32>>,
    /// Samples logged at the pixel in all (`samples` lists at most [`LISTED_SAMPLES`]).
    pub samples_total: usize,
    /// The sample shown.
    pub sample: Option<u32>,
    /// Some of the pixel's rays were judged but not kept (the detail cap).
    pub dropped: bool,
    /// Rays of the sample kept in all (`yours` is one page of them).
    pub rays_total: usize,
    /// Rays of the sample before `yours` (the page's start).
    pub offset: usize,
    /// Rays of the sample after `yours`: ask for them with `offset`.
    pub more: usize,
    /// The student's rays of the sample, in log order: at most [`PAGE_RAYS`] of them from
    /// `offset` (aligned with rayscope's tree as a page of their own).
    pub yours: Vec<ShownRay>,
    /// rayscope's ray tree of the sample.
    pub rayscope: RayTree,
    /// rayscope's rays in words, by node id.
    pub rayscope_answers: Vec<String>,
    /// The two aligned.
    pub alignment: Alignment,
    /// Where they part, explained.
    pub divergence: Option<Divergence>,
}

/// Compares the student's rays of pixel (`x`, `y`) with rayscope's tree, for sample `want` (else
/// the first one with a verdict): the first [`PAGE_RAYS`] rays of the sample.
#[must_use]
pub fn compare_pixel(
    scene: &Scene,
    settings: &RenderSettings,
    log: &PixelLog,
    x: u32,
    y: u32,
    want: Option<u32>,
) -> PixelComparison {
    compare_pixel_page(scene, settings, log, x, y, want, RayPage::default())
}

/// [`compare_pixel`] for one page of the sample's rays.
#[must_use]
pub fn compare_pixel_page(
    scene: &Scene,
    settings: &RenderSettings,
    log: &PixelLog,
    x: u32,
    y: u32,
    want: Option<u32>,
    page: RayPage,
) -> PixelComparison {
    let picked = pick_sample(log, x, y, want);
    let sample = picked.flatten();
    let (yours, rays_total) = sample_rays_page(log, x, y, picked.unwrap_or(None), page);
    let offset = page.offset.min(rays_total);
    let more = rays_total - offset - yours.len();
    let mut samples = samples_at(log, x, y);
    let samples_total = samples.len();
    samples.truncate(LISTED_SAMPLES);
    let spp = log.spp.max(1);
    let rs_sample = sample.filter(|&s| s < spp).unwrap_or(0);
    let tree = rayscope_core::trace_pixel_with(scene, scene, settings, x, y, rs_sample);
    let alignment = align(&yours, &tree, &scene.light_names);
    let divergence = alignment.divergence.map(|row| explain(&alignment, row, &yours, &tree));
    PixelComparison {
        x,
        y,
        status: log.status_at(x, y),
        code: log.code_at(x, y).map(|c| c.as_str()),
        samples,
        samples_total,
        sample,
        dropped: log.dropped_at(x, y),
        rays_total,
        offset,
        more,
        rayscope_answers: tree.nodes.iter().map(rs_answer).collect(),
        yours,
        rayscope: tree,
        alignment,
        divergence,
    }
}

fn explain(a: &Alignment, row: usize, yours: &[ShownRay], tree: &RayTree) -> Divergence {
    let r = &a.rows[row];
    if let Some(f) = r
        .yours
        .and_then(|i| yours[i].findings.iter().find(|f| !f.code.is_tie()))
    {
        return Divergence {
            row,
            code: Some(f.code.as_str()),
            summary: f.code.summary().to_string(),
            explanation: f.code.explanation().to_string(),
            detail: format!("your {} ray (line {}) {}", f.kind, f.line, f.detail),
            values: f.values.clone(),
        };
    }
    let caveat = "This is no verdict: rayscope does not cast shadow rays towards lights behind the surface, prunes branches that carry less than 1/4096 of the sample, and stops at its depth limit (set in the inspector); a tracer may differ in these and still be right. Check it if your picture differs here.";
    let (summary, detail) = match r.shape {
        Shape::OnlyRayscope => {
            let n = r.rayscope.and_then(|id| tree.nodes.get(id as usize));
            let parent = n
                .and_then(|n| n.parent)
                .and_then(|p| tree.nodes.get(p as usize))
                .and_then(|p| p.hit.as_ref())
                .map(|h| format!(" from its hit on '{}'", h.entity_name))
                .unwrap_or_default();
            let kind = n.map_or("?".to_string(), |n| {
                serde_json::to_value(n.kind)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_lowercase))
                    .unwrap_or_default()
            });
            (
                format!("rayscope casts a {kind} ray that your log does not have"),
                format!("rayscope casts a {kind} ray{parent} here; your tracer logged none like it"),
            )
        }
        _ => {
            let s = r.yours.map(|i| &yours[i]);
            let kind = s.map_or("?", |s| s.kind.as_str());
            (
                format!("your tracer casts a {kind} ray that rayscope does not"),
                format!(
                    "your {kind} ray (line {}) has no counterpart in rayscope's tree",
                    s.map_or(0, |s| s.line)
                ),
            )
        }
    };
    Divergence {
        row,
        code: None,
        summary,
        explanation: caveat.to_string(),
        detail,
        values: Vec::new(),
    }
}

/// A summary of a judged log for the UI: counts, verdicts, pixels per status, the first pixels
/// that disagree.
#[must_use]
pub fn summary_json(log: &PixelLog, list: usize) -> Value {
    let r = &log.report;
    let counts = log.counts();
    let mut bad = Vec::new();
    'rows: for y in 0..log.height {
        for x in 0..log.width {
            if log.status_at(x, y) == PixelStatus::Disagrees {
                bad.push([x, y]);
                if bad.len() >= list {
                    break 'rows;
                }
            }
        }
    }
    let codes = |v: &[rayscope_check::report::VerdictGroup]| {
        v.iter()
            .map(|g| json!({"code": g.code.as_str(), "count": g.count, "summary": g.summary}))
            .collect::<Vec<_>>()
    };
    json!({
        "rays": r.rays,
        "agree": r.agree,
        "disagree": r.disagree,
        "ties": r.ties,
        "camera_rays": r.camera_rays,
        "orphans": r.orphans,
        "skipped_lines": r.skipped_lines,
        "first_skipped": r.first_skipped,
        "headline": r.headline(),
        "causes": r.causes.iter().map(|c| json!({
            "name": c.name(),
            "code": c.code.as_str(),
            "samples": c.samples,
            "rays": c.rays,
            "summary": c.summary,
            "consequences": c.consequences.iter().map(|k| k.count).sum::<u64>(),
            // The catalogue's mistakes that show this way, in its own words.
            "catalogue": c.catalogue.iter().filter_map(|n| rayscope_core::Mistake::ALL.into_iter().map(rayscope_core::Mistake::info).find(|i| i.name == *n)).map(|i| json!({
                "name": i.name,
                "wrong": i.wrong,
                "looks": i.looks,
            })).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
        "verdicts": codes(&r.verdicts),
        "tie_verdicts": codes(&r.tie_verdicts),
        "pixels": {
            "not-logged": counts[0],
            "agrees": counts[1],
            "tie": counts[2],
            "disagrees": counts[3],
        },
        "disagreeing": bad,
        "kept": log.kept,
        "dropped": log.dropped,
        "capped": log.dropped > 0,
        "unplaced": log.unplaced,
        "width": log.width,
        "height": log.height,
        "samples_per_pixel": log.spp,
    })
}

/// Reads an image file (PNG, JPEG or PPM) of at most `max_side` pixels a side.
///
/// # Errors
/// When it cannot be read or is too large.
pub fn load_image(path: &Path, max_side: u32) -> Result<RgbImage, String> {
    let mut r = image::ImageReader::open(path)
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?
        .with_guessed_format()
        .map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(max_side);
    limits.max_image_height = Some(max_side);
    r.limits(limits);
    let img = r
        .decode()
        .map_err(|e| {
            format!(
                "cannot read {} as an image (at most {max_side} pixels a side): {e}",
                path.display()
            )
        })?
        .into_rgb8();
    Ok(RgbImage {
        width: img.width(),
        height: img.height(),
        rgb: img.into_raw(),
    })
}
