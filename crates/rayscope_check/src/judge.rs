//! The verdict engine: re-traces each logged ray with the checker's own double-precision oracle
//! and judges both the tracer's answer (what it hit, what blocked the light, the colour it
//! brought back) and the ray itself (where a camera ray points, how a secondary ray leaves its
//! parent's hit).
//!
//! Every ray is judged against its own parent as logged: a wrong camera ray's children are judged
//! from that ray, and the children of a ray whose hit is wrong are judged on their own answers
//! only. The verdicts of a pixel sample are then grouped into root causes and their consequences.
//! This module holds the shared context (the judge, the tallies, what a ray leaves its children);
//! each family of verdicts has a module of its own: `camera`, `hit`, `shadow`, `secondary`,
//! `shading`, and `causes` and `surfaces` for grouping.

use std::collections::BTreeMap;

use glam::{DMat3, DVec3, Vec3A};
use rayscope_core::integrator::Integrator;
use rayscope_core::scene::PrimRef;
use rayscope_core::{FovAxis, RenderSettings, Scene, Stage};
use rustc_hash::FxHashMap;
use serde::Serialize;
use serde_json::json;

use crate::geom::{angle, d3, reflect, refract, Geometry};
use crate::log::{Answer, HitClaim, Kind, LoggedRay};
use crate::oracle::{Oracle, OracleCamera};
use crate::tie::{is_tie, scale};
use crate::verdict::Code;

pub mod causes;

pub use causes::Cause;
mod camera;
mod hit;
mod secondary;
mod shading;
mod shadow;
mod surfaces;
mod whitted;

/// The tolerances verdicts are decided with. Lengths are relative: each is multiplied by the
/// ray's scale, max(1, the largest absolute coordinate of its origin and hit point), because
/// rounding error grows with the size of the coordinates.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Tolerances {
    /// Hit points, distances and points on surfaces (1e-4: a thousand times an f32 tracer's
    /// rounding at unit scale, a hundredth of the smallest mistake worth naming).
    pub position: f64,
    /// How near an edge or silhouette a ray may pass for a disagreement to be a tie.
    pub tie: f64,
    /// Angle in radians between a camera ray and rayscope's (at most a twentieth of the angle
    /// between neighbouring samples).
    pub camera: f64,
    /// Angle in radians between a secondary ray and the one its parent's hit calls for.
    pub direction: f64,
    /// Angle in radians between a logged normal and rayscope's.
    pub normal: f64,
    /// How far a normal's length may be from 1.
    pub unit: f64,
    /// How far from its parent's hit point a secondary ray may start.
    pub offset: f64,
    /// How far on the wrong side of a surface a secondary ray may start.
    pub side: f64,
}

impl Default for Tolerances {
    fn default() -> Self {
        Self {
            position: 1e-4,
            tie: 1e-4,
            camera: 2e-5,
            direction: 1e-4,
            normal: 1e-3,
            unit: 1e-3,
            offset: 1e-3,
            side: 2e-6,
        }
    }
}

/// A number, vector or word the tracer logged beside rayscope's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Value {
    /// What the numbers are.
    pub what: String,
    /// The tracer's.
    pub yours: serde_json::Value,
    /// rayscope's.
    pub rayscope: serde_json::Value,
}

/// One verdict on one logged ray.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Finding {
    /// The verdict.
    pub code: Code,
    /// Line (or ray number) in the log.
    pub line: u64,
    /// Pixel of the ray, when logged.
    pub pixel: Option<[u32; 2]>,
    /// Sample of the ray, when known.
    pub sample: Option<u32>,
    /// The ray's id, when logged.
    pub id: Option<i64>,
    /// The ray's kind.
    pub kind: String,
    /// What exactly is wrong with this ray.
    pub detail: String,
    /// The tracer's numbers beside rayscope's.
    pub values: Vec<Value>,
    /// The entity a verdict on what a ray met is about (the one the tracer and rayscope
    /// disagree on), so verdicts that gather on one entity or one kind of surface can be told.
    #[serde(skip)]
    pub entity: Option<u32>,
}

fn vjson(v: DVec3) -> serde_json::Value {
    let r = |x: f64| (x * 1e6).round() / 1e6;
    json!([r(v.x), r(v.y), r(v.z)])
}

fn njson(x: f64) -> serde_json::Value {
    json!((x * 1e6).round() / 1e6)
}

/// Verdict counts and first examples, merged over threads.
#[derive(Debug, Clone, Default)]
pub struct Tally {
    /// Rays judged.
    pub rays: u64,
    /// Rays with at least one verdict that is not a tie.
    pub disagree: u64,
    /// Rays whose only verdicts are ties.
    pub tied: u64,
    /// Camera rays judged.
    pub camera: u64,
    /// Camera rays with a `camera.*` verdict: placed or aimed otherwise than rayscope's.
    pub camera_disagree: u64,
    /// Rays naming a parent that is not among the rays of the same pixel sample.
    pub orphans: u64,
    /// Per code: how many rays, and the first examples by line.
    pub codes: BTreeMap<Code, (u64, Vec<Finding>)>,
    /// Back-face hits whose normal is the outward one, with the first examples.
    pub outward: (u64, Vec<Finding>),
    /// Back-face hits whose normal faces the ray, with the first examples.
    pub facing: (u64, Vec<Finding>),
    /// Back-face triangle misses a little inside an edge, and well inside: with front-face
    /// misses near edges and none well inside, the back-face ones are the same too strict
    /// inside test, not a one-sided one.
    pub back_near_edge: u64,
    /// Back-face triangle misses well inside the triangle.
    pub back_inside: u64,
    /// Refracted rays into glass with no verdict: where they exist the tracer's ratio of
    /// indices is right on the way in.
    pub entering_refracted_ok: u64,
    /// Refracted rays in the log: where there are any, a glass hit that casts none was kept
    /// from refracting by a test, not by a tracer that never refracts.
    pub refracted: u64,
    /// The nearest hits the tracer passed over, for the log-wide rule that explains them.
    pub skipped: Skipped,
    /// Reflected and refracted rays that hit the surface they leave at t ≈ 0 from an origin on
    /// the wrong side of it, however little: with offsets to the wrong side elsewhere in the log,
    /// and no such hit from the right side, that is the same offset, not acne.
    pub acne_wrong_side: u64,
    /// Such rays from an origin on the right side of the surface, or on it.
    pub acne_other: u64,
    /// Of `acne_wrong_side`, those whose origin lies farther behind the surface than an f32
    /// tracer's rounding: offset there, not rounded there.
    pub acne_wrong_side_far: u64,
    /// Glass verdicts of no reflection (kr = 0) where the reflected ray brought back black:
    /// there the two colours added, R + T, read the same.
    pub glass_black_reflection: u64,
    /// Glass verdicts of another share where the reflected or refracted ray brought back black:
    /// there R + T reads as a share of 1 or 0.
    pub glass_black_other: u64,
    /// Per root cause: the pixel samples and rays it is the first mistake of, what follows
    /// from it, and its first examples.
    pub causes: BTreeMap<Cause, CauseCount>,
    /// Examples kept per code.
    pub keep: usize,
    /// Where the wrong camera rays cross the image plane, from where rayscope puts their samples.
    pub shift: Shift,
    /// Camera rays through the centre of another cell of their pixel's grid than their sample's.
    pub order: SampleOrder,
    /// `shadow.blocked-carried-over` verdicts whose rays name no blocker (`true`).
    pub carried_unnamed: u64,
    /// Rays with a logged colour.
    pub coloured: u64,
    /// Per entity (by index): the hits on it the tracer reported, right or wrong.
    pub claimed_hits: Vec<u64>,
    /// Surface decisions (what a ray brought back from its hit) whose colour was judged.
    pub shaded_judged: u64,
    /// Surface decisions whose colour was not judged (no colour logged, a child missing, or a
    /// material the course's stage-2 rules do not cover).
    pub shaded_unjudged: u64,
}

