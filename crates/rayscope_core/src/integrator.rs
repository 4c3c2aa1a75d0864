//! Integrators: stage 1 (flat colour), stage 2 (Whitted: point lights, mirrors, Fresnel glass)
//! and the full renderer (stage 2 plus every stage-3 add-on).
//!
//! This file holds what every engine shares (the [`Integrator`], the `Job` a sample is, the
//! per-path context `PathCx`, sample positions and whether they jitter, camera rays) and the
//! choice of [`Engine`]. `rules.rs` holds the shading rules the engines share; the engines
//! switch on a hit's [`Lobe`](crate::scene::Lobe) and hand the rest of a lane's path to the
//! one-path engine through one door (`one_path.rs`, `hand_over`); each engine has its own file:
//! `one_path.rs` (one path at a time, generic over a
//! [`RayObserver`](crate::observer::RayObserver) that records rays), `packets.rs` (ray
//! packets), `camera_packets.rs` and `wave.rs` (waves of paths).
//!
//! # The full renderer's rules
//!
//! * **Whitted core.** Without stage-3 content or flags the full renderer is exactly stage 2:
//!   point lights use the course's Σ max(0, N·L)·Cm·Cl (no attenuation), mirrors and Fresnel
//!   glass recurse up to `max_depth`, glass splits into a reflected and a refracted ray.
//! * **Recursion limit.** The camera ray has depth 0, every reflected, refracted or bounce ray
//!   one more than its parent. By default ([`DepthLimit::MirrorGlass`]) a mirror or glass hit on
//!   a ray of depth ≥ `max_depth` returns black and `-l`'s bounces do not count (Russian
//!   roulette ends them); with [`DepthLimit::All`] every ray of depth > `max_depth` returns
//!   black, `-l`'s bounces counted too. Whitted images are the same under both.
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
//!   attenuated by exp(−σ·d) per channel over the distance d it travels inside; not in the
//!   2021 edition ([`crate::settings::Edition`]), whose glass colour plays no part.
//! * **Quality (`-q`).** Each of the `-x N` grid cells gets 2^q paths when a stochastic
//!   effect is on (emissive or glossy surfaces, `-l`, or an aperture), else one; sample `s`
//!   of a pixel is grid cell `s mod N²` and path `s div N²`, with its own random stream. With a
//!   stochastic effect each cell's paths start at the points of a scrambled Sobol sequence of
//!   the cell's own, so pixels converge to their area's mean; otherwise samples sit at the cell
//!   centres. Every stochastic decision draws from the sample's [`Sampler`] (`crate::sobol`)
//!   at a dimension fixed by the decision and the path vertex.

use std::sync::atomic::{AtomicBool, Ordering};

use glam::Vec3A;

use crate::camera::{cell_centre, jittered, Camera};
use crate::lights::Emitters;
use crate::math::Ray;
use crate::mistakes::Mistake;
pub(crate) use crate::sampling::concentric_disk;
use crate::scene::{Intersect, Scene};
use crate::settings::{Channel, DepthLimit, RenderSettings, Stage};
use crate::sobol::{Draw, Sampler};
use crate::surface::Surface;

mod camera_packets;
mod one_path;
mod packet_state;
mod packets;
mod rules;
mod wave;

use packet_state::PacketSetup;
pub(crate) use wave::WaveWork;

/// A sample to trace: pixel (x, y) and sample index.
pub(crate) type Job = (u32, u32, u32);

/// What one sample carries down every vertex of its path, besides the path's state: its random
/// stream, the observer recording its rays and the ray counters.
pub(crate) struct PathCx<'p, O> {
    /// The sample's random numbers.
    pub(crate) rng: &'p mut Sampler,
    /// Where the path's rays are recorded ([`crate::observer::NoObserver`] when they are not).
    pub(crate) obs: &'p mut O,
    /// Ray counts.
    pub(crate) c: &'p mut Counters,
}

