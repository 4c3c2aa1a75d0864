//! Ties: the pixels on which two correct tracers may legitimately disagree, decided from
//! rayscope's own rays, and the match rule built on them.
//!
//! A sample is a *tie* where what its rays meet depends on rounding: a ray within rounding of a
//! triangle's edge, a sphere's rim, a seam where two surfaces meet at the same distance (the
//! course box's wall corners), a shadow boundary, the critical angle. Each sample of a pixel is
//! traced as rayscope traces it and again with its camera ray moved by [`TIE`] (relative, in
//! each image direction: rounding error of a coordinate is relative to its size) in four
//! directions; every ray of the tree moves with it, so a sample whose tree meets something else
//! under any of those moves is a tie, and the colours those moves give are the colours of the
//! tie's sides. Each sample is traced again with its secondary rays (shadow, mirror, glass)
//! leaving their surface at a tenth and at ten times rayscope's offset (1e-5 of the
//! coordinates' size) and at 1e-5 and 1e-7 (the course's "1e-5 or less"), the offsets correct
//! tracers use: a shadow ray whose blocker lies that
//! close to its origin (a smooth mesh's shadow terminator, where the ray grazes its own
//! surface), or a path through glass whose way depends on where its rays start, is a tie too.
//! A sample whose tree has a hit point within `TIE` × the point's size (at least 1)
//! of another entity's surface, or a shadow ray whose only blockers lie that close to its light,
//! is a tie too: a tracer whose hit point rounds to the far side of that surface, or whose light
//! does, loses that point's light, so such a sample may be any colour from black up.
//!
//! A pixel's *tie bounds* are, per channel, the mean over its samples of each sample's darkest
//! and brightest side, widened by [`TIE`] of itself for rounding, the mistakes' output applied,
//! then written as bytes as the course writes them, `trunc(255·v)`: two tracers whose values
//! agree to rounding write the same byte except where a value lies within rounding of a
//! multiple of 1/255, and there the bounds hold both bytes. An image is a render when every
//! pixel lies within its bounds.

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use crate::film::to_byte;
use crate::integrator::{Counters, Integrator, OffsetRule};
use crate::math::Ray;
use crate::mistakes::{Mistake, Mistakes};
use crate::observer::{NoObserver, RayKind, RayObserver};
use crate::render::Mistaken;
use crate::scene::{Intersect, Scene};
use crate::settings::RenderSettings;
use crate::surface::Surface;

/// "Within rounding", relative to the size of the coordinates involved: the same tolerance the
/// ray-log checker's tie policy uses (`rayscope_check`'s `Tolerances::tie`). Far above f32
/// rounding (about 6e-8), far below a pixel (a 400-pixel-wide image's pixel spans 2.9e-3 of
/// the image plane).
pub(crate) const TIE: f32 = 1e-4;

/// The secondary-ray offsets of the other traces of each sample: a tenth and ten times
/// rayscope's (from 1e-6 of the coordinates' size up to [`TIE`]), and the course's "1e-5 or
/// less" whatever the coordinates: 1e-5 and 1e-7 (a path that grazes glass near the critical
/// angle takes another way for each; with the tenth of rayscope's, they cover a tracer's 1e-6
/// too).
const OFFSETS: [OffsetRule; 4] = [
    OffsetRule::Scaled(0.1),
    OffsetRule::Scaled(10.0),
    OffsetRule::Absolute(1e-5),
    OffsetRule::Absolute(1e-7),
];

/// Differing pixels checked together; the check of a candidate that is not the image stops
/// after the first batch that holds a pixel no tie excuses.
const BATCH: usize = 256;

/// Hit points whose neighbourhood [`Corners`] looks at are the first few of a sample's tree
/// (a Whitted tree through glass has up to 2^depth hits; the first ones carry its colour).
const MAX_CORNER_HITS: usize = 32;

/// What checking an image against a render's ties found.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Verdict {
    /// No pixel lies beyond its tie bounds: the image is the render.
    pub(crate) matches: bool,
    /// Pixels whose colour is not the render's.
    pub(crate) differing: u64,
    /// Of those, the pixels checked against their tie bounds (all of them when the image
    /// matches or the check was asked to be exhaustive).
    pub(crate) checked: u64,
    /// Checked pixels within their tie bounds.
    pub(crate) ties: u64,
    /// Checked pixels beyond their tie bounds (row-major indices).
    pub(crate) beyond: Vec<u32>,
    /// Largest distance, in levels, of a channel outside its tie bounds, over the checked
    /// pixels.
    pub(crate) worst: u8,
}

/// The scene's size at `p`: its largest coordinate, at least 1 (course scenes are of unit size
/// and students' epsilons absolute).
fn size(p: Vec3A) -> f32 {
    p.abs().max_element().max(1.0)
}