/// Camera rays that go exactly through the centre of another cell of their pixel's N×N grid
/// than rayscope's sample of their number: how many, and two sums that are equal when the cells
/// they go through are the samples they are numbered as, in another order, pixel by pixel.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SampleOrder {
    /// Rays counted.
    pub rays: u64,
    /// Those of them with no other verdict that counts against the tracer.
    pub alone: u64,
    /// Those of them through the middle cell, the centre of the pixel (odd N).
    pub middle: u64,
    /// The sum of a hash of each ray's pixel and the cell it goes through.
    cells: u64,
    /// The sum of the same hash of its pixel and the cell of its sample's number.
    numbers: u64,
    /// The sum of that hash over every numbered camera ray, whatever cell it goes through.
    every: u64,
    /// The sum of that hash over all N² numbers of each pixel whose sample 0 is logged: equal to
    /// `every` when each pixel logged has each of its samples once.
    whole: u64,
}

impl SampleOrder {
    /// Counts a ray of pixel (x, y) numbered `s` that goes through the centre of cell `cell`, the
    /// pixel's centre when `middle`.
    pub(crate) fn add(&mut self, (x, y): (u32, u32), s: u32, cell: u32, middle: bool) {
        self.rays += 1;
        self.middle += u64::from(middle);
        self.cells = self.cells.wrapping_add(Self::hash((x, y), cell));
        self.numbers = self.numbers.wrapping_add(Self::hash((x, y), s));
    }

    /// Counts any camera ray of pixel (x, y) numbered `s` of `spp`.
    pub(crate) fn numbered(&mut self, (x, y): (u32, u32), s: u32, spp: u32) {
        self.every = self.every.wrapping_add(Self::hash((x, y), s));
        if s == 0 {
            for k in 0..spp {
                self.whole = self.whole.wrapping_add(Self::hash((x, y), k));
            }
        }
    }

    /// A well-mixed hash of a pixel and a cell: two multisets of (pixel, cell) pairs are the same
    /// exactly when their sums of it agree (up to a chance of 2^-64).
    fn hash((x, y): (u32, u32), c: u32) -> u64 {
        let mut z = (u64::from(x) << 40 ^ u64::from(y) << 16 ^ u64::from(c)).wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn merge(&mut self, o: SampleOrder) {
        self.rays += o.rays;
        self.alone += o.alone;
        self.middle += o.middle;
        self.cells = self.cells.wrapping_add(o.cells);
        self.numbers = self.numbers.wrapping_add(o.numbers);
        self.every = self.every.wrapping_add(o.every);
        self.whole = self.whole.wrapping_add(o.whole);
    }

    /// True when every pixel logged has each of its samples once, so that the cells the rays
    /// go through tell a numbering from samples that share a cell.
    #[must_use]
    pub fn whole(&self) -> bool {
        self.every == self.whole
    }

    /// True when the rays counted are samples numbered in another order: each pixel's cells are
    /// its numbers, rearranged.
    #[must_use]
    pub fn renumbered(&self) -> bool {
        self.rays > 0 && self.cells == self.numbers
    }
}

/// How far, in pixels across and down, wrong camera rays cross rayscope's image plane from
/// where rayscope puts their samples: the least and the most, and how many rays.
#[derive(Debug, Clone, Copy)]
pub struct Shift {
    /// Rays counted (those crossing the plane in front of the camera).
    pub rays: u64,
    /// The least shift across and down.
    pub lo: (f64, f64),
    /// The most.
    pub hi: (f64, f64),
}

impl Default for Shift {
    fn default() -> Self {
        Self {
            rays: 0,
            lo: (f64::INFINITY, f64::INFINITY),
            hi: (f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }
}

impl Shift {
    /// Counts one ray's shift; a ray that crosses no plane in front of the camera is left out.
    pub(crate) fn add(&mut self, du: f64, dv: f64) {
        if !(du.is_finite() && dv.is_finite()) {
            return;
        }
        self.rays += 1;
        self.lo = (self.lo.0.min(du), self.lo.1.min(dv));
        self.hi = (self.hi.0.max(du), self.hi.1.max(dv));
    }

    fn merge(&mut self, o: Shift) {
        self.rays += o.rays;
        self.lo = (self.lo.0.min(o.lo.0), self.lo.1.min(o.lo.1));
        self.hi = (self.hi.0.max(o.hi.0), self.hi.1.max(o.hi.1));
    }

    /// The one shift every counted ray has (within a hundredth of a pixel), when there is one.
    fn constant(&self) -> Option<(f64, f64)> {
        const WITHIN: f64 = 0.01;
        (self.rays > 0 && self.hi.0 - self.lo.0 <= WITHIN && self.hi.1 - self.lo.1 <= WITHIN)
            .then(|| ((self.lo.0 + self.hi.0) / 2.0, (self.lo.1 + self.hi.1) / 2.0))
    }
}

/// The nearest hits (or shadow blockers) a tracer passed over, log-wide: which rule other
/// than "the smallest positive t" would pass over all of them.
#[derive(Debug, Clone, Copy)]
pub struct Skipped {
    /// Rays whose nearest hit the tracer passed over (ties not counted).
    pub rays: u64,
    /// The farthest of those hits along its ray.
    pub max_t: f64,
    /// The nearest hit the tracer kept (one rayscope agrees with) along its ray.
    pub kept_min_t: f64,
    /// The scene's size, which a minimum distance is judged against.
    pub size: f64,
    /// Passed-over rays whose kept hit's entity comes earlier in the scene file.
    pub earlier_in_file: u64,
    /// Passed-over rays whose kept hit's entity comes later in the scene file.
    pub later_in_file: u64,
    /// Passed-over rays whose kept hit lies nearer the world's origin.
    pub nearer_origin: u64,
    /// A ray the tracer got right meets an entity listed earlier beyond its nearest hit: the
    /// file's order would have kept that one, so it is not the rule.
    pub order_refuted: bool,
    /// A ray the tracer got right meets a point nearer the world's origin beyond its nearest
    /// hit: so the distance from the origin is not the rule.
    pub origin_refuted: bool,
    /// A ray the tracer got right meets an entity listed later beyond its nearest hit: so the
    /// last hit in the file's order is not the rule.
    pub last_refuted: bool,
}

impl Default for Skipped {
    fn default() -> Self {
        Skipped {
            rays: 0,
            max_t: 0.0,
            kept_min_t: f64::INFINITY,
            size: 0.0,
            earlier_in_file: 0,
            later_in_file: 0,
            nearer_origin: 0,
            order_refuted: false,
            origin_refuted: false,
            last_refuted: false,
        }
    }
}

/// What the rules say of the hit a tracer kept in place of the nearest one: whether its entity
/// comes earlier in the scene file, whether it comes later, and whether it lies nearer the
/// world's origin.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Kept {
    pub earlier: bool,
    pub later: bool,
    pub nearer: bool,
}

/// One in this many rays the tracer got right (by log line) is walked to test the nearest-hit
/// rules: enough to meet an entity behind another in any scene with more than a few, few enough
/// to cost little, and the same rays whatever the threads.
const WALK_EVERY: u64 = 16;

impl Skipped {
    fn merge(&mut self, o: Skipped) {
        self.rays += o.rays;
        self.max_t = self.max_t.max(o.max_t);
        self.kept_min_t = self.kept_min_t.min(o.kept_min_t);
        self.size = self.size.max(o.size);
        self.earlier_in_file += o.earlier_in_file;
        self.later_in_file += o.later_in_file;
        self.nearer_origin += o.nearer_origin;
        self.order_refuted |= o.order_refuted;
        self.origin_refuted |= o.origin_refuted;
        self.last_refuted |= o.last_refuted;
    }

    /// Counts a passed-over hit at `t` along its ray; `kept` tells, for a farther hit the tracer
    /// kept instead, whether its entity comes earlier in the file, whether it comes later, and
    /// whether it is nearer the world's origin.
    pub(crate) fn pass(&mut self, t: f64, kept: Option<Kept>) {
        self.rays += 1;
        self.max_t = self.max_t.max(t);
        if let Some(Kept { earlier, later, nearer }) = kept {
            self.earlier_in_file += u64::from(earlier);
            self.later_in_file += u64::from(later);
            self.nearer_origin += u64::from(nearer);
        }
    }

