//! Ray recording: integrators report every ray they cast to a [`RayObserver`]. The render path
//! uses [`NoObserver`], whose methods are empty and inlined away; the debugger and
//! `rayscope trace` use [`RayRecorder`], which builds a [`RayTree`].

use glam::Vec3A;
use serde::{Deserialize, Serialize};

use crate::math::Ray;
use crate::scene::{Scene, Surface};

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
    /// The shadow or emitter ray `id` towards light `light` was blocked by entity `blocker`.
    fn shadow(&mut self, _id: u32, _scene: &Scene, _light: &str, _blocker: Option<u32>) {}
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

impl RayObserver for RayRecorder {
    const ENABLED: bool = true;

    fn ray(&mut self, parent: Option<u32>, kind: RayKind, depth: u32, ray: &Ray, t_max: f32) -> u32 {
        if self.nodes.len() >= self.limit {
            self.dropped += 1;
            return u32::MAX;
        }
        let id = self.nodes.len() as u32;
        self.nodes.push(RayNode {
            id,
            parent: parent.filter(|&p| p != u32::MAX),
            kind,
            depth,
            origin: ray.origin.to_array(),
            direction: ray.dir.to_array(),
            t_max: t_max.is_finite().then_some(t_max),
            hit: None,
            light: None,
            blocked_by: None,
            weight: 1.0,
            value: [0.0; 3],
        });
        id
    }

    fn hit(&mut self, id: u32, scene: &Scene, t: f32, s: &Surface) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        let m = &scene.materials[s.material as usize];
        n.hit = Some(RayHitInfo {
            t,
            entity: s.entity,
            entity_name: scene.entities[s.entity as usize].name.clone(),
            point: s.point.to_array(),
            normal: s.normal.to_array(),
            front_face: s.front_face,
            material: scene.material_names[s.material as usize].clone(),
            material_kind: m.kind.name().to_string(),
        });
    }

    fn shadow(&mut self, id: u32, scene: &Scene, light: &str, blocker: Option<u32>) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        n.light = Some(light.to_string());
        n.blocked_by = blocker.map(|e| scene.entities[e as usize].name.clone());
    }

    fn result(&mut self, id: u32, weight: f32, value: Vec3A) {
        let Some(n) = self.nodes.get_mut(id as usize) else {
            return;
        };
        n.weight = weight;
        n.value = value.to_array();
    }
}
