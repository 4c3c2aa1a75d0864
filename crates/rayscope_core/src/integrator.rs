//! Integrators: stage 1 (flat colour), stage 2 (Whitted: point lights, mirrors, Fresnel glass)
//! and the full renderer (stage 2 plus every stage-3 add-on), all generic over a [`RayObserver`].
//!
//! # The full renderer's rules
//!
//! * **Whitted core.** Without stage-3 content or flags the full renderer is exactly stage 2:
//!   point lights use the course's Σ max(0, N·L)·Cm·Cl (no attenuation), mirrors and Fresnel
//!   glass recurse up to `max_depth`, glass splits into a reflected and a refracted ray.
//! * **Emissive (A).** Spheres and triangles with an Emissive material are two-sided area lights
//!   whose colour is their radiance; they show that colour and are not shaded by other lights.
//!   At every Diffuse or Glossy hit one emitter point is sampled (emitter chosen by power, a
//!   sphere by the cone it subtends, a triangle by area) and one direction is drawn from the
//!   BRDF; the two are combined by multiple importance sampling with the power heuristic, so
//!   shadows are soft and the result converges to the direct light any correct path tracer
//!   computes (Diffuse BRDF = colour / π).
//! * **Ambient (B, `-l`).** `-l` turns on indirect illumination: full path tracing, cosine /
//!   BRDF-sampled bounces with Russian roulette after three bounces, emitters found by both
//!   strategies (MIS) at every vertex, and point lights next-event-estimated at every vertex
//!   with the course's formula (a point light delivers irradiance π·Cl·max(0, N·L), which is
//!   the course's term for a Lambertian surface). Ambient light is therefore light that has
//!   bounced off other surfaces: the background stays black (there is no sky), crevices
//!   darken because fewer paths reach them, and colours bleed. In a point-light-only scene,
//!   `-l` adds the indirect light of the point-lit surfaces.
//! * **Glossy (D).** See [`crate::bsdf`]: Lambert base under a GGX dielectric coat; the number
//!   is a glossiness, α = (1 / (1 + n))². Without `-l` the coat's reflection is traced
//!   recursively (blurred reflections of the scene, up to `max_depth`) while the base gets
//!   direct light only; point lights are evaluated with the whole BRDF, π·f·Cl·max(0, N·L).
//! * **Beer (F).** A ray travelling inside a Refractive object whose colour σ is non-zero is
//!   attenuated by exp(−σ·d) per channel over the distance d it travels inside.
//! * **Quality (`-q`).** Each of the `-x N` grid cells gets 2^q paths when a stochastic
//!   effect is on (emissive or glossy surfaces, `-l`, or an aperture), else one; sample `s`
//!   of a pixel is grid cell `s mod N²` and path `s div N²`, with its own random stream. With a
//!   stochastic effect each path starts at a random point of its cell (stratified jitter), so
//!   pixels converge to their area's mean; otherwise samples sit at the cell centres.

use glam::Vec3A;

use crate::accel::ApexCull;
use crate::bsdf::Bsdf;
use crate::camera::{cell_centre, jittered, Camera};
use crate::geometry::PrimRef;
use crate::lights::{point_light_contribution, point_light_contribution_brdf, toward_point_light, Emitters};
use crate::math::{basis, offset_eps, Ray};
use crate::mistakes::{self, Mistake};
use crate::observer::{BranchFate, GlassBranch, GlassDecision, RayKind, RayObserver};
use crate::optics::{fresnel, glass_rays, mirror_ray, schlick};
use crate::rng::Rng;
pub use crate::sampling::concentric_disk;
use crate::sampling::{power_heuristic, to_local, to_world};
use crate::scene::{Hit, Intersect, Material, Scene, Surface};
use crate::settings::{Channel, RenderSettings, Stage};
use rayscope_scene::MaterialKind;

mod packets;
mod wave;
pub(crate) use packets::Job;
pub(crate) use wave::WaveWork;

/// Ray counts gathered while rendering.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Camera rays.
    pub camera: u64,
    /// Reflection, refraction and bounce rays.
    pub secondary: u64,
    /// Shadow and emitter rays.
    pub shadow: u64,
}

impl Counters {
    /// All rays.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.camera + self.secondary + self.shadow
    }

    /// Adds another set of counts.
    pub fn add(&mut self, o: &Counters) {
        self.camera += o.camera;
        self.secondary += o.secondary;
        self.shadow += o.shadow;
    }
}

/// The per-render state every sample needs.
#[derive(Debug, Clone)]
pub struct Integrator<'a, I: Intersect = Scene> {
    /// The scene.
    pub scene: &'a Scene,
    /// The intersector rays are traced with (the scene's BVH, or the reference).
    pub isect: &'a I,
    /// The settings.
    pub settings: &'a RenderSettings,
    /// Camera built from the settings.
    pub camera: Camera,
    /// The scene's area lights.
    pub emitters: Emitters,
    /// True when a stochastic effect is on, so `-q` multiplies the samples.
    pub stochastic: bool,
    /// Whitted glass branches with a smaller path weight are not traced (0: trace all).
    pub branch_cutoff: f32,
    /// Per material: a hit on it is shaded by point lights alone (see `point_lit_only`).
    pub(crate) point_lit: Vec<bool>,
    /// Side of the sample grid: N for `-x N`, 1 when a pixel takes one sample.
    grid: u32,
    /// Each grid cell's offset inside its pixel, ((i + 0.5)/N, (j + 0.5)/N), row by row; empty
    /// for grids too large to tabulate. Looked up rather than recomputed because the integer
    /// divisions that find (i, j) cost as much as making the camera ray.
    cells: Vec<[f32; 2]>,
    /// The flat list seen from the pinhole camera's centre and from each point light, for ray
    /// packets that leave or reach those points (see [`ApexCull`]).
    pub(crate) beams: Beams,
    /// Per sphere: where it sits among the BVH's sphere packets, when it is glass and no other
    /// primitive comes near it ([`Scene::sphere_alone`]), so packets of rays that refracted
    /// into it test it alone.
    pub(crate) lone_spheres: Vec<Option<(u32, u32)>>,
    /// True when some material is glass that absorbs (Beer's law, [`Self::absorb`]), so a path
    /// can travel inside a medium.
    pub(crate) media: bool,
}