    /// The verdict that explains every passed-over hit, with what shows it: a minimum distance
    /// (all passed over nearer than all kept, and near for the scene), else the file's order or
    /// the distance from the world's origin (true of every one of at least three rays).
    fn rule(&self) -> Option<(Code, String)> {
        if self.rays == 0 {
            return None;
        }
        if self.max_t < self.kept_min_t && self.kept_min_t.is_finite() && self.max_t < 0.1 * self.size.max(1.0) {
            return Some((
                Code::HitNearSkipped,
                format!(
                    "every hit your tracer passed over is nearer than t = {:.4}, and every hit it kept is at t = {:.4} or farther",
                    self.max_t, self.kept_min_t
                ),
            ));
        }
        if self.rays >= 3 && self.earlier_in_file == self.rays && !self.order_refuted {
            return Some((
                Code::HitSceneOrder,
                format!(
                    "in all {} rays that passed over the nearest hit, the hit kept belongs to an entity listed earlier in the scene file",
                    self.rays
                ),
            ));
        }
        if self.rays >= 3 && self.later_in_file == self.rays && !self.last_refuted {
            return Some((
                Code::HitSceneOrder,
                format!(
                    "in all {} rays that passed over the nearest hit, the hit kept belongs to an entity listed later in the scene file: the last entity hit wins, as when the nearest distance found so far is never updated",
                    self.rays
                ),
            ));
        }
        if self.rays >= 3 && self.nearer_origin == self.rays && !self.origin_refuted {
            return Some((
                Code::HitOriginDistance,
                format!(
                    "in all {} rays that passed over the nearest hit, the hit kept lies nearer the world's origin",
                    self.rays
                ),
            ));
        }
        None
    }
}

/// The verdicts a passed-over nearest hit is given one ray at a time.
const PASSED_OVER: [Code; 7] = [
    Code::HitFarther,
    Code::HitMissed,
    Code::HitWrongT,
    Code::HitOneSidedTriangle,
    Code::HitTriangleEdge,
    Code::ShadowMissedBlocker,
    Code::ShadowOneSidedTriangle,
];

/// One root cause's counts.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CauseCount {
    /// Pixel samples in which it is the first wrong ray (of a branch).
    pub samples: u64,
    /// Rays on which it is the first wrong verdict.
    pub rays: u64,
    /// Verdicts on rays below it (or beside it on the same ray), per code.
    pub consequences: BTreeMap<Code, u64>,
    /// The first rays it is the cause on, by line.
    pub examples: Vec<Finding>,
    /// Rays it is the cause on, per entity they are about (verdicts on what a ray met).
    pub entities: BTreeMap<u32, u64>,
    /// What the cause is, where it is more particular than its code's summary.
    pub note: Option<String>,
}

impl CauseCount {
    fn merge(&mut self, o: CauseCount, keep: usize) {
        self.samples += o.samples;
        self.rays += o.rays;
        for (e, n) in o.entities {
            *self.entities.entry(e).or_default() += n;
        }
        if self.note.is_none() {
            self.note = o.note;
        }
        for (c, n) in o.consequences {
            *self.consequences.entry(c).or_default() += n;
        }
        keep_first(&mut self.examples, o.examples, keep);
    }
}

fn keep_first(v: &mut Vec<Finding>, more: Vec<Finding>, keep: usize) {
    v.extend(more);
    v.sort_by_key(|f| f.line);
    v.truncate(keep);
}

impl Tally {
    /// An empty tally keeping `keep` examples per code.
    #[must_use]
    pub fn new(keep: usize) -> Self {
        Self {
            keep,
            ..Self::default()
        }
    }

    fn add_ray(&mut self, camera: bool, findings: Vec<Finding>) {
        self.rays += 1;
        self.camera += u64::from(camera);
        if findings.is_empty() {
            return;
        }
        let bad = findings.iter().any(|f| !f.code.is_excused());
        if bad {
            self.disagree += 1;
            // Only where the ray goes can come from flags the check was not given.
            let placed = findings
                .iter()
                .any(|f| f.code.as_str().starts_with("camera.") && !f.code.is_excused());
            self.camera_disagree += u64::from(camera && placed);
        } else if findings.iter().any(|f| f.code.is_tie()) {
            self.tied += 1;
        }
        if !bad && findings.iter().any(|f| f.code == Code::CameraSampleOrder) {
            self.order.alone += 1;
        }
        for f in findings {
            let e = self.codes.entry(f.code).or_default();
            e.0 += 1;
            if e.1.len() < self.keep {
                e.1.push(f);
            }
        }
    }

    /// Moves the cause `from` into `to`: its examples take `to`'s code, and the rays it counted
    /// under the code it loses are no longer counted there.
    /// Shadow rays blocked where nothing is in the way, in a log whose other rays report hits
    /// where there is nothing: the tracer's own surfaces block them, so they are that mistake
    /// (run after the surfaces' rule, which may gather both on one surface first).
    pub fn phantom_blockers_with_phantom_hits(&mut self) {
        let phantom = Cause::of(Code::HitPhantom);
        if self.causes.contains_key(&phantom) {
            self.fold(Code::ShadowPhantomBlocker, phantom);
        }
    }

    /// Shadow rays through the back faces of triangles, in a log whose shadow rays also pass
    /// through blockers met from the front or that are no triangles, and whose other rays meet
    /// back faces as they should: the shadow test misses blockers, whichever side it meets.
    fn one_sided_or_missed(&mut self) {
        let missed = Cause::of(Code::ShadowMissedBlocker);
        if !self.causes.contains_key(&missed) || self.codes.contains_key(&Code::HitOneSidedTriangle) {
            return;
        }
        self.move_code(Code::ShadowOneSidedTriangle, Code::ShadowMissedBlocker);
        self.recast(
            Cause {
                code: Code::ShadowOneSidedTriangle,
                or: Some(Code::HitOneSidedTriangle),
            },
            missed,
        );
    }

    /// Counts the rays and examples of verdict `from` as `to`'s, where the log as a whole shows
    /// that they are that verdict.
    fn move_code(&mut self, from: Code, to: Code) {
        if let Some((n, mut ex)) = self.codes.remove(&from) {
            for f in &mut ex {
                f.code = to;
            }
            let e = self.codes.entry(to).or_default();
            e.0 += n;
            keep_first(&mut e.1, ex, self.keep);
        }
    }

    /// Camera rays through the centre of another cell of their pixel's grid than their number's:
    /// where each pixel's samples still cover each cell once, a numbering, which stays excused;
    /// where they do not, and the log holds each sample of its pixels once, a mistake on each
    /// such ray, the cause of its sample (with some samples missing, the report says it cannot
    /// tell). Samples all through the middle cell are a pixel's samples all through its centre.
    fn sample_order(&mut self) {
        let o = self.order;
        if o.rays == 0 || o.renumbered() || !o.whole() {
            return;
        }
        let (to, note) = if o.middle == o.rays {
            (Code::CameraOnePoint, None)
        } else {
            (
                Code::CameraSubpixelGrid,
                Some(
                    "several samples of a pixel go through the same cell of its sub-pixel grid, and other cells get none"
                        .to_string(),
                ),
            )
        };
        let mut examples = self
            .codes
            .get(&Code::CameraSampleOrder)
            .map(|e| e.1.clone())
            .unwrap_or_default();
        for f in &mut examples {
            f.code = to;
        }
        self.move_code(Code::CameraSampleOrder, to);
        self.disagree += o.alone;
        self.camera_disagree += o.alone;
        let c = self.causes.entry(Cause::of(to)).or_default();
        c.samples += o.alone;
        c.rays += o.alone;
        keep_first(&mut c.examples, examples, self.keep);
        if c.note.is_none() {
            c.note = note;
        }
    }

    /// Camera rays through the corner of their sub-pixel cell, in a log whose other camera rays
    /// go through one point of their pixel whatever their sample: the cell corners that fit are
    /// the samples whose cell corner is that point (sample 0 at the pixel's corner, the cell
    /// whose corner is its centre), so they are the same mistake.
    fn one_point_or_corners(&mut self) {
        let one = self.cause_rays(Code::CameraOnePoint);
        if one > 0 && one >= self.cause_rays(Code::CameraPixelCorner) {
            self.fold(Code::CameraPixelCorner, Cause::of(Code::CameraOnePoint));
        }
    }

