//! Path tracing in waves: sixteen paths in flight, advanced one vertex at a time together.
//!
//! One path alone is a chain in which every step waits for the one before (hit, surface,
//! samples, next ray, next hit), so the core runs it at the speed of its latencies. A wave keeps
//! [`LANES`] independent paths in structure-of-arrays form and runs each step for all of them
//! at once: their rays go through the BVH as one packet and their emitter rays as another,
//! and a Lambertian vertex is shaded by the sixteen-lane forms of the rules the one-path code
//! calls (the shading frame, `math::basis_lanes`; the Lambert BRDF and its sample,
//! `bsdf::lambert_sample_lanes`; the frame change, `sampling::to_world_unit_lanes`), loops over
//! the lanes without branches that the compiler vectorises, with the same multiple importance
//! weights, Russian roulette and random numbers. A lane whose path ends takes the next sample
//! at once. Without indirect light a Lambertian vertex's bounce only looks for emitters: it
//! waits as a probe beside the vertex's emitter shadow ray, and both are traced at the start of
//! the next step, before the lanes they end take new samples, so those lanes' camera rays go in
//! that same step and the steps of a direct-lighting render shade nearly every lane.
//!
//! Each lane computes exactly what [`Integrator::sample`] computes, in the same order and
//! with the same random numbers:
//! * a vertex's light is summed as the recursive code sums it, from the last vertex back,
//!   once the path has ended (each vertex's terms are kept until then);
//! * a mirror or glass hit stays in the wave: its ray (or, on a path that has not yet bounced
//!   off a Lambertian surface, glass's reflected and then its refracted ray, one after the
//!   other, as the recursion takes them) is the lane's next ray, and the light it brings is
//!   passed on, weighted and absorbed, when it returns;
//! * a hit on any other reflection model ([`Lobe::Bsdf`]) goes on one ray at a time with the
//!   recursive code from that hit, and its result enters the sum like any other vertex's.
//!
//! So the image is the one the one-path-at-a-time loop makes, bit for bit (the tests
//! `waves_return_what_one_path_at_a_time_returns` below and `packet_render` check it). The wave
//! pays where its steps have many Lambertian vertices to shade together; the render loop stops
//! using it in renders whose steps shade few (see `render::WaveStats`).

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::{Vec3, Vec3A};

use super::camera_packets::CameraBatch;
use super::one_path::LaneAt;
use super::packets::LitLanes;
use super::rules::{Li, PathState};
use super::{Counters, Integrator, Job, MAX_BOUNCES, RR_START};
use crate::accel::PacketHits;
use crate::bsdf::{lambert_f, lambert_pdf, lambert_sample_lanes, transport_albedo};
use crate::geometry::PrimRef;
use crate::math::RayPacket;
use crate::math::{basis_lanes, not_at_most, Ray};
use crate::sampling::{power_heuristic, russian_roulette_survival, to_world_unit_lanes};
use crate::scene::{Hit, Intersect, Lobe};
use crate::simd::{lane, max_element, put, LANES};
use crate::sobol::{Draw, SamplerLanes};
use crate::surface::PacketSurfaces;

type F = [f32; LANES];
type M = [bool; LANES];
/// A lane's closest hit as [`PacketHits::get`] gives it: (t, u, v, primitive), or none.
type LaneHit = Option<(f32, f32, f32, PrimRef)>;

/// What a [`Frame`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    /// A Lambertian vertex.
    Lambert,
    /// A mirror, or glass that sent one of its rays on: passes on what that ray brings.
    Specular,
    /// Glass on a path that has not yet bounced off a Lambertian surface (Whitted): its
    /// reflected and its refracted ray, each weighted by its Fresnel weight, traced one after
    /// the other; the rest of its state is the top of the lane's [`Split`] stack.
    Split,
    /// Beer's law on what the vertex above returns: the transmittance (in `l`) of the segment
    /// that reached that vertex, inside an absorbing medium ([`Integrator::absorb`]).
    Absorb,
}

