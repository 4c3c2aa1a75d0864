//! The parallel render loop: tiles on rayon's pool, progress and cancellation callbacks, and a
//! guard that keeps NaN and infinity off the film.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::film::Film;
use crate::geometry::{PrimRef, Primitive};
use crate::integrator::{Counters, Engine, Integrator, Job, WaveWork};
use crate::math::Ray;
use crate::mistakes::{Mistake, Mistakes};
use crate::observer::{NoObserver, RayRecorder, RayTree};
use crate::scene::{Hit, Intersect, Scene};
use crate::settings::{Channel, RenderSettings};
use crate::simd::LANES;

/// Tile edge in pixels: small enough to balance two cores on tiny images, large enough to
/// keep scheduling overhead negligible. Tiles are also the unit a farm render deals out to its
/// parts ([`render_tiles_of`], [`crate::farm`]).
pub const TILE: u32 = 16;

/// The tile grid of a `width` × `height` image: (columns, rows) of [`TILE`]-pixel tiles, the last
/// column and row cut to the image. Tile `t` is column `t % columns`, row `t / columns`.
#[must_use]
pub fn tile_grid(width: u32, height: u32) -> (u32, u32) {
    (width.div_ceil(TILE), height.div_ceil(TILE))
}

/// The pixel rectangle `(x0, y0, x1, y1)` (ends exclusive) of tile `t` in a `width` × `height`
/// image.
#[must_use]
pub fn tile_rect(width: u32, height: u32, t: u32) -> (u32, u32, u32, u32) {
    let (tiles_x, _) = tile_grid(width, height);
    let (tx, ty) = (t % tiles_x, t / tiles_x);
    (
        tx * TILE,
        ty * TILE,
        (tx * TILE + TILE).min(width),
        (ty * TILE + TILE).min(height),
    )
}

/// The result of a finished render.
#[derive(Debug, Clone)]
pub struct RenderOutput {
    /// The image.
    pub film: Film,
    /// Rays cast.
    pub counters: Counters,
    /// Samples per pixel used.
    pub samples_per_pixel: u32,
    /// Samples whose value was NaN or infinite (replaced by black).
    pub nonfinite: u64,
    /// The first such sample as (x, y, sample), for a replay command.
    pub first_nonfinite: Option<(u32, u32, u32)>,
    /// Wall time of the render loop.
    pub elapsed: Duration,
}

/// The render was cancelled before it finished.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("render cancelled")]
pub struct Cancelled;

/// Renders `scene` with `settings` on the current rayon pool.
///
/// `progress(done, total)` is called with pixel counts as tiles finish; setting `cancel` stops the
/// render within one batch of samples (at most `WAVE_BATCH` paths on each thread) and returns
/// [`Cancelled`].
pub fn render(
    scene: &Scene,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
    cancel: &AtomicBool,
) -> Result<RenderOutput, Cancelled> {
    render_with(scene, scene, settings, progress, cancel)
}

/// [`render`] tracing rays with `isect` (e.g. the parry3d reference) instead of the scene's BVH.
pub fn render_with<I: Intersect>(
    scene: &Scene,
    isect: &I,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64, u64) + Sync),
    cancel: &AtomicBool,
) -> Result<RenderOutput, Cancelled> {
    if !settings.mistakes.is_empty() {
        return render_mistaken(scene, isect, settings, None, progress, cancel);
    }
    render_tiles(scene, isect, settings, None, progress, cancel)
}

/// [`render`] of only the tiles `tiles` (indices into [`tile_grid`], in any order, each at most
/// once): every pixel of those tiles gets exactly the value a full render gives it (a pixel
/// depends only on the seed, its position and its sample numbers, never on which tiles are
/// rendered beside it); the film's other pixels stay black. `progress` counts the pixels of
/// those tiles.
///
/// # Panics
/// If a tile index is outside the grid.
pub fn render_tiles_of(
    scene: &Scene,
    settings: &RenderSettings,
    tiles: &[u32],
    progress: &(dyn Fn(u64, u64) + Sync),
    cancel: &AtomicBool,
) -> Result<RenderOutput, Cancelled> {
    let (tx, ty) = tile_grid(settings.width, settings.height);
    assert!(tiles.iter().all(|&t| t < tx * ty), "tile index outside the image");
    if !settings.mistakes.is_empty() {
        return render_mistaken(scene, scene, settings, Some(tiles), progress, cancel);
    }
    render_tiles(scene, scene, settings, Some(tiles), progress, cancel)
}

