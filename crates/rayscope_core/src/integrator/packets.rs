//! Samples traced sixteen at a time: camera rays and point-light shadow rays as ray packets.
//!
//! Whenever a render has no stochastic effect (so every camera ray is a pinhole ray through a
//! fixed grid position) the render loop hands the integrator up to [`LANES`] samples at once.
//! Their camera rays are traced as one packet; every lane whose hit is lit by point lights alone
//! (stage 2's diffuse shading) gets its shadow rays traced as one packet per light; the rays that
//! mirrors and glass send on form the next packets, recursively. Each lane runs exactly the
//! arithmetic [`Integrator::sample`] runs, in the same order, so the colours and ray counts are
//! the same (the test `packet_render` renders both ways).
//!
//! Stochastic renders (path tracing, glossy coats, depth of field) hand over samples the same
//! way, but only their camera rays go as a packet: a pixel's camera rays stay together while
//! its paths scatter after the first hit, so each path goes on one ray at a time from its
//! camera ray's hit, with its own random stream, exactly as [`Integrator::sample`] would.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::Vec3A;

use super::{Counters, Glass, Integrator, Li, PathState};
use crate::accel::{Bvh4, PacketHits};
use crate::camera::{camera_dirs, jittered};
use crate::geometry::PrimRef;
use crate::lights::{add_point_light_lanes, point_light_rays};
use crate::math::Ray;
use crate::math::RayPacket;
use crate::observer::NoObserver;
use crate::optics::{specular_rays, SpecularRays};
use crate::rng::{Rng, RngLanes};
use crate::scene::{Hit, Intersect, Material, Scene, Surface};
use crate::settings::{Channel, Stage};
use crate::simd::{lane, put, LANES};
use crate::wide::{surface_frames, HitPrims, SmoothNormals, SurfaceFrames};
use rayscope_scene::MaterialKind;

/// A sample to trace: pixel (x, y) and sample index.
pub(crate) type Job = (u32, u32, u32);