/// A vertex of a path in flight, kept until the path beyond it has ended so that its light is
/// summed in the recursive code's order. One layout for every [`Kind`] (64 bytes, the kind in
/// the padding): every vertex is pushed and popped, and the Lambertian ones, by far the most,
/// are read back with whole-vector loads.
#[derive(Debug, Clone, Copy)]
struct Frame {
    /// Point lights and the emitter sample (for [`Kind::Absorb`], the transmittance).
    l: Vec3A,
    /// BRDF × cos / density of the bounce, which weights emission the bounce finds.
    w_total: Vec3A,
    /// What the bounce carries of the light reflected further along the path.
    carry: Vec3A,
    /// Density of the bounce's direction, for the weight of emission it finds.
    pdf: f32,
    kind: Kind,
}

impl Frame {
    /// A Lambertian vertex.
    fn lambert(l: Vec3A, w_total: Vec3A, carry: Vec3A, pdf: f32) -> Self {
        Frame {
            l,
            w_total,
            carry,
            pdf,
            kind: Kind::Lambert,
        }
    }

    /// A frame of a kind with no light of its own, or a [`Kind::Absorb`] with transmittance `l`.
    fn other(kind: Kind, l: Vec3A) -> Self {
        Frame {
            l,
            w_total: Vec3A::ZERO,
            carry: Vec3A::ZERO,
            pdf: 0.0,
            kind,
        }
    }
}

/// The state of a [`Kind::Split`] frame.
#[derive(Debug, Clone, Copy)]
struct Split {
    /// What the rays traced so far brought, weighted.
    sum: Vec3A,
    /// The weight of the ray being traced now.
    weight: f32,
    /// The ray still to trace, with its path state and weight.
    next: Option<(Ray, PathState, f32)>,
}

/// What a run of waves did (see [`Integrator::sample_wave`]).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct WaveWork {
    /// Wave steps taken.
    pub(crate) steps: u64,
    /// Lambertian vertices shaded.
    pub(crate) shaded: u64,
}

impl WaveWork {
    /// Adds another run's work.
    pub(crate) fn add(&mut self, o: WaveWork) {
        self.steps += o.steps;
        self.shaded += o.shaded;
    }
}

/// The paths in flight.
struct Wave {
    /// Lanes holding a path.
    on: M,
    /// Each lane's sample: an index into the jobs.
    job: [usize; LANES],
    /// Each lane's next closest-hit query (camera or bounce ray); `t_max = −∞` where none.
    rays: RayPacket,
    /// Lanes with a ray in `rays`.
    ray_on: M,
    /// The ray's hit is wanted for its reflected light too, not only its emission.
    want: M,
    /// The ray's hit where it is already known (a camera ray traced with its batch); the
    /// ray is then not traced again.
    found: [Option<LaneHit>; LANES],
    /// Path state of the ray in `rays`.
    path: [PathState; LANES],
    /// Each lane's waiting emitter shadow ray; `t_max = −∞` where none.
    shadow: RayPacket,
    /// Lanes with a shadow ray in `shadow`.
    shadow_on: M,
    /// Each lane's waiting bounce ray whose hit matters only for the emission it finds (a
    /// Lambertian vertex's bounce that carries no reflected light); `t_max = −∞` where none.
    /// It is traced with the shadow rays, before the lanes take new samples, so the lane's
    /// next camera ray goes in the same step.
    probe: RayPacket,
    /// Lanes with a bounce ray in `probe`.
    probe_on: M,
    /// Light the shadow ray adds when nothing blocks it, per axis.
    unblocked: [F; 3],
    /// Each lane's sample's random numbers.
    rng: SamplerLanes,
    /// Each path's vertices whose light is not summed yet, the last one on top.
    stack: [Vec<Frame>; LANES],
    /// Each path's glass splits in progress, the last one on top.
    splits: [Vec<Split>; LANES],
    /// Steps taken and Lambertian vertices shaded so far.
    work: WaveWork,
}

impl Wave {
    fn new() -> Self {
        Wave {
            on: [false; LANES],
            job: [0; LANES],
            rays: RayPacket::default(),
            ray_on: [false; LANES],
            want: [false; LANES],
            found: [None; LANES],
            path: [PathState::CAMERA; LANES],
            shadow: RayPacket::default(),
            shadow_on: [false; LANES],
            probe: RayPacket::default(),
            probe_on: [false; LANES],
            unblocked: [[0.0; LANES]; 3],
            rng: SamplerLanes::default(),
            stack: std::array::from_fn(|_| Vec::new()),
            splits: std::array::from_fn(|_| Vec::new()),
            work: WaveWork::default(),
        }
    }