/// [`ApexCull`]s of the points many packets' rays share.
#[derive(Debug, Clone, Default)]
pub(crate) struct Beams {
    /// From the camera's centre (pinhole cameras only).
    pub(crate) camera: Option<ApexCull>,
    /// From each point light, in the scene's order.
    pub(crate) lights: Vec<Option<ApexCull>>,
}

/// Largest grid side whose cell offsets are tabulated (16,384 cells, 128 KiB).
const MAX_TABULATED_GRID: u32 = 128;

/// A shading frame (tangent, bitangent, normal) and the local outgoing direction.
type Frame = (Vec3A, Vec3A, Vec3A, Vec3A);

/// Most non-specular bounces of a path under `-l` (Russian roulette ends nearly all before).
const MAX_BOUNCES: u32 = 64;
/// Bounces before Russian roulette starts.
const RR_START: u32 = 3;

/// Whitted glass splits into two rays at every hit, so a pixel seen through glass costs up to
/// 2^depth rays. A branch that can bring back at most this much radiance (its weight times the
/// brightest radiance any ray can return) is not traced: the ≤ 2·depth branches a sample can
/// drop then add up to less than one 8-bit level.
const MIN_BRANCH_RADIANCE: f32 = 1.0 / 4096.0;

/// State carried down a path.
#[derive(Debug, Clone, Copy)]
struct PathState {
    /// Mirror, glass and glossy-coat bounces so far (limited by `max_depth`).
    depth: u32,
    /// Non-specular (sampled) bounces so far.
    bounces: u32,
    /// The path throughput so far (what the camera's sample is multiplied by): Russian roulette
    /// keeps a path with its largest channel's probability, and glass branches are pruned by it.
    // A `Vec3`, not a `Vec3A`: its 16-byte alignment would pad the state from 32 to 48 bytes,
    // which packets and waves copy per lane.
    beta: glam::Vec3,
    /// Material whose absorbance applies to the ray (Beer's law), if it travels inside one.
    medium: Option<u32>,
    /// Split glass into both rays (Whitted) rather than choosing one by its Fresnel weight.
    branch: bool,
}

/// The rays leaving a glass hit (see [`Integrator::glass`]).
#[derive(Debug, Clone, Copy)]
struct Glass {
    /// Fresnel reflectance.
    kr: f32,
    /// The reflected ray.
    reflected: Ray,
    /// The refracted ray; none under total internal reflection.
    refracted: Option<Ray>,
    /// Medium the reflected ray travels in.
    refl_medium: Option<u32>,
    /// Medium the refracted ray travels in.
    refr_medium: Option<u32>,
}

impl PathState {
    /// The state of the ray a mirror reflects this path into.
    #[inline]
    fn mirrored(self) -> PathState {
        self.specular(self.medium, self.beta)
    }

    /// The state of a ray a mirror or glass sends on: one level deeper, travelling in `medium`,
    /// with path weight `beta`.
    #[inline]
    fn specular(self, medium: Option<u32>, beta: glam::Vec3) -> PathState {
        PathState {
            depth: self.depth + 1,
            medium,
            beta,
            ..self
        }
    }

    /// The state of a camera ray.
    const CAMERA: PathState = PathState {
        depth: 0,
        bounces: 0,
        beta: glam::Vec3::ONE,
        medium: None,
        branch: true,
    };
}

/// An emitter sample's shadow ray and the light it brings when nothing blocks it.
#[derive(Debug, Clone, Copy)]
struct ShadowRay {
    ray: Ray,
    /// Just short of the sampled point, so the emitter does not block itself.
    t_max: f32,
    /// The weighted light the sample adds when the ray is not blocked.
    unblocked: Vec3A,
    /// Beer's-law transmittance to the emitter, inside an absorbing medium.
    attenuation: Option<Vec3A>,
}

impl ShadowRay {
    /// What the sample adds, given whether the ray is blocked.
    #[inline(always)]
    fn contrib(&self, blocked: bool) -> Vec3A {
        let c = if blocked { Vec3A::ZERO } else { self.unblocked };
        self.attenuation.map_or(c, |a| c * a)
    }
}

/// Radiance arriving along a ray, split so the caller can weight emission by MIS.
#[derive(Debug, Clone, Copy, Default)]
struct Li {
    /// Radiance emitted by the surface the ray hit.
    emitted: Vec3A,
    /// Everything else (light reflected or transmitted by that surface).
    reflected: Vec3A,
    /// Density with which emitter sampling from the ray's origin would pick the hit point.
    light_pdf: f32,
}

impl Li {
    fn total(&self) -> Vec3A {
        self.emitted + self.reflected
    }

    fn reflected(v: Vec3A) -> Li {
        Li {
            reflected: v,
            ..Li::default()
        }
    }

    /// This radiance after a segment with transmittance `att` (Beer's law), if any.
    #[inline]
    fn absorbed(mut self, att: Option<Vec3A>) -> Li {
        if let Some(a) = att {
            self.emitted *= a;
            self.reflected *= a;
        }
        self
    }
}

/// True when glass of material `m` absorbs light (Beer's law, from its colour) at `stage`.
fn absorbs(stage: Stage, m: &Material) -> bool {
    stage == Stage::Full && m.kind == MaterialKind::Refractive && m.color != glam::Vec3::ZERO
}

impl<'a> Integrator<'a, Scene> {
    /// An integrator for `scene` with `settings`, tracing with the scene's BVH.
    #[must_use]
    pub fn new(scene: &'a Scene, settings: &'a RenderSettings) -> Self {
        Self::with_intersector(scene, scene, settings)
    }
}