/// True when a surface of an entity other than `entity` passes within `r` of `p`, along one of
/// the axes through it (a surface through `p` itself included).
fn near_other(scene: &Scene, p: Vec3A, entity: u32, r: f32) -> bool {
    for axis in [Vec3A::X, Vec3A::Y, Vec3A::Z] {
        let ray = Ray::new(p - axis * r, axis);
        let mut t0 = 0.0;
        // The point's own surface crosses the segment too; look past it, a few times at most.
        for _ in 0..4 {
            let Some(h) = scene.intersect(&ray, t0, 2.0 * r) else {
                break;
            };
            if scene.prim_info(h.prim).0 != entity {
                return true;
            }
            t0 = h.t;
        }
    }
    false
}

/// Records whether a sample's tree has a hit point near another entity's surface or a shadow
/// ray whose blockers lie within rounding of its light.
struct Corners {
    /// Each ray's ray and search bound, by id.
    rays: Vec<(Ray, f32)>,
    hits: usize,
    found: bool,
}

impl RayObserver for Corners {
    const ENABLED: bool = true;

    fn ray(&mut self, _parent: Option<u32>, _kind: RayKind, _depth: u32, ray: &Ray, t_max: f32) -> u32 {
        self.rays.push((*ray, t_max));
        (self.rays.len() - 1) as u32
    }

    fn hit(&mut self, _id: u32, scene: &Scene, _t: f32, s: &Surface) {
        if self.found || self.hits >= MAX_CORNER_HITS {
            return;
        }
        self.hits += 1;
        self.found = near_other(scene, s.point, s.entity, TIE * size(s.point));
    }

    fn shadow(&mut self, id: u32, scene: &Scene, _light: &str, blocker: Option<u32>, nearest: Option<(f32, &Surface)>) {
        let Some(&(ray, t_max)) = self.rays.get(id as usize) else {
            return;
        };
        if self.found || !t_max.is_finite() {
            return;
        }
        let r = TIE * size(ray.at(t_max));
        self.found = match (blocker, nearest) {
            // The nearest blocker lies within rounding of the light: all of them do.
            (Some(_), Some((t, _))) => t_max - t <= r,
            (None, _) => scene.intersect(&ray, t_max, t_max + r).is_some(),
            (Some(_), None) => false,
        };
    }
}

