//! Shadow acne recognised by what it looks like, not by where rayscope's own rounding would put
//! it: pixels of lit surfaces that lose exactly some of the point lights' light (all of one
//! light's share, or with anti-aliasing a part of it), in scattered specks or thin stripes where
//! rayscope's render is smooth. A tracer whose shadow rays hit the surface they start from does
//! that wherever its own arithmetic rounds the start point below the surface, which is why a
//! render of the mistake with rayscope's arithmetic cannot stand in for it pixel for pixel.
//!
//! Each differing pixel's colour is fitted as rayscope's colour less a share in [0, 1] of each
//! light's part of it (rayscope's render with that light removed gives the part): a pixel the
//! fit reproduces to within rounding, and which lost at least a few levels, lost light. The
//! picture is recognised as acne only when such pixels on surfaces seen directly are many,
//! split into many small pieces (a wrong shadow is a few large areas), and mostly on diffuse
//! surfaces seen directly (black specks on a mirror are the mirror's own rays, not shadows).

use std::collections::BTreeMap;

use rayscope_scene::SceneFile;
use serde::Serialize;

use super::explained::Traced;
use crate::mistakes::Mistake;
use crate::settings::{RenderSettings, Stage};

/// Most lights tried one by one; a scene with more is not judged.
const MAX_LIGHTS: usize = 8;
/// Largest distance (levels, root mean square over the channels) between a pixel and its fit
/// for the fit to explain it: byte rounding of both images and of each light's part.
const FIT_LEVELS: f32 = 2.5;
/// Least light a pixel must have lost (levels, in its brightest-changed channel) to count.
const LOST_LEVELS: f32 = 3.0;
/// Largest step (levels, any channel) from a pixel to a neighbour in rayscope's render for the
/// render to be smooth there.
const SMOOTH_LEVELS: u8 = 6;
/// Fewest lit-surface pixels that lost light, and fewest separate pieces they form, for a
/// finding: fewer is not a pattern.
const MIN_PIXELS: usize = 30;
const MIN_PIECES: usize = 12;
/// Largest mean size of a piece (pixels): specks and thin stripes, not areas.
const MAX_PIECE: f64 = 16.0;
/// Largest share of the pixels that lost light with all four neighbours lost too.
const MAX_INTERIOR: f64 = 0.4;
/// Least mean step (in shares of a light) between a pixel's lost share and its neighbours' for
/// the loss to be uneven: a wrong shadow, a missing light or a fall-off changes it smoothly.
const MIN_ROUGHNESS: f64 = 0.15;
/// Most differing pixels that gain light per pixel that loses it.
const MAX_GAINED: f64 = 0.5;
/// Least mean share of the lights' light that the specks lose: acne takes a light's whole share
/// from the samples that hit their own surface, while a slight change of shading everywhere (a
/// light's direction taken from a point a little off the hit) crosses byte boundaries in the
/// same scattered pattern, a few levels at a time.
const MIN_MEAN_SHARE: f64 = 0.2;

/// A mistake recognised from how the picture looks.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Recognised {
    /// What was recognised: `shadow-acne`, `entities-missing` (rayscope's render without
    /// some entities reproduces the picture), `entities-black` (rayscope's render with some
    /// entities painted black does) or `glass-reflection-lost` (its render with every glass's
    /// reflection lost does).
    pub code: &'static str,
    /// The catalogue's name for it; empty where the catalogue has none (the findings but acne
    /// say what the picture shows, which many mistakes can cause).
    pub mistake: &'static str,
    /// One sentence for the student: what the picture shows, what the code does, the fix.
    pub text: String,
    /// For acne the diffuse entities seen directly it was seen on, most pixels first; for
    /// missing or black entities those the picture lacks or turns black.
    pub entities: Vec<String>,
    /// Differing pixels it explains.
    pub pixels: u64,
    /// Its share of the differing pixels (0–1).
    pub share: f64,
    /// The figures behind it: pixels on surfaces seen directly, pieces, mean piece size,
    /// interior share, the mean share of the lights' light lost.
    pub numbers: BTreeMap<&'static str, f64>,
}

