//! Samples traced sixteen at a time: camera rays and point-light shadow rays as ray packets.
//!
//! Whenever a render has no stochastic effect (so every camera ray is a pinhole ray through a
//! fixed grid position) the render loop hands the integrator up to [`LANES`] samples at once.
//! Their camera rays are traced as one packet; every lane whose hit is lit by point lights alone
//! (stage 2's diffuse shading) gets its shadow rays traced as one packet per light; the rays that
//! mirrors and glass send on form the next packets, recursively. Each lane runs exactly the
//! arithmetic [`Integrator::sample`] runs, in the same order, so the colours and ray counts are
//! the same (the test `packet_render` renders both ways).

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::Vec3A;

use super::one_path::LaneAt;
use super::packet_state::Beams;
use super::rules::{Glass, Li, PathState};
use super::{Counters, Integrator, Job};
use crate::accel::PacketHits;
use crate::geometry::PrimRef;
use crate::lights::{add_point_light_lanes, point_light_rays};
use crate::math::Ray;
use crate::math::RayPacket;
use crate::optics::{specular_rays, SpecularRays};
use crate::scene::{Hit, Intersect, Lobe, Material};
use crate::settings::Stage;
use crate::simd::{lane, LANES};
use crate::sobol::Sampler;
use crate::surface::{PacketSurfaces, SurfaceFrames};