/// The tile loop of [`render_with`], for settings whose mistakes (if any) `isect` makes: every
/// tile, or only `only` (see [`render_tiles_of`]).
pub(crate) fn render_tiles<I: Intersect>(
    scene: &Scene,
    isect: &I,
    settings: &RenderSettings,
    only: Option<&[u32]>,
    progress: &(dyn Fn(u64, u64) + Sync),
    cancel: &AtomicBool,
) -> Result<RenderOutput, Cancelled> {
    let start = Instant::now();
    let integ = Integrator::with_intersector(scene, isect, settings).with_cancel(cancel);
    let spp = integ.samples_per_pixel();
    let (w, h) = (settings.width, settings.height);
    let (tiles_x, tiles_y) = tile_grid(w, h);
    // In raster order either way, so the first non-finite sample found is the first in raster
    // order among the tiles rendered.
    let tiles: Vec<u32> = match only {
        None => (0..tiles_x * tiles_y).collect(),
        Some(list) => {
            let mut v = list.to_vec();
            v.sort_unstable();
            v
        }
    };
    let total = match only {
        None => w as u64 * h as u64,
        Some(_) => tiles
            .iter()
            .map(|&t| {
                let (x0, y0, x1, y1) = tile_rect(w, h, t);
                (x1 - x0) as u64 * (y1 - y0) as u64
            })
            .sum(),
    };
    let done = AtomicU64::new(0);
    let waves = WaveStats::default();
    let results: Vec<Option<TileResult>> = tiles
        .into_par_iter()
        .map(|t| {
            if cancel.load(Ordering::Relaxed) {
                return None;
            }
            let (x0, y0, x1, y1) = tile_rect(w, h, t);
            let r = render_tile(&integ, &waves, (x0, y0, x1, y1), spp, cancel)?;
            let n = done.fetch_add(r.pixels.len() as u64, Ordering::Relaxed) + r.pixels.len() as u64;
            progress(n, total);
            Some(r)
        })
        .collect();
    if cancel.load(Ordering::Relaxed) {
        return Err(Cancelled);
    }
    let mut film = Film::new(w, h);
    let mut counters = Counters::default();
    let mut nonfinite = 0;
    let mut first_nonfinite: Option<(u32, u32, u32)> = None;
    for r in results.into_iter().flatten() {
        let tw = r.x1 - r.x0;
        for (i, p) in r.pixels.iter().enumerate() {
            let (x, y) = (r.x0 + i as u32 % tw, r.y0 + i as u32 / tw);
            film.pixels[(y * w + x) as usize] = *p;
        }
        counters.add(&r.counters);
        nonfinite += r.nonfinite;
        // Tiles are in raster order, so the first tile with a bad sample holds the first one.
        if first_nonfinite.is_none() {
            first_nonfinite = r.first_nonfinite;
        }
    }
    Ok(RenderOutput {
        film,
        counters,
        samples_per_pixel: spp,
        nonfinite,
        first_nonfinite,
        elapsed: start.elapsed(),
    })
}

struct TileResult {
    x0: u32,
    y0: u32,
    x1: u32,
    pixels: Vec<Vec3>,
    counters: Counters,
    nonfinite: u64,
    first_nonfinite: Option<(u32, u32, u32)>,
}

impl TileResult {
    /// Adds sample `s` of pixel (`x`, `y`) to `sum`, or counts it when it is NaN or infinite
    /// (remembering the first such sample in raster order, whatever order samples come in).
    #[inline]
    fn add_sample(&mut self, sum: &mut Vec3A, (x, y, s): (u32, u32, u32), v: Vec3A) {
        if v.is_finite() {
            *sum += v;
        } else {
            self.nonfinite += 1;
            if self.first_nonfinite.is_none_or(|(fx, fy, fs)| (y, x, s) < (fy, fx, fs)) {
                self.first_nonfinite = Some((x, y, s));
            }
        }
    }
}

