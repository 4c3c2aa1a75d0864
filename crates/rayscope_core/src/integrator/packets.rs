//! Samples traced sixteen at a time: camera rays and point-light shadow rays as ray packets.
//!
//! Whenever a render has no stochastic effect (so every camera ray is a pinhole ray through a
//! fixed grid position) the render loop hands the integrator up to [`LANES`] samples at once.
//! Their camera rays are traced as one packet; every lane whose hit is lit by point lights alone
//! (stage 2's diffuse shading) gets its shadow rays traced as one packet per light; mirrors and
//! glass continue one ray at a time. Each lane runs exactly the arithmetic [`Integrator::sample`]
//! runs, in the same order, so the colours and ray counts are the same.

use glam::Vec3A;

use super::{Counters, Integrator, PathState};
use crate::math::{offset_eps, Ray};
use crate::observer::NoObserver;
use crate::rng::Rng;
use crate::scene::{Hit, Intersect, Material, Surface};
use crate::settings::{Channel, Stage};
use crate::wide::{Bvh4, RayPacket, LANES};
use rayscope_scene::MaterialKind;

/// A sample to trace: pixel (x, y) and sample index.
pub type Job = (u32, u32, u32);

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
    pub fn sample_packet(&self, bvh: &Bvh4, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) {
        debug_assert!(jobs.len() <= LANES && out.len() >= jobs.len());
        let mut rays = RayPacket::default();
        let mut cam = [Ray::new(Vec3A::ZERO, Vec3A::Z); LANES];
        for (i, &(x, y, s)) in jobs.iter().enumerate() {
            let (u, v) = self.sample_position(x, y, s);
            cam[i] = self.camera.ray(u, v);
            rays.set(i, &cam[i], f32::INFINITY);
        }
        c.camera += jobs.len() as u64;
        let hits = bvh.closest_rays(&mut rays, 0.0);

        // Lanes shaded by point lights: their surface and albedo.
        let mut lit: [Option<(Surface, Vec3A)>; LANES] = [None; LANES];
        for (i, &(x, y, s)) in jobs.iter().enumerate() {
            out[i] = Vec3A::ZERO;
            let Some((t, u, v, prim)) = hits.get(i) else {
                continue;
            };
            let hit = Hit { t, u, v, prim };
            let surf = self.scene.surface(&cam[i], &hit);
            let m = &self.scene.materials[surf.material as usize];
            if self.settings.stage == Stage::One {
                out[i] = Vec3A::ZERO + Vec3A::from(m.color);
            } else if self.point_lit_only(m) {
                lit[i] = Some((surf, m.color.into()));
            } else {
                let pixel = y as u64 * self.settings.width as u64 + x as u64;
                let mut rng = Rng::for_sample(self.settings.seed, pixel, s as u64);
                let path = PathState {
                    depth: 0,
                    bounces: 0,
                    beta: 1.0,
                    medium: None,
                    branch: true,
                };
                out[i] = self
                    .trace_hit(&cam[i], &hit, &surf, path, true, 0, &mut rng, &mut NoObserver, c)
                    .total();
            }
        }
        if lit.iter().all(Option::is_none) {
            return;
        }

        // Shadow rays, one packet per light; each lane sums its lights in order, as
        // `direct_point_lights` does.
        let mut sums = [Vec3A::ZERO; LANES];
        for light in &self.scene.lights {
            let mut shadow = RayPacket::default();
            let mut cos = [0f32; LANES];
            let mut any = false;
            for (i, l) in lit.iter().enumerate() {
                let Some((s, _)) = l else { continue };
                let origin = s.point + s.normal * offset_eps(s.point, cam[i].origin);
                let to = Vec3A::from(light.position) - origin;
                let dist = to.length();
                if dist == 0.0 {
                    continue;
                }
                let dir = to / dist;
                cos[i] = s.shading_normal.dot(dir);
                c.shadow += 1;
                // Rays behind the surface cannot contribute and are not traced.
                if cos[i] > 0.0 {
                    shadow.set(i, &Ray::new(origin, dir), dist);
                    any = true;
                }
            }
            let blocked = if any {
                bvh.occluded_rays(&mut shadow, 0.0)
            } else {
                [true; LANES]
            };
            for (i, l) in lit.iter().enumerate() {
                let Some((_, albedo)) = l else { continue };
                let contrib = if cos[i] > 0.0 && !blocked[i] {
                    *albedo * Vec3A::from(light.color) * cos[i]
                } else {
                    Vec3A::ZERO
                };
                sums[i] += contrib;
            }
        }
        for (i, l) in lit.iter().enumerate() {
            if l.is_some() {
                // The emitted part (zero) plus the reflected part, as `Li::total` adds them.
                out[i] = Vec3A::ZERO + sums[i];
            }
        }
    }
}
