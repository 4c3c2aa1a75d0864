//! The anti-aliasing sample grid, fitted to the student's pixels where rayscope's own colour
//! varies across the pixel (edges): per axis, samples at (k + c)/d of the pixel for
//! k = 0..N−1. The course's grid (`-x N`) is c = ½, d = N, the cell centres; the family holds
//! the course's grid at other N (the anti-aliasing level the edges show), the cells' corners
//! (c = 0: k/N, and with N = 1 one sample at the pixel's corner), samples spaced inside the
//! pixel (c = 1, d = N + 1: (k + 1)/(N + 1)), the course's grid moved by a fitted shift, and
//! samples at random, over the pixel or within each cell (stratified), whose pixels are the
//! pixel's mean colour plus noise of a known spread.
//!
//! Each fixed member is rendered at its own sample positions for a few hundred edge pixels and
//! fits when its residual, root mean square over their channels without the [`TRIM`] worst
//! pixels, is within [`FIT_RMS`] levels; the course's grid at the declared `-x` is the null
//! hypothesis: when it fits there is no finding, unless another member fits with at most
//! [`BETTER`] of its residual. Random samples fit when the pixels' distances from their mean
//! colour, over the spread the member gives them, are those of noise.

use std::collections::BTreeMap;

use glam::Vec3A;
use rayon::prelude::*;

use super::fitted::Fitted;
use crate::film::to_byte;
use crate::integrator::{Counters, Integrator};
use crate::observer::NoObserver;

/// Largest anti-aliasing level (samples per axis) the fit tries.
const MAX_LEVEL: u32 = 8;

/// Most pixels taken of each kind: pixels that differ from rayscope's render, and edge pixels
/// of rayscope's render that do not.
const POOL: usize = 150;

/// A pixel of rayscope's render is on an edge when the pixels around it span this many levels
/// in a channel.
const EDGE_LEVELS: u8 = 3;

/// A pixel differs from rayscope's render when a channel is this many levels off.
const DIFF_LEVELS: u8 = 2;

/// Largest share of the differing pixels whose colour no sample positions near them give:
/// above it, something other than the sample grid makes the picture differ, and its edges are
/// not read.
const MAX_BEYOND: f64 = 0.05;

/// A pixel tells the members apart when their colours for it span this many levels in a
/// channel.
const SENSITIVE: u8 = 2;

/// Share of the fitted pixels left out as the worst ones (those a tie may explain).
const TRIM: f64 = 0.02;

/// A fixed member fits when its residual is at most this many levels (root mean square).
const FIT_RMS: f64 = 0.6;

/// A member other than the course's grid, or the course's grid shifted, is the finding only
/// where its residual is below this share of the course's: the pixels that differ are few
/// beside the edges that do not, so the course's residual over them all may be small too, and a
/// picture whose bytes are made otherwise leaves a residual at every edge that no grid removes.
const BETTER: f64 = 0.5;

/// Largest shift of the course's grid fitted, in pixels per axis: a whole pixel, as a sample
/// taken at x − ½ where the course takes x + ½ puts it.
const MAX_SHIFT: f64 = 1.0;

/// Fewest pixels that tell the members apart for a reading.
const MIN_PIXELS: usize = 30;

/// Side of the fine grid of positions a pixel's mean colour and spread are taken from (a
/// multiple of the levels 1, 2, 3, 4, 6 and 8, whose cells it tiles).
const FINE: u32 = 24;

/// Random samples fit when the pixels' squared distances from their mean, over the member's
/// spread, average at most this (1 for noise of exactly that spread).
const NOISE_Z2: f64 = 2.0;

/// Random samples fit only when the drifts a fixed grid leaves explain at most this χ² of
/// the pixels' distances from their means (three degrees of freedom: one in a million for
/// noise).
const SYSTEMATIC: f64 = 30.0;

/// A pixel's noise under random samples is loud at this standard deviation (levels): at or
/// above it, one channel stays within [`DIFF_LEVELS`] of the mean about two times in five.
const LOUD: f64 = 4.0;

/// Fewest loud pixels that tell whether the noise is everywhere.
const MIN_LOUD: usize = 10;

/// Largest weighted share of the loud pixels that may be as rayscope renders them under
/// random samples.
const MAX_QUIET: f64 = 0.6;

/// Most pixels random samples are judged on.
const JITTER_PIXELS: usize = 200;

/// Most pixels the shift is searched over (the fit is then checked on all of them).
const SHIFT_PIXELS: usize = 120;

/// Where one axis's samples sit: (k + `c`)/`d` of the pixel, k = 0..`n`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Axis {
    c: f64,
    d: f64,
    n: u32,
}