/// The tie bounds of pixel (`x`, `y`) under `integ`, whose output carries the mistakes `m`;
/// `offsets` are `integ` with the secondary-ray offsets of [`OFFSETS`].
fn pixel_bounds<I: Intersect>(
    integ: &Integrator<'_, I>,
    offsets: &[Integrator<'_, I>],
    m: Mistakes,
    nudges: &[[f32; 2]; 4],
    x: u32,
    y: u32,
) -> [[u8; 3]; 2] {
    let spp = integ.samples_per_pixel();
    let inv = 1.0 / spp as f32;
    let mut c = Counters::default();
    let finite = |v: Vec3A| if v.is_finite() { v } else { Vec3A::ZERO };
    let (mut lo, mut hi) = (Vec3A::ZERO, Vec3A::ZERO);
    for s in 0..spp {
        let mut corners = Corners {
            rays: Vec::new(),
            hits: 0,
            found: false,
        };
        let v = finite(integ.sample(x, y, s, &mut corners, &mut c));
        let (mut a, mut b) = (v, v);
        for &n in nudges {
            let v = finite(integ.sample_nudged(x, y, s, n, &mut NoObserver, &mut c));
            a = a.min(v);
            b = b.max(v);
        }
        for o in offsets {
            let v = finite(o.sample(x, y, s, &mut NoObserver, &mut c));
            a = a.min(v);
            b = b.max(v);
        }
        if corners.found {
            a = Vec3A::ZERO;
        }
        lo += a;
        hi += b;
    }
    let bytes = |v: Vec3A, k: f32| {
        let v = m.output(Vec3::from(v * inv * k));
        [to_byte(v.x), to_byte(v.y), to_byte(v.z)]
    };
    [bytes(lo, 1.0 - TIE), bytes(hi, 1.0 + TIE)]
}

/// The four moves of a camera ray by [`TIE`] along the image's axes, in normalised image
/// coordinates.
fn nudges<I: Intersect>(integ: &Integrator<'_, I>) -> [[f32; 2]; 4] {
    let half = integ.camera.half;
    let (du, dv) = (TIE / (2.0 * half.x), TIE / (2.0 * half.y));
    [[du, 0.0], [-du, 0.0], [0.0, dv], [0.0, -dv]]
}

/// The tie bounds of `pixels` (row-major indices, of an image `w` wide) under the integrators
/// `make` builds, whose output carries the mistakes `m`.
fn bounds_with<'a, I: Intersect + 'a>(
    make: impl Fn() -> Integrator<'a, I>,
    m: Mistakes,
    w: u32,
    pixels: &[u32],
) -> Vec<[[u8; 3]; 2]> {
    // Every glass branch traced, as a correct tracer does: rayscope's renders leave out
    // branches that together bring less than a level, so the bounds hold both.
    let make = || {
        let mut integ = make();
        integ.branch_cutoff = 0.0;
        integ
    };
    let integ = make();
    let n = nudges(&integ);
    let offsets = OFFSETS.map(|r| make().with_offset_rule(r));
    pixels
        .par_iter()
        .map(|&i| pixel_bounds(&integ, &offsets, m, &n, i % w, i / w))
        .collect()
}

/// The tie bounds of `pixels` (row-major indices) under `settings`.
fn bounds(scene: &Scene, settings: &RenderSettings, pixels: &[u32]) -> Vec<[[u8; 3]; 2]> {
    let m = settings.mistakes;
    let w = settings.width.max(1);
    if m.is_empty() {
        bounds_with(|| Integrator::new(scene, settings), m, w, pixels)
    } else {
        let wrapped = Mistaken {
            inner: scene,
            scene,
            mistakes: m,
        };
        let s = settings.mistaken(m);
        bounds_with(|| Integrator::with_intersector(scene, &wrapped, &s), m, w, pixels)
    }
}

/// How far, in levels, the largest channel of `theirs` lies outside `[lo, hi]`.
fn outside(theirs: &[u8], [lo, hi]: [[u8; 3]; 2]) -> u8 {
    (0..3)
        .map(|c| lo[c].saturating_sub(theirs[c]).max(theirs[c].saturating_sub(hi[c])))
        .max()
        .unwrap_or(0)
}

/// Checks the image `theirs` against `ours`, the render of `scene` under `settings` (RGB8 of
/// the settings' size): the pixels whose colour is not the render's are checked against their
/// tie bounds, in batches spread over the image, stopping after the first batch with a pixel
/// beyond them unless `exhaustive`.
pub(crate) fn judge(scene: &Scene, settings: &RenderSettings, ours: &[u8], theirs: &[u8], exhaustive: bool) -> Verdict {
    let mut worst = 0u8;
    let differing: Vec<u32> = (ours.chunks_exact(3).zip(theirs.chunks_exact(3)).enumerate())
        .filter(|(_, (a, b))| a != b)
        .map(|(i, _)| i as u32)
        .collect();
    let mut v = Verdict {
        differing: differing.len() as u64,
        ..Verdict::default()
    };
    // Each sum of a pixel's samples is the render's only while each pixel is its own: the
    // never-reset accumulator's pixels hold all those before them, which no tie moves.
    let whole_film = settings.mistakes.has(Mistake::AccumulatorNotReset);
    let batches = differing.len().div_ceil(BATCH);
    for b in 0..batches {
        // Batch b: every `batches`-th differing pixel from the b-th, so each batch spreads over
        // the whole image.
        let pixels: Vec<u32> = differing.iter().copied().skip(b).step_by(batches).collect();
        let found = if whole_film {
            Vec::new()
        } else {
            bounds(scene, settings, &pixels)
        };
        for (k, &i) in pixels.iter().enumerate() {
            let p = i as usize * 3;
            let (o, t) = (&ours[p..p + 3], &theirs[p..p + 3]);
            let mut bound = [[0u8; 3]; 2];
            for c in 0..3 {
                let [lo, hi] = found.get(k).copied().unwrap_or([[o[0], o[1], o[2]]; 2]);
                bound[0][c] = lo[c].min(o[c]);
                bound[1][c] = hi[c].max(o[c]);
            }
            let out = outside(t, bound);
            worst = worst.max(out);
            v.checked += 1;
            if out > 0 {
                v.beyond.push(i);
            } else {
                v.ties += 1;
            }
        }
        if !v.beyond.is_empty() && !exhaustive {
            break;
        }
    }
    v.beyond.sort_unstable();
    v.worst = worst;
    v.matches = v.beyond.is_empty();
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn outside_measures_the_largest_channel_beyond_the_bounds() {
        let b = [[10, 20, 30], [40, 20, 35]];
        assert_eq!(outside(&[10, 20, 30], b), 0);
        assert_eq!(outside(&[41, 20, 30], b), 1);
        assert_eq!(outside(&[0, 20, 30], b), 10);
        assert_eq!(outside(&[20, 23, 30], b), 3);
    }
}