/// What the tiles traced as waves of paths found. A wave step costs about the same however
/// many of its sixteen lanes reach a Lambertian surface, which is the work it shares (the other
/// lanes end, go on to a mirror's or glass's next ray, or finish alone on a glossy coat), so
/// once a few tiles show that this render's steps shade fewer than [`MIN_SHADED_PER_STEP`]
/// lanes on average (a sky that most camera rays see, glass that most paths pass through), the
/// other tiles trace their paths one at a time. Both loops compute the same values, so which one
/// a tile used never shows in the image.
#[derive(Default)]
struct WaveStats {
    /// Samples traced in waves.
    samples: AtomicU64,
    /// Steps those waves took.
    steps: AtomicU64,
    /// Lambertian vertices those waves shaded.
    shaded: AtomicU64,
}

/// Samples traced in waves before [`WaveStats`] decides (a 16×16 tile at 16 samples a pixel).
const WAVE_PILOT: u64 = 4096;

/// Most samples a path-traced tile hands to the wave engine at once: enough that a wave's lanes
/// rarely drain between batches (a 16×16 tile at 16 samples a pixel is one batch), few enough that
/// a tile's memory and the time to notice a cancel do not grow with `-x` and `-q`.
pub(crate) const WAVE_BATCH: usize = 4096;

/// Samples the one-at-a-time loop traces between looks at the cancel flag.
const CANCEL_EVERY: u32 = 256;

/// Lambertian lanes a wave step must shade on average for waves to pay. Calibrated on our
/// scenes and the course's (`rayscope bench render -f SCENE -l -x 4 --threads 1`, with waves
/// forced on and off): waves are slower than one path at a time at 3.4–9.6 shaded lanes a step
/// (the beer glasses 19 %, the glossy spheres 3 %), even at 10.5 (depth of field), and 23–39 %
/// faster at 12.5–16.
const MIN_SHADED_PER_STEP: u64 = 10;

impl WaveStats {
    /// Whether the next tile should trace its paths in waves.
    fn worthwhile(&self) -> bool {
        let samples = self.samples.load(Ordering::Relaxed);
        samples < WAVE_PILOT
            || self.shaded.load(Ordering::Relaxed) >= MIN_SHADED_PER_STEP * self.steps.load(Ordering::Relaxed)
    }

    /// Records a tile's waves.
    fn add(&self, samples: u64, work: WaveWork) {
        self.samples.fetch_add(samples, Ordering::Relaxed);
        self.steps.fetch_add(work.steps, Ordering::Relaxed);
        self.shaded.fetch_add(work.shaded, Ordering::Relaxed);
    }
}

/// Renders the tile of pixels `x0..x1` × `y0..y1` ([`tile_rect`]), or returns `None` once
/// `cancel` is set.
fn render_tile<I: Intersect>(
    integ: &Integrator<'_, I>,
    waves: &WaveStats,
    (x0, y0, x1, y1): (u32, u32, u32, u32),
    spp: u32,
    cancel: &AtomicBool,
) -> Option<TileResult> {
    let mut r = TileResult {
        x0,
        y0,
        x1,
        pixels: Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize),
        counters: Counters::default(),
        nonfinite: 0,
        first_nonfinite: None,
    };
    let engine = match integ.engine() {
        Engine::Waves if !waves.worthwhile() => Engine::CameraPackets,
        e => e,
    };
    match engine {
        Engine::Packets => {
            render_tile_packets(&mut r, y1, spp, LANES, cancel, |jobs, vals, c| {
                integ.sample_packet(jobs, vals, c)
            })?;
        }
        Engine::Waves => {
            // As many samples at once as the bound allows: a wave's lanes drain only at the end
            // of its jobs. Counted in 64 bits: pixels × samples can pass 2^32.
            let jobs = (x1 - x0) as u64 * (y1 - y0) as u64 * spp as u64;
            let batch = jobs.min(WAVE_BATCH as u64) as usize;
            let mut work = WaveWork::default();
            render_tile_packets(&mut r, y1, spp, batch, cancel, |jobs, vals, c| {
                work.add(integ.sample_wave(jobs, vals, c));
            })?;
            waves.add(jobs, work);
        }
        Engine::CameraPackets => {
            render_tile_packets(&mut r, y1, spp, LANES, cancel, |jobs, vals, c| {
                integ.sample_camera_packet(jobs, vals, c)
            })?;
        }
        Engine::OnePath => {
            let inv = 1.0 / spp as f32;
            for y in y0..y1 {
                for x in x0..x1 {
                    let mut sum = Vec3A::ZERO;
                    for s in 0..spp {
                        if s % CANCEL_EVERY == 0 && cancel.load(Ordering::Relaxed) {
                            return None;
                        }
                        let v = integ.sample(x, y, s, &mut NoObserver, &mut r.counters);
                        r.add_sample(&mut sum, (x, y, s), v);
                    }
                    r.pixels.push((sum * inv).into());
                }
            }
        }
    }
    Some(r)
}