    /// Wrong camera rays named by several verdicts, in a log where every wrong camera ray is
    /// shifted by the same fraction of a pixel from its sample's place: one mistake, that shift
    /// (an offset added twice, a half pixel on top of the sample's own), whatever each ray
    /// happens to fit alone.
    fn shifted(&mut self) {
        let camera: Vec<Cause> = self
            .causes
            .keys()
            .copied()
            .filter(|c| c.code.as_str().starts_with("camera."))
            .collect();
        let Some((du, dv)) = self.shift.constant() else {
            return;
        };
        if camera.len() < 2 || self.shift.rays != self.camera_disagree {
            return;
        }
        let to = Cause::of(Code::CameraShifted);
        let side = |v: f64, plus: &str, minus: &str| {
            if v.abs() < 0.005 {
                String::new()
            } else {
                format!("{:.3} of a pixel {}", v.abs(), if v > 0.0 { plus } else { minus })
            }
        };
        let parts: Vec<String> = [side(du, "to the right", "to the left"), side(dv, "down", "up")]
            .into_iter()
            .filter(|p| !p.is_empty())
            .collect();
        for c in camera {
            for code in c.codes() {
                self.move_code(code, Code::CameraShifted);
            }
            self.recast(c, to);
        }
        if let Some(n) = self.causes.get_mut(&to) {
            n.note = Some(format!(
                "every wrong camera ray is shifted {} from where rayscope puts its sample",
                parts.join(" and ")
            ));
        }
    }

    /// Camera rays of the diagonal's pixels with their sub-pixel row and column exchanged, in a
    /// log whose other pixels' rays go through the pixel with column and row exchanged: the same
    /// exchange, which on the diagonal moves the samples only.
    fn transposed_diagonal(&mut self) {
        if self.cause_rays(Code::CameraTransposed) > self.cause_rays(Code::CameraSubpixelGrid) {
            self.fold(Code::CameraSubpixelGrid, Cause::of(Code::CameraTransposed));
        }
    }

    /// Shadow rays blocked by nothing, their blocker unnamed, whose sibling before them is
    /// blocked: a flag not reset between lights reads so, but so does any test that blocks rays
    /// with nothing in the way. Where the log also has such rays with no blocked sibling, the
    /// flag is not what blocks them, and all are the one phantom blocker.
    fn carried_or_phantom(&mut self) {
        let carried = self.cause_rays(Code::ShadowBlockedCarriedOver);
        if self.cause_rays(Code::ShadowPhantomBlocker) > 0 && carried > 0 && self.carried_unnamed == carried {
            self.fold(Code::ShadowBlockedCarriedOver, Cause::of(Code::ShadowPhantomBlocker));
        }
    }

    /// Camera rays that fit another sub-pixel layout and a scaled image plane alike: the one the
    /// log's other camera rays show where they show only one; and a few rays of another layout
    /// beside many that fit a scaled plane are that plane's.
    fn layout_or_plane(&mut self) {
        let both = Cause {
            code: Code::CameraSubpixelGrid,
            or: Some(Code::CameraPlaneDistance),
        };
        let (layout, plane) = (
            Cause::of(Code::CameraSubpixelGrid),
            Cause::of(Code::CameraPlaneDistance),
        );
        match (self.causes.contains_key(&layout), self.causes.contains_key(&plane)) {
            (true, false) => self.recast(both, layout),
            (false, true) => self.recast(both, plane),
            _ => {}
        }
        // An image plane at the wrong distance scales every camera ray's place about the image's
        // centre, which puts a few near it inside their own pixel, some on another cell's centre:
        // beside many rays that fit the plane, those few are the plane's too.
        let few = self.cause_rays(Code::CameraSubpixelGrid);
        if few > 0 && few * 20 <= self.causes.get(&plane).map_or(0, |c| c.samples) {
            // What the layout's headline would have said is not the plane's.
            if let Some(c) = self.causes.get_mut(&layout) {
                c.note = None;
            }
            self.fold(Code::CameraSubpixelGrid, plane);
        }
    }

    /// Glass that brings back one of its two colours alone only where the other is black, in a
    /// log whose glass elsewhere adds the two colours unweighted (R + T), or adds the refracted
    /// colour unweighted beside a weighted reflection (kr·R + T), is that sum.
    fn none_or_sum(&mut self) {
        let sum = [Code::ShadingGlassSum, Code::ShadingTransmissionUnweighted]
            .into_iter()
            .map(Cause::of)
            .filter(|c| self.causes.contains_key(c))
            .max_by_key(|c| self.causes.get(c).map_or(0, |n| n.samples));
        let Some(sum) = sum else {
            return;
        };
        for (code, black) in [
            (Code::ShadingFresnelNone, self.glass_black_reflection),
            (Code::ShadingFresnel, self.glass_black_other),
        ] {
            let n = self.codes.get(&code).map_or(0, |e| e.0);
            if n > 0 && n <= black {
                self.fold(code, sum);
            }
        }
    }

    /// A reflected share that fits a known wrong formula at some glass hits, in a log whose other
    /// glass hits fit none: near normal incidence, or where the two colours are alike, every
    /// formula reads the same, so the formula is chance and the share is the tracer's own.
    fn fresnel_formula_or_other(&mut self) {
        let other = Cause::of(Code::ShadingFresnel);
        if !self.causes.contains_key(&other) {
            return;
        }
        for code in [
            Code::ShadingFresnelSchlick,
            Code::ShadingFresnelSwappedCosines,
            Code::ShadingFresnelHalf,
            Code::ShadingFresnelNone,
            Code::ShadingFresnelWeightsExchanged,
        ] {
            self.fold(code, other);
        }
    }

    /// A reflected share that fits no formula, in a log whose glass elsewhere brings back no
    /// weighted mix at all: where the two colours have one hue every colour on their line reads
    /// as a mix with some share, so those hits are the same mistake.
    fn share_or_not_a_mix(&mut self) {
        let glass = Cause::of(Code::ShadingGlass);
        let samples = |code: Code| self.causes.get(&Cause::of(code)).map_or(0, |n| n.samples);
        // Only where the colours that are no mix are as many: a few such hits among many shares
        // that fit are the rounding of colours of nearly one hue, not a mistake of their own.
        if self.causes.contains_key(&glass) && samples(Code::ShadingGlass) >= samples(Code::ShadingFresnel) {
            self.fold(Code::ShadingFresnel, glass);
        }
    }

    /// The rays of the cause of verdict `code` alone (0 where the log has none).
    fn cause_rays(&self, code: Code) -> u64 {
        self.causes.get(&Cause::of(code)).map_or(0, |n| n.rays)
    }

    /// Counts verdict `from`, and its cause, as cause `to`: [`Self::move_code`] and
    /// [`Self::recast`] together.
    fn fold(&mut self, from: Code, to: Cause) {
        self.move_code(from, to.code);
        self.recast(Cause::of(from), to);
    }

    fn recast(&mut self, from: Cause, to: Cause) {
        let Some(mut moved) = self.causes.remove(&from) else {
            return;
        };
        for f in &mut moved.examples {
            f.code = to.code;
        }
        for lost in from.codes().into_iter().filter(|c| !to.codes().contains(c)) {
            if let Some(e) = self.codes.get_mut(&lost) {
                e.0 = e.0.saturating_sub(moved.rays);
                e.1.retain(|f| moved.examples.iter().all(|m| m.line != f.line));
                if e.0 == 0 {
                    self.codes.remove(&lost);
                }
            }
        }
        let keep = self.keep;
        self.causes.entry(to).or_default().merge(moved, keep);
    }

    /// Glass hits that cast a reflection weighted by a share below 1 and no refracted ray: in a
    /// log with refracted rays elsewhere, a test kept these from refracting (a critical-angle
    /// test that fires where it should not); in one without, the tracer never refracts.
    fn refraction_test_or_none(&mut self) {
        if self.refracted > 0 {
            self.recast(
                Cause::of(Code::MissingRefraction),
                Cause::of(Code::RefractionTirInvented),
            );
        }
    }

    /// Reflections at glass a ray entering should have refracted through, where the ratio of
    /// indices upside down would also be past the critical angle: the rest of the log decides.
    /// Refracted rays into glass bent with that ratio make it the ratio; correct ones make it the
    /// critical-angle test; with neither, both stay named.
    fn tir_test_or_ratio(&mut self) {
        let both = Cause {
            code: Code::RefractionTirInvented,
            or: Some(Code::RefractionIndicesNotSwapped),
        };
        let ratio = Cause::of(Code::RefractionIndicesNotSwapped);
        if self.causes.contains_key(&ratio) {
            self.recast(both, ratio);
        } else if self.entering_refracted_ok > 0 {
            self.recast(both, Cause::of(Code::RefractionTirInvented));
        }
    }