impl<'a, I: Intersect> Integrator<'a, I> {
    /// An integrator for `scene` with `settings`, tracing with `isect`.
    #[must_use]
    pub fn with_intersector(scene: &'a Scene, isect: &'a I, settings: &'a RenderSettings) -> Self {
        let full = settings.stage == Stage::Full;
        let emitters = if full {
            Emitters::from_scene(scene)
        } else {
            Emitters::default()
        };
        let glossy = scene
            .entities
            .iter()
            .any(|e| scene.materials[e.material as usize].kind == MaterialKind::Glossy);
        let stochastic =
            full && (settings.ambient || settings.camera.aperture_radius > 0.0 || emitters.any_emission || glossy);
        // Without stochastic effects every ray returns at most Σ lights × the largest albedo
        // (mirrors and glass only pass light on), which bounds what a pruned branch could add.
        let branch_cutoff = if stochastic {
            0.0
        } else {
            let lights: f32 = scene.lights.iter().map(|l| l.color.max_element().max(0.0)).sum();
            let albedo = scene
                .materials
                .iter()
                .map(|m| m.color.max_element())
                .fold(1.0f32, f32::max);
            MIN_BRANCH_RADIANCE / (lights * albedo).max(f32::MIN_POSITIVE)
        };
        let mut camera = Camera::new(settings.camera, settings.width, settings.height);
        if I::MISTAKEN {
            isect.mistakes().adjust_camera(&mut camera);
        }
        Self {
            scene,
            isect,
            settings,
            camera,
            emitters,
            stochastic,
            branch_cutoff,
            point_lit: Vec::new(),
            grid: 1,
            cells: Vec::new(),
            beams: Beams::default(),
            lone_spheres: Vec::new(),
            media: scene.materials.iter().any(|m| absorbs(settings.stage, m)),
        }
        .with_point_lit()
        .with_grid()
        .with_beams()
    }

    /// Fills in [`Self::beams`], for renders that trace ray packets through a flat list, and
    /// [`Self::lone_spheres`].
    fn with_beams(mut self) -> Self {
        let Some(bvh) = self.isect.wide() else {
            return self;
        };
        let camera = (!self.thin_lens()).then(|| ApexCull::new(bvh, self.camera.origin.to_array()));
        self.beams = Beams {
            camera: camera.flatten(),
            lights: self
                .scene
                .lights
                .iter()
                .map(|l| ApexCull::new(bvh, l.position.to_array()))
                .collect(),
        };
        // Glass spheres only: rays start inside a sphere where they refract into it, and the
        // check costs a pass over the scene's triangles per sphere.
        let glass = |k: usize| {
            let (_, m) = self.scene.prim_info(PrimRef::Sphere(k as u32));
            self.scene.materials[m as usize].kind == MaterialKind::Refractive
        };
        self.lone_spheres = (0..self.scene.spheres.len())
            .map(|k| {
                (glass(k) && self.scene.sphere_alone(k))
                    .then(|| bvh.sphere_slot(k as u32))
                    .flatten()
            })
            .collect();
        self
    }

    /// Fills in [`Self::grid`] and [`Self::cells`].
    fn with_grid(mut self) -> Self {
        let n = if self.samples_per_pixel() == 1 {
            1
        } else {
            self.settings.aa.max(1)
        };
        self.grid = n;
        if n <= MAX_TABULATED_GRID {
            self.cells = (0..n * n).map(|c| cell_centre(c, n)).collect();
        }
        self
    }

    /// True when this render makes mistake `m`: never for rayscope's own intersectors, for
    /// which the test is a constant false.
    #[inline(always)]
    fn mistake(&self, m: Mistake) -> bool {
        I::MISTAKEN && self.isect.mistakes().has(m)
    }

    /// Offset inside its pixel of sample `s`: that of cell `s mod N²`.
    #[inline]
    pub(crate) fn cell_offset(&self, s: u32) -> [f32; 2] {
        let nn = self.grid * self.grid;
        // Samples come in order, so `s < N²` (no division) unless `-q` repeats the grid.
        let cell = if s < nn { s } else { s % nn };
        match self.cells.get(cell as usize) {
            Some(&o) => o,
            None => cell_centre(cell, self.grid),
        }
    }

    /// Paths traced through each `-x` grid position: 2^q when a stochastic effect is on, else 1.
    #[must_use]
    pub fn paths_per_cell(&self) -> u32 {
        if self.stochastic && self.settings.channel == Channel::Color {
            1 << self.settings.quality.min(16)
        } else {
            1
        }
    }

    /// Samples per pixel the settings ask for: N² grid positions × [`Self::paths_per_cell`].
    #[must_use]
    pub fn samples_per_pixel(&self) -> u32 {
        match self.settings.stage {
            Stage::One => 1,
            _ if self.settings.channel != Channel::Color => 1,
            _ => (self.settings.aa * self.settings.aa).saturating_mul(self.paths_per_cell()),
        }
    }

    /// Normalised image position of sample `s` of pixel (`x`, `y`): in cell `s mod N²` of the
    /// N×N regular grid for `-x N`, at its centre ((x + (i + 0.5)/N)/W, (y + (j + 0.5)/N)/H)
    /// when nothing is stochastic, else at a random point of the cell (stratified jitter, the
    /// first two numbers of the sample's stream); the pixel centre for stage 1 and debug channels.
    #[must_use]
    #[inline]
    pub fn sample_position(&self, x: u32, y: u32, s: u32) -> (f32, f32) {
        self.position_in_cell(x, y, s, &mut self.sample_rng(x, y, s))
    }

    /// The random stream of sample `s` of pixel (`x`, `y`).
    #[must_use]
    #[inline]
    pub fn sample_rng(&self, x: u32, y: u32, s: u32) -> Rng {
        let pixel = y as u64 * self.settings.width as u64 + x as u64;
        Rng::for_sample(self.settings.seed, pixel, s as u64)
    }