/// [`render_tile`] with the samples handed to `trace` `batch` at a time: a pixel's samples in
/// order, and when a pixel has fewer than [`LANES`], the pixels of a 4×4 block one after
/// another, so a packet's rays stay close together. Returns `None` as soon as `cancel` is set.
fn render_tile_packets(
    r: &mut TileResult,
    y1: u32,
    spp: u32,
    batch: usize,
    cancel: &AtomicBool,
    mut trace: impl FnMut(&[Job], &mut [Vec3A], &mut Counters),
) -> Option<()> {
    let inv = 1.0 / spp as f32;
    let (x0, y0, x1) = (r.x0, r.y0, r.x1);
    let tw = x1 - x0;
    r.pixels = vec![glam::Vec3::ZERO; (tw * (y1 - y0)) as usize];
    let mut jobs: Vec<Job> = Vec::with_capacity(batch);
    let mut vals = vec![Vec3A::ZERO; batch];
    // The pixel being summed: its samples arrive in order, so a running sum reproduces the
    // one-sample-at-a-time loop's additions exactly.
    let mut sum = Vec3A::ZERO;
    let mut flush = |jobs: &mut Vec<Job>, r: &mut TileResult, sum: &mut Vec3A| {
        trace(jobs, &mut vals, &mut r.counters);
        for (&(x, y, s), &v) in jobs.iter().zip(&vals) {
            r.add_sample(sum, (x, y, s), v);
            if s + 1 == spp {
                r.pixels[((y - y0) * tw + (x - x0)) as usize] = (*sum * inv).into();
                *sum = Vec3A::ZERO;
            }
        }
        jobs.clear();
    };
    let block = if (spp as usize) < LANES { 4 } else { 1 };
    for by in (y0..y1).step_by(block) {
        for bx in (x0..x1).step_by(block) {
            for y in by..(by + block as u32).min(y1) {
                for x in bx..(bx + block as u32).min(x1) {
                    // A pixel's samples go in as runs that fill the batch: pushed one by one,
                    // with a length check each, they cost 2 % of a direct-lighting render.
                    let mut s = 0;
                    while s < spp {
                        let n = (spp - s).min((batch - jobs.len()) as u32);
                        jobs.extend((s..s + n).map(|k| (x, y, k)));
                        s += n;
                        if jobs.len() == batch {
                            if cancel.load(Ordering::Relaxed) {
                                return None;
                            }
                            flush(&mut jobs, r, &mut sum);
                        }
                    }
                }
            }
        }
    }
    if !jobs.is_empty() {
        flush(&mut jobs, r, &mut sum);
    }
    Some(())
}

/// Traces sample `sample` of pixel (`x`, `y`) with a recorder and returns its ray tree.
#[must_use]
pub fn trace_pixel(scene: &Scene, settings: &RenderSettings, x: u32, y: u32, sample: u32) -> RayTree {
    trace_pixel_with(scene, scene, settings, x, y, sample)
}