impl<I: Intersect> Integrator<'_, I> {
    /// Fills in [`Self::packet`]: the point-lit materials for every render, and for renders that
    /// trace ray packets through a flat list, the beams and the lone glass spheres.
    pub(super) fn with_packet_setup(mut self) -> Self {
        self.packet.point_lit = self.scene.materials.iter().map(|m| self.point_lit_only(m)).collect();
        if !I::PACKETS {
            return self;
        }
        let camera = (!self.thin_lens()).then(|| self.isect.apex_cull(self.camera.origin.to_array()));
        self.packet.beams = Beams {
            camera: camera.flatten(),
            lights: self
                .scene
                .lights
                .iter()
                .map(|l| self.isect.apex_cull(l.position.to_array()))
                .collect(),
        };
        // Glass spheres only: rays start inside a sphere where they refract into it, and the
        // check costs a pass over the scene's triangles per sphere.
        let glass = |k: usize| {
            let (_, m) = self.scene.prim_info(PrimRef::Sphere(k as u32));
            self.scene.materials[m as usize].is_glass()
        };
        self.packet.lone_spheres = (0..self.scene.spheres.len())
            .map(|k| {
                (glass(k) && self.scene.sphere_alone(k))
                    .then(|| self.isect.sphere_slot(k as u32))
                    .flatten()
            })
            .collect();
        self
    }

    /// True when a hit on `m` is shaded by point lights alone with the course's formula, so its
    /// shadow rays can be traced as packets.
    fn point_lit_only(&self, m: &Material) -> bool {
        // The full renderer shades a Lambertian hit with point lights alone when there are no
        // emitters and no indirect light.
        m.point_lit_only(self.settings.stage, self.emitters.is_empty() && !self.settings.ambient)
    }

    /// The colours of `jobs` (at most [`LANES`]) into `out`: what [`Self::sample`] returns for
    /// each, with the rays counted in `c`. Only for renders whose [`Self::engine`] is [`Engine::Packets`].
    pub(crate) fn sample_packet(&self, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) {
        debug_assert!(jobs.len() <= LANES && out.len() >= jobs.len());
        // Each lane's image position in pixels; `pinhole_rays` divides by the image size for all
        // lanes at once as it makes the directions.
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
            Some(vals) => self.trace_packet(&mut lanes, jobs, c, vals),
            None => {
                let mut vals = [Vec3A::ZERO; LANES];
                self.trace_packet(&mut lanes, jobs, c, &mut vals);
                out[..jobs.len()].copy_from_slice(&vals[..jobs.len()]);
            }
        }
    }

    /// [`Self::trace`]'s total for each lane's ray, into `vals` (zero in lanes not in use): the
    /// rays are traced as a packet, then the shadow rays of point-lit hits (one packet per
    /// light), then the reflected rays of mirrors and glass (one packet) and glass's refracted
    /// rays (another), recursively. `jobs[i]` is the sample lane `i` belongs to. The rays'
    /// `t_max` is left at their hits: traced in place, as a copy of the packet cost a `memcpy`.
    fn trace_packet(&self, lanes: &mut PathPacket, jobs: &[Job], c: &mut Counters, vals: &mut [Vec3A; LANES]) {
        *vals = [Vec3A::ZERO; LANES];
        if self.cancelled() {
            return;
        }
        if lanes.depth >= MAX_PACKET_DEPTH {
            // Deep recursion continues one ray at a time, whose stack frames are smaller.
            for i in (0..LANES).filter(|&i| lanes.on[i]) {
                let mut rng = self.lane_rng(jobs[i]);
                let ray = lanes.ray(i);
                vals[i] = self.hand_over(&ray, LaneAt::Ray, lanes.paths[i], &mut rng, c).total();
            }
            return;
        }
        // Camera rays leave the camera's centre; the beam test sees whether these do.
        let mut hits = PacketHits::default();
        // Rays inside a sphere nothing else comes near (glass seen from within) test it alone.
        let alone = match lanes.inside {
            Inside::Sphere(k) => self.packet.lone_spheres.get(k as usize).copied().flatten(),
            _ => None,
        };
        if !alone.is_some_and(|slot| self.isect.closest_packet_inside(&mut lanes.rays, 0.0, slot, &mut hits)) {
            self.isect
                .closest_packet(&mut lanes.rays, 0.0, self.packet.beams.camera.as_ref(), &mut hits);
        }
        let surf = PacketSurfaces::new(self.scene, &lanes.rays, &hits);

        // Lanes lit by point lights alone (the common case) are found without a branch per
        // lane; the others go through `next`.
        let mut lit = LitLanes::default();
        let mut other = [false; LANES];
        let mut ior = [1.0; LANES];
        // Lanes without a hit have material 0, which a scene without objects lacks.
        let material = |mat: u32| {
            let point_lit = self.packet.point_lit.get(mat as usize).copied().unwrap_or(false);
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
            next[i] = match m.lobe() {
                _ if self.settings.stage == Stage::One => {
                    vals[i] = Vec3A::ZERO + Vec3A::from(m.color);
                    Next::Done
                }
                Lobe::Mirror | Lobe::Dielectric if path.depth >= self.settings.max_depth => Next::Done,
                Lobe::Mirror => {
                    let sp = specular.get_or_insert_with(|| specular_rays(&lanes.rays, &surf.frames, &ior));
                    let r = Ray::new(lane(&surf.frames.outside, i), lane(&sp.reflected, i));
                    child(&mut reflected).set(i, &r, path.mirrored(), reflected_in);
                    Next::Mirror
                }
                Lobe::Dielectric if path.branch || self.settings.stage != Stage::Full => {
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
                // Glass after a sampled bounce picks one ray at random; the other kinds here are
                // lit by more than point lights. Their lanes go on one path at a time.
                Lobe::Dielectric | Lobe::Lambert | Lobe::Bsdf | Lobe::Emitter => {
                    let mut rng = self.lane_rng(jobs[i]);
                    let Some((t, u, v, prim)) = hits.get(i) else {
                        unreachable!("lane {i} has a surface, so it has a hit")
                    };
                    let hit = Hit { t, u, v, prim };
                    let (ray, s) = (lanes.ray(i), surf.get(i));
                    vals[i] = self.hand_over(&ray, LaneAt::Hit(&hit, &s), path, &mut rng, c).total();
                    Next::Done
                }
            };
        }

        let lights = self.point_lights_packet(&lit, &surf.frames, c);
        // Children in the order the one-ray recursion traces them: each lane's reflected ray
        // before its refracted one (lanes are independent, so only the per-lane order matters).
        let (mut from_reflected, mut from_refracted) = ([Vec3A::ZERO; LANES], [Vec3A::ZERO; LANES]);
        self.children(reflected.as_mut(), jobs, c, &mut from_reflected);
        self.children(refracted.as_mut(), jobs, c, &mut from_refracted);
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
    fn children(&self, lanes: Option<&mut PathPacket>, jobs: &[Job], c: &mut Counters, vals: &mut [Vec3A; LANES]) {
        let Some(lanes) = lanes else {
            return;
        };
        let n = lanes.on.iter().filter(|&&on| on).count();
        c.secondary += n as u64;
        self.trace_packet(lanes, jobs, c, vals);
    }

    /// Point-light shading of the `lit` lanes at surfaces `frames`, per axis, with their shadow
    /// rays made and traced as one packet per light ([`point_light_rays`]), so each lane's sum
    /// is what `direct_point_lights` adds up, in the same order.
    pub(super) fn point_lights_packet(
        &self,
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
                self.isect,
                &frames.outside,
                &frames.shading_normal,
                &lit.on,
                light.position.to_array(),
                self.packet.beams.lights.get(k).and_then(Option::as_ref),
            );
            c.shadow += u64::from(vis.rays);
            add_point_light_lanes(&mut sums, &lit.alb, light.color.to_array(), &vis);
        }
        sums
    }

    /// The random numbers of a sample, for lanes that continue one ray at a time: stateless,
    /// so the same wherever the path stands.
    fn lane_rng(&self, (x, y, s): Job) -> Sampler {
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