impl<I: Intersect> Integrator<'_, I> {
    /// The BVH to trace packets through, when this render's samples may be traced as packets:
    /// colour renders without stochastic effects, on rayscope's own BVH.
    #[must_use]
    pub fn packet_bvh(&self) -> Option<&Bvh4> {
        if self.settings.channel != Channel::Color || self.stochastic {
            return None;
        }
        self.isect.wide()
    }

    /// The BVH to trace camera rays through [`LANES`] at a time, when this render's samples are
    /// stochastic paths (so not whole packets): colour renders on rayscope's own BVH.
    #[must_use]
    pub fn camera_packet_bvh(&self) -> Option<&Bvh4> {
        if self.settings.channel != Channel::Color || !self.stochastic {
            return None;
        }
        self.isect.wide()
    }

    /// What [`Self::sample`] returns for each of `jobs` (at most [`LANES`]), into `out`, with
    /// the rays counted in `c`: the camera rays traced as one packet, each path then one ray at
    /// a time from its camera ray's hit. A pixel's camera rays stay together even where its
    /// paths scatter after the first bounce.
    pub(crate) fn sample_camera_packet(&self, bvh: &Bvh4, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) {
        debug_assert!(jobs.len() <= LANES && out.len() >= jobs.len());
        let cams = self.camera_batch(Some(bvh), 0, jobs, c);
        for k in 0..jobs.len() {
            // Self::radiance from the hit found with the batch.
            let hit = cams.hits.get(k).map(|(t, u, v, prim)| Hit { t, u, v, prim });
            let mut rng = cams.rng.get(k);
            out[k] = self
                .trace_found(
                    &cams.rays.ray(k),
                    hit,
                    PathState::CAMERA,
                    true,
                    0,
                    &mut rng,
                    &mut NoObserver,
                    c,
                )
                .total();
        }
    }

    /// The camera rays of `jobs` (at most [`LANES`], starting at job `job0`), traced as one
    /// packet when `bvh` is given: a pixel's samples stay together until their first hit.
    pub(super) fn camera_batch(&self, bvh: Option<&Bvh4>, job0: usize, jobs: &[Job], c: &mut Counters) -> CameraBatch {
        let mut b = CameraBatch {
            job0,
            len: jobs.len(),
            ..CameraBatch::default()
        };
        if self.thin_lens() {
            for (k, &(x, y, s)) in jobs.iter().enumerate() {
                // Self::sample's start: the sample's stream and camera ray.
                let mut rng = self.sample_rng(x, y, s);
                let ray = self.camera_ray(x, y, s, &mut rng);
                b.rays.set(k, &ray, f32::INFINITY);
                b.rng.set(k, &rng);
            }
        } else {
            // The same for a pinhole camera, all lanes at once: the samples' streams, each lane's
            // cell centre jittered by the stream's first two numbers, then the directions.
            let (mut pixel, mut sample, mut on) = ([0; LANES], [0; LANES], [false; LANES]);
            let (mut px, mut py) = ([0.0; LANES], [0.0; LANES]);
            let width = u64::from(self.settings.width);
            for (k, &(x, y, s)) in jobs.iter().enumerate() {
                (pixel[k], sample[k], on[k]) = (u64::from(y) * width + u64::from(x), u64::from(s), true);
                [px[k], py[k]] = self.cell_offset(s);
            }
            b.rng = RngLanes::for_samples(self.settings.seed, &pixel, &sample);
            if self.stochastic && self.settings.channel == Channel::Color {
                let n = self.grid as f32;
                let (jx, jy) = (b.rng.next_f32(&on), b.rng.next_f32(&on));
                for k in 0..LANES {
                    px[k] = jittered(px[k], jx[k], n);
                    py[k] = jittered(py[k], jy[k], n);
                }
            }
            for (k, &(x, y, _)) in jobs.iter().enumerate() {
                (px[k], py[k]) = (x as f32 + px[k], y as f32 + py[k]);
            }
            self.pinhole_rays(&mut b.rays, jobs.len(), &px, &py);
        }
        c.camera += jobs.len() as u64;
        if let Some(bvh) = bvh {
            // Traced in place (users of the batch read only origins and directions).
            bvh.closest_rays_from(&mut b.rays, 0.0, self.beams.camera.as_ref(), &mut b.hits);
        }
        b
    }

    /// Sets `rays` (unused in every lane) to the pinhole camera's rays through pixel positions
    /// (`px`, `py`) in the first `n` lanes, as [`Camera::ray`](crate::camera::Camera::ray)
    /// makes them. Written in place: a packet returned by value was copied with `memcpy`.
    fn pinhole_rays(&self, rays: &mut RayPacket, n: usize, px: &[f32; LANES], py: &[f32; LANES]) {
        let (w, h) = (self.settings.width as f32, self.settings.height as f32);
        rays.d = camera_dirs(&self.camera, px, py, w, h);
        let o = self.camera.origin.to_array();
        for k in 0..n {
            for a in 0..3 {
                rays.o[a][k] = o[a];
            }
            rays.t_max[k] = f32::INFINITY;
        }
    }

    /// Fills in [`Self::point_lit`].
    pub(super) fn with_point_lit(mut self) -> Self {
        self.point_lit = self.scene.materials.iter().map(|m| self.point_lit_only(m)).collect();
        self
    }

    /// True when a hit on `m` is shaded by point lights alone with the course's formula, so its
    /// shadow rays can be traced as packets.
    fn point_lit_only(&self, m: &Material) -> bool {
        match self.settings.stage {
            Stage::One => false,
            Stage::Two => matches!(
                m.kind,
                MaterialKind::Diffuse | MaterialKind::Glossy | MaterialKind::Emissive
            ),
            // The full renderer shades a Lambertian hit with point lights alone when there are
            // no emitters and no indirect light.
            Stage::Full => m.kind == MaterialKind::Diffuse && self.emitters.is_empty() && !self.settings.ambient,
        }
    }

    /// The colours of `jobs` (at most [`LANES`]) into `out`: what [`Self::sample`] returns for
    /// each, with the rays counted in `c`. Only for renders where [`Self::packet_bvh`] is `Some`.
    pub(crate) fn sample_packet(&self, bvh: &Bvh4, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) {
        debug_assert!(jobs.len() <= LANES && out.len() >= jobs.len());
        // Self::sample_position, its divisions done for all lanes at once with the directions.
        // Unused lanes aim at the image's corner; they are never switched on.
        let (mut u, mut v) = ([0.0; LANES], [0.0; LANES]);
        for (i, &(x, y, s)) in jobs.iter().enumerate() {
            let [ox, oy] = self.cell_offset(s);
            (u[i], v[i]) = (x as f32 + ox, y as f32 + oy);
        }
        let mut lanes = PathPacket::default();
        self.pinhole_rays(&mut lanes.rays, jobs.len(), &u, &v);
        lanes.on[..jobs.len()].fill(true);
        c.camera += jobs.len() as u64;
        // Straight into `out` when it has room for every lane (the render loop's batches do).
        match out.first_chunk_mut::<LANES>() {
            Some(vals) => self.trace_packet(bvh, &mut lanes, jobs, c, vals),
            None => {
                let mut vals = [Vec3A::ZERO; LANES];
                self.trace_packet(bvh, &mut lanes, jobs, c, &mut vals);
                out[..jobs.len()].copy_from_slice(&vals[..jobs.len()]);
            }
        }
    }

    /// [`Self::trace`]'s total for each lane's ray, into `vals` (zero in lanes not in use): the
    /// rays are traced as a packet, then the shadow rays of point-lit hits (one packet per
    /// light), then the reflected rays of mirrors and glass (one packet) and glass's refracted
    /// rays (another), recursively. `jobs[i]` is the sample lane `i` belongs to. The rays'
    /// `t_max` is left at their hits: traced in place, as a copy of the packet cost a `memcpy`.
    fn trace_packet(
        &self,
        bvh: &Bvh4,
        lanes: &mut PathPacket,
        jobs: &[Job],
        c: &mut Counters,
        vals: &mut [Vec3A; LANES],
    ) {
        *vals = [Vec3A::ZERO; LANES];
        if lanes.depth >= MAX_PACKET_DEPTH {
            // Deep recursion continues one ray at a time, whose stack frames are smaller.
            for i in (0..LANES).filter(|&i| lanes.on[i]) {
                let mut rng = self.lane_rng(jobs[i]);
                let ray = lanes.ray(i);
                vals[i] = self
                    .trace(&ray, lanes.paths[i], true, 0, &mut rng, &mut NoObserver, c)
                    .total();
            }
            return;
        }
        // Camera rays leave the camera's centre; the beam test sees whether these do.
        let mut hits = PacketHits::default();
        // Rays inside a sphere nothing else comes near (glass seen from within) test it alone.
        let alone = match lanes.inside {
            Inside::Sphere(k) => self.lone_spheres.get(k as usize).copied().flatten(),
            _ => None,
        };
        if !alone.is_some_and(|slot| bvh.closest_rays_inside(&mut lanes.rays, 0.0, slot, &mut hits)) {
            bvh.closest_rays_from(&mut lanes.rays, 0.0, self.beams.camera.as_ref(), &mut hits);
        }
        let surf = PacketSurfaces::new(self.scene, &lanes.rays, &hits);

        // Lanes lit by point lights alone (the common case) are found without a branch per
        // lane; the others go through `next`.
        let mut lit = LitLanes::default();
        let mut other = [false; LANES];
        let mut ior = [1.0; LANES];
        // Lanes without a hit have material 0, which a scene without objects lacks.
        let material = |mat: u32| {
            let point_lit = self.point_lit.get(mat as usize).copied().unwrap_or(false);
            let (albedo, value) = self
                .scene
                .materials
                .get(mat as usize)
                .map_or((glam::Vec3::ZERO, 1.0), |m| (m.color, m.value));
            (point_lit, albedo, value)
        };
        if surf.one_prim {
            // Every lane hit (so is on) and has the same material: looked up once and written
            // to every lane from registers.
            let (point_lit, albedo, value) = material(surf.material[0]);
            lit.on = [point_lit; LANES];
            other = [!point_lit; LANES];
            for a in 0..3 {
                lit.alb[a] = [albedo[a]; LANES];
            }
            ior = [value; LANES];
        } else {
            for i in 0..LANES {
                let (point_lit, albedo, value) = material(surf.material[i]);
                let on = lanes.on[i] & surf.hit[i];
                lit.on[i] = on & point_lit;
                other[i] = on & !lit.on[i];
                for a in 0..3 {
                    lit.alb[a][i] = albedo[a];
                }
                ior[i] = value;
            }
        }
        // Only a tag per lane: the distance, path state and Fresnel weight are read back from
        // the packet's own arrays. (Tags carrying copies of them were built with narrow stores
        // and read back with wide loads, and that store-forwarding stall was 5 % of scene 2.)
        let mut next = [Next::Done; LANES];
        // Most packets make no child rays, so the child packets are made when needed.
        let (mut reflected, mut refracted): (Option<PathPacket>, Option<PathPacket>) = (None, None);
        // Mirror and glass rays, computed for the whole packet once some lane needs them.
        let mut specular: Option<SpecularRays> = None;
        for i in 0..LANES {
            if !other[i] {
                continue;
            }
            let path = lanes.paths[i];
            let m = &self.scene.materials[surf.material[i] as usize];
            // The sphere a reflected ray starts inside (it leaves on the ray's side: inside when
            // the ray hit the sphere from within), and the one a refracted ray does.
            let sphere = match hits.get(i) {
                Some((.., PrimRef::Sphere(k))) => Some(k),
                _ => None,
            };
            let front = surf.frames.front_face[i];
            let (reflected_in, refracted_in) = (sphere.filter(|_| !front), sphere.filter(|_| front));
            next[i] = match m.kind {
                _ if self.settings.stage == Stage::One => {
                    vals[i] = Vec3A::ZERO + Vec3A::from(m.color);
                    Next::Done
                }
                MaterialKind::Reflective | MaterialKind::Refractive if path.depth >= self.settings.max_depth => {
                    Next::Done
                }
                MaterialKind::Reflective => {
                    let sp = specular.get_or_insert_with(|| specular_rays(&lanes.rays, &surf.frames, &ior));
                    let r = Ray::new(lane(&surf.frames.outside, i), lane(&sp.reflected, i));
                    child(&mut reflected).set(i, &r, path.mirrored(), reflected_in);
                    Next::Mirror
                }
                MaterialKind::Refractive if path.branch || self.settings.stage != Stage::Full => {
                    let sp = specular.get_or_insert_with(|| specular_rays(&lanes.rays, &surf.frames, &ior));
                    let (refl_medium, refr_medium) = self.glass_media(&surf.get(i), m, path);
                    let g = Glass {
                        kr: sp.kr[i],
                        reflected: Ray::new(lane(&surf.frames.outside, i), lane(&sp.reflected, i)),
                        refracted: sp.has_refracted[i].then(|| Ray::new(lane(&sp.inside, i), lane(&sp.refracted, i))),
                        refl_medium,
                        refr_medium,
                    };
                    if let Some((r, p)) = self.glass_reflected(&g, path) {
                        child(&mut reflected).set(i, &r, p, reflected_in);
                    }
                    if let Some((r, p)) = self.glass_refracted(&g, path) {
                        child(&mut refracted).set(i, &r, p, refracted_in);
                    }
                    Next::Glass
                }
                _ => {
                    let mut rng = self.lane_rng(jobs[i]);
                    let Some((t, u, v, prim)) = hits.get(i) else {
                        unreachable!("lane {i} has a surface, so it has a hit")
                    };
                    let hit = Hit { t, u, v, prim };
                    let (ray, s) = (lanes.ray(i), surf.get(i));
                    vals[i] = self
                        .trace_hit(&ray, &hit, &s, path, true, 0, &mut rng, &mut NoObserver, c)
                        .total();
                    Next::Done
                }
            };
        }

        let lights = self.point_lights_packet(bvh, &lit, &surf.frames, c);
        // Children in the order the one-ray recursion traces them: each lane's reflected ray
        // before its refracted one (lanes are independent, so only the per-lane order matters).
        let (mut from_reflected, mut from_refracted) = ([Vec3A::ZERO; LANES], [Vec3A::ZERO; LANES]);
        self.children(bvh, reflected.as_mut(), jobs, c, &mut from_reflected);
        self.children(bvh, refracted.as_mut(), jobs, c, &mut from_refracted);
        let on = |p: &Option<PathPacket>, i: usize| p.as_ref().is_some_and(|p| p.on[i]);
        // Beer's law, for packets with a path in an absorbing medium.
        let absorb = |i: usize, li: Li| {
            if lanes.absorbing {
                self.absorb(lanes.paths[i], surf.t[i], li)
            } else {
                li
            }
        };
        for i in 0..LANES {
            if lit.on[i] {
                vals[i] = absorb(i, Li::reflected(lane(&lights, i))).total();
                continue;
            }
            let li = match next[i] {
                Next::Done => continue,
                Next::Mirror => Li::reflected(from_reflected[i]),
                Next::Glass => {
                    let kr = specular.as_ref().map_or(0.0, |sp| sp.kr[i]);
                    let mut out = Vec3A::ZERO;
                    if on(&reflected, i) {
                        out += from_reflected[i] * kr;
                    }
                    if on(&refracted, i) {
                        out += from_refracted[i] * (1.0 - kr);
                    }
                    Li::reflected(out)
                }
            };
            vals[i] = absorb(i, li).total();
        }
    }

    /// The child rays `lanes` traced as a packet (and counted) into `vals`, which stays zero
    /// when there are none.
    fn children(
        &self,
        bvh: &Bvh4,
        lanes: Option<&mut PathPacket>,
        jobs: &[Job],
        c: &mut Counters,
        vals: &mut [Vec3A; LANES],
    ) {
        let Some(lanes) = lanes else {
            return;
        };
        let n = lanes.on.iter().filter(|&&on| on).count();
        c.secondary += n as u64;
        self.trace_packet(bvh, lanes, jobs, c, vals);
    }

    /// Point-light shading of the `lit` lanes at surfaces `frames`, per axis, with their shadow
    /// rays made and traced as one packet per light ([`point_light_rays`]), so each lane's sum
    /// is what `direct_point_lights` adds up, in the same order.
    pub(super) fn point_lights_packet(
        &self,
        bvh: &Bvh4,
        lit: &LitLanes,
        frames: &SurfaceFrames,
        c: &mut Counters,
    ) -> [[f32; LANES]; 3] {
        let mut sums = [[0.0; LANES]; 3];
        if !lit.on.iter().any(|&l| l) {
            return sums;
        }
        for (k, light) in self.scene.lights.iter().enumerate() {
            let vis = point_light_rays(
                bvh,
                &frames.outside,
                &frames.shading_normal,
                &lit.on,
                light.position.to_array(),
                self.beams.lights.get(k).and_then(Option::as_ref),
            );
            c.shadow += u64::from(vis.rays);
            add_point_light_lanes(&mut sums, &lit.alb, light.color.to_array(), &vis);
        }
        sums
    }

    /// The random stream of a sample, for lanes that continue one ray at a time. Each such lane
    /// starts the stream afresh, as the sample's own stream would be at that point: renders
    /// traced as packets have no stochastic effect, so nothing before draws from it.
    fn lane_rng(&self, (x, y, s): Job) -> Rng {
        self.sample_rng(x, y, s)
    }
}