/// [`trace_pixel`] tracing rays with `isect`.
#[must_use]
pub fn trace_pixel_with<I: Intersect>(
    scene: &Scene,
    isect: &I,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    sample: u32,
) -> RayTree {
    if !settings.mistakes.is_empty() {
        return trace_pixel_mistaken(scene, isect, settings, x, y, sample);
    }
    record_pixel(&Integrator::with_intersector(scene, isect, settings), x, y, sample)
}

/// Traces sample `sample` of pixel (`x`, `y`) with `integ` and a recorder.
pub(crate) fn record_pixel<I: Intersect>(integ: &Integrator<'_, I>, x: u32, y: u32, sample: u32) -> RayTree {
    let mut rec = RayRecorder::default();
    let mut c = Counters::default();
    let v = integ.sample(x, y, sample, &mut rec, &mut c);
    RayTree {
        x,
        y,
        sample,
        nodes: rec.nodes,
        color: v.to_array(),
    }
}

/// An intersector that traces rays as a tracer with `mistakes` would (one-sided triangles), and
/// whose renders make the integrator's mistakes ([`Intersect::MISTAKEN`]). It offers no wide
/// BVH, so its renders run one ray at a time.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Mistaken<'a, I: Intersect> {
    /// The intersector rays are really traced with.
    pub inner: &'a I,
    /// The scene (for the triangles' normals).
    pub scene: &'a Scene,
    /// The mistakes.
    pub mistakes: Mistakes,
}

impl<I: Intersect> Mistaken<'_, I> {
    /// The nearest distance along a ray the student's tracer accepts a hit at.
    #[inline]
    fn t_min(&self, t_min: f32) -> f32 {
        if self.mistakes.has(Mistake::MinHitDistance) {
            t_min.max(crate::mistakes::MIN_HIT)
        } else {
            t_min
        }
    }

    /// True when the hit must be skipped: a triangle seen from the side the student's
    /// one-sided test rejects.
    #[inline]
    fn culled(&self, ray: &Ray, hit: &Hit) -> bool {
        let PrimRef::Triangle(i) = hit.prim else {
            return false;
        };
        if self.mistakes.has(Mistake::StrictEdges) {
            let m = crate::mistakes::EDGE_MARGIN;
            if hit.u < m || hit.v < m || hit.u + hit.v > 1.0 - m {
                return true;
            }
        }
        if !self.mistakes.has(Mistake::OneSidedTriangles) {
            return false;
        }
        let front = self.scene.triangles[i as usize].geometric_normal().dot(ray.dir) < 0.0;
        // With reversed normals the student's front is rayscope's back.
        front == self.mistakes.has(Mistake::ReversedNormals)
    }

    /// The hit behind `lo` a tracer with [`Mistake::PlaneHitsBehind`] or
    /// [`Mistake::SphereNearRootBehind`] keeps: the most negative of the planes' distances at or
    /// below `lo`, and of the near roots at or below `lo` of the spheres whose far root lies
    /// beyond it. It is nearer than any hit the correct test accepts, so it is the student's
    /// nearest hit, below `t_max`.
    fn behind(&self, ray: &Ray, lo: f32, t_max: f32) -> Option<Hit> {
        let planes = self.mistakes.has(Mistake::PlaneHitsBehind);
        let spheres = self.mistakes.has(Mistake::SphereNearRootBehind);
        if !planes && !spheres {
            return None;
        }
        let mut best: Option<Hit> = None;
        let mut keep = |t: f32, prim: PrimRef| {
            if t <= lo && t < t_max && best.as_ref().is_none_or(|b| t < b.t) {
                best = Some(Hit {
                    t,
                    u: 0.0,
                    v: 0.0,
                    prim,
                });
            }
        };
        if planes {
            for (k, p) in self.scene.planes.iter().enumerate() {
                if let Some(h) = p.intersect(ray, f32::NEG_INFINITY, f32::INFINITY) {
                    keep(h.t, PrimRef::Plane(k as u32));
                }
            }
        }
        if spheres {
            for (k, s) in self.scene.spheres.iter().enumerate() {
                if s.intersect(ray, lo, f32::INFINITY).is_some() {
                    if let Some(h) = s.intersect(ray, f32::NEG_INFINITY, f32::INFINITY) {
                        keep(h.t, PrimRef::Sphere(k as u32));
                    }
                }
            }
        }
        best
    }

    /// The nearest plane the ray meets after `lo` and no farther than `t` (a hit the walk steps
    /// past) plus the walk's step, below `t_max`: a triangle lying in a plane (a slab's face on
    /// the ground) is met at the same distance as the plane, and stepping past the culled
    /// triangle would step past the plane too, which the student's test of each entity keeps.
    fn coplanar_plane(&self, ray: &Ray, lo: f32, t: f32, t_max: f32) -> Option<Hit> {
        let hi = (t + t.abs() * 1e-5).min(t_max);
        (self.scene.planes.iter().enumerate())
            .filter_map(|(k, p)| p.intersect(ray, lo, hi).map(|h| (k, h.t)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(k, t)| Hit {
                t,
                u: 0.0,
                v: 0.0,
                prim: PrimRef::Plane(k as u32),
            })
    }
}