    /// Passed-over nearest hits that one rule explains, log-wide (a minimum distance, the
    /// file's order, the distance from the world's origin), are that rule's verdict, not one
    /// verdict per ray about the surface passed over.
    fn nearest_rule(&mut self) {
        let Some((code, why)) = self.skipped.rule() else {
            return;
        };
        let to = Cause::of(code);
        let from: Vec<Cause> = (self.causes.keys())
            .filter(|c| c.codes().iter().all(|k| PASSED_OVER.contains(k)))
            .copied()
            .collect();
        if from.is_empty() {
            return;
        }
        for k in PASSED_OVER {
            if let Some((n, mut ex)) = self.codes.remove(&k) {
                for f in &mut ex {
                    f.code = code;
                    f.detail = format!("{why}; here {}", f.detail);
                }
                let e = self.codes.entry(code).or_default();
                e.0 += n;
                keep_first(&mut e.1, ex, self.keep);
            }
        }
        for c in from {
            if let Some(moved) = self.causes.get_mut(&c) {
                for f in &mut moved.examples {
                    f.detail = format!("{why}; here {}", f.detail);
                }
            }
            self.recast(c, to);
        }
    }

    /// Self-intersections of secondary rays whose origins all lie (if only by a rounding step)
    /// on the wrong side of the surface, in a log whose other secondary rays are offset to the
    /// wrong side, or where every such origin lies beyond rounding on that side: one offset
    /// mistake, whose rays start too near the surface for their origins alone to tell.
    fn acne_or_wrong_side(&mut self) {
        let acne = Cause::of(Code::SecondaryAcne);
        let wrong = Cause::of(Code::SecondaryOffsetWrongSide);
        // Every such hit from an origin offset to the wrong side, beyond rounding: the offset is
        // the mistake even where no other ray shows it (an offset within the tolerance for a
        // secondary ray's origin, taken along a normal that faces the wrong way).
        let all_far = self.acne_wrong_side_far == self.acne_wrong_side
            && self.cause_rays(Code::SecondaryAcne) <= self.acne_wrong_side;
        if !(self.causes.contains_key(&wrong) || all_far) || self.acne_wrong_side == 0 || self.acne_other > 0 {
            return;
        }
        self.move_code(Code::SecondaryAcne, Code::SecondaryOffsetWrongSide);
        self.recast(acne, wrong);
    }

    /// A tracer that misses triangles near their edges on the front face, and on the back face
    /// only near edges too, has an inside test that is too strict, not a one-sided one: its
    /// back-face misses are counted as such.
    fn one_sided_or_edges(&mut self) {
        let edge = Cause::of(Code::HitTriangleEdge);
        if !self.causes.contains_key(&edge) || self.back_near_edge == 0 || self.back_inside > 0 {
            return;
        }
        for code in [Code::HitOneSidedTriangle, Code::ShadowOneSidedTriangle] {
            self.move_code(code, Code::HitTriangleEdge);
        }
        self.recast(
            Cause {
                code: Code::ShadowOneSidedTriangle,
                or: Some(Code::HitOneSidedTriangle),
            },
            edge,
        );
    }

    fn add_causes(&mut self, sample: &causes::SampleCauses, findings: &[Vec<Finding>]) {
        for c in sample.distinct() {
            self.causes.entry(c).or_default().samples += 1;
        }
        for &(i, c) in &sample.roots {
            let e = self.causes.entry(c).or_default();
            e.rays += 1;
            if let Some(ent) = findings[i].iter().find(|f| !f.code.is_excused()).and_then(|f| f.entity) {
                *e.entities.entry(ent).or_default() += 1;
            }
            if e.examples.len() < self.keep {
                if let Some(f) = findings[i].iter().find(|f| !f.code.is_excused()) {
                    e.examples.push(f.clone());
                }
            }
        }
        for &(c, code) in &sample.consequences {
            *self.causes.entry(c).or_default().consequences.entry(code).or_default() += 1;
        }
    }

    /// Adds another tally's counts and examples (keeping the first examples by line).
    #[must_use]
    pub fn merge(mut self, o: Tally) -> Tally {
        self.rays += o.rays;
        self.disagree += o.disagree;
        self.tied += o.tied;
        self.camera += o.camera;
        self.camera_disagree += o.camera_disagree;
        self.orphans += o.orphans;
        self.back_near_edge += o.back_near_edge;
        self.back_inside += o.back_inside;
        self.entering_refracted_ok += o.entering_refracted_ok;
        self.refracted += o.refracted;
        self.skipped.merge(o.skipped);
        self.acne_wrong_side += o.acne_wrong_side;
        self.acne_other += o.acne_other;
        self.acne_wrong_side_far += o.acne_wrong_side_far;
        self.glass_black_reflection += o.glass_black_reflection;
        self.glass_black_other += o.glass_black_other;
        self.shaded_judged += o.shaded_judged;
        self.shaded_unjudged += o.shaded_unjudged;
        self.shift.merge(o.shift);
        self.order.merge(o.order);
        self.carried_unnamed += o.carried_unnamed;
        self.coloured += o.coloured;
        if self.claimed_hits.len() < o.claimed_hits.len() {
            self.claimed_hits.resize(o.claimed_hits.len(), 0);
        }
        for (a, b) in self.claimed_hits.iter_mut().zip(&o.claimed_hits) {
            *a += b;
        }
        let keep = self.keep.max(o.keep);
        self.keep = keep;
        for (c, (n, ex)) in o.codes {
            let e = self.codes.entry(c).or_default();
            e.0 += n;
            keep_first(&mut e.1, ex, keep);
        }
        for (c, count) in o.causes {
            self.causes.entry(c).or_default().merge(count, keep);
        }
        self.outward.0 += o.outward.0;
        keep_first(&mut self.outward.1, o.outward.1, keep);
        self.facing.0 += o.facing.0;
        keep_first(&mut self.facing.1, o.facing.1, keep);
        self
    }

    /// Turns the normal conventions into a verdict: when back-face hits use both, the rarer one
    /// is inconsistent with the rest. Those rays are counted as disagreeing.
    pub fn finish(&mut self) {
        self.sample_order();
        self.nearest_rule();
        self.shifted();
        self.transposed_diagonal();
        self.one_point_or_corners();
        self.layout_or_plane();
        self.carried_or_phantom();
        self.acne_or_wrong_side();
        self.one_sided_or_edges();
        self.refraction_test_or_none();
        self.tir_test_or_ratio();
        self.one_sided_or_missed();
        self.none_or_sum();
        self.fresnel_formula_or_other();
        self.share_or_not_a_mix();
        let (out, fac) = (self.outward.0, self.facing.0);
        if out == 0 || fac == 0 {
            return;
        }
        let minority = if out < fac { &self.outward } else { &self.facing };
        let (n, ex) = minority.clone();
        self.disagree += n;
        let e = self.codes.entry(Code::HitNormalInconsistent).or_default();
        e.0 += n;
        keep_first(&mut e.1, ex.clone(), self.keep);
        // Decided over the whole log, so each such ray is a cause of its own sample.
        let c = self.causes.entry(Cause::of(Code::HitNormalInconsistent));
        let c = c.or_default();
        c.samples += n;
        c.rays += n;
        keep_first(&mut c.examples, ex, self.keep);
    }
}

/// rayscope's closest hit of a ray, in double precision where it matters.
#[derive(Debug, Clone, Copy)]
struct RsHit {
    prim: PrimRef,
    entity: u32,
    material: u32,
    /// Distance from the logged origin.
    t: f64,
    point: DVec3,
    own: DVec3,
    front: bool,
    /// Uncertainty of `own` in radians, from the rounding of the point it is computed at.
    un: f64,
    /// The normal shading uses, on the side of `own`: a mesh's interpolated vertex normal where
    /// it has them, else `own`.
    shade: DVec3,
}

/// The surface a secondary ray leaves: rayscope's hit of its parent ray.
#[derive(Debug, Clone, Copy)]
struct Leave {
    point: DVec3,
    /// Unit normal facing the parent ray.
    facing: DVec3,
    /// Unit shading normal facing the parent ray (the interpolated normal of a smooth mesh).
    shade: DVec3,
    front: bool,
    entity: u32,
    material: u32,
    parent_dir: DVec3,
    /// The length of the parent's direction as logged (1 for a unit direction).
    parent_len: f64,
    parent_origin: DVec3,
    /// Uncertainty of the normal in radians.
    un: f64,
}

/// What judging a ray leaves for its children.
#[derive(Debug, Clone, Copy)]
struct Eval {
    rs: Option<RsHit>,
    /// The ray and its answer held up (or were not logged), so its children can be judged
    /// against rayscope's hit of it.
    sound: bool,
    origin: DVec3,
    dir: DVec3,
    /// The length of the ray's direction as logged.
    dir_len: f64,
}

impl Eval {
    fn leave(&self) -> Option<Leave> {
        let h = self.rs.filter(|_| self.sound)?;
        Some(Leave {
            point: h.point,
            facing: if h.front { h.own } else { -h.own },
            shade: if h.front { h.shade } else { -h.shade },
            front: h.front,
            entity: h.entity,
            material: h.material,
            parent_dir: self.dir,
            parent_len: self.dir_len,
            parent_origin: self.origin,
            un: h.un,
        })
    }
}

/// Most triangles an entity may have for a wrong hit or blocker to be searched for the triangle
/// whose plane it lies in: the course's triangles and quads, not models.
const FEW_TRIANGLES: usize = 16;

/// The judge for one scene and one set of render flags.
pub struct Judge<'a> {
    scene: &'a Scene,
    settings: &'a RenderSettings,
    geo: Geometry<'a>,
    /// The checker's own visibility.
    oracle: Oracle,
    /// The checker's own camera.
    cam: OracleCamera,
    rot: DMat3,
    cam_origin: DVec3,
    pinhole: bool,
    jitter: bool,
    grid: u32,
    spp: u32,
    cam_tol: f64,
    /// The tolerances in use.
    pub tol: Tolerances,
}