/// The child packet in `slot`, made with no lane in use the first time a lane needs it.
// Written out, so the packet is made where it lives: `get_or_insert_with` was compiled as a
// call that built it and then copied it.
#[inline(always)]
fn child(slot: &mut Option<PathPacket>) -> &mut PathPacket {
    match slot {
        Some(p) => p,
        None => slot.insert(PathPacket {
            inside: Inside::Unset,
            ..PathPacket::default()
        }),
    }
}

/// Copies lane 0 of `v` to every lane.
#[inline]
fn broadcast<T: Copy>(v: &mut [T; LANES]) {
    *v = [v[0]; LANES];
}

/// A packet of rays to trace with each lane's path state.
#[derive(Clone)]
struct PathPacket {
    /// The rays: `t_max` is +∞ for lanes in use, −∞ for the others.
    rays: RayPacket,
    /// Which lanes are in use.
    on: [bool; LANES],
    /// Each lane's path state.
    paths: [PathState; LANES],
    /// The deepest path in use (a check per packet; a pass over the lanes' states was 2 % of a
    /// direct-lighting render).
    depth: u32,
    /// Some path in use travels inside an absorbing medium.
    absorbing: bool,
    /// Whether every ray in use starts inside one sphere.
    inside: Inside,
}

/// Whether a packet's rays all start inside one sphere.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Inside {
    /// No ray yet.
    Unset,
    /// Every ray so far starts inside this sphere.
    Sphere(u32),
    /// Some ray does not, or the packet was not tracked.
    No,
}