impl Axis {
    /// The samples' positions, as offsets from the pixel's left or top edge.
    fn positions(self) -> Vec<f32> {
        (0..self.n).map(|k| ((f64::from(k) + self.c) / self.d) as f32).collect()
    }

    /// The positions for a sentence: "0, 0.25, 0.5, 0.75".
    fn said(self) -> String {
        let p: Vec<String> = (0..self.n).map(|k| number((f64::from(k) + self.c) / self.d)).collect();
        p.join(", ")
    }
}

/// A value to three decimals, without trailing zeros.
fn number(v: f64) -> String {
    let s = format!("{v:.3}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".into()
    } else {
        s.into()
    }
}

/// A fixed member of the family: the same grid on both axes except for the shift.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Member {
    /// The course's cell centres, (k + ½)/N.
    Course(u32),
    /// The cells' corners, k/N.
    Corner(u32),
    /// Spaced inside the pixel, (k + 1)/(N + 1).
    Interior(u32),
    /// The course's grid at N moved by (dx, dy) pixels.
    Shifted(u32, [f64; 2]),
    /// N samples on the pixel's diagonal, sample k at the course's k-th cell centre across and
    /// down alike: one loop counter used for both axes.
    Diagonal(u32),
}

impl Member {
    /// The grid's axes, x then y.
    fn axes(self) -> [Axis; 2] {
        let n = match self {
            Member::Course(n)
            | Member::Corner(n)
            | Member::Interior(n)
            | Member::Shifted(n, _)
            | Member::Diagonal(n) => n,
        };
        let nf = f64::from(n);
        match self {
            Member::Course(_) | Member::Diagonal(_) => [Axis { c: 0.5, d: nf, n }; 2],
            Member::Corner(_) => [Axis { c: 0.0, d: nf, n }; 2],
            Member::Interior(_) => [Axis { c: 1.0, d: nf + 1.0, n }; 2],
            Member::Shifted(_, s) => s.map(|s| Axis {
                c: 0.5 + s * nf,
                d: nf,
                n,
            }),
        }
    }

    /// Samples per axis.
    fn level(self) -> u32 {
        self.axes()[0].n
    }
}

/// What the student's edges say about their anti-aliasing.
#[derive(Debug, Clone, Default, PartialEq)]
pub(crate) struct Reading {
    /// Samples per axis the edges show, where they show it.
    pub(crate) level: Option<u32>,
    /// The finding (or, with [`Fitted::allowed`], what the edges show that is no mistake).
    pub(crate) fitted: Option<Fitted>,
}

/// A pixel the fit uses, with the student's colour.
struct Pixel {
    x: u32,
    y: u32,
    theirs: [u8; 3],
    /// The student's pixel differs from rayscope's.
    differs: bool,
    /// How many pixels of its kind (differing, or an edge that does not) it stands for.
    weight: f64,
}

/// rayscope's colour at offset (`ox`, `oy`) inside pixel (`x`, `y`), as the render's sample
/// there computes it.
fn colour_at<I: crate::scene::Intersect>(integ: &Integrator<'_, I>, x: u32, y: u32, o: [f32; 2]) -> Vec3A {
    let (w, h) = (integ.settings.width as f32, integ.settings.height as f32);
    let ray = integ.camera.ray((x as f32 + o[0]) / w, (y as f32 + o[1]) / h);
    let mut rng = integ.sample_rng(x, y, 0);
    integ.radiance(&ray, 0, &mut rng, &mut NoObserver, &mut Counters::default())
}

/// The bytes `m`'s samples give pixel `p`: their colours averaged, as the render averages.
fn predict<I: crate::scene::Intersect>(integ: &Integrator<'_, I>, p: &Pixel, m: Member) -> [u8; 3] {
    let [ax, ay] = m.axes();
    let (xs, ys) = (ax.positions(), ay.positions());
    let at: Vec<[f32; 2]> = if matches!(m, Member::Diagonal(_)) {
        xs.iter().zip(&ys).map(|(&x, &y)| [x, y]).collect()
    } else {
        ys.iter().flat_map(|&y| xs.iter().map(move |&x| [x, y])).collect()
    };
    let mut sum = Vec3A::ZERO;
    for &o in &at {
        let v = colour_at(integ, p.x, p.y, o);
        if v.is_finite() {
            sum += v;
        }
    }
    let v = sum * (1.0 / at.len() as f32);
    [to_byte(v.x), to_byte(v.y), to_byte(v.z)]
}