    /// [`Self::sample_position`], drawing the jitter from `rng`, the sample's fresh stream.
    #[inline]
    fn position_in_cell(&self, x: u32, y: u32, s: u32, rng: &mut Rng) -> (f32, f32) {
        let [mut ox, mut oy] = self.cell_offset(s);
        if self.mistake(Mistake::PixelCorners) {
            // The cell's top-left corner, (i/N, j/N), rather than its centre.
            let n = self.grid as f32;
            ox = (ox * n - 0.5).round() / n;
            oy = (oy * n - 0.5).round() / n;
        }
        if self.stochastic && self.settings.channel == Channel::Color {
            // Paths spread over their cell, so a pixel converges to the integral over its area
            // (edges antialiased as a box filter would) rather than to N×N point samples.
            let n = self.grid as f32;
            ox = jittered(ox, rng.next_f32(), n);
            oy = jittered(oy, rng.next_f32(), n);
        }
        let w = self.settings.width as f32;
        let h = self.settings.height as f32;
        ((x as f32 + ox) / w, (y as f32 + oy) / h)
    }

    /// True when camera rays start on a lens (depth of field) rather than at a pinhole.
    #[inline]
    fn thin_lens(&self) -> bool {
        self.settings.stage == Stage::Full && self.settings.camera.aperture_radius > 0.0
    }

    /// The camera ray of sample `s` of pixel (`x`, `y`); `rng` is the sample's fresh stream
    /// ([`Self::sample_rng`]).
    // Always inlined: with the jitter it is past the inliner's limit, and as a call it costs the
    // path-traced box 3 % (`rayscope bench render -f scenes/emissive.txt -w 200 -h 200 -x 2 -q 2
    // -l --threads 1`).
    #[must_use]
    #[inline(always)]
    pub fn camera_ray(&self, x: u32, y: u32, s: u32, rng: &mut Rng) -> Ray {
        let (u, v) = self.position_in_cell(x, y, s, rng);
        if self.thin_lens() {
            self.camera
                .lens_ray(u, v, concentric_disk(rng.next_f32(), rng.next_f32()))
        } else {
            self.camera.ray(u, v)
        }
    }

    /// Colour of one sample of pixel (`x`, `y`).
    #[inline]
    pub fn sample<O: RayObserver>(&self, x: u32, y: u32, s: u32, obs: &mut O, c: &mut Counters) -> Vec3A {
        let y = if self.mistake(Mistake::ImageFlipped) {
            self.settings.height - 1 - y
        } else {
            y
        };
        let mut rng = self.sample_rng(x, y, s);
        let ray = self.camera_ray(x, y, s, &mut rng);
        c.camera += 1;
        if self.settings.channel != Channel::Color {
            return self.channel(&ray, obs);
        }
        let id = obs.ray(None, RayKind::Camera, 0, &ray, f32::INFINITY);
        let v = self.radiance(&ray, id, &mut rng, obs, c);
        obs.result(id, 1.0, v);
        v
    }

    /// Radiance along `ray` (a camera ray, reported to `obs` as `id`) with a fresh path state.
    #[inline]
    pub fn radiance<O: RayObserver>(&self, ray: &Ray, id: u32, rng: &mut Rng, obs: &mut O, c: &mut Counters) -> Vec3A {
        self.trace(ray, PathState::CAMERA, true, id, rng, obs, c).total()
    }

    fn channel<O: RayObserver>(&self, ray: &Ray, obs: &mut O) -> Vec3A {
        let id = obs.ray(None, RayKind::Camera, 0, ray, f32::INFINITY);
        let Some(hit) = self.isect.intersect(ray, 0.0, f32::INFINITY) else {
            return Vec3A::ZERO;
        };
        let s = self.scene.surface(ray, &hit);
        obs.hit(id, self.scene, hit.t, &s);
        match self.settings.channel {
            Channel::Normal => s.shading_normal * 0.5 + Vec3A::splat(0.5),
            Channel::Depth => {
                // Scenes of planes alone have no bounds; fall back to a fixed range then.
                let b = &self.scene.bounds;
                let far = if b.is_empty() {
                    100.0
                } else {
                    (b.max - b.min).length().max(1.0) + (self.camera.origin - b.center()).length()
                };
                Vec3A::splat(1.0 - (hit.t / far).clamp(0.0, 1.0))
            }
            Channel::Entity => entity_color(s.entity),
            Channel::Albedo | Channel::Color => self.scene.materials[s.material as usize].color.into(),
            Channel::Cost => {
                let cost = self.scene.traversal_cost(ray);
                heat((cost as f32 / 64.0).min(1.0))
            }
        }
    }