impl Inside {
    /// The state once a ray starting inside sphere `k` (or in none) joins the packet.
    #[inline]
    fn with(self, k: Option<u32>) -> Inside {
        match (self, k) {
            (Inside::Unset, Some(k)) => Inside::Sphere(k),
            (Inside::Sphere(j), Some(k)) if j == k => self,
            _ => Inside::No,
        }
    }
}

impl Default for PathPacket {
    #[inline(always)]
    fn default() -> Self {
        Self {
            rays: RayPacket::default(),
            on: [false; LANES],
            paths: [PathState::CAMERA; LANES],
            depth: 0,
            absorbing: false,
            inside: Inside::No,
        }
    }
}

impl PathPacket {
    /// Puts `ray` with `path` in lane `i`; the ray starts inside sphere `inside`, if given.
    #[inline]
    fn set(&mut self, i: usize, ray: &Ray, path: PathState, inside: Option<u32>) {
        self.inside = self.inside.with(inside);
        self.rays.set(i, ray, f32::INFINITY);
        self.on[i] = true;
        self.paths[i] = path;
        self.depth = self.depth.max(path.depth);
        self.absorbing |= path.medium.is_some();
    }

    /// Lane `i`'s ray.
    #[inline]
    fn ray(&self, i: usize) -> Ray {
        self.rays.ray(i)
    }
}