    /// Lane `i`'s ray in `rays`.
    #[inline]
    fn ray(&self, i: usize) -> Ray {
        self.rays.ray(i)
    }

    /// Pushes a [`Kind::Absorb`] frame on lane `i`'s stack when `att` is some, under the vertex
    /// pushed next.
    #[inline]
    fn push_absorb(&mut self, i: usize, att: Option<Vec3A>) {
        if let Some(a) = att {
            self.stack[i].push(Frame::other(Kind::Absorb, a));
        }
    }

    /// Gives lane `i` the ray `ray` (a mirror's or glass's, with state `path`) to trace next.
    #[inline]
    fn launch(&mut self, i: usize, ray: &Ray, path: PathState) {
        self.rays.set(i, ray, f32::INFINITY);
        (self.path[i], self.want[i], self.ray_on[i], self.found[i]) = (path, true, true, None);
    }

    /// Ends the ray lane `i` traced last, which brought `li`: sums the kept vertices from the
    /// last back, as the recursive code returns through them, until one has another ray to
    /// trace (glass's refracted ray after its reflected one), which the lane then traces; with
    /// none left, stores the sample's value and frees the lane.
    #[inline]
    fn finish(&mut self, i: usize, mut li: Li, out: &mut [Vec3A]) {
        while let Some(f) = self.stack[i].pop() {
            li = match f.kind {
                Kind::Lambert => {
                    let mis = if li.light_pdf > 0.0 {
                        power_heuristic(f.pdf, li.light_pdf)
                    } else {
                        1.0
                    };
                    Li::reflected(f.l + (f.w_total * li.emitted * mis + f.carry * li.reflected))
                }
                Kind::Specular => Li::reflected(li.total()),
                Kind::Absorb => li.absorbed(Some(f.l)),
                Kind::Split => {
                    let split = self.splits[i].last_mut().expect("a split frame has its state");
                    split.sum += li.total() * split.weight;
                    if let Some((ray, path, weight)) = split.next.take() {
                        split.weight = weight;
                        self.stack[i].push(f);
                        self.launch(i, &ray, path);
                        return;
                    }
                    let sum = split.sum;
                    self.splits[i].pop();
                    Li::reflected(sum)
                }
            };
        }
        out[self.job[i]] = li.total();
        self.on[i] = false;
    }
}

/// The dimension of `draw` at each lane's path vertex.
#[inline]
fn dims(w: &Wave, draw: Draw) -> [u32; LANES] {
    std::array::from_fn(|i| draw.dim(w.path[i].vertex()))
}