/// Share of a triangle's altitude within which a miss counts as near its edge: a tenth, far
/// beyond rounding (which [`Tolerances::tie`] covers) and within the margins too strict inside
/// tests use.
const EDGE_SHARE: f64 = 0.1;

/// The smallest share of a sample a missing refracted ray must carry to be a verdict.
const MIN_SHARE: f64 = 0.01;

/// The scale tolerances are multiplied by.
/// Relative distance within which an origin computed in f32 lies on the surface it was computed
/// on: f32's rounding of coordinates, with a margin. An origin offset as the course's 1e-5 is
/// ten times farther.
const SURFACE_ROUNDING: f64 = 1e-6;

/// Relative distance along a ray within which an f32 tracer's `t` for the surface its origin
/// lies on can come out on the other side of 0: a few of f32's steps at the coordinates' size.
/// A surface the exact ray meets farther behind its origin is no rounding-error hit (acne); a
/// tracer that counts it accepts hits behind the origin.
const T_ROUNDING: f64 = 2.5e-7;

impl<'a> Judge<'a> {
    /// True when the catalogue's mistake `m` can show in a picture of the judged scene under the
    /// judged settings: only those are named beside a verdict.
    pub(crate) fn can_show(&self, m: rayscope_core::Mistake) -> bool {
        rayscope_core::contents::SceneContents::of(self.scene).can_show(m, self.settings)
    }

    /// A judge for `scene` rendered with `settings`.
    #[must_use]
    pub fn new(scene: &'a Scene, settings: &'a RenderSettings) -> Self {
        let integ = Integrator::new(scene, settings);
        let spp = integ.samples_per_pixel();
        let grid = if spp == 1 { 1 } else { settings.aa.max(1) };
        let cam = OracleCamera::new(settings);
        let pinhole = !(settings.stage == Stage::Full && settings.camera.aperture_radius > 0.0);
        let jitter = integ.stochastic;
        let tol = Tolerances::default();
        // A twentieth of the angle between neighbouring samples at the image centre, at most the
        // default: tight enough to tell grid positions apart on any image size.
        let spacing = 2.0 * cam.half.0 / (f64::from(settings.width) * f64::from(grid));
        let cam_tol = tol.camera.min(0.05 * spacing);
        Self {
            scene,
            settings,
            cam_origin: cam.origin,
            rot: cam.rotation,
            cam,
            geo: Geometry::new(scene),
            oracle: Oracle::new(scene),
            pinhole,
            jitter,
            grid,
            spp,
            cam_tol,
            tol,
        }
    }

