//! Samples traced sixteen at a time: camera rays and point-light shadow rays as ray packets.
//!
//! Whenever a render has no stochastic effect (so every camera ray is a pinhole ray through a
//! fixed grid position) the render loop hands the integrator up to [`LANES`] samples at once.
//! Their camera rays are traced as one packet; every lane whose hit is lit by point lights alone
//! (stage 2's diffuse shading) gets its shadow rays traced as one packet per light; the rays that
//! mirrors and glass send on form the next packets, recursively. Each lane runs exactly the
//! arithmetic [`Integrator::sample`] runs, in the same order, so the colours and ray counts are
//! the same (the test `packet_render` renders both ways).

use glam::Vec3A;

use super::{Counters, Integrator, Li, PathState};
use crate::math::{offset_eps, Ray};
use crate::observer::NoObserver;
use crate::rng::Rng;
use crate::scene::{Hit, Intersect, Material, Surface};
use crate::settings::{Channel, Stage};
use crate::wide::{Bvh4, RayPacket, LANES};
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
        let mut lanes = [None; LANES];
        for (i, &(x, y, s)) in jobs.iter().enumerate() {
            let (u, v) = self.sample_position(x, y, s);
            lanes[i] = Some((self.camera.ray(u, v), PathState::CAMERA));
        }
        c.camera += jobs.len() as u64;
        let vals = self.trace_packet(bvh, &lanes, jobs, c);
        out[..jobs.len()].copy_from_slice(&vals[..jobs.len()]);
    }

    /// [`Self::trace`]'s total for each lane's ray: the rays are traced as a packet, then the
    /// shadow rays of point-lit hits (one packet per light), then the reflected rays of mirrors
    /// and glass (one packet) and glass's refracted rays (another), recursively. `jobs[i]` is
    /// the sample lane `i` belongs to.
    fn trace_packet(&self, bvh: &Bvh4, lanes: &Lanes, jobs: &[Job], c: &mut Counters) -> [Vec3A; LANES] {
        let mut vals = [Vec3A::ZERO; LANES];
        if lanes.iter().flatten().any(|(_, p)| p.depth >= MAX_PACKET_DEPTH) {
            // Deep recursion continues one ray at a time, whose stack frames are smaller.
            for (i, lane) in lanes.iter().enumerate() {
                if let Some((ray, path)) = lane {
                    let mut rng = self.lane_rng(jobs[i]);
                    vals[i] = self.trace(ray, *path, true, 0, &mut rng, &mut NoObserver, c).total();
                }
            }
            return vals;
        }
        let mut rays = RayPacket::default();
        for (i, lane) in lanes.iter().enumerate() {
            if let Some((ray, _)) = lane {
                rays.set(i, ray, f32::INFINITY);
            }
        }
        let hits = bvh.closest_rays(&mut rays, 0.0);

        let mut next = [Next::Done; LANES];
        let (mut reflected, mut refracted): (Lanes, Lanes) = ([None; LANES], [None; LANES]);
        for (i, lane) in lanes.iter().enumerate() {
            let (Some((ray, path)), Some((t, u, v, prim))) = (lane, hits.get(i)) else {
                continue;
            };
            let (ray, path) = (*ray, *path);
            let hit = Hit { t, u, v, prim };
            let s = self.scene.surface(&ray, &hit);
            let m = &self.scene.materials[s.material as usize];
            next[i] = match m.kind {
                _ if self.settings.stage == Stage::One => {
                    vals[i] = Vec3A::ZERO + Vec3A::from(m.color);
                    Next::Done
                }
                _ if self.point_lit_only(m) => Next::Lit(s, m.color.into(), t, path),
                MaterialKind::Reflective | MaterialKind::Refractive if path.depth >= self.settings.max_depth => {
                    Next::Done
                }
                MaterialKind::Reflective => {
                    reflected[i] = Some(Self::mirror(&ray, &s, path));
                    Next::Mirror(t, path)
                }
                MaterialKind::Refractive if path.branch || self.settings.stage != Stage::Full => {
                    let g = self.glass(&ray, &s, m, path);
                    reflected[i] = self.glass_reflected(&g, path);
                    refracted[i] = self.glass_refracted(&g, path);
                    Next::Glass(g.kr, t, path)
                }
                _ => {
                    let mut rng = self.lane_rng(jobs[i]);
                    vals[i] = self
                        .trace_hit(&ray, &hit, &s, path, true, 0, &mut rng, &mut NoObserver, c)
                        .total();
                    Next::Done
                }
            };
        }

        let lights = self.point_lights_packet(bvh, lanes, &next, c);
        // Children in the order the one-ray recursion traces them: each lane's reflected ray
        // before its refracted one (lanes are independent, so only the per-lane order matters).
        let from_reflected = self.children(bvh, &reflected, jobs, c);
        let from_refracted = self.children(bvh, &refracted, jobs, c);
        for i in 0..LANES {
            let (li, t, path) = match next[i] {
                Next::Done => continue,
                Next::Lit(_, _, t, path) => (Li::reflected(lights[i]), t, path),
                Next::Mirror(t, path) => (Li::reflected(from_reflected[i]), t, path),
                Next::Glass(kr, t, path) => {
                    let mut out = Vec3A::ZERO;
                    if reflected[i].is_some() {
                        out += from_reflected[i] * kr;
                    }
                    if refracted[i].is_some() {
                        out += from_refracted[i] * (1.0 - kr);
                    }
                    (Li::reflected(out), t, path)
                }
            };
            vals[i] = self.absorb(path, t, li).total();
        }
        vals
    }

    /// The child rays `lanes` traced as a packet (and counted), or nothing when there are none.
    fn children(&self, bvh: &Bvh4, lanes: &Lanes, jobs: &[Job], c: &mut Counters) -> [Vec3A; LANES] {
        let n = lanes.iter().flatten().count();
        if n == 0 {
            return [Vec3A::ZERO; LANES];
        }
        c.secondary += n as u64;
        self.trace_packet(bvh, lanes, jobs, c)
    }

    /// Point-light shading of the `Lit` lanes, with their shadow rays made and traced as one
    /// packet per light ([`Bvh4::light_rays`], which runs the single-ray code's arithmetic per
    /// lane), so each lane's sum is what `direct_point_lights` adds up.
    fn point_lights_packet(&self, bvh: &Bvh4, lanes: &Lanes, next: &[Next; LANES], c: &mut Counters) -> [Vec3A; LANES] {
        let mut sums = [Vec3A::ZERO; LANES];
        // Lit lanes in structure-of-arrays form: shadow-ray origins, shading normals, albedos.
        let mut lit = [false; LANES];
        let (mut org, mut ns, mut alb) = ([[0f32; LANES]; 3], [[0f32; LANES]; 3], [[0f32; LANES]; 3]);
        for (i, n) in next.iter().enumerate() {
            let (Next::Lit(s, albedo, ..), Some((ray, _))) = (n, lanes[i]) else {
                continue;
            };
            lit[i] = true;
            let origin = s.point + s.normal * offset_eps(s.point, ray.origin);
            for a in 0..3 {
                org[a][i] = origin[a];
                ns[a][i] = s.shading_normal[a];
                alb[a][i] = albedo[a];
            }
        }
        if !lit.iter().any(|&l| l) {
            return sums;
        }
        for light in &self.scene.lights {
            let vis = bvh.light_rays(&org, &ns, &lit, light.position.to_array());
            c.shadow += u64::from(vis.rays);
            let col = Vec3A::from(light.color);
            for i in 0..LANES {
                if !lit[i] {
                    continue;
                }
                let contrib = if vis.visible[i] {
                    Vec3A::new(alb[0][i], alb[1][i], alb[2][i]) * col * vis.cos[i]
                } else {
                    Vec3A::ZERO
                };
                sums[i] += contrib;
            }
        }
        sums
    }

    /// The random stream of a sample, for lanes that continue one ray at a time. Each such lane
    /// starts the stream afresh, as the sample's own stream would be at that point: renders
    /// traced as packets have no stochastic effect, so nothing before draws from it.
    fn lane_rng(&self, (x, y, s): Job) -> Rng {
        let pixel = y as u64 * self.settings.width as u64 + x as u64;
        Rng::for_sample(self.settings.seed, pixel, s as u64)
    }
}

/// Each lane's ray and path state, `None` for an unused lane.
type Lanes = [Option<(Ray, PathState)>; LANES];

/// Packet recursion deeper than this continues one ray at a time (each level holds a few
/// kilobytes of stack).
const MAX_PACKET_DEPTH: u32 = 12;

/// What a lane still needs once its packet's closest hits are known.
#[derive(Debug, Clone, Copy)]
enum Next {
    /// Nothing: its value is final.
    Done,
    /// Point lights at this surface with this albedo; hit distance and path (Beer's law).
    Lit(Surface, Vec3A, f32, PathState),
    /// A mirror: its reflected ray's radiance.
    Mirror(f32, PathState),
    /// Glass with this Fresnel reflectance: its reflected and refracted rays' radiance.
    Glass(f32, f32, PathState),
}