/// Camera rays traced ahead, one packet of consecutive samples, with their hits and the
/// samples' random streams after them.
#[derive(Default)]
pub(super) struct CameraBatch {
    /// Index of the first sample in the jobs.
    pub(super) job0: usize,
    /// Samples in the batch.
    pub(super) len: usize,
    /// Samples taken so far (by a wave's lanes).
    pub(super) taken: usize,
    /// The camera rays (`t_max` at their hits once traced).
    pub(super) rays: RayPacket,
    /// Their closest hits, when traced.
    pub(super) hits: PacketHits,
    /// Each sample's random stream after its camera ray.
    pub(super) rng: RngLanes,
}

/// Packet recursion deeper than this continues one ray at a time (each level holds a few
/// kilobytes of stack).
const MAX_PACKET_DEPTH: u32 = 12;

/// The lanes whose hits are lit by point lights alone, and their albedos (the shadow rays start
/// from the packet's [`SurfaceFrames`]).
#[derive(Default)]
#[repr(align(64))]
pub(super) struct LitLanes {
    /// Which lanes.
    pub(super) on: [bool; LANES],
    /// Albedos, per axis.
    pub(super) alb: [[f32; LANES]; 3],
}

/// The surfaces a packet's rays hit, in structure-of-arrays form: per lane, what
/// [`Scene::surface`] returns ([`surface_frames`] computes the geometry).
#[repr(align(64))]
pub(super) struct PacketSurfaces {
    /// Every lane hit the same primitive.
    one_prim: bool,
    /// Lanes whose ray hit something.
    hit: [bool; LANES],
    /// Hit distance.
    t: [f32; LANES],
    /// Hit points, normals and offset origins.
    pub(super) frames: SurfaceFrames,
    /// Entity index.
    entity: [u32; LANES],
    /// Material index.
    pub(super) material: [u32; LANES],
}