    /// Radiance along `ray`, which has already been reported to `obs` as `id`. With
    /// `want_reflected` false only the hit surface's own emission is computed.
    #[allow(clippy::too_many_arguments)]
    fn trace<O: RayObserver>(
        &self,
        ray: &Ray,
        path: PathState,
        want_reflected: bool,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Li {
        let hit = self.isect.intersect(ray, 0.0, f32::INFINITY);
        self.trace_found(ray, hit, path, want_reflected, id, rng, obs, c)
    }

    /// [`Self::trace`] once the ray's closest hit has been found: `hit`, or none.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn trace_found<O: RayObserver>(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        path: PathState,
        want_reflected: bool,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Li {
        let Some(hit) = hit else {
            return Li::default();
        };
        let s = self.scene.surface(ray, &hit);
        self.trace_hit(ray, &hit, &s, path, want_reflected, id, rng, obs, c)
    }

    /// [`Self::trace`] from the ray's closest hit `hit`, whose surface is `s`.
    #[allow(clippy::too_many_arguments)]
    fn trace_hit<O: RayObserver>(
        &self,
        ray: &Ray,
        hit: &Hit,
        s: &Surface,
        path: PathState,
        want_reflected: bool,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Li {
        let reversed;
        let s = if self.mistake(Mistake::ReversedNormals) {
            reversed = self.reversed_normal(hit, s);
            &reversed
        } else {
            s
        };
        if O::ENABLED {
            obs.hit(id, self.scene, hit.t, s);
        }
        let m = &self.scene.materials[s.material as usize];
        let stage = self.settings.stage;
        if stage == Stage::One {
            return Li::reflected(m.color.into());
        }
        let full = stage == Stage::Full;
        let out = match m.kind {
            MaterialKind::Emissive if full => Li {
                emitted: m.color.into(),
                reflected: Vec3A::ZERO,
                light_pdf: if self.emitters.is_empty() {
                    0.0
                } else {
                    self.emitters.pdf(self.scene, ray.origin, hit.prim, s.point)
                },
            },
            _ if !want_reflected => return Li::default(),
            MaterialKind::Diffuse | MaterialKind::Glossy if full => self.shade(ray, s, m, path, id, rng, obs, c),
            MaterialKind::Diffuse | MaterialKind::Glossy | MaterialKind::Emissive => {
                Li::reflected(self.direct_point_lights(s, ray, None, Vec3A::from(m.color), id, path.depth, obs, c))
            }
            MaterialKind::Reflective => {
                if path.depth >= self.settings.max_depth {
                    return Li::default();
                }
                let (r, child) = Self::mirror(ray, s, path);
                Li::reflected(self.secondary(&r, child, id, RayKind::Reflection, 1.0, rng, obs, c))
            }
            MaterialKind::Refractive => {
                if path.depth >= self.settings.max_depth {
                    return Li::default();
                }
                Li::reflected(self.refractive(ray, s, m, path, id, rng, obs, c))
            }
        };
        self.absorb(path, hit.t, out)
    }

    /// The surface as a tracer with [`Mistake::ReversedNormals`] sees it: a triangle's normal
    /// (v2 − v0) × (v1 − v0), not turned towards the ray.
    #[cold]
    fn reversed_normal(&self, hit: &Hit, s: &Surface) -> Surface {
        let triangle =
            matches!(hit.prim, PrimRef::Triangle(_)) && self.scene.entities[s.entity as usize].kind == "Triangle";
        if !triangle {
            return *s;
        }
        if !s.front_face {
            // Seen from behind, the reversed normal is the one that faces the ray.
            return Surface { front_face: true, ..*s };
        }
        Surface {
            normal: -s.normal,
            shading_normal: -s.shading_normal,
            front_face: false,
            ..*s
        }
    }

    /// Fresnel glass: both rays while the path is still deterministic, one chosen by its
    /// Fresnel weight after a sampled bounce.
    #[allow(clippy::too_many_arguments)]
    fn refractive<O: RayObserver>(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        path: PathState,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        let g = self.glass(ray, s, m, path);
        if path.branch || self.settings.stage != Stage::Full {
            let mut out = Vec3A::ZERO;
            let reflected = self.glass_reflected(&g, path);
            let refracted = self.glass_refracted(&g, path);
            if O::ENABLED {
                let fate = |kept: bool, exists: bool| match (kept, exists) {
                    (true, _) => BranchFate::Traced,
                    (false, true) => BranchFate::Pruned,
                    (false, false) => BranchFate::Absent,
                };
                let fates = (
                    fate(reflected.is_some(), g.kr > 0.0),
                    fate(refracted.is_some(), g.refracted.is_some()),
                );
                obs.glass(id, &self.glass_decision(ray, s, m, &g, path, fates));
            }
            if let Some((r, p)) = reflected {
                out += self.secondary(&r, p, id, RayKind::Reflection, g.kr, rng, obs, c) * g.kr;
            }
            if let Some((r, p)) = refracted {
                out += self.secondary(&r, p, id, RayKind::Refraction, 1.0 - g.kr, rng, obs, c) * (1.0 - g.kr);
            }
            out
        } else {
            let child = |medium| path.specular(medium, path.beta);
            match g.refracted {
                Some(r) if rng.next_f32() >= g.kr => {
                    if O::ENABLED {
                        let fates = (BranchFate::NotChosen, BranchFate::Traced);
                        obs.glass(id, &self.glass_decision(ray, s, m, &g, path, fates));
                    }
                    self.secondary(&r, child(g.refr_medium), id, RayKind::Refraction, 1.0, rng, obs, c)
                }
                _ => {
                    if O::ENABLED {
                        let refr = if g.refracted.is_some() {
                            BranchFate::NotChosen
                        } else {
                            BranchFate::Absent
                        };
                        obs.glass(
                            id,
                            &self.glass_decision(ray, s, m, &g, path, (BranchFate::Traced, refr)),
                        );
                    }
                    self.secondary(
                        &g.reflected,
                        child(g.refl_medium),
                        id,
                        RayKind::Reflection,
                        1.0,
                        rng,
                        obs,
                        c,
                    )
                }
            }
        }
    }

    /// What the recorder shows of a glass hit: the indices and angles Snell's law and Fresnel
    /// used (as this render's mistakes, if any, chose them) and the fates of both rays.
    #[cold]
    #[allow(clippy::too_many_arguments)]
    fn glass_decision(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        g: &Glass,
        path: PathState,
        (refl_fate, refr_fate): (BranchFate, BranchFate),
    ) -> GlassDecision {
        let swap = !s.front_face && !self.mistake(Mistake::RefractionNoIndexSwap);
        let (n1, n2) = if swap { (m.value, 1.0) } else { (1.0, m.value) };
        let cos_i = (-ray.dir.dot(s.normal)).clamp(0.0, 1.0);
        let beta = path.beta.max_element();
        // Measured from the ray actually sent, so a wrong refraction formula shows.
        let cos_t = g.refracted.map(|r| -r.dir.dot(s.normal));
        let split = path.branch || self.settings.stage != Stage::Full;
        let (wr, wt) = if split { (g.kr, 1.0 - g.kr) } else { (1.0, 1.0) };
        GlassDecision {
            entering: s.front_face,
            n1,
            n2,
            cos_i,
            cos_t,
            tir: (n1 / n2).powi(2) * (1.0 - cos_i * cos_i).max(0.0) >= 1.0,
            reflectance: g.kr,
            prune_below: if split { self.branch_cutoff } else { 0.0 },
            reflected: GlassBranch {
                fate: refl_fate,
                weight: wr,
                path_weight: beta * wr,
                origin: Some(g.reflected.origin.to_array()),
                direction: Some(g.reflected.dir.to_array()),
            },
            refracted: GlassBranch {
                fate: refr_fate,
                weight: if g.refracted.is_some() { wt } else { 0.0 },
                path_weight: if g.refracted.is_some() { beta * wt } else { 0.0 },
                origin: g.refracted.map(|r| r.origin.to_array()),
                direction: g.refracted.map(|r| r.dir.to_array()),
            },
        }
    }

    /// The two rays leaving a glass hit, before any is chosen or pruned.
    #[inline]
    fn glass(&self, ray: &Ray, s: &Surface, m: &Material, path: PathState) -> Glass {
        if I::MISTAKEN {
            return self.mistaken_glass(ray, s, m, path);
        }
        let eps = offset_eps(s.point, ray.origin);
        let (kr, reflected, refracted) = glass_rays(ray.dir, s.normal, s.point, eps, s.front_face, m.value);
        let (refl_medium, refr_medium) = self.glass_media(s, m, path);
        Glass {
            kr,
            reflected,
            refracted,
            refl_medium,
            refr_medium,
        }
    }

    /// [`Self::glass`] as a tracer with this render's glass mistakes computes it.
    #[cold]
    fn mistaken_glass(&self, ray: &Ray, s: &Surface, m: &Material, path: PathState) -> Glass {
        let swap = !s.front_face && !self.mistake(Mistake::RefractionNoIndexSwap);
        let (n1, n2) = if swap { (m.value, 1.0) } else { (1.0, m.value) };
        let cos_i = (-ray.dir.dot(s.normal)).clamp(0.0, 1.0);
        let tir = {
            let eta = n1 / n2;
            eta * eta * (1.0 - cos_i * cos_i).max(0.0) >= 1.0
        };
        let kr = if tir {
            1.0
        } else if self.mistake(Mistake::NoFresnel) {
            0.0
        } else if self.mistake(Mistake::FresnelHalf) {
            0.5
        } else if self.mistake(Mistake::Schlick) {
            schlick(cos_i, n1, n2)
        } else {
            fresnel(cos_i, n1, n2)
        };
        // Leaving the glass without the flip, the normal is the outward one, facing away from
        // the ray: Snell's formula then gets cos θᵢ < 0 and the offsets go to the wrong sides.
        let n = if !s.front_face && self.mistake(Mistake::RefractionNoNormalFlip) {
            -s.normal
        } else {
            s.normal
        };
        let eps = offset_eps(s.point, ray.origin);
        let refracted = if tir {
            None
        } else {
            let eta = n1 / n2;
            let c = -ray.dir.dot(n);
            let cos_t = (1.0 - eta * eta * (1.0 - c * c)).max(0.0).sqrt();
            Some((ray.dir * eta + n * (eta * c - cos_t)).normalize())
        };
        let (refl_medium, refr_medium) = self.glass_media(s, m, path);
        let no_tir = tir && self.mistake(Mistake::NoTir);
        Glass {
            // Without total internal reflection the ray that should reflect brings nothing.
            kr: if no_tir { 0.0 } else { kr },
            reflected: mirror_ray(ray.dir, n, s.point, eps),
            refracted: refracted.map(|t| Ray::new(s.point - n * eps, t)),
            refl_medium,
            refr_medium,
        }
    }

    /// The media a glass hit's reflected and refracted rays travel in.
    #[inline]
    fn glass_media(&self, s: &Surface, m: &Material, path: PathState) -> (Option<u32>, Option<u32>) {
        let absorbing = absorbs(self.settings.stage, m);
        let this = absorbing.then_some(s.material);
        // Reflected rays stay on the incoming side; refracted rays cross into the other medium
        // (the outside of every object is air).
        if s.front_face {
            (path.medium, this)
        } else {
            (this, None)
        }
    }

    /// Whitted glass's reflected ray (weight `kr`) and its path, unless it is pruned.
    #[inline]
    fn glass_reflected(&self, g: &Glass, path: PathState) -> Option<(Ray, PathState)> {
        (g.kr > 0.0 && path.beta.max_element() * g.kr >= self.branch_cutoff)
            .then(|| (g.reflected, path.specular(g.refl_medium, path.beta * g.kr)))
    }

    /// Whitted glass's refracted ray (weight 1 − `kr`) and its path, unless there is none (total
    /// internal reflection) or it is pruned.
    #[inline]
    fn glass_refracted(&self, g: &Glass, path: PathState) -> Option<(Ray, PathState)> {
        let r = g
            .refracted
            .filter(|_| path.beta.max_element() * (1.0 - g.kr) >= self.branch_cutoff)?;
        Some((r, path.specular(g.refr_medium, path.beta * (1.0 - g.kr))))
    }

    /// A mirror's reflected ray and its path.
    #[inline]
    fn mirror(ray: &Ray, s: &Surface, path: PathState) -> (Ray, PathState) {
        let eps = offset_eps(s.point, ray.origin);
        (mirror_ray(ray.dir, s.normal, s.point, eps), path.mirrored())
    }

    /// Beer's law over the segment of length `t` a ray travelled inside an absorbing medium.
    #[inline]
    fn absorb(&self, path: PathState, t: f32, out: Li) -> Li {
        out.absorbed(self.transmittance(path, t))
    }

    /// Beer's-law transmittance over distance `t` for a ray with state `path`, when it travels
    /// inside an absorbing medium.
    #[inline]
    fn transmittance(&self, path: PathState, t: f32) -> Option<Vec3A> {
        path.medium.map(|mi| {
            let sigma = Vec3A::from(self.scene.materials[mi as usize].color);
            (-sigma * t).exp()
        })
    }

    /// A Diffuse or Glossy hit in the full renderer: point lights, one emitter sample and one
    /// BRDF sample (MIS), and the bounce's indirect light where the rules carry it.
    #[allow(clippy::too_many_arguments)]
    fn shade<O: RayObserver>(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        path: PathState,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Li {
        let ambient = self.settings.ambient;
        let coat_only = !ambient && !self.emitters.any_emission;
        let Some(bsdf) = Bsdf::of(m, coat_only) else {
            return Li::default();
        };
        let n = s.shading_normal;
        let (t, b) = basis(n);
        let mut wo = to_local(-ray.dir, t, b, n);
        if wo.z < 1e-4 {
            // Interpolated normals can face away from the viewer near silhouettes.
            wo = Vec3A::new(wo.x, wo.y, 1e-4).normalize();
        }
        let frame = (t, b, n, wo);
        let lambert = matches!(bsdf, Bsdf::Lambert { .. });
        let origin = s.point + s.normal * offset_eps(s.point, ray.origin);
        let mut l = self.direct_point_lights(
            s,
            ray,
            (!lambert).then_some((&bsdf, frame)),
            Vec3A::from(m.color),
            id,
            path.depth,
            obs,
            c,
        );

        // Emitter sampling, weighted against BRDF sampling. With no observer recording the
        // rays, the shadow ray waits and is traced together with the bounce ray below, whose
        // query does not depend on it (`Intersect::intersect_and_occluded`); its light is still
        // added before the bounce's, so the sum is the same.
        let mut pending: Option<ShadowRay> = None;
        if !self.emitters.is_empty() {
            let (u0, u1, u2) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
            if let Some(ls) = self.emitters.sample(self.scene, origin, u0, u1, u2) {
                let wi = to_local(ls.dir, t, b, n);
                let (f, _) = bsdf.eval(wo, wi);
                if wi.z > 0.0 && ls.dir.dot(s.normal) > 0.0 && f != Vec3A::ZERO {
                    let shadow = Ray::new(origin, ls.dir);
                    let t_max = ls.dist * (1.0 - 1e-4);
                    c.shadow += 1;
                    let sid = obs.ray(Some(id), RayKind::Emitter, path.depth, &shadow, t_max);
                    let w = power_heuristic(ls.pdf, bsdf.pdf(wo, wi));
                    let sr = ShadowRay {
                        ray: shadow,
                        t_max,
                        unblocked: f * ls.radiance * (wi.z * w / ls.pdf),
                        // Beer's law for rays that stay inside the medium the hit lies in.
                        attenuation: self.transmittance(path, ls.dist),
                    };
                    if O::ENABLED {
                        let blocker = self
                            .isect
                            .occluder(&shadow, 0.0, t_max)
                            .map(|p| self.scene.prim_info(p).0);
                        let e = &self.emitters.list[ls.emitter as usize];
                        let nearest = self.nearest_blocker(&shadow, t_max, blocker);
                        let name = &self.scene.entities[e.entity as usize].name;
                        obs.shadow(sid, self.scene, name, blocker, nearest.as_ref().map(|(t, s)| (*t, s)));
                        let contrib = sr.contrib(blocker.is_some());
                        obs.result(sid, w, contrib);
                        l += contrib;
                    } else {
                        pending = Some(sr);
                    }
                }
            }
        }
        // Where no bounce ray follows, the waiting shadow ray is traced alone.
        let alone = |l: Vec3A, pending: Option<ShadowRay>| match pending {
            Some(sr) => l + sr.contrib(self.isect.occluded(&sr.ray, 0.0, sr.t_max)),
            None => l,
        };

        // BRDF sampling: emitters it finds (MIS) and, where carried, indirect light.
        let coated = !lambert;
        if !(self.emitters.any_emission || ambient || coated) {
            return Li::reflected(alone(l, pending));
        }
        let (u0, u1, u2) = (rng.next_f32(), rng.next_f32(), rng.next_f32());
        let Some(bs) = bsdf.sample(wo, u0, u1, u2) else {
            return Li::reflected(alone(l, pending));
        };
        let wi_w = to_world(bs.wi, t, b, n).normalize();
        if wi_w.dot(s.normal) <= 0.0 {
            return Li::reflected(alone(l, pending));
        }
        let w_total = bs.f * (bs.wi.z / bs.pdf);
        let mut carry = if ambient {
            w_total
        } else {
            bs.f_coat * (bs.wi.z / bs.pdf)
        };
        let mut child = PathState {
            depth: path.depth,
            bounces: path.bounces + 1,
            beta: path.beta * glam::Vec3::from(carry),
            medium: path.medium,
            branch: false,
        };
        let mut want = carry.max_element() > 0.0;
        if ambient {
            want &= path.bounces < MAX_BOUNCES;
            if want && path.bounces >= RR_START {
                let p = child.beta.max_element().min(0.95);
                if rng.next_f32() < p {
                    carry /= p;
                    child.beta /= p;
                } else {
                    want = false;
                }
            }
        } else {
            // Without -l only the coat's reflection recurses, like a blurred mirror.
            want &= path.depth < self.settings.max_depth;
            child.depth += 1;
        }
        if !want && self.emitters.is_empty() && !self.emitters.any_emission {
            return Li::reflected(alone(l, pending));
        }
        let r = Ray::new(origin, wi_w);
        c.secondary += 1;
        let cid = obs.ray(Some(id), RayKind::Bounce, child.depth, &r, f32::INFINITY);
        let hit = match pending {
            Some(sr) => {
                let (hit, blocked) = self.isect.intersect_and_occluded(&r, &sr.ray, sr.t_max);
                l += sr.contrib(blocked);
                hit
            }
            None => self.isect.intersect(&r, 0.0, f32::INFINITY),
        };
        let li = self.trace_found(&r, hit, child, want, cid, rng, obs, c);
        let mis = if li.light_pdf > 0.0 {
            power_heuristic(bs.pdf, li.light_pdf)
        } else {
            1.0
        };
        let contrib = w_total * li.emitted * mis + carry * li.reflected;
        obs.result(cid, mis, contrib);
        l += contrib;
        Li::reflected(l)
    }

    #[allow(clippy::too_many_arguments)]
    fn secondary<O: RayObserver>(
        &self,
        r: &Ray,
        path: PathState,
        parent: u32,
        kind: RayKind,
        weight: f32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        c.secondary += 1;
        let id = obs.ray(Some(parent), kind, path.depth, r, f32::INFINITY);
        let v = self.trace(r, path, true, id, rng, obs, c).total();
        obs.result(id, weight, v);
        v
    }

    /// The closest surface on a shadow ray the occluder query found `blocker` on, for the
    /// recorder: its distance and surface.
    #[cold]
    fn nearest_blocker(&self, shadow: &Ray, t_max: f32, blocker: Option<u32>) -> Option<(f32, Surface)> {
        blocker?;
        let hit = self.isect.intersect(shadow, 0.0, t_max)?;
        Some((hit.t, self.scene.surface(shadow, &hit)))
    }

    /// Point lights: the course's Σ max(0, N·L) · albedo · light colour over visible lights, or
    /// with a BRDF, Σ π · f · light colour · max(0, N·L). The shadow rays are recorded at
    /// `depth`, that of the ray whose hit they light.
    #[allow(clippy::too_many_arguments)]
    fn direct_point_lights<O: RayObserver>(
        &self,
        s: &Surface,
        ray: &Ray,
        brdf: Option<(&Bsdf, Frame)>,
        albedo: Vec3A,
        parent: u32,
        depth: u32,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        let mut sum = Vec3A::ZERO;
        let eps = offset_eps(s.point, ray.origin);
        let origin = if I::MISTAKEN {
            mistakes::shadow_origin(self.isect.mistakes(), s.point, s.normal, eps)
        } else {
            s.point + s.normal * eps
        };
        for (li, light) in self.scene.lights.iter().enumerate() {
            if li > 0 && self.mistake(Mistake::FirstLightOnly) {
                break;
            }
            // A student's huge offset moves the shadow ray only: the light's direction is
            // still taken from the hit point.
            let from = if self.mistake(Mistake::HugeShadowOffset) {
                s.point
            } else {
                origin
            };
            let Some((l, dist, cos)) = toward_point_light(from, s.shading_normal, Vec3A::from(light.position)) else {
                continue;
            };
            let shadow = Ray::new(origin, l);
            c.shadow += 1;
            let reach = if self.mistake(Mistake::ShadowPastLight) {
                f32::INFINITY
            } else {
                dist
            };
            let id = obs.ray(Some(parent), RayKind::Shadow, depth, &shadow, reach);
            let blocker = if O::ENABLED {
                self.isect
                    .occluder(&shadow, 0.0, reach)
                    .map(|p| self.scene.prim_info(p).0)
            } else if cos <= 0.0 || self.isect.occluded(&shadow, 0.0, reach) {
                // Shadow rays behind the surface cannot contribute; only the recorder needs them traced.
                Some(u32::MAX)
            } else {
                None
            };
            if O::ENABLED {
                let nearest = self.nearest_blocker(&shadow, reach, blocker);
                let name = &self.scene.light_names[li];
                obs.shadow(id, self.scene, name, blocker, nearest.as_ref().map(|(t, s)| (*t, s)));
            }
            let contrib = if blocker.is_none() && cos > 0.0 {
                match brdf {
                    None => point_light_contribution(albedo, Vec3A::from(light.color), cos),
                    Some((bsdf, (t, b, n, wo))) => {
                        let (f, _) = bsdf.eval(wo, to_local(l, t, b, n));
                        point_light_contribution_brdf(f, Vec3A::from(light.color), cos)
                    }
                }
            } else {
                Vec3A::ZERO
            };
            let contrib = if self.mistake(Mistake::LightFalloff) {
                contrib / (dist * dist)
            } else {
                contrib
            };
            obs.result(id, cos.max(0.0), contrib);
            sum += contrib;
        }
        if self.mistake(Mistake::AmbientTerm) {
            sum += albedo * mistakes::AMBIENT;
        }
        sum
    }
}

/// A distinct, stable colour for entity `i`.
#[must_use]
pub fn entity_color(i: u32) -> Vec3A {
    // Golden-ratio hue steps keep neighbouring ids far apart.
    let h = (i as f32 * 0.618_034 + 0.1).fract();
    let f = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        1.0 - 0.8 * (k.min(4.0 - k).clamp(0.0, 1.0))
    };
    Vec3A::new(f(5.0), f(3.0), f(1.0)) * 0.85 + Vec3A::splat(0.1)
}

/// A blue→cyan→green→yellow→red ramp for `t` ∈ [0, 1].
#[must_use]
pub fn heat(t: f32) -> Vec3A {
    let t = t.clamp(0.0, 1.0) * 4.0;
    let stops = [
        Vec3A::new(0.0, 0.0, 0.6),
        Vec3A::new(0.0, 0.8, 1.0),
        Vec3A::new(0.1, 0.9, 0.1),
        Vec3A::new(1.0, 0.9, 0.0),
        Vec3A::new(1.0, 0.1, 0.0),
    ];
    let i = (t as usize).min(3);
    stops[i].lerp(stops[i + 1], t - i as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn disk_samples_inside() {
        for i in 0..32 {
            for j in 0..32 {
                let p = concentric_disk(i as f32 / 31.0, j as f32 / 31.0);
                assert!(p.length() <= 1.0 + 1e-6);
            }
        }
    }
}
