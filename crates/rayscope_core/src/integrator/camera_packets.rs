//! Camera rays traced sixteen at a time, ahead of the paths that start from them.
//!
//! Stochastic renders (path tracing, glossy coats, depth of field) hand over samples sixteen at a
//! time, but only their camera rays go as a packet: a pixel's camera rays stay together while
//! its paths scatter after the first hit, so each path goes on one ray at a time from its
//! camera ray's hit, with its own random numbers, exactly as [`Integrator::sample`] would
//! ([`crate::integrator::Engine::CameraPackets`]). Waves of paths take their camera rays from
//! the same batches.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::Vec3A;

use super::one_path::LaneAt;
use super::rules::PathState;
use super::{Counters, Integrator, Job};
use crate::accel::PacketHits;
use crate::camera::camera_dirs;
use crate::math::RayPacket;
use crate::sampling::concentric_disk_lane;
use crate::scene::{Hit, Intersect};
use crate::simd::LANES;
use crate::sobol::{Draw, SamplerLanes};

impl<I: Intersect> Integrator<'_, I> {
    /// What [`Self::sample`] returns for each of `jobs` (at most [`LANES`]), into `out`, with
    /// the rays counted in `c`: the camera rays traced as one packet, each path then one ray at
    /// a time from its camera ray's hit. A pixel's camera rays stay together even where its
    /// paths scatter after the first bounce.
    pub(crate) fn sample_camera_packet(&self, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) {
        debug_assert!(jobs.len() <= LANES && out.len() >= jobs.len());
        let cams = self.camera_batch(true, 0, jobs, c);
        for k in 0..jobs.len() {
            // Each path goes on one ray at a time from its camera ray's hit, found with the batch.
            let hit = cams.hits.get(k).map(|(t, u, v, prim)| Hit { t, u, v, prim });
            let mut rng = cams.rng.0[k];
            let ray = cams.rays.ray(k);
            out[k] = self
                .hand_over(&ray, LaneAt::Found(hit), PathState::CAMERA, &mut rng, c)
                .total();
        }
    }

    /// The camera rays of `jobs` (at most [`LANES`], starting at job `job0`), traced as one
    /// packet when `trace`: a pixel's samples stay together until their first hit.
    pub(super) fn camera_batch(&self, trace: bool, job0: usize, jobs: &[Job], c: &mut Counters) -> CameraBatch {
        let mut b = CameraBatch {
            job0,
            len: jobs.len(),
            ..CameraBatch::default()
        };
        if self.thin_lens() && I::MISTAKEN {
            for (k, &(x, y, s)) in jobs.iter().enumerate() {
                // Each sample's own numbers, and its lens ray drawn from them.
                b.rng.0[k] = self.sample_rng(x, y, s);
                let ray = self.camera_ray(x, y, s, &mut b.rng.0[k]);
                b.rays.set(k, &ray, f32::INFINITY);
            }
        } else if self.thin_lens() {
            self.lens_batch(&mut b, jobs);
        } else {
            // The same for a pinhole camera, the directions all lanes at once: the samples'
            // numbers, each lane's cell centre moved to its point in the cell where it jitters.
            let (mut px, mut py) = ([0.0; LANES], [0.0; LANES]);
            let jitters = self.jitters();
            for (k, &(x, y, s)) in jobs.iter().enumerate() {
                b.rng.0[k] = self.sample_rng(x, y, s);
                [px[k], py[k]] = self.cell_offset(s);
                if jitters {
                    [px[k], py[k]] = self.jittered_offset([px[k], py[k]], self.cell_point(s, &b.rng.0[k]));
                }
            }
            for (k, &(x, y, _)) in jobs.iter().enumerate() {
                (px[k], py[k]) = (x as f32 + px[k], y as f32 + py[k]);
            }
            self.pinhole_rays(&mut b.rays, jobs.len(), &px, &py);
        }
        c.camera += jobs.len() as u64;
        if trace {
            // Traced in place (users of the batch read only origins and directions).
            self.isect
                .closest_packet(&mut b.rays, 0.0, self.packet.beams.camera.as_ref(), &mut b.hits);
        }
        b
    }

    /// The samples' numbers and lens rays, into `b`: what [`Self::camera_ray`] makes for each
    /// of `jobs` (at most [`LANES`]), all lanes at once, for a render without mistakes.
    fn lens_batch(&self, b: &mut CameraBatch, jobs: &[Job]) {
        let (mut px, mut py) = ([0.0; LANES], [0.0; LANES]);
        // Each lane's pixel, as the position's arithmetic takes it.
        let (mut fx, mut fy) = ([0.0f32; LANES], [0.0f32; LANES]);
        // Each lane's stratum and its place in it, for its pixel and lens points.
        let (mut stratum, mut index) = ([0; LANES], [0; LANES]);
        for (k, &(x, y, s)) in jobs.iter().enumerate() {
            // A batch mostly holds one pixel's samples, whose numbers share the pixel's hash.
            b.rng.0[k] = match k.checked_sub(1).map(|j| jobs[j]) {
                Some((xp, yp, _)) if (xp, yp) == (x, y) => b.rng.0[k - 1].with_sample(s),
                _ => self.sample_rng(x, y, s),
            };
            [px[k], py[k]] = self.cell_offset(s);
            (fx[k], fy[k]) = (x as f32, y as f32);
            (stratum[k], index[k]) = self.camera_stratum(s);
        }
        let (jitters, whole) = (self.jitters(), self.whole_pixel_net());
        let [at, lens] = b.rng.camera_points(Draw::Pixel.dim(0), &stratum, &index);
        let (w, h) = (self.settings.width as f32, self.settings.height as f32);
        let (mut u, mut v) = ([0.0; LANES], [0.0; LANES]);
        // Every lane, a loop of fixed length that vectorises; lanes past the jobs are not used.
        for k in 0..LANES {
            if whole {
                [px[k], py[k]] = [at[0][k], at[1][k]];
            } else if jitters {
                [px[k], py[k]] = self.jittered_offset([px[k], py[k]], [at[0][k], at[1][k]]);
            }
            // `camera_ray`'s position, moved by a nudge of zero.
            (u[k], v[k]) = ((fx[k] + px[k]) / w + 0.0, (fy[k] + py[k]) / h + 0.0);
        }
        let mut disk = [[0.0; LANES]; 2];
        for k in 0..LANES {
            [disk[0][k], disk[1][k]] = concentric_disk_lane(lens[0][k], lens[1][k]);
        }
        let (o, d) = self.camera.lens_rays(&u, &v, &disk);
        // Lanes past the jobs keep the packet's unused rays.
        let n = jobs.len();
        for a in 0..3 {
            b.rays.o[a][..n].copy_from_slice(&o[a][..n]);
            b.rays.d[a][..n].copy_from_slice(&d[a][..n]);
        }
        b.rays.t_max[..n].fill(f32::INFINITY);
    }

    /// Sets `rays` (unused in every lane) to the pinhole camera's rays through pixel positions
    /// (`px`, `py`) in the first `n` lanes, as [`Camera::ray`](crate::camera::Camera::ray)
    /// makes them. Written in place: a packet returned by value was copied with `memcpy`.
    pub(super) fn pinhole_rays(&self, rays: &mut RayPacket, n: usize, px: &[f32; LANES], py: &[f32; LANES]) {
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
}

/// Camera rays traced ahead, one packet of consecutive samples, with their hits and the
/// samples' random numbers.
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
    /// Each sample's random numbers.
    pub(super) rng: SamplerLanes,
}
