//! Ray recording: integrators report every ray they cast to a [`RayObserver`]. The render path
//! uses [`NoObserver`], whose methods are empty and inlined away; the debugger and
//! `rayscope trace` use [`RayRecorder`], which builds a [`RayTree`].

use glam::Vec3A;
use serde::{Deserialize, Serialize};

use crate::math::Ray;
use crate::scene::Scene;
use crate::surface::Surface;

/// Why a ray was cast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RayKind {
    /// From the camera through the image plane.
    Camera,
    /// Towards a point light, to test visibility.
    Shadow,
    /// Mirror reflection (Reflective, or the reflected part of Refractive).
    Reflection,
    /// Transmission into or out of a Refractive material.
    Refraction,
    /// Towards a sampled point on an emissive surface.
    Emitter,
    /// A sampled bounce (diffuse or glossy) for indirect light.
    Bounce,
}

impl RayKind {
    /// The kind's word, as in `trace --json` and ray logs.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            RayKind::Camera => "camera",
            RayKind::Shadow => "shadow",
            RayKind::Reflection => "reflection",
            RayKind::Refraction => "refraction",
            RayKind::Emitter => "emitter",
            RayKind::Bounce => "bounce",
        }
    }
}

/// Receives the rays an integrator casts. All methods default to doing nothing.
pub trait RayObserver {
    /// False for observers that record nothing, so integrators can skip bookkeeping.
    const ENABLED: bool;
    /// A ray was cast; returns its id for the calls that follow.
    fn ray(&mut self, _parent: Option<u32>, _kind: RayKind, _depth: u32, _ray: &Ray, _t_max: f32) -> u32 {
        0
    }
    /// The ray `id` hit `surface` at `t`.
    fn hit(&mut self, _id: u32, _scene: &Scene, _t: f32, _surface: &Surface) {}
    /// The shadow or emitter ray `id` towards light `light` was blocked by entity `blocker`;
    /// `nearest` is the closest surface in the way and its distance, when the intersector finds it.
    fn shadow(
        &mut self,
        _id: u32,
        _scene: &Scene,
        _light: &str,
        _blocker: Option<u32>,
        _nearest: Option<(f32, &Surface)>,
    ) {
    }
    /// The glass hit of ray `id` split (or not) into the rays `decision` describes.
    fn glass(&mut self, _id: u32, _decision: &GlassDecision) {}
    /// The ray `id` carried `value` back, scaled by `weight` in its parent (Fresnel, BSDF, …).
    fn result(&mut self, _id: u32, _weight: f32, _value: Vec3A) {}
}

/// The observer of the render path: records nothing and costs nothing.
#[derive(Debug, Clone, Copy, Default)]
pub struct NoObserver;

impl RayObserver for NoObserver {
    const ENABLED: bool = false;
}

/// What a recorded ray hit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayHitInfo {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Entity index.
    pub entity: u32,
    /// Entity name.
    pub entity_name: String,
    /// Hit point.
    pub point: [f32; 3],
    /// Unit normal facing the ray.
    pub normal: [f32; 3],
    /// True when the primitive's own normal faced the ray.
    pub front_face: bool,
    /// Material name.
    pub material: String,
    /// Material type.
    pub material_kind: String,
}

/// What happened to one of the two rays a glass hit can send on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BranchFate {
    /// Cast: it is the hit's child of the same kind.
    Traced,
    /// Not cast because its path weight times the brightest radiance any ray can bring back is
    /// below 1/4096: it could not change an 8-bit value of the pixel.
    Pruned,
    /// Not cast: after a sampled bounce glass follows one ray, chosen by its Fresnel weight.
    NotChosen,
    /// There is no such ray: the refraction under total internal reflection, or a reflection
    /// of weight 0.
    Absent,
}