impl<I: Intersect> Integrator<'_, I> {
    /// What [`Self::sample`] returns for each of `jobs`, into `out`, with the rays counted in
    /// `c`: the samples' paths traced as waves of [`LANES`]. Only for renders whose
    /// [`Self::engine`] is [`Engine::Waves`]. Returns the steps the wave took and the vertices it shaded.
    pub(crate) fn sample_wave(&self, jobs: &[Job], out: &mut [Vec3A], c: &mut Counters) -> WaveWork {
        debug_assert!(out.len() >= jobs.len());
        let mut w = Wave::new();
        let mut cams = CameraBatch::default();
        let mut next = 0;
        // Where the wave's packets test every primitive (a room's list) every ray meets every
        // primitive wherever it starts, so a camera ray goes in the wave's next packet, in the
        // lane it would otherwise leave idle. In a tree, camera rays are traced ahead, a pixel's
        // samples together, whose walks share their nodes.
        let ahead = !self.isect.packets_test_everything();
        loop {
            // The waiting shadow rays and bounce probes first: the lanes whose paths they end
            // take new samples in this same step.
            self.settle(&mut w, out);
            for i in 0..LANES {
                if w.on[i] {
                    continue;
                }
                if cams.taken == cams.len {
                    if next == jobs.len() {
                        break;
                    }
                    let batch = &jobs[next..jobs.len().min(next + LANES)];
                    cams = self.camera_batch(ahead, next, batch, c);
                    next += batch.len();
                }
                // The lane's first step starts from its camera ray, or from its hit.
                let k = cams.taken;
                cams.taken += 1;
                w.rng.0[i] = cams.rng.0[k];
                let t_max = if ahead { f32::NEG_INFINITY } else { f32::INFINITY };
                w.rays.set(i, &cams.rays.ray(k), t_max);
                (w.on[i], w.job[i], w.ray_on[i], w.want[i]) = (true, cams.job0 + k, true, true);
                w.found[i] = ahead.then(|| cams.hits.get(k));
                w.path[i] = PathState::CAMERA;
            }
            if !w.on.contains(&true) || self.cancelled() {
                break;
            }
            self.wave_step(&mut w, out, c);
            w.work.steps += 1;
        }
        w.work
    }

    /// Traces the wave's waiting shadow rays and bounce probes and adds what they bring to their
    /// vertices, ending the paths that have no ray left to trace.
    fn settle(&self, w: &mut Wave, out: &mut [Vec3A]) {
        let shadows = w.shadow_on.contains(&true);
        let probes = w.probe_on.contains(&true);
        if !(shadows || probes) {
            return;
        }
        let blocked = if shadows {
            self.isect.scattered_occluded_packet(&mut w.shadow, 0.0)
        } else {
            [false; LANES]
        };
        let found = if probes {
            self.isect.scattered_closest_packet(&mut w.probe, 0.0)
        } else {
            PacketHits::default()
        };
        w.shadow.t_max = [f32::NEG_INFINITY; LANES];
        w.probe.t_max = [f32::NEG_INFINITY; LANES];
        for i in 0..LANES {
            if !w.shadow_on[i] {
                continue;
            }
            w.shadow_on[i] = false;
            let top = w.stack[i].last_mut().expect("a shadow ray belongs to a vertex");
            debug_assert_eq!(top.kind, Kind::Lambert);
            if !blocked[i] {
                top.l += lane(&w.unblocked, i);
            }
            if !(w.ray_on[i] | w.probe_on[i]) {
                // The vertex sent no bounce: its light is what it returns.
                let l = top.l;
                w.stack[i].pop();
                w.finish(i, Li::reflected(l), out);
            }
        }
        for i in 0..LANES {
            if !w.probe_on[i] {
                continue;
            }
            w.probe_on[i] = false;
            let li = self.probe_light(w, i, found.get(i));
            w.finish(i, li, out);
        }
    }

    /// What lane `i`'s bounce probe brings from its closest hit `hit`: an emitter's light, with
    /// the density emitter sampling gives the point, and nothing from any other surface, as the
    /// wave's hits on rays not wanted for their reflected light do.
    #[inline]
    fn probe_light(&self, w: &Wave, i: usize, hit: LaneHit) -> Li {
        let Some((t, u, v, prim)) = hit else {
            return Li::default();
        };
        let m = &self.scene.materials[self.scene.prim_info(prim).1 as usize];
        if m.lobe() != Lobe::Emitter {
            return Li::default();
        }
        let ray = w.probe.ray(i);
        Li {
            emitted: m.color.into(),
            reflected: Vec3A::ZERO,
            light_pdf: if self.emitters.is_empty() {
                0.0
            } else {
                let point = self.scene.surface(&ray, &Hit { t, u, v, prim }).point;
                self.emitters.pdf(self.scene, ray.origin, prim, point)
            },
        }
        .absorbed(self.transmittance(w.path[i], t))
    }

    /// Traces the wave's rays and takes every path one vertex on.
    fn wave_step(&self, w: &mut Wave, out: &mut [Vec3A], c: &mut Counters) {
        let mut hits = if (0..LANES).any(|i| w.ray_on[i] & w.found[i].is_none()) {
            self.isect.scattered_closest_packet(&mut w.rays, 0.0)
        } else {
            PacketHits::default()
        };
        for i in 0..LANES {
            if let Some(h) = w.found[i].take() {
                hits.set(i, h);
            }
        }
        // Only the lanes given new rays below trace them next; a lane given one here (glass's
        // second ray, once the vertex below it is summed) has no hit in `hits` yet.
        let traced = w.ray_on;
        w.rays.t_max = [f32::NEG_INFINITY; LANES];
        if !traced.contains(&true) {
            return;
        }
        let surf = PacketSurfaces::new(self.scene, &w.rays, &hits);
        // Each lane's hit, by its lobe: an emitter's light, a mirror's or glass's next ray, another
        // reflection model's path traced on one ray at a time; Lambertian hits are marked and
        // shaded together below.
        let mut diffuse = [false; LANES];
        let mut dist = [0.0; LANES];
        for i in 0..LANES {
            if !traced[i] {
                continue;
            }
            let Some((t, u, v, prim)) = hits.get(i) else {
                w.ray_on[i] = false;
                w.finish(i, Li::default(), out);
                continue;
            };
            let path = w.path[i];
            dist[i] = t;
            let m = &self.scene.materials[surf.material[i] as usize];
            let li = match m.lobe() {
                Lobe::Emitter => Li {
                    emitted: m.color.into(),
                    reflected: Vec3A::ZERO,
                    light_pdf: if self.emitters.is_empty() {
                        0.0
                    } else {
                        self.emitters
                            .pdf(self.scene, lane(&w.rays.o, i), prim, surf.get(i).point)
                    },
                }
                .absorbed(self.transmittance(path, t)),
                _ if !w.want[i] => Li::default(),
                Lobe::Lambert => {
                    diffuse[i] = true;
                    continue;
                }
                Lobe::Mirror | Lobe::Dielectric => match self.specular_hit(w, i, t, &surf, c) {
                    Some(li) => li,
                    None => continue,
                },
                Lobe::Bsdf => {
                    // Other reflection models: the rest of the path one ray at a time.
                    let mut rng = w.rng.0[i];
                    let hit = Hit { t, u, v, prim };
                    let (ray, s) = (w.ray(i), surf.get(i));
                    self.hand_over(&ray, LaneAt::Hit(&hit, &s), path, &mut rng, c)
                }
            };
            w.ray_on[i] = false;
            w.finish(i, li, out);
        }
        if diffuse.contains(&true) {
            w.work.shaded += diffuse.iter().map(|&d| u64::from(d)).sum::<u64>();
            self.shade_wave(w, &surf, &diffuse, &dist, out, c);
        }
    }

    /// Beer's law on the light each emitter shadow ray of `shadow` (`dist` long) brings, for
    /// the vertices inside an absorbing medium. Out of line, and apart from the loop that
    /// computes that light, which its branch and `exp` would keep from being vectorised.
    #[inline(never)]
    fn absorb_unblocked(&self, w: &mut Wave, shadow: &M, dist: &F) {
        for i in 0..LANES {
            if let (true, Some(a)) = (shadow[i], self.transmittance(w.path[i], dist[i])) {
                let u = lane(&w.unblocked, i) * a;
                put(&mut w.unblocked, i, u.to_array());
            }
        }
    }

    /// Lane `i`'s hit, at distance `t`, on a mirror or on glass: gives the lane the ray the
    /// vertex sends on and returns `None`, or returns what the vertex returns where it sends
    /// none. Out of line, so the wave's Lambertian steps stay compact.
    #[inline(never)]
    fn specular_hit(&self, w: &mut Wave, i: usize, t: f32, surf: &PacketSurfaces, c: &mut Counters) -> Option<Li> {
        let path = w.path[i];
        if path.depth >= self.settings.max_depth {
            return Some(Li::default());
        }
        let (ray, s) = (w.ray(i), surf.get(i));
        let m = &self.scene.materials[s.material as usize];
        let att = self.transmittance(path, t);
        let (r, p) = if m.lobe() == Lobe::Mirror {
            self.mirror(&ray, &s, path)
        } else {
            let g = self.glass(&ray, &s, m, path);
            if path.branch {
                // Whitted's split (the path has not yet bounced off a Lambertian surface): both
                // rays, each with its Fresnel weight, the reflected one first.
                let refl = self.glass_reflected(&g, path).map(|(r, p)| (r, p, g.kr));
                let refr = self.glass_refracted(&g, path).map(|(r, p)| (r, p, 1.0 - g.kr));
                let (first, next) = match (refl, refr) {
                    (Some(a), b) => (a, b),
                    (None, Some(b)) => (b, None),
                    (None, None) => return Some(Li::reflected(Vec3A::ZERO).absorbed(att)),
                };
                c.secondary += 1 + u64::from(next.is_some());
                w.push_absorb(i, att);
                w.stack[i].push(Frame::other(Kind::Split, Vec3A::ZERO));
                w.splits[i].push(Split {
                    sum: Vec3A::ZERO,
                    weight: first.2,
                    next,
                });
                w.launch(i, &first.0, first.1);
                return None;
            }
            // One ray, chosen by its Fresnel weight.
            let child = |medium| path.specular(medium, path.beta);
            match g.refracted {
                Some(r) if w.rng.0[i].get1d(Draw::GlassChoice.dim(path.vertex())) >= g.kr => (r, child(g.refr_medium)),
                _ => (g.reflected, child(g.refl_medium)),
            }
        };
        w.push_absorb(i, att);
        w.stack[i].push(Frame::other(Kind::Specular, Vec3A::ZERO));
        w.launch(i, &r, p);
        c.secondary += 1;
        None
    }

    /// Shades the Lambertian hits in `d`, the shading the one-path code does at a Lambertian
    /// vertex: point lights, one emitter sample (its shadow ray left in the wave) and one BRDF
    /// sample (its ray left in the wave). `dist` is each hit's distance along its ray.
    fn shade_wave(&self, w: &mut Wave, surf: &PacketSurfaces, d: &M, dist: &F, out: &mut [Vec3A], c: &mut Counters) {
        let ambient = self.settings.ambient;
        let f_frames = &surf.frames;
        let (n, ng, org) = (&f_frames.shading_normal, &f_frames.normal, &f_frames.outside);
        // The Lambert BRDF of each lane's material; point lights take the colour as is.
        let mut f = [[0.0; LANES]; 3];
        let mut lit = LitLanes::default();
        for i in 0..LANES {
            if !d[i] {
                continue;
            }
            let m = &self.scene.materials[surf.material[i] as usize];
            put(&mut f, i, lambert_f(transport_albedo(m)).to_array());
            put(&mut lit.alb, i, m.color.to_array());
            lit.on[i] = true;
        }
        // Point lights by the course's formula (no BRDF), one packet per light.
        let l = self.point_lights_packet(&lit, f_frames, c);
        let (tb, bb) = basis_lanes(n);
        // glam's dot: (x·x' + y·y') + z·z'.
        let dot = |x: &[F; 3], y: &[F; 3], i: usize| x[0][i] * y[0][i] + x[1][i] * y[1][i] + x[2][i] * y[2][i];
        // A Lambert BRDF's outgoing direction only decides whether it reflects at all, and
        // shade's correction keeps it above the surface, so it is not computed here.

        // Emitter sampling, weighted against BRDF sampling; the shadow ray waits in the wave.
        let mut shadow = [false; LANES];
        if !self.emitters.is_empty() {
            let u0 = w.rng.get1d(d, &dims(w, Draw::LightChoice));
            let [u1, u2] = w.rng.get2d(d, &dims(w, Draw::LightPoint));
            let ls = self.emitters.sample_lanes(self.scene, org, d, [&u0, &u1, &u2]);
            for i in 0..LANES {
                let wiz = dot(&ls.dir, n, i);
                let front = dot(&ls.dir, ng, i) > 0.0;
                let fz = (f[0][i] != 0.0) | (f[1][i] != 0.0) | (f[2][i] != 0.0);
                let go = ls.ok[i] & (wiz > 0.0) & front & fz;
                let wgt = power_heuristic(ls.pdf[i], lambert_pdf(wiz));
                let k = wiz * wgt / ls.pdf[i];
                for a in 0..3 {
                    w.unblocked[a][i] = f[a][i] * ls.radiance[a][i] * k;
                    w.shadow.o[a][i] = org[a][i];
                    w.shadow.d[a][i] = ls.dir[a][i];
                }
                w.shadow.t_max[i] = if go {
                    ls.dist[i] * (1.0 - 1e-4)
                } else {
                    f32::NEG_INFINITY
                };
                shadow[i] = go;
            }
            if self.media {
                self.absorb_unblocked(w, &shadow, &ls.dist);
            }
            c.shadow += shadow.iter().map(|&s| u64::from(s)).sum::<u64>();
        }
        w.shadow_on = shadow;

        // BRDF sampling: emitters it finds (MIS) and, where carried, indirect light.
        let bounce = self.emitters.any_emission || ambient;
        // A Lambert BRDF has one lobe, so no lobe is drawn.
        let [u1, u2] = if bounce {
            w.rng.get2d(d, &dims(w, Draw::BsdfDirection))
        } else {
            [[0.0; LANES]; 2]
        };
        let bs = lambert_sample_lanes(&u1, &u2);
        let wi = to_world_unit_lanes(&bs.wi, &tb, &bb, n);
        let pdf = &bs.pdf;
        // The sample is kept where it is drawn, valid, and leaves on the outer side.
        let ok: M = std::array::from_fn(|i| bounce & d[i] & bs.ok[i] & not_at_most(dot(&wi, ng, i), 0.0));
        // The bounce's weights, Russian roulette, and whether its hit's reflected light counts.
        let (mut wt, mut carry) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3]);
        let (mut beta, mut want, mut rr) = ([[0.0; LANES]; 3], [false; LANES], [false; LANES]);
        for i in 0..LANES {
            let ratio = bs.wi[2][i] / pdf[i];
            let path = &w.path[i];
            for a in 0..3 {
                wt[a][i] = f[a][i] * ratio;
                // Without -l only a specular part's reflection is carried, and Lambert has none.
                carry[a][i] = if ambient { wt[a][i] } else { 0.0 * ratio };
                beta[a][i] = path.beta[a] * carry[a][i];
            }
            let most = max_element([carry[0][i], carry[1][i], carry[2][i]]);
            want[i] = if ambient {
                let on = (most > 0.0) & (path.bounces < MAX_BOUNCES);
                rr[i] = ok[i] & on & (path.bounces >= RR_START);
                on
            } else {
                (most > 0.0) & (path.depth < self.settings.max_depth)
            };
        }
        if rr.contains(&true) {
            let u = w.rng.get1d(&rr, &dims(w, Draw::Roulette));
            for i in 0..LANES {
                let p = russian_roulette_survival(Vec3::new(beta[0][i], beta[1][i], beta[2][i]));
                let keep = u[i] < p;
                let scale = rr[i] & keep;
                for a in 0..3 {
                    carry[a][i] = if scale { carry[a][i] / p } else { carry[a][i] };
                    beta[a][i] = if scale { beta[a][i] / p } else { beta[a][i] };
                }
                want[i] = if rr[i] { keep } else { want[i] };
            }
        }
        // With nothing to find, a bounce that carries nothing is not traced.
        let found_nothing = self.emitters.is_empty() && !self.emitters.any_emission;
        for i in 0..LANES {
            if !d[i] {
                continue;
            }
            if ok[i] & (want[i] | !found_nothing) {
                let path = w.path[i];
                if self.media {
                    w.push_absorb(i, self.transmittance(path, dist[i]));
                }
                w.stack[i].push(Frame::lambert(lane(&l, i), lane(&wt, i), lane(&carry, i), pdf[i]));
                w.path[i] = PathState {
                    depth: path.depth + u32::from(!ambient),
                    bounces: path.bounces + 1,
                    beta: lane(&beta, i).into(),
                    medium: path.medium,
                    branch: false,
                };
                // Without indirect light no bounce carries reflected light: each only looks for
                // emission, and waits with the shadow ray as a probe. With it, a bounce is the
                // lane's next ray even where Russian roulette ended the path (a probe packet of
                // those few lanes costs more than it frees).
                let probe = !ambient & !want[i];
                let next = if probe { &mut w.probe } else { &mut w.rays };
                for a in 0..3 {
                    next.o[a][i] = org[a][i];
                    next.d[a][i] = wi[a][i];
                }
                next.t_max[i] = f32::INFINITY;
                w.want[i] = want[i];
                w.ray_on[i] = !probe;
                w.probe_on[i] = probe;
                c.secondary += 1;
            } else {
                w.ray_on[i] = false;
                if self.media {
                    w.push_absorb(i, self.transmittance(w.path[i], dist[i]));
                }
                if w.shadow_on[i] {
                    // The vertex's light is final once its shadow ray is traced.
                    w.stack[i].push(Frame::lambert(lane(&l, i), Vec3A::ZERO, Vec3A::ZERO, 0.0));
                } else {
                    w.finish(i, Li::reflected(lane(&l, i)), out);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {

    use super::*;
    use crate::integrator::Engine;
    use crate::observer::NoObserver;
    use crate::scene::Scene;
    use crate::settings::{RenderSettings, Stage};

    #[test]
    fn waves_return_what_one_path_at_a_time_returns() {
        // Our scenes with emitters, point lights, mirrors, glass (absorbing too), every
        // reflection model, depth of field and OBJ meshes, and two of the course's scenes, with
        // and without indirect light: every sample's value bit for bit, and the ray counts.
        let mut paths: Vec<_> = (rayscope_testkit::ENGINE_SCENES.iter())
            .map(|n| rayscope_testkit::scene(&format!("{n}.txt")))
            .collect();
        // The course's bunny scene, and its scene 2: a room small enough for a flat list, a
        // mirror, and glass seen directly (both of its rays traced, one after the other).
        if let Some(course) = rayscope_testkit::course_part() {
            for n in ["sample_scene_obj", "sample_scene_2"] {
                paths.push(course.scene(&format!("{n}.txt")));
            }
        }
        let (mut waves, mut in_list) = (0, 0);
        for path in &paths {
            let file = rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
            let scene = Scene::from_file(&file);
            // The depth-of-field scene through its lens too.
            let lens = path.ends_with("dof.txt");
            let apertures: &[f32] = if lens { &[0.0, 0.1] } else { &[0.0] };
            for (ambient, &aperture) in [true, false]
                .into_iter()
                .flat_map(|a| apertures.iter().map(move |r| (a, r)))
            {
                let mut settings = RenderSettings {
                    width: 40,
                    height: 30,
                    aa: 2,
                    quality: 1,
                    ambient,
                    stage: Stage::Full,
                    ..RenderSettings::default()
                };
                if aperture > 0.0 {
                    settings.camera.aperture_radius = aperture;
                    settings.camera.focal_length = 3.6;
                }
                let integ = Integrator::new(&scene, &settings);
                if integ.engine() != Engine::Waves {
                    assert!(!integ.stochastic, "{}: stochastic renders go in waves", path.display());
                    continue;
                }
                let spp = integ.samples_per_pixel();
                let jobs: Vec<Job> = (0..30)
                    .flat_map(|y| (0..40).flat_map(move |x| (0..spp).map(move |s| (x, y, s))))
                    .collect();
                let mut got = vec![Vec3A::ZERO; jobs.len()];
                let mut counted = Counters::default();
                let shaded = integ.sample_wave(&jobs, &mut got, &mut counted).shaded;
                let mut want = Counters::default();
                for (k, &(x, y, s)) in jobs.iter().enumerate() {
                    let v = integ.sample(x, y, s, &mut NoObserver, &mut want);
                    assert_eq!(
                        got[k].to_array().map(f32::to_bits),
                        v.to_array().map(f32::to_bits),
                        "{} -r {aperture} -l {ambient}: pixel ({x}, {y}) sample {s}: {} against {v}",
                        path.display(),
                        got[k]
                    );
                }
                assert_eq!(
                    counted,
                    want,
                    "{} -r {aperture} -l {ambient}: ray counts",
                    path.display()
                );
                assert!(shaded > 0 || !ambient, "{}: the wave shaded nothing", path.display());
                waves += 1;
                // Camera rays go in the wave's packets in a room with a list, else ahead.
                in_list += usize::from(scene.packets_test_everything());
            }
        }
        assert!(waves >= 15, "only {waves} of the renders went in waves");
        assert!(
            in_list > 0 && in_list < waves,
            "{in_list} of {waves} renders used a list: both ways to trace camera rays must be tested"
        );
    }
}