    /// The scene judged against.
    #[must_use]
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The render settings judged under.
    #[must_use]
    pub fn settings(&self) -> &'a RenderSettings {
        self.settings
    }

    /// Samples per pixel under the settings.
    #[must_use]
    pub fn samples_per_pixel(&self) -> u32 {
        self.spp
    }

    fn name(&self, e: u32) -> &str {
        self.scene.entities.get(e as usize).map_or("?", |x| x.name.as_str())
    }

    fn light_name(&self, l: u32) -> &str {
        self.scene.light_names.get(l as usize).map_or("?", String::as_str)
    }

    /// The oracle's closest hit of `o + t d` with `t_min < t < t_max`, as a distance from `from`.
    fn trace(&self, o: DVec3, d: DVec3, t_min: f64, t_max: f64, from: DVec3) -> Option<RsHit> {
        let h = self.oracle.closest(o, d, t_min, t_max)?;
        let un = self.geo.normal_uncertainty(h.prim, d, h.normal, scale(&[o, h.point]));
        let shade =
            self.geo
                .shading_normal(h.prim, h.point)
                .map_or(h.normal, |s| if s.dot(h.normal) < 0.0 { -s } else { s });
        Some(RsHit {
            prim: h.prim,
            entity: h.entity,
            material: h.material,
            t: (h.point - from).dot(d),
            point: h.point,
            own: h.normal,
            front: h.front,
            un,
            shade,
        })
    }

    /// For a shadow ray the tracer says reaches its light at `dist`, though something blocks
    /// it: whether a shadow test that takes the tracer's "closest" hit on the whole ray and
    /// compares its distance with the light's would say so, with the hit kept (among each
    /// entity's nearest) being the first in the scene's order, the last, or the one nearest the
    /// world's origin.
    fn kept_beyond(&self, o: DVec3, d: DVec3, dist: f64) -> Kept {
        let mut hits = Vec::new();
        let mut lo = 0.0;
        while hits.len() < 64 {
            let Some(h) = self.oracle.closest(o, d, lo, f64::INFINITY) else {
                break;
            };
            lo = h.t + h.t.abs() * 1e-9 + 1e-12;
            // Each entity's own test answers one hit, its nearest (a sphere's near root).
            if hits.iter().all(|k: &crate::oracle::OracleHit| k.entity != h.entity) {
                hits.push(h);
            }
        }
        let first = hits.iter().min_by_key(|h| h.entity);
        let last = hits.iter().max_by_key(|h| h.entity);
        let nearest_origin = hits.iter().min_by(|a, b| a.point.length().total_cmp(&b.point.length()));
        Kept {
            earlier: first.is_none_or(|h| h.t >= dist),
            later: last.is_none_or(|h| h.t >= dist),
            nearer: nearest_origin.is_none_or(|h| h.t >= dist),
        }
    }

    /// For a ray whose nearest hit `h` the tracer got right: whether an entity's own nearest hit
    /// beyond it (past `margin`) is listed earlier, or lies nearer the world's origin, which
    /// refutes the rule that would have kept it.
    fn walk_agreeing(&self, r: &LoggedRay, h: &RsHit, margin: f64, s: &mut Skipped) {
        if !r.line.is_multiple_of(WALK_EVERY) || s.order_refuted && s.origin_refuted && s.last_refuted {
            return;
        }
        let (o, d) = (r.origin, r.direction);
        let mut seen = vec![h.entity];
        let mut lo = h.t + margin;
        for _ in 0..64 {
            let Some(k) = self.oracle.closest(o, d, lo, f64::INFINITY) else {
                break;
            };
            lo = k.t + k.t.abs() * 1e-9 + 1e-12;
            if seen.contains(&k.entity) {
                continue;
            }
            seen.push(k.entity);
            s.order_refuted |= k.entity < h.entity;
            s.last_refuted |= k.entity > h.entity;
            s.origin_refuted |= k.point.length() < h.point.length() - margin;
        }
    }

    /// Counts a nearest hit at `t` the tracer passed over, unless the verdicts its ray just got,
    /// `found`, are all ties; `kept` gives the rules' answers for it (see [`Skipped::pass`]).
    fn passed_over(&self, found: &[Finding], t: f64, kept: impl FnOnce() -> Option<Kept>, s: &mut Skipped) {
        if found.iter().any(|x| !x.code.is_excused()) {
            s.size = s.size.max(self.scene_size());
            s.pass(t, kept());
        }
    }

    /// The diagonal of the scene's bounded entities (planes have no size), at least 1.
    fn scene_size(&self) -> f64 {
        let b = &self.scene.bounds;
        if b.is_empty() {
            1.0
        } else {
            f64::from((b.max - b.min).length()).max(1.0)
        }
    }

    fn finding(&self, r: &LoggedRay, kind: &Kind, code: Code, detail: String, values: Vec<Value>) -> Finding {
        Finding {
            code,
            line: r.line,
            pixel: r.pixel,
            sample: r.sample,
            id: r.id,
            kind: kind.name().to_string(),
            detail,
            values,
            entity: None,
        }
    }

    /// Judges the rays of one pixel sample (or any set of rays whose `parent` links stay inside
    /// it), adding their verdicts to `tally`.
    pub fn judge_group(&self, rays: &[LoggedRay], tally: &mut Tally) {
        self.judge_group_inner(rays, tally, false);
    }

    /// [`Judge::judge_group`], also returning each ray's verdicts (ties included), in the order of
    /// `rays`. The log-wide verdict on mixed normal conventions (`hit.normal-inconsistent`) is
    /// decided over the whole log by [`Tally::finish`] and is not among them.
    pub fn judge_group_findings(&self, rays: &[LoggedRay], tally: &mut Tally) -> Vec<Vec<Finding>> {
        self.judge_group_inner(rays, tally, true)
    }

    fn judge_group_inner(&self, rays: &[LoggedRay], tally: &mut Tally, keep: bool) -> Vec<Vec<Finding>> {
        SCRATCH.with(|s| self.judge_group_with(rays, tally, keep, &mut s.borrow_mut()))
    }

    fn judge_group_with(
        &self,
        rays: &[LoggedRay],
        tally: &mut Tally,
        keep: bool,
        s: &mut Scratch,
    ) -> Vec<Vec<Finding>> {
        let n = rays.len();
        let Scratch {
            parent,
            depth,
            order,
            evals,
            kinds,
            findings,
        } = s;
        parents(rays, SCAN_MOST, parent);
        tally.orphans += rays
            .iter()
            .zip(parent.iter())
            .filter(|(r, p)| r.parent.is_some() && p.is_none())
            .count() as u64;
        // Parents before children; a cycle of parent links is cut after 64 steps.
        depth.clear();
        depth.extend((0..n).map(|i| {
            let (mut d, mut cur) = (0, parent[i]);
            while let Some(p) = cur {
                d += 1;
                if d > 64 {
                    break;
                }
                cur = parent[p];
            }
            d
        }));
        order.clear();
        order.extend(0..n);
        // Tracers log a parent before its children: then the log's order is already that one.
        if depth.windows(2).any(|w| w[0] > w[1]) {
            order.sort_by_key(|&i| (depth[i], i));
        }
        evals.clear();
        evals.resize(n, None);
        findings.clear();
        findings.resize_with(n, Vec::new);
        kinds.clear();
        kinds.resize(n, Kind::Camera);
        for &i in order.iter() {
            let leave = parent[i].and_then(|p| evals[p].as_ref()).and_then(Eval::leave);
            let (eval, kind) = self.judge_ray(&rays[i], leave.as_ref(), &mut findings[i], tally);
            evals[i] = Some(eval);
            kinds[i] = kind;
        }
        self.tir_invented(rays, parent, evals, kinds, findings);
        tally.carried_unnamed += self.carried_over(rays, parent, kinds, findings);
        tally.refracted += kinds.iter().filter(|k| **k == Kind::Refraction).count() as u64;
        tally.entering_refracted_ok += (0..n)
            .filter(|&i| {
                kinds[i] == Kind::Refraction
                    && findings[i].is_empty()
                    && parent[i]
                        .and_then(|p| evals[p].as_ref())
                        .and_then(Eval::leave)
                        .is_some_and(|lv| lv.front)
            })
            .count() as u64;
        self.shading(rays, parent, evals, kinds, findings, tally);
        if findings.iter().any(|f| !f.is_empty()) {
            tally.add_causes(&causes::causes(order, parent, findings), findings);
        }
        let mut out = Vec::with_capacity(if keep { n } else { 0 });
        for (i, f) in findings.drain(..).enumerate() {
            if keep {
                out.push(f.clone());
            }
            tally.coloured += u64::from(rays[i].color.is_some());
            tally.add_ray(kinds[i] == Kind::Camera, f);
        }
        out
    }

    /// The ray's kind: as logged, else inferred (a ray naming a light is a shadow ray, a ray
    /// from the camera without a parent a camera ray).
    #[must_use]
    pub fn kind_of(&self, r: &LoggedRay) -> Kind {
        self.infer_kind(r)
    }

    fn infer_kind(&self, r: &LoggedRay) -> Kind {
        if let Some(k) = &r.kind {
            return k.clone();
        }
        if r.light.is_some() || r.blocked_by != Answer::NotLogged {
            return Kind::Shadow;
        }
        let l = scale(&[r.origin, self.cam_origin]);
        if r.parent.is_none() && (r.origin - self.cam_origin).length() <= self.tol.position * l {
            return Kind::Camera;
        }
        Kind::Other("ray".into())
    }

    /// Judges one ray; returns what its children need and its kind.
    fn judge_ray(&self, r: &LoggedRay, leave: Option<&Leave>, f: &mut Vec<Finding>, tally: &mut Tally) -> (Eval, Kind) {
        let kind = self.infer_kind(r);
        let (o, d) = (r.origin, r.direction);
        let mut sound = true;
        if kind == Kind::Camera && r.parent.is_none() {
            let before = f.len();
            self.camera(r, &kind, f, (&mut tally.shift, &mut tally.order));
            sound &= f.len() == before;
        }
        // Where rayscope traces from: the logged origin, moved off the surface it leaves by
        // rayscope's own offset when it lies closer than that (or on the wrong side), so the
        // answer compared is that of the ray the tracer meant to cast.
        // Hits closer than where the ray, followed from its logged origin, gets rayscope's own
        // offset off the surface it leaves are the rounding of that surface, not answers.
        let (mut t_skip, mut toward_light_behind) = (0.0, false);
        if let Some(lv) = leave {
            (t_skip, toward_light_behind) = self.leaving(r, &kind, lv);
            let before = f.len();
            self.derivation(r, &kind, lv, f);
            sound &= f.len() == before;
        }
        let light = if kind == Kind::Shadow {
            self.aim(r, &kind, leave.map(|lv| lv.point), f)
        } else {
            None
        };
        let t_max = light.map_or(f64::INFINITY, |li| {
            (d3(Vec3A::from(self.scene.lights[li as usize].position)) - o).length()
        });
        let mut rs = self.trace(o, d, t_skip, t_max, o);
        if leave.is_none() {
            // No parent to say which surface the ray leaves: a hit at t ≈ 0 on a surface the
            // origin lies on is taken for the one it leaves.
            if let Some(h) = rs {
                let l = scale(&[o, h.point]);
                if h.t < self.tol.position * l && self.geo.distance(h.prim, o) <= self.tol.position * l {
                    rs = self.trace(o, d, self.tol.position * l, t_max, o);
                }
            }
        }
        // A shadow ray toward a light behind the surface contributes nothing whatever it meets,
        // so what the tracer says about it is not judged.
        if !toward_light_behind {
            sound &= self.judge_claim(r, &kind, rs.as_ref(), leave, t_max, f, tally);
            if let (Kind::Shadow, Some(li)) = (&kind, light) {
                self.judge_blocker(r, &kind, li, rs.as_ref(), t_skip, leave, f, tally);
            }
        }
        (
            Eval {
                rs,
                sound,
                origin: o,
                dir: d,
                dir_len: r.dir_len,
            },
            kind,
        )
    }

    /// Judges what the tracer says ray `r` hit against rayscope's answer `rs`; false when that
    /// gave a verdict (the ray's children are then judged on their own answers only).
    #[allow(clippy::too_many_arguments)]
    fn judge_claim(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        rs: Option<&RsHit>,
        leave: Option<&Leave>,
        t_max: f64,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) -> bool {
        // What the tracer found.
        let claim = match r.hit {
            Answer::NotLogged => r.end.and_then(|end| self.segment_claim(r, end, t_max)),
            other => Some(other),
        };
        // A hit logged without a name is judged as one on the surface its point lies on.
        let unnamed = matches!(r.hit, Answer::Found(HitClaim { entity: None, .. }));
        let claim = claim.map(|c| match c {
            Answer::Found(mut h) if unnamed => {
                h.entity = self.entity_at(r, &h, rs);
                Answer::Found(h)
            }
            other => other,
        });
        if let Some(claim) = claim {
            let before = f.len();
            self.hit(r, kind, claim, rs, leave, f, tally);
            if unnamed {
                for x in &mut f[before..] {
                    x.detail = x
                        .detail
                        .replace("your tracer names '", "your tracer's hit point lies on '");
                }
            }
            let claimed = match claim {
                Answer::Found(c) => c.entity,
                _ => None,
            };
            if let Some(e) = claimed {
                let e = e as usize;
                if tally.claimed_hits.len() <= e {
                    tally.claimed_hits.resize(self.scene.entities.len().max(e + 1), 0);
                }
                tally.claimed_hits[e] += 1;
            }
            hit_entities(&mut f[before..], claimed, rs.map(|h| h.entity));
            // After a tie the tracer's ray may go on from the other surface: its children are
            // judged on their own answers only.
            return f.len() == before;
        }
        true
    }

    /// Judges what shadow ray `r`, aimed at light `li`, says is in the way.
    #[allow(clippy::too_many_arguments)]
    fn judge_blocker(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        rs: Option<&RsHit>,
        t_skip: f64,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let blocked = r.blocked_by;
        let before = f.len();
        // A blocker logged without a name is judged as the surface it stands for.
        let judged = match blocked {
            Answer::Found(Some(e)) => Answer::Found(e),
            Answer::Found(None) => match self.unnamed_blocker(r, li, rs, leave) {
                Some(e) => Answer::Found(e),
                None => {
                    self.blocked_by_nothing(r, kind, li, f);
                    Answer::NotLogged
                }
            },
            Answer::Nothing => Answer::Nothing,
            Answer::NotLogged => Answer::NotLogged,
        };
        if judged != Answer::NotLogged {
            self.blocked(r, kind, li, rs, t_skip, judged, leave, f, tally);
        }
        if blocked == Answer::Found(None) {
            for v in f[before..].iter_mut().flat_map(|x| &mut x.values) {
                if v.what.starts_with("blocker of light") {
                    v.yours = json!(shadow::UNNAMED_BLOCKER);
                }
            }
        }
        let named = match judged {
            Answer::Found(e) => Some(e),
            _ => None,
        };
        blocker_entities(&mut f[before..], named, rs.map(|h| h.entity));
    }

    /// Where rayscope traces a ray cast from its parent's hit `lv`: the distance to skip so that
    /// the ray starts rayscope's own offset off the surface it leaves (when the logged origin lies
    /// closer than that, or on the wrong side), and whether it is a shadow ray toward a light
    /// behind that surface.
    fn leaving(&self, r: &LoggedRay, kind: &Kind, lv: &Leave) -> (f64, bool) {
        let (o, d) = (r.origin, r.direction);
        let side = d.dot(lv.facing);
        let l = scale(&[lv.point, lv.parent_origin]);
        let eps = 1e-5 * l;
        let sigma = (o - lv.point).dot(lv.facing);
        let mut t_skip = 0.0;
        if side.abs() > 1e-9 {
            let s = side.signum();
            if sigma * s < eps {
                t_skip = ((s * eps - sigma) / side).clamp(0.0, self.tol.position * l);
            }
        }
        (t_skip, *kind == Kind::Shadow && side <= 0.0)
    }
}