/// Renders pixels of the scene under `base` with one light removed: light `k`, the pixels, RGB8.
pub(crate) type WithoutLight<'a> = &'a (dyn Fn(usize, &[(u32, u32)]) -> Vec<u8> + Sync);

/// Shadow acne in `theirs`, if the picture shows it: `ours` is rayscope's render under `base`
/// (RGB8, `base`'s size), `differing` the pixels where they differ and `traced` their parts;
/// `without` renders pixels with a light removed.
pub(crate) fn recognise(
    file: &SceneFile,
    without: WithoutLight<'_>,
    base: &RenderSettings,
    ours: &[u8],
    theirs: &[u8],
    differing: &[u32],
    traced: &Traced,
) -> Option<Recognised> {
    let lights = file.lights.len();
    if base.stage != Stage::Two || lights == 0 || lights > MAX_LIGHTS || differing.len() < MIN_PIXELS {
        return None;
    }
    let w = base.width;
    let pixels: Vec<(u32, u32)> = differing.iter().map(|&i| (i % w, i / w)).collect();
    // Each light's part of each differing pixel: rayscope's colour less the colour without it.
    let parts: Vec<Vec<u8>> = (0..lights).map(|k| without(k, &pixels)).collect();
    let mut lost = vec![false; ours.len() / 3];
    // The share of the lights' light each pixel lost (the sum of its shares): 0 where the pixel
    // is rayscope's colour, NaN where the fit does not explain it.
    let mut share = vec![0.0f32; ours.len() / 3];
    let mut lights_lost = vec![0.0f64; lights];
    for (j, &i) in differing.iter().enumerate() {
        let p = i as usize * 3;
        let c = rgb(&ours[p..p + 3]);
        let s = rgb(&theirs[p..p + 3]);
        let d: Vec<[f32; 3]> = parts
            .iter()
            .map(|without| {
                let o = rgb(&without[j * 3..j * 3 + 3]);
                [c[0] - o[0], c[1] - o[1], c[2] - o[2]]
            })
            .collect();
        let a = shares_lost(c, s, &d);
        let mut fit = c;
        for (dk, ak) in d.iter().zip(&a) {
            for ch in 0..3 {
                fit[ch] -= ak * dk[ch];
            }
        }
        let rms = ((0..3).map(|ch| (fit[ch] - s[ch]).powi(2)).sum::<f32>() / 3.0).sqrt();
        let loss = (0..3).map(|ch| c[ch] - fit[ch]).fold(0.0f32, f32::max);
        if rms <= FIT_LEVELS && loss >= LOST_LEVELS {
            lost[i as usize] = true;
            share[i as usize] = a.iter().sum();
            for (k, ak) in a.iter().enumerate() {
                lights_lost[k] += f64::from(*ak);
            }
        } else {
            share[i as usize] = f32::NAN;
        }
    }
    // Only pixels where rayscope's render is smooth tell a speck from an edge.
    let h = base.height;
    let speck: Vec<u32> = differing
        .iter()
        .copied()
        .filter(|&i| lost[i as usize] && smooth(ours, w, h, i))
        .collect();
    // Acne only takes light away: where many pixels gain light beside those that lose it, the
    // shading or the shadows moved (an object placed or shaped otherwise), which loses light in
    // some pixels and adds it in others.
    let gained = differing
        .iter()
        .filter(|&&i| {
            let p = i as usize * 3;
            (0..3).any(|c| f32::from(theirs[p + c]) >= f32::from(ours[p + c]) + LOST_LEVELS)
                && (0..3).all(|c| theirs[p + c] >= ours[p + c])
        })
        .count();
    let losing = lost.iter().filter(|&&l| l).count();
    if gained as f64 > MAX_GAINED * losing as f64 {
        return None;
    }
    let direct = direct_diffuse_share(traced, &lost);
    let (pieces, interior) = pieces(&speck, &lost, w, h);
    let mean = speck.len() as f64 / pieces.max(1) as f64;
    let specks = pieces >= MIN_PIECES && mean <= MAX_PIECE && interior <= MAX_INTERIOR;
    // With anti-aliasing the specks are smaller than a pixel: each pixel loses the share of its
    // samples that hit their own surface, which changes from pixel to pixel.
    let uneven = roughness(&speck, &share, w, h);
    let mean_share = speck.iter().map(|&i| f64::from(share[i as usize])).sum::<f64>() / speck.len().max(1) as f64;
    if speck.len() < MIN_PIXELS || direct < 0.5 || !(specks || uneven >= MIN_ROUGHNESS) || mean_share < MIN_MEAN_SHARE {
        return None;
    }
    let explained = lost.iter().filter(|&&l| l).count() as u64;
    let (entities, elsewhere) = entities(traced, &lost);
    let names: Vec<String> = file
        .lights
        .iter()
        .zip(&lights_lost)
        .filter(|(_, &n)| n > 0.2 * lights_lost.iter().copied().fold(0.0, f64::max))
        .map(|(l, _)| l.name.clone())
        .collect();
    let also = if elsewhere {
        ", and where they are seen in mirrors and through glass"
    } else {
        ""
    };
    let how = if specks {
        "the light of {} in scattered specks"
    } else {
        "a share of the light of {} that changes unevenly from pixel to pixel (specks smaller than a pixel, averaged by your anti-aliasing)"
    };
    let text = format!(
        "shadow acne ('{}'): {explained} pixels lose {} where rayscope's picture is smooth, on {}{also}. Your shadow rays hit the surface they start from: start each one a little off the surface, on the light's side (the hit point plus about 1e-4 times the normal turned towards the light), or ignore blockers nearer than that.",
        Mistake::NoShadowOffset.name(),
        how.replace("{}", &list(&names, 3)),
        list(&entities, 4),
    );
    let numbers = BTreeMap::from([
        ("direct_pixels", speck.len() as f64),
        ("pieces", pieces as f64),
        ("mean_piece", mean),
        ("interior_share", interior),
        ("direct_diffuse_share", direct),
        ("roughness", uneven),
        ("mean_share", mean_share),
    ]);
    Some(Recognised {
        code: "shadow-acne",
        mistake: Mistake::NoShadowOffset.name(),
        text,
        entities,
        pixels: explained,
        share: explained as f64 / differing.len() as f64,
        numbers,
    })
}