/// How a render computes its samples. Every engine returns the same pixels, bit for bit, and
/// the same ray counts; they differ in how much work sixteen samples share.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Engine {
    /// Sixteen samples traced together, recursively, as ray packets, with their shadow rays,
    /// mirror and glass rays as packets too (`integrator/packets.rs`, `sample_packet`).
    Packets,
    /// Sixteen paths advanced together a vertex a step, their rays and shadow rays traced as
    /// packets and their Lambertian vertices shaded in lanes (`integrator/wave.rs`).
    Waves,
    /// The camera rays of sixteen samples traced as one packet, each path then traced one ray at
    /// a time from its first hit (`integrator/packets.rs`, `sample_camera_packet`).
    CameraPackets,
    /// One path at a time, recursively (`integrator.rs`, [`Integrator::sample`]): the engine
    /// every other one is checked against, and the one that records rays.
    OnePath,
}

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
    pub(crate) isect: &'a I,
    /// The settings.
    pub settings: &'a RenderSettings,
    /// Camera built from the settings.
    pub camera: Camera,
    /// The scene's area lights.
    pub(crate) emitters: Emitters,
    /// True when a stochastic effect is on, so `-q` multiplies the samples.
    pub stochastic: bool,
    /// Whitted glass branches with a smaller path weight are not traced (0: trace all).
    pub branch_cutoff: f32,
    /// Side of the sample grid: N for `-x N`, 1 when a pixel takes one sample.
    grid: u32,
    /// Each grid cell's offset inside its pixel, ((i + 0.5)/N, (j + 0.5)/N), row by row; empty
    /// for grids too large to tabulate. Looked up rather than recomputed because the integer
    /// divisions that find (i, j) cost as much as making the camera ray.
    cells: Vec<[f32; 2]>,
    /// What only the engines that trace ray packets use ([`PacketSetup`]).
    pub(crate) packet: PacketSetup,
    /// True when some material is glass that absorbs (Beer's law, [`Self::absorb`]), so a path
    /// can travel inside a medium.
    pub(crate) media: bool,
    /// How far secondary rays start off their surface ([`Self::offset`]), in the one-path
    /// engine: rayscope's own offset in every render; `diagnose`'s ties trace with the other
    /// offsets correct tracers use.
    pub(crate) offset_rule: OffsetRule,
    /// Set when the render is cancelled: every ray traced after that returns black at once, so
    /// a cancel reaches inside a path however deep it branches.
    cancel: &'a AtomicBool,
}

/// How far secondary rays start off the surface they leave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum OffsetRule {
    /// [`Surface::offset`] (1e-5 of the coordinates' size) times this factor.
    Scaled(f32),
    /// This distance whatever the coordinates (the course's 1e-5).
    Absolute(f32),
}

/// The cancel flag of integrators that are never cancelled.
static NEVER_CANCELLED: AtomicBool = AtomicBool::new(false);

/// Largest grid side whose cell offsets are tabulated (16,384 cells, 128 KiB).
const MAX_TABULATED_GRID: u32 = 128;

/// Most non-specular bounces of a path under `-l` (Russian roulette ends nearly all before).
const MAX_BOUNCES: u32 = 64;
/// Bounces before Russian roulette starts.
const RR_START: u32 = 3;

