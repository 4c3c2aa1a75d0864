//! The verdict engine: re-traces each logged ray with rayscope's own intersection and judges both
//! the tracer's answer (what it hit, what blocked the light) and the ray itself (where a camera
//! ray points, how a secondary ray leaves its parent's hit).
//!
//! Every ray is judged against its own parent as logged, so one mistake gives one verdict where
//! it happens, not a cascade below it: a wrong camera ray's children are judged from that ray, and
//! the children of a ray whose hit is wrong are judged on their own answers only.

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
use crate::verdict::Code;

pub mod causes;

pub use causes::Cause;
mod shading;
mod surfaces;

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
    /// Camera rays with a verdict.
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
    /// Per root cause: the pixel samples and rays it is the first mistake of, what follows
    /// from it, and its first examples.
    pub causes: BTreeMap<Cause, CauseCount>,
    /// Examples kept per code.
    pub keep: usize,
    /// Surface decisions (what a ray brought back from its hit) whose colour was judged.
    pub shaded_judged: u64,
    /// Surface decisions whose colour was not judged (no colour logged, a child missing, or a
    /// material the course's stage-2 rules do not cover).
    pub shaded_unjudged: u64,
}

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
        let bad = findings.iter().any(|f| !f.code.is_tie());
        if bad {
            self.disagree += 1;
            self.camera_disagree += u64::from(camera);
        } else if !findings.is_empty() {
            self.tied += 1;
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

    /// Reflections at glass a ray entering should have refracted through, where the ratio of
    /// indices upside down would also be past the critical angle: the rest of the log decides.
    /// Refracted rays into glass bent with that ratio make it the ratio; correct ones make it the
    /// critical-angle test; with neither, both stay named.
    fn tir_test_or_ratio(&mut self) {
        let both = Cause {
            code: Code::RefractionTirInvented,
            or: Some(Code::RefractionIndicesNotSwapped),
        };
        let ratio = Cause {
            code: Code::RefractionIndicesNotSwapped,
            or: None,
        };
        if self.causes.contains_key(&ratio) {
            self.recast(both, ratio);
        } else if self.entering_refracted_ok > 0 {
            self.recast(
                both,
                Cause {
                    code: Code::RefractionTirInvented,
                    or: None,
                },
            );
        }
    }

    /// A tracer that misses triangles near their edges on the front face, and on the back face
    /// only near edges too, has an inside test that is too strict, not a one-sided one: its
    /// back-face misses are counted as such.
    fn one_sided_or_edges(&mut self) {
        let edge = Cause {
            code: Code::HitTriangleEdge,
            or: None,
        };
        if !self.causes.contains_key(&edge) || self.back_near_edge == 0 || self.back_inside > 0 {
            return;
        }
        for code in [Code::HitOneSidedTriangle, Code::ShadowOneSidedTriangle] {
            if let Some((n, mut ex)) = self.codes.remove(&code) {
                for f in &mut ex {
                    f.code = Code::HitTriangleEdge;
                }
                let e = self.codes.entry(Code::HitTriangleEdge).or_default();
                e.0 += n;
                keep_first(&mut e.1, ex, self.keep);
            }
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
            if let Some(ent) = findings[i].iter().find(|f| !f.code.is_tie()).and_then(|f| f.entity) {
                *e.entities.entry(ent).or_default() += 1;
            }
            if e.examples.len() < self.keep {
                if let Some(f) = findings[i].iter().find(|f| !f.code.is_tie()) {
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
        self.shaded_judged += o.shaded_judged;
        self.shaded_unjudged += o.shaded_unjudged;
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
        self.one_sided_or_edges();
        self.tir_test_or_ratio();
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
        let c = self.causes.entry(Cause {
            code: Code::HitNormalInconsistent,
            or: None,
        });
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
            parent_origin: self.origin,
            un: h.un,
        })
    }
}

/// A sample offset or image-plane half extents, with the mistake it stands for (none: rayscope's).
type Guess = ((f64, f64), Option<(Code, &'static str)>);

/// A position-and-projection guess for a camera ray.
#[derive(Debug, Clone, Copy)]
struct CamGuess {
    /// Offset of the sample in its pixel.
    off: (f64, f64),
    /// Half extents of the image plane (signs flip the image).
    half: (f64, f64),
    pos_code: Option<(Code, &'static str)>,
    proj_code: Option<(Code, &'static str)>,
}

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

/// Fresnel reflectance (unpolarised) where the parent ray meets glass of index `ior`.
fn glass_fresnel(lv: &Leave, ior: f64) -> f64 {
    let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
    let cos_i = (-lv.parent_dir.dot(lv.facing)).clamp(0.0, 1.0);
    let sin2_t = (n1 / n2).powi(2) * (1.0 - cos_i * cos_i);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// The scale tolerances are multiplied by.
/// Relative distance within which an origin computed in f32 lies on the surface it was computed
/// on: f32's rounding of coordinates, with a margin. An origin offset as the course's 1e-5 is
/// ten times farther.
const SURFACE_ROUNDING: f64 = 1e-6;

fn scale(points: &[DVec3]) -> f64 {
    points.iter().map(|p| p.abs().max_element()).fold(1.0, f64::max)
}

impl<'a> Judge<'a> {
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
        let n = rays.len();
        let parent = parents(rays, 32);
        tally.orphans += rays
            .iter()
            .zip(&parent)
            .filter(|(r, p)| r.parent.is_some() && p.is_none())
            .count() as u64;
        // Parents before children; a cycle of parent links is cut after 64 steps.
        let depth: Vec<u32> = (0..n)
            .map(|i| {
                let (mut d, mut cur) = (0, parent[i]);
                while let Some(p) = cur {
                    d += 1;
                    if d > 64 {
                        break;
                    }
                    cur = parent[p];
                }
                d
            })
            .collect();
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&i| (depth[i], i));
        let mut evals: Vec<Option<Eval>> = vec![None; n];
        let mut findings: Vec<Vec<Finding>> = vec![Vec::new(); n];
        let mut kinds: Vec<Kind> = Vec::with_capacity(n);
        kinds.resize(n, Kind::Camera);
        for &i in &order {
            let leave = parent[i].and_then(|p| evals[p]).and_then(|e| e.leave());
            let (eval, kind) = self.judge_ray(&rays[i], leave.as_ref(), &mut findings[i], tally);
            evals[i] = Some(eval);
            kinds[i] = kind;
        }
        self.tir_invented(rays, &parent, &evals, &kinds, &mut findings);
        tally.entering_refracted_ok += (0..n)
            .filter(|&i| {
                kinds[i] == Kind::Refraction
                    && findings[i].is_empty()
                    && parent[i]
                        .and_then(|p| evals[p])
                        .and_then(|e| e.leave())
                        .is_some_and(|lv| lv.front)
            })
            .count() as u64;
        self.shading(rays, &parent, &evals, &kinds, &mut findings, tally);
        tally.add_causes(&causes::causes(&order, &parent, &findings), &findings);
        let mut out = Vec::with_capacity(if keep { n } else { 0 });
        for (i, f) in findings.into_iter().enumerate() {
            if keep {
                out.push(f.clone());
            }
            tally.add_ray(kinds[i] == Kind::Camera, f);
        }
        out
    }

    /// Glass hits where the tracer reflected and did not refract although rayscope refracts.
    fn tir_invented(
        &self,
        rays: &[LoggedRay],
        parent: &[Option<usize>],
        evals: &[Option<Eval>],
        kinds: &[Kind],
        findings: &mut [Vec<Finding>],
    ) {
        // Only a reflection can be the invented half of a total internal reflection.
        if !kinds.contains(&Kind::Reflection) {
            return;
        }
        let mut children: FxHashMap<usize, Vec<usize>> = FxHashMap::default();
        for (i, p) in parent.iter().enumerate() {
            if let Some(p) = p {
                children.entry(*p).or_default().push(i);
            }
        }
        for (p, kids) in children {
            let Some(lv) = evals[p].and_then(|e| e.leave()) else {
                continue;
            };
            let m = &self.scene.materials[lv.material as usize];
            if !m.is_glass() {
                continue;
            }
            let refl = kids.iter().find(|&&k| kinds[k] == Kind::Reflection);
            let refr = kids.iter().any(|&k| kinds[k] == Kind::Refraction);
            let (Some(&k), false) = (refl, refr) else {
                continue;
            };
            let ior = f64::from(m.value);
            let eta = if lv.front { 1.0 / ior } else { ior };
            let cos_i = -lv.parent_dir.dot(lv.facing);
            let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
            // A refracted ray that would carry a negligible share of the sample may be pruned
            // (rayscope prunes Whitted branches below 1/4096 of a level): only a missing
            // refraction worth at least MIN_SHARE of the sample is a verdict.
            let share = self.path_weight(p, parent, evals, kinds) * (1.0 - glass_fresnel(&lv, ior));
            if sin2_t < 1.0 - 1e-3 && share >= MIN_SHARE {
                let t = refract(lv.parent_dir, lv.facing, eta).unwrap_or(DVec3::ZERO);
                // With the index ratio upside down the ray is past the critical angle: that is
                // the mistake, and the reflection only its consequence.
                let sin2_inverted = (1.0 - cos_i * cos_i) / (eta * eta);
                if sin2_inverted >= 1.0 - 1e-3 {
                    // Entering, this ray alone cannot tell a ratio upside down from a critical-
                    // angle test with the leaving side's ratio: both are named, and the log's
                    // other refracted rays decide (see `Tally::finish`).
                    findings[k].push(self.finding(
                        &rays[k],
                        &kinds[k],
                        Code::RefractionTirInvented,
                        format!(
                            "entering '{}' your tracer reflected only, as if past the critical angle; sin²θt = {sin2_t:.4} < 1, so the ray refracts",
                            self.name(lv.entity)
                        ),
                        vec![],
                    ));
                    findings[k].push(self.finding(
                        &rays[k],
                        &kinds[k],
                        Code::RefractionIndicesNotSwapped,
                        format!(
                            "{} '{}' (index {}) your tracer reflected only, as η = {:.4} would have it (sin²θt = {sin2_inverted:.4} > 1, past the critical angle); with η = n1 / n2 = {eta:.4} sin²θt = {sin2_t:.4} and the ray refracts",
                            if lv.front { "entering" } else { "leaving" },
                            self.name(lv.entity),
                            m.value,
                            1.0 / eta
                        ),
                        vec![Value {
                            what: "refracted direction".into(),
                            yours: json!("none"),
                            rayscope: vjson(t),
                        }],
                    ));
                    continue;
                }
                let f = self.finding(
                    &rays[k],
                    &kinds[k],
                    Code::RefractionTirInvented,
                    format!(
                        "at '{}' (index {}) sin²θt = {sin2_t:.4} < 1, so the ray refracts; your tracer cast this reflection and no refracted ray",
                        self.name(lv.entity),
                        m.value
                    ),
                    vec![Value {
                        what: "refracted direction".into(),
                        yours: json!("none"),
                        rayscope: vjson(t),
                    }],
                );
                findings[k].push(f);
            }
        }
    }

    /// The share of its sample that ray `i` carries by Fresnel's weights at the glass hits above
    /// it (mirrors pass everything on).
    fn path_weight(&self, i: usize, parent: &[Option<usize>], evals: &[Option<Eval>], kinds: &[Kind]) -> f64 {
        let (mut w, mut k) = (1.0, i);
        for _ in 0..64 {
            let Some(p) = parent[k] else {
                break;
            };
            if let Some(lv) = evals[p].and_then(|e| e.leave()) {
                let m = &self.scene.materials[lv.material as usize];
                if m.is_glass() {
                    let kr = glass_fresnel(&lv, f64::from(m.value));
                    w *= match kinds[k] {
                        Kind::Reflection => kr,
                        Kind::Refraction => 1.0 - kr,
                        _ => 1.0,
                    };
                }
            }
            k = p;
        }
        w
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
            self.camera(r, &kind, f);
            sound &= f.len() == before;
        }
        // Where rayscope traces from: the logged origin, moved off the surface it leaves by
        // rayscope's own offset when it lies closer than that (or on the wrong side), so the
        // answer compared is that of the ray the tracer meant to cast.
        // Hits closer than where the ray, followed from its logged origin, gets rayscope's own
        // offset off the surface it leaves are the rounding of that surface, not answers.
        let mut t_skip = 0.0;
        let mut toward_light_behind = false;
        if let Some(lv) = leave {
            let side = d.dot(lv.facing);
            let l = scale(&[lv.point, lv.parent_origin]);
            let eps = 1e-5 * l;
            let sigma = (o - lv.point).dot(lv.facing);
            if side.abs() > 1e-9 {
                let s = side.signum();
                if sigma * s < eps {
                    t_skip = ((s * eps - sigma) / side).clamp(0.0, self.tol.position * l);
                }
            }
            toward_light_behind = kind == Kind::Shadow && side <= 0.0;
            let before = f.len();
            self.derivation(r, &kind, lv, f);
            sound &= f.len() == before;
        }
        let light = if kind == Kind::Shadow {
            self.aim(r, &kind, f)
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
        if toward_light_behind {
            // A shadow ray toward a light behind the surface contributes nothing whatever it
            // meets, so what the tracer says about it is not judged.
            return (
                Eval {
                    rs,
                    sound,
                    origin: o,
                    dir: d,
                },
                kind,
            );
        }
        // What the tracer found.
        let claim = match r.hit {
            Answer::NotLogged => r.end.and_then(|end| self.segment_claim(r, end, t_max)),
            other => Some(other),
        };
        if let Some(claim) = claim {
            let before = f.len();
            self.hit(r, &kind, claim, rs.as_ref(), leave, f, tally);
            let claimed = match claim {
                Answer::Found(c) => c.entity,
                _ => None,
            };
            for x in &mut f[before..] {
                x.entity = match x.code {
                    Code::HitPhantom
                    | Code::HitWrongT
                    | Code::HitPointOffRay
                    | Code::HitBehindOrigin
                    | Code::HitNormalWrong => claimed.or(rs.map(|h| h.entity)),
                    Code::HitMissed | Code::HitFarther | Code::HitOneSidedTriangle | Code::HitTriangleEdge => {
                        rs.map(|h| h.entity)
                    }
                    _ => None,
                };
            }
            // After a tie the tracer's ray may go on from the other surface: its children are
            // judged on their own answers only.
            sound &= f.len() == before;
        }
        if kind == Kind::Shadow {
            if let (Some(li), blocked) = (light, r.blocked_by) {
                if blocked != Answer::NotLogged {
                    let before = f.len();
                    self.blocked(r, &kind, li, rs.as_ref(), t_skip, blocked, leave, f, tally);
                    let named = match blocked {
                        Answer::Found(e) => Some(e),
                        _ => None,
                    };
                    for x in &mut f[before..] {
                        x.entity = match x.code {
                            Code::ShadowPhantomBlocker | Code::ShadowWrongBlocker => named,
                            Code::ShadowMissedBlocker | Code::ShadowOneSidedTriangle | Code::HitTriangleEdge => {
                                rs.map(|h| h.entity)
                            }
                            _ => None,
                        };
                    }
                }
            }
        }
        (
            Eval {
                rs,
                sound,
                origin: o,
                dir: d,
            },
            kind,
        )
    }

    /// A `from`/`to` segment's end as a claimed hit, when it lies on a surface of the scene.
    fn segment_claim(&self, r: &LoggedRay, end: DVec3, t_max: f64) -> Option<Answer<HitClaim>> {
        let len = r.dir_len;
        let l = scale(&[r.origin, end]);
        let w = self.tol.position * l;
        if len > t_max {
            return None;
        }
        self.trace(r.origin, r.direction, (len - w).max(0.0), len + w, r.origin)
            .map(|_| {
                Answer::Found(HitClaim {
                    t: Some(1.0),
                    point: Some(end),
                    normal: None,
                    entity: None,
                })
            })
    }

    /// The camera ray against rayscope's camera for its pixel and sample.
    fn camera(&self, r: &LoggedRay, kind: &Kind, f: &mut Vec<Finding>) {
        let Some([x, y]) = r.pixel else {
            return;
        };
        if !self.pinhole {
            return;
        }
        let l = scale(&[r.origin, self.cam_origin]);
        if (r.origin - self.cam_origin).length() > self.tol.position * l {
            f.push(self.finding(
                r,
                kind,
                Code::CameraOrigin,
                format!(
                    "starts {:.3e} away from the camera",
                    (r.origin - self.cam_origin).length()
                ),
                vec![Value {
                    what: "origin".into(),
                    yours: vjson(r.origin),
                    rayscope: vjson(self.cam_origin),
                }],
            ));
            return;
        }
        if self.jitter {
            return;
        }
        let rs_dir = |s: u32| self.cam.ray(x, y, s).1;
        let d = r.direction;
        let candidates: Vec<u32> = match r.sample {
            Some(s) => vec![s],
            None => (0..self.spp).collect(),
        };
        let (s, err) = candidates
            .iter()
            .map(|&s| (s, angle(d, rs_dir(s))))
            .fold((0, f64::INFINITY), |a, b| if b.1 < a.1 { b } else { a });
        if err <= self.cam_tol {
            return;
        }
        let rs = rs_dir(s);
        let dc = (self.rot.transpose() * d).normalize();
        let (w, h) = (f64::from(self.settings.width), f64::from(self.settings.height));
        let t = (f64::from(self.settings.camera.fov_deg).to_radians() * 0.5).tan();
        let aspect = w / h;
        let horizontal = self.settings.camera.fov_axis == FovAxis::Horizontal;
        let half = if horizontal { (t, t / aspect) } else { (t * aspect, t) };
        let n = f64::from(self.grid);
        let (i, j) = (f64::from(s % self.grid), f64::from(s / self.grid));
        let mut offs: Vec<Guess> = vec![
            (((i + 0.5) / n, (j + 0.5) / n), None),
            (
                (i / n, j / n),
                Some((
                    Code::CameraPixelCorner,
                    "through the top-left corner of its pixel (or sub-pixel cell), not the centre",
                )),
            ),
        ];
        if self.grid > 1 {
            offs.push((
                ((j + 0.5) / n, (i + 0.5) / n),
                Some((
                    Code::CameraSubpixelGrid,
                    "with the sample's row and column swapped (rayscope numbers samples row by row: i = s mod N, j = s div N)",
                )),
            ));
            offs.push((
                (0.5, 0.5),
                Some((
                    Code::CameraSubpixelGrid,
                    "through the pixel centre instead of sample s's grid cell",
                )),
            ));
            offs.push((
                (i / (n - 1.0), j / (n - 1.0)),
                Some((
                    Code::CameraSubpixelGrid,
                    "on a grid that spans the pixel's corners instead of cell centres",
                )),
            ));
        }
        let mut projs: Vec<Guess> = vec![(half, None)];
        if self.settings.width != self.settings.height {
            let swapped = if horizontal { (t * aspect, t) } else { (t, t / aspect) };
            projs.push((
                swapped,
                Some((
                    Code::CameraFovAxis,
                    if horizontal {
                        "with a vertical field of view: the 60° spans the image height instead of its width"
                    } else {
                        "with a horizontal field of view where --fov-axis vertical was asked for"
                    },
                )),
            ));
            projs.push((
                (t, t),
                Some((
                    Code::CameraAspect,
                    "with the aspect ratio ignored: a square image plane on a non-square image",
                )),
            ));
            let inverted = if horizontal { (t, t * aspect) } else { (t / aspect, t) };
            projs.push((
                inverted,
                Some((
                    Code::CameraAspect,
                    "with the aspect ratio the wrong way round (height / width instead of width / height)",
                )),
            ));
        }
        projs.push((
            (half.0, -half.1),
            Some((Code::CameraFlipped, "with the image upside down (row 0 at the bottom)")),
        ));
        projs.push((
            (-half.0, half.1),
            Some((Code::CameraFlipped, "with the image mirrored left to right")),
        ));
        let dir_of = |g: &CamGuess| {
            let u = (f64::from(x) + g.off.0) / w;
            let v = (f64::from(y) + g.off.1) / h;
            DVec3::new((2.0 * u - 1.0) * g.half.0, (1.0 - 2.0 * v) * g.half.1, 1.0).normalize()
        };
        let mut best: Option<(f64, CamGuess)> = None;
        for &(off, pc) in &offs {
            for &(hh, qc) in &projs {
                if pc.is_none() && qc.is_none() {
                    continue;
                }
                let g = CamGuess {
                    off,
                    half: hh,
                    pos_code: pc,
                    proj_code: qc,
                };
                let e = angle(dir_of(&g), dc);
                if best.is_none_or(|(b, _)| e < b) {
                    best = Some((e, g));
                }
            }
        }
        // Where the tracer's ray crosses rayscope's image plane.
        let (us, vs) = if dc.z > 0.0 {
            ((dc.x / dc.z / half.0 + 1.0) * 0.5, (1.0 - dc.y / dc.z / half.1) * 0.5)
        } else {
            (f64::NAN, f64::NAN)
        };
        let rs_uv = {
            let (ox, oy) = offs[0].0;
            ((f64::from(x) + ox) / w, (f64::from(y) + oy) / h)
        };
        let values = vec![
            Value {
                what: "direction".into(),
                yours: vjson(d),
                rayscope: vjson(rs),
            },
            Value {
                what: "image position (u, v)".into(),
                yours: if us.is_finite() {
                    json!([(us * 1e6).round() / 1e6, (vs * 1e6).round() / 1e6])
                } else {
                    json!("behind the camera")
                },
                rayscope: json!([(rs_uv.0 * 1e6).round() / 1e6, (rs_uv.1 * 1e6).round() / 1e6]),
            },
        ];
        let off_by = format!("{:.4}° off", err.to_degrees());
        if let Some((_, g)) = best.filter(|(e, _)| *e <= self.cam_tol) {
            for (code, why) in [g.pos_code, g.proj_code].into_iter().flatten() {
                f.push(self.finding(
                    r,
                    kind,
                    code,
                    format!("{off_by}; it fits a camera ray {why}"),
                    values.clone(),
                ));
            }
            return;
        }
        if dc.z <= 0.0 {
            f.push(self.finding(
                r,
                kind,
                Code::CameraDirection,
                "points backwards, away from the image plane: the course's camera looks along +z".into(),
                values,
            ));
            return;
        }
        // A uniformly scaled image plane: another distance to the plane, or another FOV.
        let p = dir_of(&CamGuess {
            off: offs[0].0,
            half,
            pos_code: None,
            proj_code: None,
        });
        let (xr, yr) = (p.x / p.z, p.y / p.z);
        let (xs, ys) = (dc.x / dc.z, dc.y / dc.z);
        let k = (xs * xr + ys * yr) / (xr * xr + yr * yr).max(1e-300);
        let fit = DVec3::new(k * xr, k * yr, 1.0).normalize();
        if (k - 1.0).abs() > 1e-4 && k > 0.0 && angle(fit, dc) <= self.cam_tol {
            let fov = 2.0 * (k * if horizontal { half.0 } else { half.1 }).atan();
            f.push(self.finding(
                r,
                kind,
                Code::CameraPlaneDistance,
                format!(
                    "{off_by}; it fits an image plane at distance {:.4} instead of 1 (or a field of view of {:.2}° instead of {}°)",
                    1.0 / k,
                    fov.to_degrees(),
                    self.settings.camera.fov_deg
                ),
                values,
            ));
            return;
        }
        let (px, py) = ((us * w).floor(), (vs * h).floor());
        let detail = if px == f64::from(x) && py == f64::from(y) {
            f.push(self.finding(
                r,
                kind,
                Code::CameraSubpixelGrid,
                format!(
                    "{off_by}; it passes through its own pixel, but not where rayscope puts sample {s} (random jitter, or another sub-pixel layout)"
                ),
                values,
            ));
            return;
        } else if px.is_finite() {
            format!("{off_by}; it passes through pixel ({px}, {py}) of rayscope's image instead of ({x}, {y})")
        } else {
            off_by
        };
        f.push(self.finding(r, kind, Code::CameraDirection, detail, values));
    }

    /// Which light a shadow ray aims at; a verdict when it aims at none (or not at the one named).
    fn aim(&self, r: &LoggedRay, kind: &Kind, f: &mut Vec<Finding>) -> Option<u32> {
        let lights = &self.scene.lights;
        let to = |li: u32| d3(Vec3A::from(lights[li as usize].position)) - r.origin;
        let off = |li: u32| {
            let v = to(li);
            if v.length_squared() == 0.0 {
                0.0
            } else {
                angle(r.direction, v)
            }
        };
        let pick = match r.light {
            Some(li) => Some((li, off(li))),
            None => (0..lights.len() as u32)
                .map(|li| (li, off(li)))
                .fold(None, |a: Option<(u32, f64)>, b| match a {
                    Some(a) if a.1 <= b.1 => Some(a),
                    _ => Some(b),
                }),
        };
        let (li, err) = pick?;
        if err <= self.tol.direction {
            return Some(li);
        }
        let target = to(li);
        let backwards = angle(r.direction, -target) <= self.tol.direction;
        let detail = if backwards {
            format!(
                "points straight away from light '{}': the direction looks like point − light instead of light − point",
                self.light_name(li)
            )
        } else {
            format!(
                "{:.3}° away from the direction to light '{}'{}",
                err.to_degrees(),
                self.light_name(li),
                if r.light.is_none() { " (the nearest light)" } else { "" }
            )
        };
        f.push(self.finding(
            r,
            kind,
            Code::ShadowNotAtLight,
            detail,
            vec![Value {
                what: "direction".into(),
                yours: vjson(r.direction),
                rayscope: vjson(target.normalize()),
            }],
        ));
        None
    }

    /// The tracer's hit (or miss) against rayscope's.
    #[allow(clippy::too_many_arguments)]
    fn hit(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        claim: Answer<HitClaim>,
        rs: Option<&RsHit>,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o, d) = (r.origin, r.direction);
        let hit_values = |ts: Option<f64>, ps: Option<DVec3>, es: Option<u32>| {
            let mut v = vec![Value {
                what: "entity".into(),
                yours: es.map_or(
                    if ps.is_some() || ts.is_some() {
                        json!("(not logged)")
                    } else {
                        json!("nothing")
                    },
                    |e| json!(self.name(e)),
                ),
                rayscope: rs.map_or(json!("nothing"), |h| json!(self.name(h.entity))),
            }];
            if ts.is_some() || rs.is_some() {
                v.push(Value {
                    what: "t".into(),
                    yours: ts.map_or(json!(null), njson),
                    rayscope: rs.map_or(json!(null), |h| njson(h.t)),
                });
            }
            if ps.is_some() || rs.is_some() {
                v.push(Value {
                    what: "point".into(),
                    yours: ps.map_or(json!(null), vjson),
                    rayscope: rs.map_or(json!(null), |h| vjson(h.point)),
                });
            }
            v
        };
        let c = match claim {
            Answer::NotLogged => return,
            Answer::Nothing => {
                let Some(h) = rs else {
                    return;
                };
                let m = self.geo.margin(h.prim, o, d, h.point);
                let l = scale(&[o, h.point]);
                let v = hit_values(None, None, None);
                if m <= self.tol.tie * l {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("passes {m:.2e} from the edge of '{}'", self.name(h.entity)),
                        v,
                    ));
                } else if let Some(share) = self.triangle_miss(h, tally) {
                    f.push(self.finding(r, kind, Code::HitTriangleEdge, self.edge_detail(h, share, "trace"), v));
                } else if matches!(h.prim, PrimRef::Triangle(_)) && !h.front {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitOneSidedTriangle,
                        format!(
                            "rayscope hits the back face of triangle '{}' at t = {:.6}; your tracer reports no hit",
                            self.name(h.entity),
                            h.t
                        ),
                        v,
                    ));
                } else {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitMissed,
                        format!(
                            "rayscope hits '{}' at t = {:.6}; your tracer reports no hit",
                            self.name(h.entity),
                            h.t
                        ),
                        v,
                    ));
                }
                return;
            }
            Answer::Found(c) => c,
        };
        let ts = c.t.map(|t| t * r.dir_len).or_else(|| c.point.map(|p| (p - o).dot(d)));
        let Some(ts) = ts else {
            // Only an entity (or a normal): judge the entity.
            if let (Some(e), Some(h)) = (c.entity, rs) {
                if e != h.entity {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitFarther,
                        format!(
                            "your tracer names '{}' but the nearest hit is '{}' at t = {:.6}",
                            self.name(e),
                            self.name(h.entity),
                            h.t
                        ),
                        hit_values(None, None, Some(e)),
                    ));
                }
            }
            return;
        };
        let ps = c.point.unwrap_or(o + d * ts);
        let l = scale(&[o, ps]);
        let pos = self.tol.position * l;
        let v = || hit_values(Some(ts), Some(ps), c.entity);
        if let (Some(p), Some(t)) = (c.point, c.t) {
            let on_ray = o + d * (t * r.dir_len);
            if (p - on_ray).length() > pos {
                f.push(self.finding(
                    r,
                    kind,
                    Code::HitPointOffRay,
                    format!(
                        "the point is {:.3e} from origin + t · direction (t = {t})",
                        (p - on_ray).length()
                    ),
                    vec![Value {
                        what: "point".into(),
                        yours: vjson(p),
                        rayscope: vjson(on_ray),
                    }],
                ));
                return;
            }
        }
        if ts < -pos {
            f.push(self.finding(
                r,
                kind,
                Code::HitBehindOrigin,
                format!("t = {ts:.6} is behind the ray's origin"),
                v(),
            ));
            return;
        }
        // Self-intersection: the surface the ray leaves, at t ≈ 0.
        if let Some(lv) = leave {
            let same = c.entity.map_or((ps - lv.point).length() <= pos, |e| e == lv.entity);
            let genuine = rs.is_some_and(|h| h.entity == lv.entity && h.t <= pos);
            let sigma = (o - lv.point).dot(lv.facing);
            let heading = d.dot(lv.facing);
            // From an origin offset the way the ray goes, the surface it leaves lies behind it:
            // a hit there at t clearly below 0 is a root behind the origin that the intersection
            // test accepted, not rounding.
            if same && ts < -SURFACE_ROUNDING * l && sigma * heading > 0.0 {
                f.push(self.finding(
                    r,
                    kind,
                    Code::HitBehindOrigin,
                    format!(
                        "it hits '{}', the surface it leaves, at t = {ts:.2e}, behind its origin, which is correctly offset {:.2e} off that surface: the intersection test accepted a root behind the ray (for a sphere, the near root of a ray that starts inside it)",
                        self.name(lv.entity),
                        sigma.abs()
                    ),
                    v(),
                ));
                return;
            }
            if same && ts <= pos && !genuine {
                let code = if *kind == Kind::Shadow {
                    Code::ShadowAcne
                } else {
                    Code::SecondaryAcne
                };
                f.push(self.finding(r, kind, code, self.acne_detail(r, lv, ts), v()));
                return;
            }
        }
        let Some(h) = rs else {
            let on = c.entity.map(|e| self.geo.entity_distance(e, ps));
            if let Some((dist, Some(prim))) = on {
                if dist <= pos && self.geo.margin(prim, o, d, ps) <= self.tol.tie * l {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the ray grazes the edge of '{}'", self.name(c.entity.unwrap_or(0))),
                        v(),
                    ));
                    return;
                }
            }
            f.push(self.finding(
                r,
                kind,
                Code::HitPhantom,
                format!(
                    "your tracer reports {} at t = {ts:.6}; rayscope's trace of this ray hits nothing",
                    c.entity.map_or("a hit".to_string(), |e| format!("'{}'", self.name(e)))
                ),
                v(),
            ));
            return;
        };
        let cos = h.own.dot(d).abs().max(1e-3);
        let same_t = (ts - h.t).abs() <= pos / cos;
        let same_entity = c.entity.is_none_or(|e| e == h.entity);
        if same_entity && same_t {
            if let Some(n) = c.normal {
                self.normal(r, kind, n, h, f, tally);
            }
            return;
        }
        let l2 = scale(&[o, ps, h.point]);
        let tie = self.tol.tie * l2;
        if !same_entity {
            let e = c.entity.unwrap_or(h.entity);
            let (dist, prim) = self.geo.entity_distance(e, ps);
            if same_t && dist <= pos {
                f.push(self.finding(
                    r,
                    kind,
                    Code::TieEdge,
                    format!(
                        "'{}' and '{}' meet where the ray hits, at the same distance",
                        self.name(e),
                        self.name(h.entity)
                    ),
                    v(),
                ));
                return;
            }
            if ts < h.t {
                if dist <= pos && prim.is_some_and(|p| self.geo.margin(p, o, d, ps) <= tie) {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the ray grazes the edge of '{}'", self.name(e)),
                        v(),
                    ));
                } else {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitPhantom,
                        format!(
                            "your tracer reports '{}' at t = {ts:.6}, but {} there; rayscope's nearest hit is '{}' at t = {:.6}",
                            self.name(e),
                            if dist <= pos { "the ray misses it" } else { "it is not" },
                            self.name(h.entity),
                            h.t
                        ),
                        v(),
                    ));
                }
                return;
            }
        } else if ts < h.t && c.entity.is_none() {
            f.push(self.finding(
                r,
                kind,
                Code::HitPhantom,
                format!(
                    "your tracer reports a hit at t = {ts:.6}; rayscope's nearest is '{}' at t = {:.6}",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
            return;
        }
        // The tracer's hit lies beyond rayscope's nearest one.
        if c.entity == Some(h.entity) {
            f.push(self.finding(
                r,
                kind,
                Code::HitWrongT,
                format!(
                    "'{}' is hit at t = {:.6}, your tracer says t = {ts:.6}",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
        } else if self.geo.margin(h.prim, o, d, h.point) <= tie {
            f.push(self.finding(
                r,
                kind,
                Code::TieGrazing,
                format!("the ray grazes the edge of '{}'", self.name(h.entity)),
                v(),
            ));
        } else if let Some(share) = self.triangle_miss(h, tally) {
            f.push(self.finding(
                r,
                kind,
                Code::HitTriangleEdge,
                format!(
                    "{}, before the hit it reports at t = {ts:.6}",
                    self.edge_detail(h, share, "trace")
                ),
                v(),
            ));
        } else if matches!(h.prim, PrimRef::Triangle(_)) && !h.front {
            f.push(self.finding(
                r,
                kind,
                Code::HitOneSidedTriangle,
                format!(
                    "the ray passes through the back face of triangle '{}' at t = {:.6} before the hit your tracer reports",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
        } else {
            f.push(self.finding(
                r,
                kind,
                Code::HitFarther,
                format!(
                    "'{}' at t = {:.6} is nearer than the hit your tracer reports at t = {ts:.6}",
                    self.name(h.entity),
                    h.t
                ),
                v(),
            ));
        }
    }

    /// A triangle rayscope's trace meets and the tracer did not: a miss a little inside an
    /// edge on its front face is the inside test's margin (`Some` with the share of the altitude
    /// it passes inside); one on the back face is counted for the log-wide decision between a
    /// too strict inside test and a one-sided one (see [`Tally::finish`]).
    fn triangle_miss(&self, h: &RsHit, tally: &mut Tally) -> Option<f64> {
        let share = self.geo.edge_share(h.prim, h.point)?;
        let near = share < EDGE_SHARE;
        if h.front {
            return near.then_some(share);
        }
        if near {
            tally.back_near_edge += 1;
        } else {
            tally.back_inside += 1;
        }
        None
    }

    fn edge_detail(&self, h: &RsHit, share: f64, kind: &str) -> String {
        format!(
            "rayscope's {kind} meets triangle '{}' at t = {:.6}, {:.1} % of the triangle's height inside its nearest edge; your tracer does not",
            self.name(h.entity),
            h.t,
            100.0 * share
        )
    }

    fn acne_detail(&self, r: &LoggedRay, lv: &Leave, ts: f64) -> String {
        let sigma = (r.origin - lv.point).dot(lv.facing);
        let where_ = if sigma.abs() <= 1e-9 * scale(&[lv.point]) {
            "it starts exactly on the surface (no offset)".to_string()
        } else if sigma * r.direction.dot(lv.facing) < 0.0 {
            format!(
                "its origin is offset {:.2e} to the wrong side of the surface",
                sigma.abs()
            )
        } else {
            format!("its origin is only {:.2e} off the surface", sigma.abs())
        };
        format!(
            "it hits '{}', the surface it leaves, at t = {ts:.2e}: {where_}",
            self.name(lv.entity)
        )
    }

    /// The logged normal against the surface's two acceptable normals.
    fn normal(&self, r: &LoggedRay, kind: &Kind, n: DVec3, h: &RsHit, f: &mut Vec<Finding>, tally: &mut Tally) {
        let len = n.length();
        let values = vec![Value {
            what: "normal".into(),
            yours: vjson(n),
            rayscope: vjson(if h.front { h.own } else { -h.own }),
        }];
        if len.is_nan() || len <= 0.0 {
            f.push(self.finding(r, kind, Code::HitNormalWrong, "the normal is zero".into(), values));
            return;
        }
        if (len - 1.0).abs() > self.tol.unit {
            f.push(self.finding(
                r,
                kind,
                Code::HitNormalNotUnit,
                format!("the normal has length {len:.6}"),
                values.clone(),
            ));
        }
        let nh = n / len;
        let own = self.geo.shading_normal(h.prim, h.point).unwrap_or(h.own);
        let (a_plus, a_minus) = (
            angle(nh, own).min(angle(nh, h.own)),
            angle(nh, -own).min(angle(nh, -h.own)),
        );
        let tol = self.tol.normal;
        if a_plus.min(a_minus) > tol {
            f.push(self.finding(
                r,
                kind,
                Code::HitNormalWrong,
                format!(
                    "{:.3}° from the surface's normal at this point",
                    a_plus.min(a_minus).to_degrees()
                ),
                values,
            ));
            return;
        }
        let outward = a_plus <= tol;
        if h.front && !outward {
            let code = if matches!(h.prim, PrimRef::Triangle(i) if self.scene.vertex_normals(i).is_none()) {
                Code::HitNormalReversedWinding
            } else {
                Code::HitNormalWrong
            };
            f.push(self.finding(
                r,
                kind,
                code,
                format!(
                    "on the front of '{}' the normal points away from the ray and is not the outward normal",
                    self.name(h.entity)
                ),
                values,
            ));
            return;
        }
        if !h.front {
            // A back-face hit: the outward normal or the facing one, as long as it is always the same.
            let detail = if outward {
                format!("on the back of '{}' this normal is the outward one, while most of your back-face normals face the ray", self.name(h.entity))
            } else {
                format!("on the back of '{}' this normal faces the ray, while most of your back-face normals are the outward ones", self.name(h.entity))
            };
            let fnd = self.finding(r, kind, Code::HitNormalInconsistent, detail, values);
            // Counted on the side; `Tally::finish` decides which convention is the odd one out.
            let side = if outward { &mut tally.outward } else { &mut tally.facing };
            side.0 += 1;
            if side.1.len() < tally.keep {
                side.1.push(fnd);
            }
        }
    }

    /// A shadow ray's blocker (or none) against rayscope's segment to the light.
    #[allow(clippy::too_many_arguments)]
    fn blocked(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        li: u32,
        rs: Option<&RsHit>,
        t_skip: f64,
        blocked: Answer<u32>,
        leave: Option<&Leave>,
        f: &mut Vec<Finding>,
        tally: &mut Tally,
    ) {
        let (o_trace, d) = (r.origin, r.direction);
        let light = d3(Vec3A::from(self.scene.lights[li as usize].position));
        let dist = (light - o_trace).length();
        // `rs` is the ray's closest hit on the segment to this light.
        let b = rs.copied();
        let l = scale(&[r.origin, light]);
        let pos = self.tol.position * l;
        let values = |yours: Option<u32>, rs: Option<u32>| {
            vec![Value {
                what: format!("blocker of light '{}'", self.light_name(li)),
                yours: yours.map_or(json!("none: light reached"), |e| json!(self.name(e))),
                rayscope: rs.map_or(json!("none: light reached"), |e| json!(self.name(e))),
            }]
        };
        match blocked {
            Answer::NotLogged => {}
            Answer::Nothing => {
                let Some(b) = b else {
                    return;
                };
                let v = values(None, Some(b.entity));
                if (b.t - dist).abs() <= pos {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieLightOnSurface,
                        format!("light '{}' lies on '{}'", self.light_name(li), self.name(b.entity)),
                        v,
                    ));
                } else if self.geo.margin(b.prim, o_trace, d, b.point) <= self.tol.tie * l {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieGrazing,
                        format!("the shadow ray grazes the edge of '{}'", self.name(b.entity)),
                        v,
                    ));
                } else if let Some(share) = self.triangle_miss(&b, tally) {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::HitTriangleEdge,
                        format!(
                            "{}, between the point and light '{}'",
                            self.edge_detail(&b, share, "shadow ray"),
                            self.light_name(li)
                        ),
                        v,
                    ));
                } else if matches!(b.prim, PrimRef::Triangle(_)) && !b.front {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowOneSidedTriangle,
                        format!(
                            "triangle '{}' lies between the point and light '{}' (t = {:.6} of {:.6}) and the ray meets its back face",
                            self.name(b.entity),
                            self.light_name(li),
                            b.t,
                            dist
                        ),
                        v,
                    ));
                } else {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowMissedBlocker,
                        format!(
                            "'{}' lies between the point and light '{}' (t = {:.6} of {:.6})",
                            self.name(b.entity),
                            self.light_name(li),
                            b.t,
                            dist
                        ),
                        v,
                    ));
                }
            }
            Answer::Found(e) => {
                if b.is_some_and(|b| b.entity == e) {
                    return;
                }
                let on_segment = self.geo.entity_intersect(e, o_trace, d, t_skip, dist);
                if on_segment.is_some() && b.is_some() {
                    return;
                }
                let v = values(Some(e), b.map(|b| b.entity));
                if let (Some((t, _)), None) = (on_segment, b) {
                    // On the segment in double precision, not in rayscope's f32 trace: rounding.
                    let touching = t <= pos;
                    f.push(self.finding(
                        r,
                        kind,
                        if touching { Code::TieEdge } else { Code::TieGrazing },
                        format!(
                            "'{}' {} the shadow ray within rounding",
                            self.name(e),
                            if touching {
                                "touches the point it leaves, at"
                            } else {
                                "grazes"
                            }
                        ),
                        v,
                    ));
                    return;
                }
                // The origin lies on the named surface too (the point it leaves is where two
                // surfaces meet, an edge of the box): whether that surface blocks the ray at
                // t ≈ 0 is rounding.
                let on_named = self.geo.entity_distance(e, r.origin).0 <= SURFACE_ROUNDING * l
                    && self
                        .geo
                        .entity_intersect(e, r.origin, d, -SURFACE_ROUNDING * l, SURFACE_ROUNDING * l)
                        .is_some();
                if on_named && leave.is_some_and(|lv| lv.entity != e) {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieEdge,
                        format!(
                            "it starts where '{}' meets '{}', the surface it leaves: '{}' touches its origin within rounding",
                            self.name(e),
                            leave.map_or("?", |lv| self.name(lv.entity)),
                            self.name(e)
                        ),
                        v,
                    ));
                    return;
                }
                if on_named && leave.is_none() && r.parent.is_some() {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieEdge,
                        format!(
                            "it starts on '{}', at a hit of its parent ray that is itself a tie (two surfaces meet there): which surface it leaves is rounding",
                            self.name(e)
                        ),
                        v,
                    ));
                    return;
                }
                if let Some(lv) = leave {
                    if e == lv.entity && on_segment.is_none() {
                        let t_self = self.geo.entity_intersect(e, r.origin, d, -pos, dist).map(|x| x.0);
                        // Acne only if the ray meets the surface it leaves at t ≈ 0 from its
                        // origin (no offset, or one within rounding); from an offset origin the
                        // name is wrong for another reason, judged below.
                        if t_self.is_some_and(|t| t >= -SURFACE_ROUNDING * l) {
                            let t_self = t_self.unwrap_or(0.0);
                            f.push(self.finding(r, kind, Code::ShadowAcne, self.acne_detail(r, lv, t_self), v));
                            return;
                        }
                    }
                } else if on_segment.is_none() && self.geo.entity_distance(e, r.origin).0 <= SURFACE_ROUNDING * l {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowAcne,
                        format!(
                            "it is blocked by '{}', the surface its origin lies on (no offset?)",
                            self.name(e)
                        ),
                        v,
                    ));
                    return;
                }
                if let Some(b) = b {
                    // Named after an entity beyond the light: the blocker test accepts hits past
                    // the light, and this one came first in the tracer's list.
                    if let Some((t, _)) = self.geo.entity_intersect(e, o_trace, d, dist + pos, f64::INFINITY) {
                        f.push(self.finding(
                            r,
                            kind,
                            Code::ShadowBlockedBeyondLight,
                            format!(
                                "your tracer names '{}', which is on the ray at t = {t:.6}, beyond light '{}' at {dist:.6} ('{}' does block it, at t = {:.6})",
                                self.name(e),
                                self.light_name(li),
                                self.name(b.entity),
                                b.t
                            ),
                            v,
                        ));
                        return;
                    }
                    f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowWrongBlocker,
                        format!(
                            "'{}' is not on the shadow ray; '{}' blocks it (t = {:.6})",
                            self.name(e),
                            self.name(b.entity),
                            b.t
                        ),
                        v,
                    ));
                    return;
                }
                match self.geo.entity_intersect(e, o_trace, d, t_skip, f64::INFINITY) {
                    Some((t, _)) if (t - dist).abs() <= pos => f.push(self.finding(
                        r,
                        kind,
                        Code::TieLightOnSurface,
                        format!("light '{}' lies on '{}'", self.light_name(li), self.name(e)),
                        v,
                    )),
                    Some((t, _)) => f.push(self.finding(
                        r,
                        kind,
                        Code::ShadowBlockedBeyondLight,
                        format!(
                            "'{}' is on the ray at t = {t:.6}, beyond light '{}' at {dist:.6}",
                            self.name(e),
                            self.light_name(li)
                        ),
                        v,
                    )),
                    None => {
                        let (_, prim) = self.geo.entity_distance(e, o_trace);
                        let graze = prim.is_some_and(|p| {
                            // Where the ray's line meets the primitive's surface, against its edge.
                            let t = self.geo.intersect(p, o_trace, d, f64::MIN, f64::MAX).unwrap_or(0.0);
                            self.geo.margin(p, o_trace, d, o_trace + d * t) <= self.tol.tie * l
                        });
                        if graze {
                            f.push(self.finding(
                                r,
                                kind,
                                Code::TieGrazing,
                                format!("the shadow ray grazes the edge of '{}'", self.name(e)),
                                v,
                            ));
                        } else {
                            f.push(self.finding(
                                r,
                                kind,
                                Code::ShadowPhantomBlocker,
                                format!(
                                    "'{}' is not on the segment to light '{}'; rayscope finds nothing in the way",
                                    self.name(e),
                                    self.light_name(li)
                                ),
                                v,
                            ));
                        }
                    }
                }
            }
        }
    }

    /// How a secondary ray leaves its parent's hit: where it starts, and its direction for its kind.
    fn derivation(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) {
        let (o, d) = (r.origin, r.direction);
        let l = scale(&[o, lv.point, lv.parent_origin]);
        let away = (o - lv.point).length();
        if away > self.tol.offset * l {
            f.push(self.finding(
                r,
                kind,
                Code::SecondaryOriginNotAtHit,
                format!(
                    "starts {away:.4} away from its parent's hit on '{}'",
                    self.name(lv.entity)
                ),
                vec![Value {
                    what: "origin".into(),
                    yours: vjson(o),
                    rayscope: vjson(lv.point),
                }],
            ));
            return;
        }
        let m = &self.scene.materials[lv.material as usize];
        let material_mismatch = match kind {
            Kind::Refraction => !m.is_glass(),
            Kind::Reflection => !m.sends_reflection_rays(self.settings.stage),
            _ => false,
        };
        if material_mismatch {
            f.push(self.finding(
                r,
                kind,
                Code::SecondaryWrongMaterial,
                format!(
                    "a {} ray from '{}', whose material is {}",
                    kind.name(),
                    self.name(lv.entity),
                    m.kind.name()
                ),
                vec![],
            ));
            return;
        }
        let before = f.len();
        let expected = match kind {
            Kind::Reflection => Some(self.reflection(r, kind, lv, f)),
            Kind::Refraction => self.refraction(r, kind, lv, f),
            _ => None,
        };
        let direction_wrong = f.len() > before;
        // The side the ray starts on, against the side it should go to.
        let goes = expected.unwrap_or(d).dot(lv.facing);
        let sigma = (o - lv.point).dot(lv.facing);
        // A shadow ray toward a light behind the surface contributes nothing, wherever it starts.
        let judged = !(*kind == Kind::Shadow && goes <= 0.0);
        if judged && goes.abs() > 1e-9 && sigma * goes.signum() < -self.tol.side * l {
            // A wrong direction explains an origin on its own side.
            let consistent_with_own = sigma * d.dot(lv.facing) > 0.0;
            if !(direction_wrong && consistent_with_own) {
                f.push(self.finding(
                    r,
                    kind,
                    Code::SecondaryOffsetWrongSide,
                    format!(
                        "its origin is {:.2e} {} the surface of '{}', but the ray goes {}",
                        sigma.abs(),
                        if sigma > 0.0 { "in front of" } else { "behind" },
                        self.name(lv.entity),
                        if goes > 0.0 {
                            "back out on the incoming side"
                        } else {
                            "through the surface"
                        }
                    ),
                    vec![Value {
                        what: "offset along the normal facing the incoming ray".into(),
                        yours: njson(sigma),
                        rayscope: njson(goes.signum() * 1e-5 * l),
                    }],
                ));
            }
        }
    }

    /// A reflected ray against the mirror image of its parent; returns the expected direction.
    fn reflection(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) -> DVec3 {
        let want = reflect(lv.parent_dir, lv.facing).normalize();
        let err = angle(r.direction, want);
        if err > self.tol.direction + 2.0 * lv.un {
            let into = r.direction.dot(lv.facing) < 0.0;
            // The formula a student most often gets wrong, r = d − (d · n) n: the factor 2 lost.
            let no_two = (lv.parent_dir - lv.facing * lv.parent_dir.dot(lv.facing)).normalize_or_zero();
            let fits = if angle(r.direction, no_two) <= self.tol.direction + 2.0 * lv.un {
                "; it fits d − (d · n) n, the formula without its factor 2"
            } else if into {
                "; it goes into the surface"
            } else {
                ""
            };
            f.push(self.finding(
                r,
                kind,
                Code::ReflectionNotMirror,
                format!(
                    "{:.3}° from the mirror direction at '{}'{fits}",
                    err.to_degrees(),
                    self.name(lv.entity),
                ),
                vec![Value {
                    what: "direction".into(),
                    yours: vjson(r.direction),
                    rayscope: vjson(want),
                }],
            ));
        }
        want
    }

    /// A refracted ray against Snell's law at its parent's hit; returns the expected direction.
    fn refraction(&self, r: &LoggedRay, kind: &Kind, lv: &Leave, f: &mut Vec<Finding>) -> Option<DVec3> {
        let m = &self.scene.materials[lv.material as usize];
        let ior = f64::from(m.value);
        let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
        let eta = n1 / n2;
        let (dp, nf) = (lv.parent_dir, lv.facing);
        let cos_i = -dp.dot(nf);
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i);
        let ds = r.direction;
        // Near grazing exit the refracted angle swings by dθt/dθi = η cos θi / cos θt per radian
        // of the normal's uncertainty.
        let amp = eta * cos_i.abs() / (1.0 - sin2_t).max(1e-12).sqrt();
        let tol = self.tol.direction + lv.un * (1.0 + amp);
        let name = self.name(lv.entity);
        let leaving = if lv.front { "entering" } else { "leaving" };
        let value = |want: Option<DVec3>| {
            vec![Value {
                what: "direction".into(),
                yours: vjson(ds),
                rayscope: want.map_or(json!("none: total internal reflection"), vjson),
            }]
        };
        // The formula with the normal left unflipped (the outward one where the ray leaves).
        let unflipped = |eta: f64| {
            let n = -nf;
            let c = -dp.dot(n);
            let k = 1.0 - eta * eta * (1.0 - c * c);
            (dp * eta + n * (eta * c - k.max(0.0).sqrt())).normalize()
        };
        let matches = |v: Option<DVec3>| v.is_some_and(|v| angle(ds, v) <= tol);
        let want = refract(dp, nf, eta);
        if (sin2_t - 1.0).abs() <= 1e-3 {
            if !matches(want) && want.is_none_or(|w| angle(ds, w) > 1e-2) {
                // Not even near the grazing refraction: judged below like any other ray.
            } else {
                if want.is_none() {
                    f.push(self.finding(
                        r,
                        kind,
                        Code::TieCriticalAngle,
                        format!("sin²θt = {sin2_t:.6} at '{name}'"),
                        value(want),
                    ));
                }
                return want;
            }
        }
        if matches(want) {
            return want;
        }
        // The normal's sign does not change whether total internal reflection happens (the test
        // uses cos²θi), so under it a refracted ray means the test itself is missing.
        let tir = want.is_none();
        if !tir && !lv.front && matches(Some(unflipped(eta))) {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionNormalNotFlipped,
                format!("{leaving} '{name}' the ray bends back into the glass, as the outward normal makes it"),
                value(want),
            ));
            return want;
        }
        if !tir && !lv.front && matches(Some(unflipped(1.0 / eta))) {
            for code in [Code::RefractionNormalNotFlipped, Code::RefractionIndicesNotSwapped] {
                f.push(self.finding(
                    r,
                    kind,
                    code,
                    format!("{leaving} '{name}' the ray fits the outward normal with the indices unswapped"),
                    value(want),
                ));
            }
            return want;
        }
        if matches(refract(dp, nf, 1.0 / eta)) {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionIndicesNotSwapped,
                format!(
                    "{leaving} '{name}' the ray bends with η = {:.4} instead of {:.4}",
                    1.0 / eta,
                    eta
                ),
                value(want),
            ));
            return want;
        }
        if want.is_none() {
            f.push(self.finding(
                r,
                kind,
                Code::RefractionTirMissed,
                format!(
                    "{leaving} '{name}' at {:.2}° from the normal, past the critical angle of {:.2}° (sin²θt = {sin2_t:.4} > 1): nothing is transmitted",
                    cos_i.clamp(-1.0, 1.0).acos().to_degrees(),
                    (1.0 / eta).min(1.0).asin().to_degrees()
                ),
                value(want),
            ));
            return want;
        }
        let sin_i = dp.cross(nf).length();
        let sin_t = ds.cross(nf).length();
        let detail = if ds.dot(nf) > 0.0 {
            format!("{leaving} '{name}' the refracted ray goes back out on the side the ray came from")
        } else if sin_i > 1e-6 {
            format!(
                "{leaving} '{name}' it bends as if n1 / n2 were {:.4}, not {:.4}",
                sin_t / sin_i,
                eta
            )
        } else {
            format!("{leaving} '{name}' at normal incidence it should go straight through")
        };
        f.push(self.finding(r, kind, Code::RefractionSnell, detail, value(want)));
        want
    }
}

/// Each ray's parent in `rays`: the last ray logged with its `parent` id, never itself. Groups
/// of at most `scan` rays are searched directly, which for the handful of rays of a sample is
/// sooner than building a map.
fn parents(rays: &[LoggedRay], scan: usize) -> Vec<Option<usize>> {
    let own = |i: usize, p: Option<usize>| p.filter(|&p| p != i);
    if rays.len() <= scan {
        rays.iter()
            .enumerate()
            .map(|(i, r)| own(i, r.parent.and_then(|p| rays.iter().rposition(|q| q.id == Some(p)))))
            .collect()
    } else {
        let ids: FxHashMap<i64, usize> = rays
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.id.map(|id| (id, i)))
            .collect();
        rays.iter()
            .enumerate()
            .map(|(i, r)| own(i, r.parent.and_then(|p| ids.get(&p).copied())))
            .collect()
    }
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
        assert_eq!(parents(&rays, 32), want);
        assert_eq!(parents(&rays, 0), want);
    }
}