impl PacketSurfaces {
    /// The surfaces of `hits`, found by tracing `rays`.
    pub(super) fn new(scene: &Scene, rays: &RayPacket, hits: &PacketHits) -> Self {
        let mut g = HitPrims::default();
        (g.hit, g.t) = hits.distances();
        let (mut entity, mut material) = ([0; LANES], [0; LANES]);
        // One pixel's samples mostly meet one primitive: its data is then looked up for the
        // first lane and copied to the others (the same values a lookup per lane finds).
        let one_prim = hits.one_prim();
        let lanes = if one_prim { 1 } else { LANES };
        for i in 0..lanes {
            let Some((_, _, _, prim)) = hits.get(i) else {
                continue;
            };
            (entity[i], material[i]) = scene.prim_info(prim);
            match prim {
                PrimRef::Plane(k) => put(&mut g.a, i, scene.planes[k as usize].normal.to_array()),
                PrimRef::Sphere(k) => {
                    let sp = &scene.spheres[k as usize];
                    g.sphere[i] = true;
                    put(&mut g.a, i, sp.center.to_array());
                    g.radius[i] = sp.radius;
                }
                PrimRef::Triangle(k) => {
                    let tri = &scene.triangles[k as usize];
                    g.triangle[i] = true;
                    put(&mut g.a, i, tri.e1().to_array());
                    put(&mut g.b, i, tri.e2().to_array());
                    if let Some(ns) = scene.vertex_normals(k) {
                        let sm = g.smooth.get_or_insert_with(SmoothNormals::default);
                        sm.on[i] = true;
                        for (c, n) in ns.iter().enumerate() {
                            put(&mut sm.vn[c], i, n.to_array());
                        }
                    }
                }
            }
        }
        if let Some(sm) = &mut g.smooth {
            // Every lane's: those without vertex normals ignore theirs.
            (sm.bu, sm.bv) = hits.barycentrics();
        }
        if one_prim {
            broadcast(&mut g.sphere);
            broadcast(&mut g.triangle);
            g.a.iter_mut().chain(g.b.iter_mut()).for_each(broadcast);
            broadcast(&mut g.radius);
            broadcast(&mut entity);
            broadcast(&mut material);
            if let Some(sm) = &mut g.smooth {
                broadcast(&mut sm.on);
                sm.vn.iter_mut().flatten().for_each(broadcast);
            }
        }
        Self {
            frames: surface_frames(rays, &g),
            one_prim,
            hit: g.hit,
            t: g.t,
            entity,
            material,
        }
    }