/// Whitted glass splits into two rays at every hit, so a pixel seen through glass costs up to
/// 2^depth rays. A branch that can bring back at most this much radiance (its weight times the
/// brightest radiance any ray can return) is not traced: the ≤ 2·depth branches a sample can
/// drop then add up to less than one 8-bit level.
const MIN_BRANCH_RADIANCE: f32 = 1.0 / 4096.0;

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
            .any(|e| scene.materials[e.material as usize].scatters_at_random());
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
            grid: 1,
            cells: Vec::new(),
            packet: PacketSetup::default(),
            media: scene
                .materials
                .iter()
                .any(|m| m.absorbs(settings.stage, settings.edition)),
            offset_rule: OffsetRule::Scaled(1.0),
            cancel: &NEVER_CANCELLED,
        }
        .with_grid()
        .with_packet_setup()
    }

    /// The same integrator, stopping its paths once `cancel` is set.
    #[must_use]
    pub(crate) fn with_cancel(self, cancel: &'a AtomicBool) -> Self {
        Self { cancel, ..self }
    }

    /// The same integrator, its secondary rays leaving their surface by `rule` (one-path
    /// engine only).
    #[must_use]
    pub(crate) fn with_offset_rule(self, rule: OffsetRule) -> Self {
        Self {
            offset_rule: rule,
            ..self
        }
    }

    /// How far rays leaving `s`, hit by `ray`, start off it by [`Self::offset_rule`] (exactly
    /// [`Surface::offset`] in every render), or by a student's own epsilon for every ray
    /// (`ray-offset=E`).
    #[must_use]
    #[inline(always)]
    pub(crate) fn offset(&self, s: &Surface, ray: &Ray) -> f32 {
        if I::MISTAKEN {
            if let Some(e) = self.isect.mistakes().ray_offset() {
                return e;
            }
        }
        match self.offset_rule {
            OffsetRule::Scaled(k) => s.offset(ray) * k,
            OffsetRule::Absolute(eps) => eps,
        }
    }

    /// True once the render is cancelled; the paths then return black and the render loop
    /// discards what they made.
    #[inline]
    pub(crate) fn cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// The engine this render's samples take, by this rule: debug channels, and intersectors
    /// whose packet queries are not faster than single rays ([`Intersect::PACKETS`]: the parry3d
    /// reference, renders with mistakes), and `--depth-limit all` (whose rule only this engine
    /// applies) go [`Engine::OnePath`]; a render with nothing
    /// stochastic goes [`Engine::Packets`]; a stochastic one (only the full stage has stochastic
    /// effects) goes [`Engine::Waves`]. The render loop turns `Waves` into
    /// [`Engine::CameraPackets`] for the remaining tiles when the first tiles' waves shaded too
    /// few lanes a step to pay (`render.rs`, `WaveStats`); the pixels are the same either way.
    /// Recorded samples ([`crate::render::trace_pixel`]) always go one path at a time.
    #[must_use]
    pub fn engine(&self) -> Engine {
        if !I::PACKETS || self.settings.channel != Channel::Color || self.settings.depth_limit == DepthLimit::All {
            Engine::OnePath
        } else if self.stochastic {
            Engine::Waves
        } else {
            Engine::Packets
        }
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

    /// True when samples sit at random points of their grid cells and `-q` multiplies them: a
    /// colour render with a stochastic effect on. Every engine places its samples by this.
    #[must_use]
    #[inline(always)]
    pub(crate) fn jitters(&self) -> bool {
        self.stochastic && self.settings.channel == Channel::Color
    }

    /// A sample's offset inside its pixel, `cell` (its cell's centre), moved to the point `u` of
    /// the cell ([`Self::cell_point`]) where [`Self::jitters`]: paths spread over their cell, so
    /// a pixel converges to the integral over its area (edges antialiased as a box filter
    /// would) rather than to N×N point samples.
    #[must_use]
    #[inline(always)]
    pub(crate) fn jittered_offset(&self, cell: [f32; 2], u: [f32; 2]) -> [f32; 2] {
        let n = self.grid as f32;
        [jittered(cell[0], u[0], n), jittered(cell[1], u[1], n)]
    }

    /// Where in its `-x` grid cell sample `s` lies, in [0, 1)², from `rng`, its numbers: the
    /// cell's paths (sample `s` is path `s div N²` of cell `s mod N²`) take the points of a
    /// scrambled Sobol sequence of the cell's own, so the first 2^k paths of every cell are a
    /// (0, k, 2)-net in it.
    #[must_use]
    #[inline(always)]
    pub(crate) fn cell_point(&self, s: u32, rng: &Sampler) -> [f32; 2] {
        let (cell, path) = self.cell_and_path(s);
        rng.get2d_in_stratum(Draw::Pixel.dim(0), cell, path)
    }

    /// Sample `s`'s cell and its place among the cell's paths.
    #[inline(always)]
    fn cell_and_path(&self, s: u32) -> (u32, u32) {
        let nn = self.grid * self.grid;
        if s < nn {
            (s, 0)
        } else {
            (s % nn, s / nn)
        }
    }

    /// True when a sample's pixel and lens points come from one scrambled Sobol sequence over
    /// the whole pixel rather than one per cell: a lens render whose grid side N is a power of
    /// two. The first N²·2^q points of that sequence put 2^q in every cell, as the cells' own
    /// sequences do, and the pixel and lens points of all the pixel's samples together are one
    /// 4-D net, which blurs out-of-focus edges with less noise than one net per cell, whose lens
    /// points are stratified within the cell only. (Without a lens the two give the same noise:
    /// each cell's points are a (0, k, 2)-net in it either way.)
    #[inline(always)]
    pub(crate) fn whole_pixel_net(&self) -> bool {
        self.thin_lens() && self.grid.is_power_of_two()
    }

    /// Sample `s`'s stratum and index for its camera numbers ([`Sampler::get2d_in_stratum`],
    /// [`Sampler::lens_in_stratum`]): the whole pixel's where [`Self::whole_pixel_net`], else
    /// its cell's.
    #[inline(always)]
    pub(crate) fn camera_stratum(&self, s: u32) -> (u32, u32) {
        if self.whole_pixel_net() {
            (0, s)
        } else {
            self.cell_and_path(s)
        }
    }

    /// Paths traced through each `-x` grid position: 2^q when a stochastic effect is on, else 1.
    #[must_use]
    pub(crate) fn paths_per_cell(&self) -> u32 {
        if self.jitters() {
            1 << self.settings.quality.min(16)
        } else {
            1
        }
    }

    /// Samples per pixel the settings ask for: N² grid positions × `Self::paths_per_cell`.
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
    /// when nothing is stochastic, else at the point [`Self::cell_point`] gives; the pixel centre for stage 1 and debug channels.
    #[must_use]
    #[inline]
    pub fn sample_position(&self, x: u32, y: u32, s: u32) -> (f32, f32) {
        self.position_in_cell(x, y, s, &self.sample_rng(x, y, s))
    }

    /// The random numbers of sample `s` of pixel (`x`, `y`).
    #[must_use]
    #[inline]
    pub fn sample_rng(&self, x: u32, y: u32, s: u32) -> Sampler {
        let pixel = y as u64 * self.settings.width as u64 + x as u64;
        Sampler::new(self.settings.seed, pixel, s)
    }

    /// [`Self::sample_position`], with `rng` the sample's numbers.
    #[inline]
    fn position_in_cell(&self, x: u32, y: u32, s: u32, rng: &Sampler) -> (f32, f32) {
        let centre = self.cell_offset(s);
        let [mut ox, mut oy] = centre;
        if self.mistake(Mistake::PixelCorners) {
            // The cell's top-left corner, (i/N, j/N), rather than its centre.
            let n = self.grid as f32;
            ox = (ox * n - 0.5).round() / n;
            oy = (oy * n - 0.5).round() / n;
        }
        if self.whole_pixel_net() {
            // The point in the pixel, moved as a mistake moves the cell.
            let (stratum, index) = self.camera_stratum(s);
            let [u, v] = rng.get2d_in_stratum(Draw::Pixel.dim(0), stratum, index);
            [ox, oy] = [u + (ox - centre[0]), v + (oy - centre[1])];
        } else if self.jitters() {
            [ox, oy] = self.jittered_offset([ox, oy], self.cell_point(s, rng));
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

    /// The camera ray of sample `s` of pixel (`x`, `y`); `rng` is the sample's numbers
    /// ([`Self::sample_rng`]).
    // Always inlined: with the jitter it is past the inliner's limit, and as a call it costs the
    // path-traced box 3 % (`rayscope bench render -f scenes/emissive.txt -w 200 -h 200 -x 2 -q 2
    // -l --threads 1`).
    #[must_use]
    #[inline(always)]
    pub fn camera_ray(&self, x: u32, y: u32, s: u32, rng: &mut Sampler) -> Ray {
        self.camera_ray_nudged(x, y, s, rng, [0.0; 2])
    }

    /// [`Self::camera_ray`] through the sample's image position moved by `nudge` (normalised
    /// image coordinates; adding zero leaves the position exactly as it was).
    #[must_use]
    #[inline(always)]
    pub(crate) fn camera_ray_nudged(&self, x: u32, y: u32, s: u32, rng: &mut Sampler, nudge: [f32; 2]) -> Ray {
        let (u, v) = self.position_in_cell(x, y, s, rng);
        let (u, v) = (u + nudge[0], v + nudge[1]);
        if self.thin_lens() {
            let (stratum, index) = self.camera_stratum(s);
            let [l0, l1] = rng.lens_in_stratum(Draw::Pixel.dim(0), stratum, index);
            self.camera.lens_ray(u, v, concentric_disk(l0, l1))
        } else {
            self.camera.ray(u, v)
        }
    }
}

/// A distinct, stable colour for entity `i`.
#[must_use]
pub(crate) fn entity_color(i: u32) -> Vec3A {
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