/// One ray a glass hit can send on.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GlassBranch {
    /// What became of it.
    pub fate: BranchFate,
    /// Its factor in the hit's radiance (Fresnel reflectance, or 1 − it).
    pub weight: f32,
    /// The largest channel of the whole path's weight up to and including this ray.
    pub path_weight: f32,
    /// Where it starts, the hit point offset to its side of the surface, and its unit
    /// direction (both absent for a refraction under total internal reflection).
    pub origin: Option<[f32; 3]>,
    /// See `origin`.
    pub direction: Option<[f32; 3]>,
}

/// How a ray met glass: the indices, angles and Fresnel split Snell's law works with.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GlassDecision {
    /// True when the ray enters the glass (it hit the front face), false when it leaves.
    pub entering: bool,
    /// Index of refraction on the incoming side.
    pub n1: f32,
    /// Index of refraction on the far side.
    pub n2: f32,
    /// Cosine of the angle between the incoming ray and the normal facing it.
    pub cos_i: f32,
    /// Cosine of the angle between the refracted ray and the reversed normal (`None` under
    /// total internal reflection).
    pub cos_t: Option<f32>,
    /// Total internal reflection: sin θₜ = (n₁/n₂)·sin θᵢ would exceed 1.
    pub tir: bool,
    /// Fresnel reflectance: the reflected ray's weight.
    pub reflectance: f32,
    /// Path weights below this are pruned (0: nothing is).
    pub prune_below: f32,
    /// The reflected ray.
    pub reflected: GlassBranch,
    /// The refracted ray.
    pub refracted: GlassBranch,
}

/// One recorded ray.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RayNode {
    /// Index in [`RayTree::nodes`].
    pub id: u32,
    /// Parent ray, `None` for camera rays.
    pub parent: Option<u32>,
    /// Why it was cast.
    pub kind: RayKind,
    /// Number of bounces before it (camera rays: 0).
    pub depth: u32,
    /// Origin.
    pub origin: [f32; 3],
    /// Secondary rays: `origin` minus the parent's hit point, computed exactly (the offset that
    /// keeps the ray off the surface it leaves).
    pub offset: Option<[f64; 3]>,
    /// Secondary rays whose offset lies along the parent's hit normal: the offset as a multiple
    /// of that normal (`origin = point + k·normal`); negative for rays that go through.
    pub offset_along_normal: Option<f64>,
    /// Unit direction.
    pub direction: [f32; 3],
    /// Upper bound of the search (`None`: unbounded).
    pub t_max: Option<f32>,
    /// What it hit (`None`: nothing; shadow rays report blockers in `blocked_by`).
    pub hit: Option<RayHitInfo>,
    /// Shadow/emitter rays: the light it tested.
    pub light: Option<String>,
    /// Shadow/emitter rays: the entity in the way, if any.
    pub blocked_by: Option<String>,
    /// Shadow/emitter rays: the closest surface in the way, with its distance (`t`), point
    /// and face, when the ray is blocked.
    pub blocker: Option<RayHitInfo>,
    /// Glass hits: the indices, angles and Fresnel split, and what became of both rays.
    pub glass: Option<GlassDecision>,
    /// Factor applied to `value` in the parent (Fresnel reflectance, BSDF weight, …).
    pub weight: f32,
    /// Radiance it brought back.
    pub value: [f32; 3],
}

/// The rays cast for one sample of one pixel, in casting order.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RayTree {
    /// Pixel column (0-based, from the left).
    pub x: u32,
    /// Pixel row (0-based, from the top).
    pub y: u32,
    /// Sample index within the pixel.
    pub sample: u32,
    /// Rays; a node's parent always comes before it.
    pub nodes: Vec<RayNode>,
    /// The sample's final colour.
    pub color: [f32; 3],
}

/// Builds a [`RayTree`]; stops recording past `limit` rays so a runaway path cannot exhaust memory.
#[derive(Debug, Clone)]
pub struct RayRecorder {
    /// Rays recorded so far.
    pub nodes: Vec<RayNode>,
    /// Most rays kept.
    pub limit: usize,
    /// Rays cast but not kept because of `limit`.
    pub dropped: usize,
}