    /// Lane `i`'s surface as [`Scene::surface`] returns it.
    #[inline]
    pub(super) fn get(&self, i: usize) -> Surface {
        let f = &self.frames;
        Surface {
            point: lane(&f.point, i),
            normal: lane(&f.normal, i),
            shading_normal: lane(&f.shading_normal, i),
            front_face: f.front_face[i],
            entity: self.entity[i],
            material: self.material[i],
        }
    }
}

/// What a lane still needs once its packet's closest hits are known.
#[derive(Debug, Clone, Copy)]
enum Next {
    /// Nothing: its value is final.
    Done,
    /// A mirror: its reflected ray's radiance.
    Mirror,
    /// Glass: its reflected and refracted rays' radiance, weighted by the Fresnel reflectance.
    Glass,
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::math::offset_eps;
    use crate::rng::Rng;

    /// Random packets from points inside and outside `scene`'s objects, in random directions.
    fn packets(scene: &Scene, seed: u64, mut check: impl FnMut(&RayPacket, &PacketSurfaces, usize)) {
        let bvh = &scene.wide;
        let mut rng = Rng::for_sample(seed, 0, 0);
        let mut r = move || rng.next_f32() * 2.0 - 1.0;
        let mut hits = 0;
        for _ in 0..300 {
            let mut rays = RayPacket::default();
            let o = Vec3A::new(r() * 0.9, r() * 0.9, 1.5 + r() * 1.4);
            for i in 0..LANES {
                // Some lanes off, so unused lanes are covered too.
                if i % 7 != 3 {
                    let d = Vec3A::new(r(), r(), r()).normalize();
                    rays.set(i, &Ray::new(o, d), f32::INFINITY);
                }
            }
            let mut traced = rays.clone();
            let h = bvh.closest_rays(&mut traced, 0.0);
            let surf = PacketSurfaces::new(scene, &rays, &h);
            for i in 0..LANES {
                assert_eq!(surf.hit[i], h.get(i).is_some(), "lane {i}");
                if surf.hit[i] {
                    hits += 1;
                    check(&rays, &surf, i);
                }
            }
        }
        assert!(hits > 1000, "only {hits} hits");
    }