fn rgb(b: &[u8]) -> [f32; 3] {
    [f32::from(b[0]), f32::from(b[1]), f32::from(b[2])]
}

/// The share in [0, 1] of each light's part `d[k]` that best turns colour `c` into `s`
/// (least squares under the bounds, by coordinate descent: the problem is convex and small).
fn shares_lost(c: [f32; 3], s: [f32; 3], d: &[[f32; 3]]) -> Vec<f32> {
    let mut a = vec![0.0f32; d.len()];
    let dot = |x: [f32; 3], y: [f32; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    for _ in 0..24 {
        for k in 0..d.len() {
            let norm = dot(d[k], d[k]);
            if norm < 1.0 {
                a[k] = 0.0;
                continue;
            }
            // What the other lights' shares leave of c − s for this one to explain.
            let mut r = [c[0] - s[0], c[1] - s[1], c[2] - s[2]];
            for (j, dj) in d.iter().enumerate() {
                if j != k {
                    for ch in 0..3 {
                        r[ch] -= a[j] * dj[ch];
                    }
                }
            }
            a[k] = (dot(r, d[k]) / norm).clamp(0.0, 1.0);
        }
    }
    a
}

/// True when rayscope's render steps by at most [`SMOOTH_LEVELS`] from pixel `i` to each of its
/// eight neighbours.
fn smooth(ours: &[u8], w: u32, h: u32, i: u32) -> bool {
    let (x, y) = (i % w, i / w);
    let p = i as usize * 3;
    for ny in y.saturating_sub(1)..=(y + 1).min(h - 1) {
        for nx in x.saturating_sub(1)..=(x + 1).min(w - 1) {
            let q = (ny * w + nx) as usize * 3;
            if (0..3).any(|c| ours[p + c].abs_diff(ours[q + c]) > SMOOTH_LEVELS) {
                return false;
            }
        }
    }
    true
}

/// The 4-connected pieces the pixels `px` form, and the share of them whose four neighbours all
/// lost light (`lost`) too.
fn pieces(px: &[u32], lost: &[bool], w: u32, h: u32) -> (usize, f64) {
    let mut member = vec![false; lost.len()];
    for &i in px {
        member[i as usize] = true;
    }
    let neighbours = |i: u32| {
        let (x, y) = (i % w, i / w);
        [
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h).then(|| i + w),
        ]
    };
    let interior = px
        .iter()
        .filter(|&&i| neighbours(i).iter().all(|n| n.is_some_and(|n| lost[n as usize])))
        .count();
    let mut seen = vec![false; lost.len()];
    let mut count = 0;
    let mut stack = Vec::new();
    for &start in px {
        if seen[start as usize] {
            continue;
        }
        count += 1;
        seen[start as usize] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            for n in neighbours(i).into_iter().flatten() {
                if member[n as usize] && !seen[n as usize] {
                    seen[n as usize] = true;
                    stack.push(n);
                }
            }
        }
    }
    (count, interior as f64 / px.len().max(1) as f64)
}