impl Default for RayRecorder {
    fn default() -> Self {
        Self {
            nodes: Vec::new(),
            limit: 100_000,
            dropped: 0,
        }
    }
}

/// What a ray that hit `s` at `t` records.
fn hit_info(scene: &Scene, t: f32, s: &Surface) -> RayHitInfo {
    let m = &scene.materials[s.material as usize];
    RayHitInfo {
        t,
        entity: s.entity,
        entity_name: scene.entities[s.entity as usize].name.clone(),
        point: s.point.to_array(),
        normal: s.normal.to_array(),
        front_face: s.front_face,
        material: scene.material_names[s.material as usize].clone(),
        material_kind: m.kind.name().to_string(),
    }
}

/// A secondary ray's offset from its parent's hit point `h`, and that offset as a multiple of
/// the hit normal when it lies along it.
fn offset_from(h: &RayHitInfo, origin: [f32; 3]) -> ([f64; 3], Option<f64>) {
    // Differences of two f32s are exact in f64.
    let o: [f64; 3] = std::array::from_fn(|i| f64::from(origin[i]) - f64::from(h.point[i]));
    let n = h.normal.map(f64::from);
    let k = o[0] * n[0] + o[1] * n[1] + o[2] * n[2];
    let len = (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt();
    let lateral = (0..3).map(|i| (o[i] - k * n[i]).powi(2)).sum::<f64>().sqrt();
    // The origin is the f32 sum point + k·normal, so each coordinate carries a rounding error
    // of up to half an ulp of the point's: about 0.6 % of an offset of 1e-5 of the coordinates.
    let along = lateral <= 0.05 * len || len == 0.0;
    (o, along.then_some(k))
}

impl RayObserver for RayRecorder {
    const ENABLED: bool = true;

    fn ray(&mut self, parent: Option<u32>, kind: RayKind, depth: u32, ray: &Ray, t_max: f32) -> u32 {
        if self.nodes.len() >= self.limit {
            self.dropped += 1;
            return u32::MAX;
        }
        let id = self.nodes.len() as u32;
        let parent = parent.filter(|&p| p != u32::MAX);
        let origin = ray.origin.to_array();
        let (offset, offset_along_normal) = parent
            .and_then(|p| self.nodes.get(p as usize))
            .and_then(|p| p.hit.as_ref())
            .map_or((None, None), |h| {
                let (o, k) = offset_from(h, origin);
                (Some(o), k)
            });
        self.nodes.push(RayNode {
            id,
            parent,
            kind,
            depth,
            origin,
            offset,
            offset_along_normal,
            direction: ray.dir.to_array(),
            t_max: t_max.is_finite().then_some(t_max),
            hit: None,
            light: None,
            blocked_by: None,
            blocker: None,
            glass: None,
            weight: 1.0,
            value: [0.0; 3],
        });
        id
    }

    fn hit(&mut self, id: u32, scene: &Scene, t: f32, s: &Surface) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        n.hit = Some(hit_info(scene, t, s));
    }

    fn shadow(&mut self, id: u32, scene: &Scene, light: &str, blocker: Option<u32>, nearest: Option<(f32, &Surface)>) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        n.light = Some(light.to_string());
        n.blocked_by = blocker.map(|e| scene.entities[e as usize].name.clone());
        n.blocker = blocker.and(nearest).map(|(t, s)| hit_info(scene, t, s));
    }

    fn glass(&mut self, id: u32, decision: &GlassDecision) {
        if let Some(n) = self.nodes.get_mut(id as usize) {
            n.glass = Some(*decision);
        }
    }

    fn result(&mut self, id: u32, weight: f32, value: Vec3A) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        n.weight = weight;
        n.value = value.to_array();
    }
}