/// Up to `most` of `v`, evenly spread over it.
fn spread<T: Copy>(v: &[T], most: usize) -> Vec<T> {
    let stride = v.len().div_ceil(most.max(1)).max(1);
    v.iter().step_by(stride).copied().collect()
}

/// The pixels the fit looks at: up to [`POOL`] of those that differ from rayscope's render
/// `ours`, and as many of its edges that do not; and the share of the differing pixels whose
/// colour lies beyond what rayscope's colours around them span, which no sample positions near
/// the pixel give.
fn pool(ours: &[u8], theirs: &[u8], w: u32, h: u32) -> (Vec<Pixel>, f64) {
    let at = |i: u32, c: usize| ours[(i * 3) as usize + c];
    let (mut differing, mut edges, mut beyond) = (Vec::new(), Vec::new(), 0usize);
    for i in 0..w * h {
        let (x, y) = (i % w, i / w);
        let (mut lo, mut hi) = ([u8::MAX; 3], [0u8; 3]);
        for yy in y.saturating_sub(1)..=(y + 1).min(h - 1) {
            for xx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
                for c in 0..3 {
                    lo[c] = lo[c].min(at(yy * w + xx, c));
                    hi[c] = hi[c].max(at(yy * w + xx, c));
                }
            }
        }
        let p = (i * 3) as usize;
        if (0..3).any(|c| ours[p + c].abs_diff(theirs[p + c]) >= DIFF_LEVELS) {
            differing.push(i);
            let t = &theirs[p..p + 3];
            if (0..3).any(|c| t[c].saturating_add(DIFF_LEVELS) < lo[c] || t[c] > hi[c].saturating_add(DIFF_LEVELS)) {
                beyond += 1;
            }
        } else if (0..3).any(|c| hi[c] - lo[c] >= EDGE_LEVELS) {
            edges.push(i);
        }
    }
    let share = beyond as f64 / differing.len().max(1) as f64;
    let kinds = [
        (spread(&differing, POOL), differing.len(), true),
        (spread(&edges, POOL), edges.len(), false),
    ];
    let pixels = kinds
        .into_iter()
        .flat_map(|(some, all, differs)| {
            let weight = all as f64 / some.len().max(1) as f64;
            some.into_iter().map(move |i| {
                let p = (i * 3) as usize;
                Pixel {
                    x: i % w,
                    y: i / w,
                    theirs: [theirs[p], theirs[p + 1], theirs[p + 2]],
                    differs,
                    weight,
                }
            })
        })
        .collect();
    (pixels, share)
}

/// Root mean square residual, in levels, of `pred` against the pixels' colours, each pixel
/// weighted by what it stands for, without the [`TRIM`] worst pixels' share of the weight.
fn rms(pixels: &[&Pixel], pred: &[[u8; 3]]) -> f64 {
    let mut se: Vec<(f64, f64)> = pixels
        .iter()
        .zip(pred)
        .map(|(p, q)| {
            let e = (0..3).map(|c| f64::from(p.theirs[c].abs_diff(q[c])).powi(2)).sum();
            (e, p.weight)
        })
        .collect();
    se.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = se.iter().map(|e| e.1).sum();
    let (mut sum, mut kept) = (0.0, 0.0);
    for (e, w) in se {
        if kept + w > total * (1.0 - TRIM) && kept > 0.0 {
            break;
        }
        sum += e * w;
        kept += w;
    }
    (sum / (3.0 * kept).max(f64::MIN_POSITIVE)).sqrt()
}

/// The fixed members tried before any shift is fitted, simplest first.
fn fixed_members() -> Vec<Member> {
    let levels = 1..=MAX_LEVEL;
    let course = levels.clone().map(Member::Course);
    let corner = levels.clone().map(Member::Corner);
    // One interior sample is the course's one sample at the pixel's centre.
    let interior = levels.clone().filter(|&n| n > 1).map(Member::Interior);
    let diagonal = levels.filter(|&n| n > 1).map(Member::Diagonal);
    course.chain(corner).chain(interior).chain(diagonal).collect()
}