/// Most culled hits one query steps past before it gives up (a ray grazing a mesh can meet many).
const MAX_CULLED: usize = 1024;

/// The hit before the next one on a walk along a ray: its primitive and distance.
type Last = Option<(PrimRef, f32)>;

/// True when `hit` is the walk's previous hit found again: the same primitive within rounding
/// of the same distance (a sphere's other root is another hit).
#[inline]
fn again(hit: &Hit, last: Last) -> bool {
    last.is_some_and(|(p, t)| p == hit.prim && hit.t - t <= t.abs() * 1e-5)
}

/// The t to look for the next hit beyond `hit` from. Asked again from its own t, a primitive's
/// t can come out a rounding step larger: the first step is one float past the hit, and a hit
/// found again is stepped past by a hundred-thousandth of its distance.
#[inline]
fn past(hit: &Hit, last: Last) -> f32 {
    if again(hit, last) {
        hit.t + hit.t.abs() * 1e-5
    } else {
        hit.t.next_up()
    }
}

impl<I: Intersect> Intersect for Mistaken<'_, I> {
    const MISTAKEN: bool = true;

    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut lo = self.t_min(t_min);
        if let Some(h) = self.behind(ray, lo, t_max) {
            return Some(h);
        }
        let by_origin = self.mistakes.has(Mistake::NearestByOriginDistance);
        let by_order = self.mistakes.has(Mistake::FirstHitInSceneOrder);
        if !by_origin && !by_order {
            let mut last: Last = None;
            for _ in 0..MAX_CULLED {
                let hit = self.inner.intersect(ray, lo, t_max)?;
                if !again(&hit, last) && !self.culled(ray, &hit) {
                    return Some(hit);
                }
                if let Some(p) = self.coplanar_plane(ray, lo, hit.t, t_max) {
                    return Some(p);
                }
                lo = past(&hit, last);
                last = Some((hit.prim, hit.t));
            }
            return None;
        }
        // The student's loop over every entity keeps another hit than the nearest: walk all
        // hits along the ray, nearest first, take each entity's nearest (its own intersection
        // test answers one hit: a sphere's near root, a model's nearest triangle), and keep the
        // one the student's comparison prefers (the first of equals, as a strict `<` does).
        let key = |h: &Hit| -> f32 {
            if by_origin {
                (ray.origin + ray.dir * h.t).length()
            } else {
                self.scene.prim_info(h.prim).0 as f32
            }
        };
        let mut best: Option<(f32, Hit)> = None;
        let mut last: Last = None;
        let mut seen: Vec<u32> = Vec::new();
        for _ in 0..MAX_CULLED {
            let Some(hit) = self.inner.intersect(ray, lo, t_max) else {
                break;
            };
            lo = past(&hit, last);
            let repeat = again(&hit, last);
            last = Some((hit.prim, hit.t));
            let entity = self.scene.prim_info(hit.prim).0;
            if repeat || seen.contains(&entity) {
                continue;
            }
            if self.culled(ray, &hit) {
                continue;
            }
            seen.push(entity);
            let k = key(&hit);
            if best.as_ref().is_none_or(|(b, _)| k < *b) {
                best = Some((k, hit));
            }
        }
        best.map(|(_, h)| h)
    }

    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        let lo = self.t_min(t_min);
        // The shadow test takes the closest hit, which a hit behind the origin always is.
        if let Some(h) = self.behind(ray, lo, t_max) {
            return Some(h.prim);
        }
        if self.mistakes.has(Mistake::NearestByOriginDistance) || self.mistakes.has(Mistake::FirstHitInSceneOrder) {
            // The course's template invites a shadow test that takes the closest-hit function's
            // answer on the whole ray and compares its distance with the light's.
            return self
                .intersect(ray, t_min, f32::INFINITY)
                .filter(|h| h.t < t_max)
                .map(|h| h.prim);
        }
        let shadowless = self.mistakes.any_shadowless();
        if !self.mistakes.has(Mistake::OneSidedTriangles) && !self.mistakes.has(Mistake::StrictEdges) && !shadowless {
            return self.inner.occluder(ray, lo, t_max);
        }
        // Any hit blocks, whichever the student's nearest-hit rule would keep, but one on an
        // entity that casts no shadow.
        let passes = |h: &Hit| {
            shadowless && {
                let entity = self.scene.prim_info(h.prim).0;
                self.mistakes.shadowless(self.scene.entities[entity as usize].kind)
            }
        };
        let (mut lo, mut last): (f32, Last) = (lo, None);
        for _ in 0..MAX_CULLED {
            let hit = self.inner.intersect(ray, lo, t_max)?;
            if !again(&hit, last) && !self.culled(ray, &hit) && !passes(&hit) {
                return Some(hit.prim);
            }
            if let Some(p) = self.coplanar_plane(ray, lo, hit.t, t_max).filter(|p| !passes(p)) {
                return Some(p.prim);
            }
            lo = past(&hit, last);
            last = Some((hit.prim, hit.t));
        }
        None
    }

    fn mistakes(&self) -> Mistakes {
        self.mistakes
    }
}