    fn load(path: &Path) -> Scene {
        Scene::from_file(&rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e:?}", path.display())))
    }

    /// Each lane's surface is what `Scene::surface` returns for its ray and hit, bit for bit,
    /// and its offset origin is the single-ray code's: on planes, spheres (from inside and out),
    /// flat triangles and the smooth ones of meshes (our torus, the course's bunny).
    #[test]
    fn packet_surfaces_are_scene_surfaces() {
        let mut scenes = vec![
            (rayscope_testkit::scene("room.txt"), 1),
            (rayscope_testkit::scene("obj.txt"), 2),
        ];
        if let Some(course) = rayscope_testkit::course_part() {
            scenes.push((course.scene("sample_scene_2.txt"), 1));
            scenes.push((course.scene("sample_scene_obj.txt"), 2));
        }
        for (path, seed) in scenes {
            let name = path.display();
            let scene = load(&path);
            let mut kinds = [0; 3];
            packets(&scene, seed, |rays, surf, i| {
                let ray = Ray::new(lane(&rays.o, i), lane(&rays.d, i));
                let mut traced = rays.clone();
                let (t, u, v, prim) = scene.wide.closest_rays(&mut traced, 0.0).get(i).unwrap();
                kinds[match prim {
                    PrimRef::Plane(_) => 0,
                    PrimRef::Sphere(_) => 1,
                    PrimRef::Triangle(_) => 2,
                }] += 1;
                let want = scene.surface(&ray, &Hit { t, u, v, prim });
                let got = surf.get(i);
                let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
                assert_eq!(bits(got.point), bits(want.point), "{name} lane {i} point");
                assert_eq!(bits(got.normal), bits(want.normal), "{name} lane {i} normal");
                assert_eq!(bits(got.shading_normal), bits(want.shading_normal), "{name} lane {i}");
                assert_eq!(
                    (got.front_face, got.entity, got.material),
                    (want.front_face, want.entity, want.material)
                );
                let outside = want.point + want.normal * offset_eps(want.point, ray.origin);
                let f = &surf.frames.outside;
                assert_eq!([f[0][i], f[1][i], f[2][i]].map(f32::to_bits), bits(outside));
            });
            assert!(kinds.iter().filter(|&&k| k > 0).count() >= 2, "{name}: {kinds:?}");
        }
    }
}