/// The mean distance between the lost share of each pixel of `px` and the mean of its four
/// neighbours' (those the fit explains).
fn roughness(px: &[u32], share: &[f32], w: u32, h: u32) -> f64 {
    let mut sum = 0.0f64;
    let mut n = 0u64;
    for &i in px {
        let (x, y) = (i % w, i / w);
        let around = [
            (x > 0).then(|| i - 1),
            (x + 1 < w).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h).then(|| i + w),
        ];
        let known: Vec<f32> = around
            .into_iter()
            .flatten()
            .map(|j| share[j as usize])
            .filter(|v| !v.is_nan())
            .collect();
        if !known.is_empty() {
            let mean = known.iter().sum::<f32>() / known.len() as f32;
            sum += f64::from((share[i as usize] - mean).abs());
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// Among the traced pixels that lost light, the share on a diffuse surface seen directly.
fn direct_diffuse_share(traced: &Traced, lost: &[bool]) -> f64 {
    let (mut direct, mut all) = (0u64, 0u64);
    for (&i, &k) in traced.pixels.iter().zip(&traced.part_of) {
        if lost[i as usize] {
            all += 1;
            let p = &traced.parts[k];
            if p.seen_in.is_empty() && p.material == "Diffuse" {
                direct += 1;
            }
        }
    }
    direct as f64 / all.max(1) as f64
}

/// The diffuse entities seen directly at the traced pixels that lost light, most first, and
/// whether pixels seen in mirrors or through glass lost light too.
fn entities(traced: &Traced, lost: &[bool]) -> (Vec<String>, bool) {
    let mut count: BTreeMap<&str, u64> = BTreeMap::new();
    let mut elsewhere = false;
    for (&i, &k) in traced.pixels.iter().zip(&traced.part_of) {
        if lost[i as usize] {
            let p = &traced.parts[k];
            if p.seen_in.is_empty() && p.material == "Diffuse" {
                *count.entry(p.entity.as_str()).or_default() += 1;
            } else {
                elsewhere = true;
            }
        }
    }
    let mut v: Vec<(&str, u64)> = count.into_iter().collect();
    v.sort_by(|a, b| b.1.cmp(&a.1).then_with(|| a.0.cmp(b.0)));
    (v.into_iter().map(|(n, _)| n.to_string()).collect(), elsewhere)
}

/// The first `n` of `items`, joined as a sentence says them, with how many more there are.
pub(crate) fn list(items: &[String], n: usize) -> String {
    let shown: Vec<&str> = items.iter().take(n).map(String::as_str).collect();
    match (shown.as_slice(), items.len() > n) {
        ([], _) => String::new(),
        ([one], false) => (*one).to_string(),
        (_, true) => format!("{} and {} more", shown.join(", "), items.len() - n),
        (_, false) => format!("{} and {}", shown[..shown.len() - 1].join(", "), shown[shown.len() - 1]),
    }
}