/// [`render_with`] (every tile, or only `only`) for settings with mistakes: the scene traced
/// through a [`Mistaken`] intersector under [`RenderSettings::mistaken`], its colours written as
/// the student's code would.
fn render_mistaken<I: Intersect>(
    scene: &Scene,
    isect: &I,
    settings: &RenderSettings,
    only: Option<&[u32]>,
    progress: &(dyn Fn(u64, u64) + Sync),
    cancel: &AtomicBool,
) -> Result<RenderOutput, Cancelled> {
    let m = settings.mistakes;
    let wrapped = Mistaken {
        inner: isect,
        scene,
        mistakes: m,
    };
    let s = settings.mistaken(m);
    let mut out = render_tiles(scene, &wrapped, &s, only, progress, cancel)?;
    if s.channel == Channel::Color {
        m.apply_to_film(&mut out.film);
    }
    Ok(out)
}

/// [`trace_pixel_with`] for settings with mistakes.
fn trace_pixel_mistaken<I: Intersect>(
    scene: &Scene,
    isect: &I,
    settings: &RenderSettings,
    x: u32,
    y: u32,
    sample: u32,
) -> RayTree {
    let m = settings.mistakes;
    let wrapped = Mistaken {
        inner: isect,
        scene,
        mistakes: m,
    };
    let s = settings.mistaken(m);
    record_pixel(&Integrator::with_intersector(scene, &wrapped, &s), x, y, sample)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn waves_stop_once_their_steps_shade_few_lanes() {
        let work = |steps, shaded| WaveWork { steps, shaded };
        let w = WaveStats::default();
        assert!(w.worthwhile(), "the first tiles go in waves");
        w.add(WAVE_PILOT / 2, work(1000, 0));
        assert!(w.worthwhile(), "one small tile decides nothing");
        w.add(WAVE_PILOT / 2, work(1000, 2 * 1000 * MIN_SHADED_PER_STEP - 1));
        assert!(
            !w.worthwhile(),
            "fewer shaded lanes a step than needed: one path at a time"
        );
        let full = WaveStats::default();
        full.add(WAVE_PILOT, work(1000, 1000 * MIN_SHADED_PER_STEP));
        assert!(full.worthwhile(), "steps that shade enough lanes stay in waves");
    }
}