/// Each ray's parent in `rays`: the last ray logged with its `parent` id, never itself. Groups
/// of at most `scan` rays are searched directly, which for the handful of rays of a sample is
/// sooner than building a map.
/// The entity each verdict on a hit is about: the one the tracer named where its answer is the
/// wrong one, the one rayscope meets where the tracer missed it.
fn hit_entities(found: &mut [Finding], claimed: Option<u32>, rayscope: Option<u32>) {
    for x in found {
        x.entity = match x.code {
            Code::HitPhantom
            | Code::HitWrongT
            | Code::HitPointOffRay
            | Code::HitBehindOrigin
            | Code::HitNormalWrong => claimed.or(x.entity).or(rayscope),
            Code::HitMissed | Code::HitFarther | Code::HitOneSidedTriangle | Code::HitTriangleEdge => rayscope,
            _ => None,
        };
    }
}

/// The entity each verdict on a shadow ray's blocker is about: the blocker the tracer named, or
/// the one rayscope finds in the way.
fn blocker_entities(found: &mut [Finding], named: Option<u32>, rayscope: Option<u32>) {
    for x in found {
        x.entity = match x.code {
            // A blocker logged without a name keeps the entity its verdict found it could be.
            Code::ShadowPhantomBlocker | Code::ShadowWrongBlocker | Code::ShadowBlockedBeyondLight => {
                named.or(x.entity)
            }
            Code::ShadowMissedBlocker | Code::ShadowOneSidedTriangle | Code::HitTriangleEdge => rayscope,
            _ => None,
        };
    }
}

/// The most rays of a sample whose parents are found by scanning their ids; more are mapped.
const SCAN_MOST: usize = 32;

fn parents(rays: &[LoggedRay], scan: usize, out: &mut Vec<Option<usize>>) {
    let own = |i: usize, p: Option<usize>| p.filter(|&p| p != i);
    out.clear();
    if rays.len() <= scan.min(SCAN_MOST) {
        // The ids side by side first, so that each scan reads them rather than a cache line of
        // every ray.
        let mut ids = [None; SCAN_MOST];
        for (slot, r) in ids.iter_mut().zip(rays) {
            *slot = r.id;
        }
        let ids = &ids[..rays.len()];
        out.extend(
            rays.iter()
                .enumerate()
                .map(|(i, r)| own(i, r.parent.and_then(|p| ids.iter().rposition(|&q| q == Some(p))))),
        );
    } else {
        let ids: FxHashMap<i64, usize> = rays
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.id.map(|id| (id, i)))
            .collect();
        out.extend(
            rays.iter()
                .enumerate()
                .map(|(i, r)| own(i, r.parent.and_then(|p| ids.get(&p).copied()))),
        );
    }
}

/// The buffers judging one sample uses, kept per thread from sample to sample: most samples
/// are a few rays, and allocating these for each cost more than judging them.
#[derive(Default)]
struct Scratch {
    parent: Vec<Option<usize>>,
    depth: Vec<u32>,
    order: Vec<usize>,
    evals: Vec<Option<Eval>>,
    kinds: Vec<Kind>,
    findings: Vec<Vec<Finding>>,
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::default();
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(id: Option<i64>, parent: Option<i64>) -> LoggedRay {
        LoggedRay {
            id,
            parent,
            ..LoggedRay::for_tests([0, 0], 0, 1)
        }
    }

    #[test]
    fn parents_are_the_last_ray_with_the_id_whether_scanned_or_mapped() {
        // Ids repeat (a tracer that numbers rays per bounce), a parent is missing, a ray names
        // itself, and one has no id.
        let rays = vec![
            ray(Some(0), None),
            ray(Some(1), Some(0)),
            ray(Some(1), Some(0)),
            ray(Some(2), Some(1)),
            ray(Some(3), Some(9)),
            ray(Some(4), Some(4)),
            ray(None, Some(2)),
        ];
        let want = vec![None, Some(0), Some(0), Some(2), None, None, Some(3)];
        let mut got = Vec::new();
        parents(&rays, SCAN_MOST, &mut got);
        assert_eq!(got, want);
        parents(&rays, 0, &mut got);
        assert_eq!(got, want);
    }
}