/// Reads the student's anti-aliasing from `theirs` (RGB8 of the settings' size) against
/// rayscope's render `ours` under `integ`'s settings, whose grid is `declared`×`declared` for
/// the command line's `-x asked` (one sample at stage 1, whatever `-x` says).
pub(crate) fn read<I: crate::scene::Intersect + Sync>(
    integ: &Integrator<'_, I>,
    ours: &[u8],
    theirs: &[u8],
    declared: u32,
    asked: u32,
) -> Reading {
    let (w, h) = (integ.settings.width, integ.settings.height);
    let (pool, beyond) = pool(ours, theirs, w, h);
    if pool.is_empty() || beyond > MAX_BEYOND {
        return Reading::default();
    }
    let members = fixed_members();
    let preds: Vec<Vec<[u8; 3]>> = pool
        .par_iter()
        .map(|p| members.iter().map(|&m| predict(integ, p, m)).collect())
        .collect();
    let telling: Vec<bool> = preds
        .iter()
        .map(|ps| {
            (0..3).any(|c| {
                let (lo, hi) = ps.iter().fold((u8::MAX, 0u8), |(l, h), q| (l.min(q[c]), h.max(q[c])));
                hi - lo >= SENSITIVE
            })
        })
        .collect();
    // The pixels that tell the members apart, and those that differ whatever the members
    // tell: a member fits only where it explains them too.
    let kept: Vec<bool> = pool.iter().zip(&telling).map(|(p, &t)| t || p.differs).collect();
    let pixels: Vec<&Pixel> = pool.iter().zip(&kept).filter(|(_, &k)| k).map(|(p, _)| p).collect();
    if telling.iter().filter(|&&t| t).count() < MIN_PIXELS {
        return Reading::default();
    }
    let column = |k: usize| -> Vec<[u8; 3]> {
        preds
            .iter()
            .zip(&kept)
            .filter(|(_, &t)| t)
            .map(|(ps, _)| ps[k])
            .collect()
    };
    let fits: Vec<(Member, f64)> = members
        .iter()
        .enumerate()
        .map(|(k, &m)| (m, rms(&pixels, &column(k))))
        .collect();
    let course_rms = fits.iter().find(|(m, _)| *m == Member::Course(declared)).map_or_else(
        || rms(&pixels, &predict_all(integ, &pixels, Member::Course(declared))),
        |f| f.1,
    );
    let facts = Facts {
        pixels: pixels.len(),
        declared,
        asked,
        stage1: integ.settings.stage == crate::settings::Stage::One,
        course_rms,
    };
    let null = Reading {
        level: Some(declared),
        fitted: None,
    };
    let best = fits
        .iter()
        .copied()
        .filter(|f| f.1 <= FIT_RMS)
        .min_by(|a, b| a.1.total_cmp(&b.1));
    match best {
        // Strictly better, whatever the course's grid leaves: where it fits exactly nothing
        // fits better, and a picture off by a level everywhere (its bytes made otherwise)
        // leaves a residual at the edges that no grid takes away.
        Some((m, r)) if m != Member::Course(declared) && r < BETTER * course_rms => {
            return Reading {
                level: Some(m.level()),
                fitted: Some(finding(m, r, &facts)),
            };
        }
        _ if course_rms <= FIT_RMS => return null,
        _ => {}
    }
    // The course's grid moved: at the declared level, and at the level whose course grid
    // comes closest.
    let nearest = fits
        .iter()
        .filter(|(m, _)| matches!(m, Member::Course(_)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(declared, |f| f.0.level());
    let levels = if nearest == declared {
        vec![declared]
    } else {
        vec![declared, nearest]
    };
    let (m, r) = fit_shifts(integ, &pixels, &levels);
    if r <= FIT_RMS && r < BETTER * course_rms {
        return Reading {
            level: Some(m.level()),
            fitted: Some(finding(m, r, &facts)),
        };
    }
    read_jitter(integ, &pixels, &facts)
}

/// `m`'s bytes for each of `pixels`.
fn predict_all<I: crate::scene::Intersect + Sync>(
    integ: &Integrator<'_, I>,
    pixels: &[&Pixel],
    m: Member,
) -> Vec<[u8; 3]> {
    pixels.par_iter().map(|p| predict(integ, p, m)).collect()
}

/// What every finding's sentence and figures need.
#[derive(Clone, Copy)]
struct Facts {
    /// Pixels fitted.
    pixels: usize,
    /// Samples per axis of rayscope's render.
    declared: u32,
    /// The command line's `-x` (`declared` but at stage 1).
    asked: u32,
    /// The render is stage 1, which takes one sample a pixel whatever `-x` says.
    stage1: bool,
    /// Residual of the course's grid at `declared`, in levels.
    course_rms: f64,
}

/// The course's grid at level `n` moved by the shift that fits `pixels` best, searched from
/// `from` axis by axis in the steps of `schedule` (step, steps each way), and its residual.
fn fit_shift<I: crate::scene::Intersect + Sync>(
    integ: &Integrator<'_, I>,
    pixels: &[&Pixel],
    n: u32,
    from: [f64; 2],
    schedule: &[(f64, i32)],
) -> ([f64; 2], f64) {
    let cost = |s: [f64; 2]| rms(pixels, &predict_all(integ, pixels, Member::Shifted(n, s)));
    let mut s = from;
    let mut now = cost(s);
    for &(step, reach) in schedule {
        for axis in 0..2 {
            let centre = s[axis];
            for k in -reach..=reach {
                let mut t = s;
                t[axis] = centre + f64::from(k) * step;
                if k == 0 || t[axis].abs() > MAX_SHIFT {
                    continue;
                }
                let c = cost(t);
                if c < now {
                    (s, now) = (t, c);
                }
            }
        }
    }
    (s, now)
}

/// The course's grid moved, at the one of `levels` and by the shift that fit `pixels` best:
/// each axis searched over half a pixel each way in eighths of a pixel, three times around
/// the best so far, then in thirty-seconds and sixty-fourths, and the best checked on all of
/// them.
fn fit_shifts<I: crate::scene::Intersect + Sync>(
    integ: &Integrator<'_, I>,
    pixels: &[&Pixel],
    levels: &[u32],
) -> (Member, f64) {
    let some = spread(pixels, SHIFT_PIXELS);
    let schedule = [(0.125, 4), (0.125, 4), (0.125, 4), (1.0 / 32.0, 2), (1.0 / 64.0, 1)];
    let (n, s, _) = levels
        .iter()
        .map(|&n| {
            let (s, r) = fit_shift(integ, &some, n, [0.0; 2], &schedule);
            (n, s, r)
        })
        .min_by(|a, b| a.2.total_cmp(&b.2))
        .unwrap_or((1, [0.0; 2], f64::INFINITY));
    let m = Member::Shifted(n, s);
    (m, rms(pixels, &predict_all(integ, pixels, m)))
}

/// The pixels' mean colour and its spread for random samples: per pixel and channel, in
/// levels, the mean over the [`FINE`] grid and the variance of a pixel's mean for each member.
struct Spread {
    mean: [f64; 3],
    /// Per level in [`JITTER_LEVELS`]: the variance over the pixel (samples anywhere) and the
    /// mean of the cells' variances over the cell count (one sample in each cell).
    var: Vec<([f64; 3], [f64; 3])>,
    /// What moving the samples changes, per channel: the right column's mean less the left's,
    /// the bottom row's less the top's, and the border's less the whole pixel's (samples spread
    /// wider or narrower). A fixed grid other than the course's leaves residuals along these;
    /// noise does not.
    drift: [[f64; 3]; 3],
}

/// Levels whose cells the [`FINE`] grid tiles.
const JITTER_LEVELS: [u32; 6] = [1, 2, 3, 4, 6, 8];

/// The spread of `p`'s colour over its area, from the [`FINE`] grid.
fn spread_of<I: crate::scene::Intersect>(integ: &Integrator<'_, I>, p: &Pixel) -> Spread {
    let f = FINE as usize;
    let mut v = vec![[0.0f64; 3]; f * f];
    for j in 0..f {
        for i in 0..f {
            let o = [(i as f32 + 0.5) / FINE as f32, (j as f32 + 0.5) / FINE as f32];
            let c = colour_at(integ, p.x, p.y, o);
            v[j * f + i] = [0, 1, 2].map(|k| 255.0 * f64::from(c[k]));
        }
    }
    let var_of = |cells: &[[f64; 3]]| -> [f64; 3] {
        let n = cells.len() as f64;
        [0, 1, 2].map(|k| {
            let m = cells.iter().map(|c| c[k]).sum::<f64>() / n;
            cells.iter().map(|c| (c[k] - m).powi(2)).sum::<f64>() / n
        })
    };
    let mean = [0, 1, 2].map(|k| v.iter().map(|c| c[k]).sum::<f64>() / (f * f) as f64);
    let var = JITTER_LEVELS
        .iter()
        .map(|&n| {
            let side = f / n as usize;
            let nn = f64::from(n * n);
            let pixel = var_of(&v).map(|x| x / nn);
            let mut cells = [0.0; 3];
            for cj in 0..n as usize {
                for ci in 0..n as usize {
                    let cell: Vec<[f64; 3]> = (0..side * side)
                        .map(|k| v[(cj * side + k / side) * f + ci * side + k % side])
                        .collect();
                    let cv = var_of(&cell);
                    for k in 0..3 {
                        cells[k] += cv[k] / (nn * nn);
                    }
                }
            }
            (pixel, cells)
        })
        .collect();
    let line = |at: &dyn Fn(usize) -> usize| -> [f64; 3] {
        [0, 1, 2].map(|k| (0..f).map(|t| v[at(t)][k]).sum::<f64>() / f as f64)
    };
    let (left, right) = (line(&|t| t * f), line(&|t| t * f + f - 1));
    let (top, bottom) = (line(&|t| t), line(&|t| (f - 1) * f + t));
    let drift = [
        [0, 1, 2].map(|k| right[k] - left[k]),
        [0, 1, 2].map(|k| bottom[k] - top[k]),
        [0, 1, 2].map(|k| (left[k] + right[k] + top[k] + bottom[k]) / 4.0 - mean[k]),
    ];
    Spread { mean, var, drift }
}

/// One channel of a pixel under random samples: the student's distance from the mean colour
/// (levels), what the pixel stands for, and the drifts a fixed grid would leave.
struct Channel {
    r: f64,
    weight: f64,
    drift: [f64; 3],
    /// Per level in [`JITTER_LEVELS`], the variance over the pixel and within the cells, with
    /// the byte's rounding.
    var: Vec<[f64; 2]>,
}

/// The channels random samples are judged on: those of `pixels` not clipped.
fn channels(pixels: &[&Pixel], spreads: &[Spread]) -> Vec<Channel> {
    let mean_weight = pixels.iter().map(|p| p.weight).sum::<f64>() / pixels.len().max(1) as f64;
    let mut out = Vec::new();
    for (p, s) in pixels.iter().zip(spreads) {
        for c in 0..3 {
            if matches!(p.theirs[c], 0 | 255) || s.mean[c] >= 255.0 {
                continue;
            }
            out.push(Channel {
                // The byte truncates: its middle is half a level up; its rounding adds 1/12.
                r: f64::from(p.theirs[c]) + 0.5 - s.mean[c],
                weight: p.weight / mean_weight,
                drift: s.drift.map(|d| d[c]),
                var: s.var.iter().map(|v| [v.0[c], v.1[c]].map(|x| x + 1.0 / 12.0)).collect(),
            });
        }
    }
    out
}

/// How much of the channels' distances from their means the drifts explain, in units of the
/// noise (χ² of the weighted least-squares fit of the distances to the drifts): small for
/// noise, large for a fixed grid that is not the course's.
fn systematic(ch: &[Channel], l: usize, k: usize) -> f64 {
    let mut a = [[0.0f64; 3]; 3];
    let mut b = [0.0f64; 3];
    for c in ch {
        let w = c.weight / c.var[l][k];
        for ((ai, bi), &di) in a.iter_mut().zip(&mut b).zip(&c.drift) {
            *bi += w * di * c.r;
            for (aij, &dj) in ai.iter_mut().zip(&c.drift) {
                *aij += w * di * dj;
            }
        }
    }
    // Solves a x = b by elimination (a is symmetric and positive semi-definite).
    let mut m = a;
    let mut x = b;
    for col in 0..3 {
        let piv = m[col][col];
        if piv.abs() < 1e-9 {
            continue;
        }
        let (pivot_row, pivot_x) = (m[col], x[col]);
        for row in (0..3).filter(|&r| r != col) {
            let f = m[row][col] / piv;
            for (mrj, &mcj) in m[row].iter_mut().zip(&pivot_row) {
                *mrj -= f * mcj;
            }
            x[row] -= f * pivot_x;
        }
    }
    (0..3)
        .filter(|&i| m[i][i].abs() >= 1e-9)
        .map(|i| b[i] * x[i] / m[i][i])
        .sum()
}

/// Random samples: the member whose spread makes the pixels likeliest, when the pixels are
/// noise of that spread about their mean colour and nothing along the drifts a fixed grid
/// leaves.
fn read_jitter<I: crate::scene::Intersect + Sync>(
    integ: &Integrator<'_, I>,
    pixels: &[&Pixel],
    facts: &Facts,
) -> Reading {
    let pixels = spread(pixels, JITTER_PIXELS);
    let pixels = &pixels[..];
    let spreads: Vec<Spread> = pixels.par_iter().map(|p| spread_of(integ, p)).collect();
    let ch = channels(pixels, &spreads);
    if ch.len() < MIN_PIXELS {
        return Reading::default();
    }
    let total: f64 = ch.iter().map(|c| c.weight).sum();
    // The likeliest member (level, stratified) with its log-likelihood and mean z².
    let mut best: Option<(usize, usize, f64, f64)> = None;
    for l in 0..JITTER_LEVELS.len() {
        for k in 0..2 {
            let (mut ll, mut z2) = (0.0, 0.0);
            for c in &ch {
                let v = c.var[l][k];
                let z = c.r * c.r / v;
                ll -= 0.5 * c.weight * (z + v.ln());
                z2 += c.weight * z;
            }
            if best.is_none_or(|b| ll > b.2) {
                best = Some((l, k, ll, z2 / total));
            }
        }
    }
    let Some((l, k, _, mean_z2)) = best else {
        return Reading::default();
    };
    let drift = systematic(&ch, l, k);
    if mean_z2 > NOISE_Z2 || drift > SYSTEMATIC || !noise_everywhere(pixels, &spreads, l, k) {
        return Reading::default();
    }
    let n = JITTER_LEVELS[l];
    // The noise's size tells one sample in each cell of the declared grid; otherwise samples
    // anywhere in the pixel and stratified ones of another level give noise too alike to name
    // a kind or a level, or to rule a level out.
    let cells = k == 1 && n == facts.declared;
    Reading {
        level: cells.then_some(n),
        fitted: Some(jitter_finding(
            n,
            cells,
            mean_z2,
            &Facts {
                pixels: pixels.len(),
                ..*facts
            },
        )),
    }
}

/// True when the pixels whose noise under level `l` and kind `k` would be large (a standard
/// deviation of [`LOUD`] levels or more) mostly differ from rayscope's render, as random
/// samples make them: noise is at every edge of the picture. A difference confined to some
/// edges (a glass's refraction bent otherwise, one object moved) leaves the others as they
/// are. Fewer than [`MIN_LOUD`] such pixels tell nothing, and pass.
fn noise_everywhere(pixels: &[&Pixel], spreads: &[Spread], l: usize, k: usize) -> bool {
    let (mut loud, mut quiet, mut count) = (0.0, 0.0, 0usize);
    for (p, s) in pixels.iter().zip(spreads) {
        let v = if k == 0 { s.var[l].0 } else { s.var[l].1 };
        if v.iter().all(|&v| v < LOUD * LOUD) {
            continue;
        }
        count += 1;
        loud += p.weight;
        if !p.differs {
            quiet += p.weight;
        }
    }
    count < MIN_LOUD || quiet <= MAX_QUIET * loud
}

/// The figures every finding carries.
fn figures(facts: &Facts) -> BTreeMap<&'static str, f64> {
    let mut numbers = BTreeMap::new();
    numbers.insert("pixels", facts.pixels as f64);
    numbers.insert("course_rms_levels", facts.course_rms);
    numbers.insert("declared_level", f64::from(facts.declared));
    numbers
}

/// The finding for random samples: one within each cell of the `n`×`n` grid when `cells`,
/// else anywhere in the pixel (`n` the level whose noise is likeliest).
fn jitter_finding(n: u32, cells: bool, mean_z2: f64, facts: &Facts) -> Fitted {
    let mut numbers = figures(facts);
    numbers.insert("level", f64::from(n));
    numbers.insert("noise_z2", mean_z2);
    let d = facts.declared;
    let text = if cells {
        format!(
            "your anti-aliasing samples are jittered at random within each cell of the pixel's {n}×{n} grid (read from {} edge pixels) — that is allowed: each pixel still averages its area, and its edges differ from rayscope's regular grid by noise only.",
            facts.pixels
        )
    } else {
        format!(
            "your samples are jittered at random within the pixel (read from {} edge pixels) — that is allowed: each pixel still averages its area, and its edges differ from rayscope's regular grid by noise only; one sample at random in each cell of a {d}×{d} grid keeps that noise smallest.",
            facts.pixels
        )
    };
    Fitted {
        code: if cells { "aa-jittered-cells" } else { "aa-jittered" },
        text: capitalised(&text),
        numbers,
        allowed: true,
    }
}

/// `s` with its first letter upper-case.
fn capitalised(s: &str) -> String {
    let mut c = s.chars();
    c.next()
        .map(|f| f.to_uppercase().chain(c).collect())
        .unwrap_or_default()
}

/// The finding for the fixed member `m` fitted with residual `rms`.
fn finding(m: Member, rms: f64, facts: &Facts) -> Fitted {
    let mut numbers = figures(facts);
    numbers.insert("rms_levels", rms);
    let [ax, ay] = m.axes();
    let n = ax.n;
    numbers.insert("level", f64::from(n));
    let d = facts.declared;
    let course = Member::Course(d).axes()[0];
    let theirs_at = format!("(from its corner: {})", ax.said());
    let ours_at = if d == 1 {
        "the course's one sample sits at the pixel's centre (0.5)".to_string()
    } else {
        format!("the course's sit at cell centres ({})", course.said())
    };
    let count = if n == d {
        String::new()
    } else {
        format!(", {n}×{n} a pixel where rayscope's render takes {d}×{d}")
    };
    let from = format!("fitted from {} edge pixels", facts.pixels);
    let (code, text) = match m {
        // Stage 1 anti-aliased with the command line's -x: a student who honours -x there.
        Member::Course(_) if facts.stage1 && n == facts.asked && n > 1 => {
            return Fitted {
                code: "aa-stage1",
                text: format!(
                    "Your stage-1 picture is anti-aliased on the -x {n} grid, {n}×{n} samples a pixel at the cells' centres ({from}) — that is allowed where -x is asked for at stage 1: the course's own stage-1 images take one ray through each pixel's centre whatever -x says, and so does rayscope's --stage 1."
                ),
                numbers,
                allowed: true,
            };
        }
        Member::Course(_) if facts.stage1 => (
            "aa-level",
            format!(
                "Your stage-1 picture has {n}×{n} samples a pixel where -x {a} asks for {a}×{a} ({from}); the course's own stage-1 images take one ray through each pixel's centre whatever -x says.",
                a = facts.asked
            ),
        ),
        Member::Course(_) => (
            "aa-level",
            format!(
                "Your picture has {n}×{n} samples a pixel, not {d}×{d} ({from}): its edges are rayscope's render at -x {n}."
            ),
        ),
        Member::Corner(1) => (
            "aa-corner",
            format!("Your picture takes one sample a pixel, at the pixel's corner (0, 0) ({from}); {ours_at}."),
        ),
        Member::Corner(_) => (
            "aa-corner",
            format!("Your anti-aliasing samples sit at k/{n} of the pixel {theirs_at}{count} ({from}); {ours_at}."),
        ),
        Member::Interior(_) => (
            "aa-interior",
            format!(
                "Your anti-aliasing samples sit at k/{} of the pixel {theirs_at}, none on its edges{count} ({from}); {ours_at}.",
                n + 1
            ),
        ),
        Member::Diagonal(_) => (
            "aa-diagonal",
            format!(
                "Your anti-aliasing samples lie on the pixel's diagonal, at {n} places, the k-th at the k-th cell centre across and down alike ({}), where the course's {d}×{d} cover the whole pixel ({from}): one loop counter used for both axes does this.",
                ax.said()
            ),
        ),
        Member::Shifted(_, s) => {
            numbers.insert("shift_x", s[0]);
            numbers.insert("shift_y", s[1]);
            let way = |v: f64, plus: &str, minus: &str| {
                format!("{} px {}", number(v.abs()), if v < 0.0 { minus } else { plus })
            };
            (
                "aa-shifted",
                format!(
                    "Your anti-aliasing samples sit {} and {} of the course's (from the pixel's corner: {} across, {} down){count} ({from}); {ours_at}.",
                    way(s[0], "right", "left"),
                    way(s[1], "down", "up"),
                    ax.said(),
                    ay.said()
                ),
            )
        }
    };
    numbers.insert("start_x", ax.c / ax.d);
    numbers.insert("step_x", 1.0 / ax.d);
    numbers.insert("start_y", ay.c / ay.d);
    numbers.insert("step_y", 1.0 / ay.d);
    Fitted {
        code,
        text,
        numbers,
        allowed: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn members_place_their_samples() {
        assert_eq!(
            Member::Course(4).axes()[0].positions(),
            vec![0.125, 0.375, 0.625, 0.875]
        );
        assert_eq!(Member::Corner(4).axes()[0].positions(), vec![0.0, 0.25, 0.5, 0.75]);
        assert_eq!(Member::Interior(4).axes()[1].positions(), vec![0.2, 0.4, 0.6, 0.8]);
        let s = Member::Shifted(4, [0.375, -0.125]).axes();
        assert_eq!(s[0].positions(), vec![0.5, 0.75, 1.0, 1.25]);
        assert_eq!(s[1].positions(), vec![0.0, 0.25, 0.5, 0.75]);
        assert_eq!(Member::Corner(4).axes()[0].said(), "0, 0.25, 0.5, 0.75");
        // The course's positions are those of the render's grid, bit for bit.
        for n in 1..=MAX_LEVEL {
            let p = Member::Course(n).axes()[0].positions();
            for (k, v) in p.iter().enumerate() {
                assert_eq!(*v, crate::camera::cell_centre(k as u32, n)[0]);
            }
        }
    }

    #[test]
    fn spread_keeps_at_most_the_asked_share_evenly() {
        let v: Vec<u32> = (0..10).collect();
        assert_eq!(spread(&v, 4), vec![0, 3, 6, 9]);
        assert_eq!(spread(&v, 20), v);
    }
}
