//! How much of a picture's difference a candidate explains, part by part, and what can be said
//! of the parts nothing explains: how they differ and which pixels to log next.
//!
//! A render that reproduces most of one entity's differing pixels without breaking pixels the
//! image had right is evidence for its mistake even while other mistakes remain; one that only
//! moves the overall PSNR is not. A candidate that is neither a match nor such a partial fit is
//! not offered at all: a wrong name sends a student to the wrong code.

use rayon::prelude::*;
use serde::Serialize;

use crate::observer::{RayKind, RayTree};
use crate::render::trace_pixel;
use crate::scene::Scene;
use crate::settings::RenderSettings;

/// Side of the blocks both images are averaged over for the downsampled comparison at full size.
pub(crate) const BLOCK: u32 = 4;

/// Most differing pixels whose ray trees are traced for the attribution.
const MAX_TRACED: usize = 20_000;

/// Averages an RGB8 grid of `w`×`h` over blocks of `k`×`k` (partial blocks at the edges), as f32.
pub(crate) fn block_means(rgb: &[u8], w: u32, h: u32, k: u32) -> Vec<f32> {
    let (bw, bh) = (w.div_ceil(k), h.div_ceil(k));
    let mut sum = vec![0.0f32; (bw * bh * 3) as usize];
    let mut count = vec![0u32; (bw * bh) as usize];
    for y in 0..h {
        for x in 0..w {
            let b = ((y / k) * bw + x / k) as usize;
            let p = ((y * w + x) * 3) as usize;
            for c in 0..3 {
                sum[b * 3 + c] += f32::from(rgb[p + c]);
            }
            count[b] += 1;
        }
    }
    for (b, n) in count.iter().enumerate() {
        for c in 0..3 {
            sum[b * 3 + c] /= *n as f32;
        }
    }
    sum
}

/// Per [`BLOCK`]×[`BLOCK`] block of `w`×`h`: whether the candidate is brighter than the image
/// at some of its pixels and darker at others (by `threshold` or more, channels summed). Speckle
/// that falls on other pixels in each tracer does that; a smooth difference (a light moved, a
/// fall-off) leaves the candidate on one side of the image across the block, and a block average
/// that comes near the image's there is a coincidence of brightness, not the same mistake.
fn speckled_blocks(candidate: &[u8], image: &[u8], (w, h): (u32, u32), threshold: u8) -> Vec<bool> {
    let bw = w.div_ceil(BLOCK);
    let mut sides = vec![(false, false); (bw * h.div_ceil(BLOCK)) as usize];
    for y in 0..h {
        for x in 0..w {
            let p = ((y * w + x) * 3) as usize;
            let d = &mut sides[((y / BLOCK) * bw + x / BLOCK) as usize];
            let signed: i32 = (0..3)
                .map(|c| i32::from(candidate[p + c]) - i32::from(image[p + c]))
                .sum();
            let apart = (0..3).any(|c| candidate[p + c].abs_diff(image[p + c]) >= threshold);
            d.0 |= apart && signed > 0;
            d.1 |= apart && signed < 0;
        }
    }
    sides.into_iter().map(|(brighter, darker)| brighter && darker).collect()
}

/// Flagged pixels of a `w`×`h` mask with three or more of their eight neighbours flagged.
fn areas(mask: &[bool], w: u32, h: u32) -> u64 {
    let (w, h) = (w as i64, h as i64);
    let at = |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h && mask[(y * w + x) as usize];
    let mut n = 0;
    for y in 0..h {
        for x in 0..w {
            if !at(x, y) {
                continue;
            }
            let near = (-1..=1)
                .flat_map(|dy| (-1..=1).map(move |dx| (dx, dy)))
                .filter(|&(dx, dy)| (dx, dy) != (0, 0) && at(x + dx, y + dy))
                .count();
            n += u64::from(near >= 3);
        }
    }
    n
}

/// Where a pixel's difference belongs: the first entity its camera ray's path meets that is not
/// a mirror, the mirrors it is seen in, and that entity's material kind (empty for the
/// background).
fn attribute(tree: &RayTree) -> (String, Vec<String>, String) {
    let mut seen_in = Vec::new();
    let Some(mut node) = tree.nodes.first() else {
        return ("(background)".into(), seen_in, String::new());
    };
    loop {
        let Some(h) = &node.hit else {
            return ("(background)".into(), seen_in, String::new());
        };
        if h.material_kind == "Reflective" {
            let child = tree
                .nodes
                .iter()
                .find(|c| c.parent == Some(node.id) && c.kind == RayKind::Reflection);
            if let Some(c) = child {
                seen_in.push(h.entity_name.clone());
                node = c;
                continue;
            }
        }
        return (h.entity_name.clone(), seen_in, h.material_kind.to_string());
    }
}

/// Share of a part's differing pixels a render must reproduce to explain that part.
pub(crate) const PART_PERCENT: f64 = 60.0;

/// Share of all differing pixels a render must reproduce to explain the picture in part.
const WHOLE_PERCENT: f64 = 50.0;

/// Most pixels a partial explanation may break (the image has them as rayscope renders them,
/// the explanation's render not, outside speckled blocks, whose speckle is judged on average)
/// per pixel it reproduces: room for another mistake that undoes this one here and there. A
/// render that changes much the image has right is another mistake that shares some pixels'
/// colours with the image's.
const BREAKS_PER_FIX: f64 = 0.5;

/// Most pixels in areas ([`Explained::broken_areas`]) a partial explanation may break per
/// pixel it reproduces: speckle breaks pixels one by one, a mistake that is not the image's
/// changes whole areas the image has right (a shadow removed, a surface recoloured).
const AREA_BREAKS_PER_FIX: f64 = 0.1;

/// A block average within this many levels of the image's is the image's there.
const BLOCK_LEVELS: f32 = 1.0;

/// Share of the differing pixels a render that is not the image pixel for pixel must reproduce
/// to explain all of the difference (acne, whose speckles fall on other pixels in each tracer).
const FULL_PERCENT: f64 = 95.0;

/// Pixels listed for the student to log next.
const NEXT_PIXELS: usize = 6;

/// Fewest differing pixels of an entity, black in the picture, that say the picture turns it
/// black.
const FEW_BLACK: u64 = 3;

/// What the differing pixels' ray trees end on: the entity, the mirrors it is seen in, and the
/// kind of its material (empty for the background).
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct Part {
    pub(crate) entity: String,
    pub(crate) seen_in: Vec<String>,
    pub(crate) material: String,
}

/// The differing pixels traced for the attribution, each with the part it belongs to.
#[derive(Debug, Clone, Default)]
pub(crate) struct Traced {
    /// Pixel indices (row-major), evenly spread over the differing pixels.
    pub(crate) pixels: Vec<u32>,
    /// Index into [`Self::parts`] of each traced pixel.
    pub(crate) part_of: Vec<usize>,
    /// The parts, largest first.
    pub(crate) parts: Vec<Part>,
    /// Traced pixels of each part.
    pub(crate) counts: Vec<u64>,
}

impl Traced {
    /// Traces up to [`MAX_TRACED`] of the `differing` pixels under `base` and groups them by part.
    pub(crate) fn of(scene: &Scene, base: &RenderSettings, differing: &[u32]) -> Traced {
        if differing.is_empty() {
            return Traced::default();
        }
        let w = base.width.max(1);
        let step = differing.len().div_ceil(MAX_TRACED);
        let pixels: Vec<u32> = differing.iter().copied().step_by(step).collect();
        let labels: Vec<Part> = pixels
            .par_iter()
            .map(|&i| {
                let tree = trace_pixel(scene, base, i % w, i / w, 0);
                let (entity, seen_in, material) = attribute(&tree);
                Part {
                    entity,
                    seen_in,
                    material,
                }
            })
            .collect();
        let mut parts: Vec<Part> = Vec::new();
        let mut counts: Vec<u64> = Vec::new();
        let mut part_of = Vec::with_capacity(labels.len());
        for l in labels {
            let k = match parts.iter().position(|p| *p == l) {
                Some(k) => k,
                None => {
                    parts.push(l);
                    counts.push(0);
                    parts.len() - 1
                }
            };
            counts[k] += 1;
            part_of.push(k);
        }
        // Largest first, then by name, so the order is the same on every run.
        let mut order: Vec<usize> = (0..parts.len()).collect();
        order.sort_by(|&a, &b| {
            counts[b]
                .cmp(&counts[a])
                .then_with(|| parts[a].entity.cmp(&parts[b].entity))
        });
        let mut rank = vec![0; parts.len()];
        for (r, &k) in order.iter().enumerate() {
            rank[k] = r;
        }
        Traced {
            pixels,
            part_of: part_of.into_iter().map(|k| rank[k]).collect(),
            parts: order.iter().map(|&k| parts[k].clone()).collect(),
            counts: order.iter().map(|&k| counts[k]).collect(),
        }
    }

    /// The glass entities the differing pixels end on (directly or seen in mirrors), largest
    /// part first.
    pub(crate) fn glass_entities(&self) -> Vec<String> {
        let mut out: Vec<String> = Vec::new();
        for p in self.parts.iter().filter(|p| p.material == "Refractive") {
            if !out.contains(&p.entity) {
                out.push(p.entity.clone());
            }
        }
        out
    }

    /// The entities the image turns black: those (not the background) of the parts seen
    /// directly whose traced pixels, at least [`FEW_BLACK`], are mostly (three in four) black in
    /// `image` and not in `ours`; and where what a mirror shows is black but for no such entity,
    /// the mirror, when three in four of the traced pixels of all the parts seen in it are black.
    pub(crate) fn blackened(&self, ours: &[u8], image: &[u8]) -> Vec<String> {
        let mut black = vec![0u64; self.parts.len()];
        for (&i, &k) in self.pixels.iter().zip(&self.part_of) {
            let p = i as usize * 3;
            if image[p..p + 3] == [0, 0, 0] && ours[p..p + 3] != [0, 0, 0] {
                black[k] += 1;
            }
        }
        // A pixel or two black on an entity are an edge or a corner the picture's tracer
        // resolved otherwise, not the entity turned black.
        let mostly = |b: u64, n: u64| n >= FEW_BLACK && b * 4 >= n * 3;
        let mut entities: Vec<String> = Vec::new();
        for (k, part) in self.parts.iter().enumerate() {
            let direct = part.seen_in.is_empty() && !part.material.is_empty();
            if direct && mostly(black[k], self.counts[k]) && !entities.contains(&part.entity) {
                entities.push(part.entity.clone());
            }
        }
        // Per mirror seen first: the black and all traced pixels of the parts seen in it that
        // no entity found black above explains.
        let mut mirrors: Vec<(&str, u64, u64)> = Vec::new();
        for (k, part) in self.parts.iter().enumerate() {
            let Some(front) = part.seen_in.first() else {
                continue;
            };
            if entities.contains(&part.entity) {
                continue;
            }
            match mirrors.iter_mut().find(|m| m.0 == front) {
                Some(m) => {
                    m.1 += black[k];
                    m.2 += self.counts[k];
                }
                None => mirrors.push((front, black[k], self.counts[k])),
            }
        }
        for (mirror, b, n) in mirrors {
            if mostly(b, n) && !entities.iter().any(|e| e == mirror) {
                entities.push(mirror.to_string());
            }
        }
        entities
    }

    /// Traced pixels of part `k`.
    fn of_part(&self, k: usize) -> impl Iterator<Item = u32> + '_ {
        self.pixels
            .iter()
            .zip(&self.part_of)
            .filter(move |(_, &p)| p == k)
            .map(|(&i, _)| i)
    }

    /// How part `k` differs: darker, brighter, black, a colour shift, and whether the
    /// differences are speckle (isolated pixels) or areas, with the course's item it belongs to.
    pub(crate) fn how(&self, k: usize, ours: &[u8], image: &[u8], w: u32, h: u32, differs: &[bool]) -> String {
        let luma = |b: &[u8], i: u32| {
            let p = i as usize * 3;
            0.2126 * f64::from(b[p]) + 0.7152 * f64::from(b[p + 1]) + 0.0722 * f64::from(b[p + 2])
        };
        let (mut darker, mut brighter, mut black, mut isolated, mut n) = (0u64, 0u64, 0u64, 0u64, 0u64);
        for i in self.of_part(k) {
            n += 1;
            let (a, b) = (luma(ours, i), luma(image, i));
            if b + 2.0 < a {
                darker += 1;
            } else if b > a + 2.0 {
                brighter += 1;
            }
            let p = i as usize * 3;
            if image[p..p + 3] == [0, 0, 0] && ours[p..p + 3] != [0, 0, 0] {
                black += 1;
            }
            let (x, y) = (i % w, i / w);
            let neighbours = [
                (x > 0).then(|| i - 1),
                (x + 1 < w).then(|| i + 1),
                (y > 0).then(|| i - w),
                (y + 1 < h).then(|| i + w),
            ];
            if neighbours.iter().flatten().all(|&j| !differs[j as usize]) {
                isolated += 1;
            }
        }
        let most = |c: u64| c * 4 >= n * 3;
        let tone = if most(black) {
            "black"
        } else if most(darker) {
            "darker"
        } else if most(brighter) {
            "brighter"
        } else if darker + brighter < n / 2 {
            "another colour"
        } else {
            "darker in places, brighter in others"
        };
        let spread = if isolated * 2 >= n {
            ", in scattered single pixels (speckle)"
        } else {
            ""
        };
        let item = match self.parts[k].material.as_str() {
            "" => "camera rays and the background, stage 1",
            "Diffuse" => "diffuse shading and shadow rays, stage 1",
            "Reflective" => "mirror reflection, stage 2",
            "Refractive" => "refraction and Fresnel, stage 2",
            "Emissive" => "emissive materials, stage 3",
            "Glossy" => "glossy materials, stage 3",
            _ => "its material",
        };
        if self.parts[k].seen_in.is_empty() {
            format!("{tone}{spread} ({item})")
        } else {
            format!("{tone}{spread} ({item}, or the mirror reflection it is seen in, stage 2)")
        }
    }

    /// Up to [`NEXT_PIXELS`] pixels to log next, `(x, y)`: spread over the largest parts, a
    /// few from each, evenly over its traced pixels.
    pub(crate) fn next_pixels(&self, w: u32) -> Vec<(u32, u32)> {
        let mut out = Vec::new();
        let parts = self.parts.len().min(3);
        for k in 0..parts {
            let want = (NEXT_PIXELS - out.len()).div_ceil(parts - k);
            let px: Vec<u32> = self.of_part(k).collect();
            let step = px.len().div_ceil(want.max(1)).max(1);
            out.extend(
                px.iter()
                    .skip(step / 2)
                    .step_by(step)
                    .take(want)
                    .map(|&i| (i % w, i / w)),
            );
        }
        out
    }
}

/// How much of a part's difference a render reproduces.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PartExplained {
    /// The entity (as in [`super::Share::entity`]).
    pub entity: String,
    /// The mirrors it is seen in, nearest first.
    pub seen_in: Vec<String>,
    /// Its differing pixels traced.
    pub pixels: u64,
    /// The share of them the render reproduces, in percent.
    pub percent: f64,
    /// Of those it reproduces, the share the image has clipped (as [`Explained::clipped`]).
    #[serde(skip)]
    pub clipped_share: f64,
    /// Of those it reproduces, the share the image has black.
    #[serde(skip)]
    pub black_share: f64,
}

/// How much of the difference between the image and rayscope's render a candidate's render
/// reproduces.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Explained {
    /// Differing pixels that the candidate's render has as the image has them.
    pub pixels: u64,
    /// Their share of the differing pixels, in percent.
    pub percent: f64,
    /// Of `pixels`, those the image has clipped (a channel at 255, every channel at 0 or 255):
    /// any mistake that brightens enough clips them alike, so they are no evidence of which.
    #[serde(skip)]
    pub clipped: u64,
    /// Pixels the image has as rayscope renders them that the candidate's render changes.
    pub new_pixels: u64,
    /// Of `new_pixels`, those in areas (three or more of their eight neighbours are such
    /// pixels too) rather than speckle.
    #[serde(skip)]
    pub broken_areas: u64,
    /// Differing pixels the candidate's render changes, but not to the image's colour.
    pub changed_otherwise: u64,
    /// The share of the image's squared error against rayscope's render that the candidate's
    /// render removes, in percent (negative where it adds error).
    pub error_percent: f64,
    /// Per part of the attribution, largest first.
    pub parts: Vec<PartExplained>,
}

impl Explained {
    /// Of the `candidate`'s render against rayscope's `ours` and the `image` (all `w`×`h`),
    /// with the `threshold` of [`super::differing_pixels`] and `differs` flagging the pixels it
    /// found. A pixel is reproduced when the candidate has it as the image has it, or, for
    /// speckle that falls where each tracer's rounding puts it (acne), when the pixel's
    /// [`BLOCK`]×[`BLOCK`] block is speckled (see [`speckled_blocks`]) and the candidate's
    /// average over it closes most of the gap between rayscope's average there and the image's.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn of(
        candidate: &[u8],
        ours: &[u8],
        image: &[u8],
        (w, h): (u32, u32),
        threshold: u8,
        differs: &[bool],
        traced: &Traced,
    ) -> Explained {
        let (mc, mo, mi) = (
            block_means(candidate, w, h, BLOCK),
            block_means(ours, w, h, BLOCK),
            block_means(image, w, h, BLOCK),
        );
        let bw = w.div_ceil(BLOCK);
        let speckled = speckled_blocks(candidate, image, (w, h), threshold);
        let reproduces = |i: usize| {
            let p = i * 3;
            if (0..3).all(|c| candidate[p + c].abs_diff(image[p + c]) < threshold) {
                return true;
            }
            let (x, y) = (i as u32 % w, i as u32 / w);
            let block = ((y / BLOCK) * bw + x / BLOCK) as usize;
            if !speckled[block] {
                return false;
            }
            let b = block * 3;
            (0..3).all(|c| {
                let gap = (mo[b + c] - mi[b + c]).abs();
                (mc[b + c] - mi[b + c]).abs() <= (0.25 * gap).max(BLOCK_LEVELS)
            })
        };
        let changes = |i: usize| {
            let p = i * 3;
            (0..3).any(|c| candidate[p + c].abs_diff(ours[p + c]) >= threshold)
        };
        let clipped = |i: usize| {
            let p = &image[i * 3..i * 3 + 3];
            p.contains(&255) && p.iter().all(|&v| v == 0 || v == 255)
        };
        let (mut pixels, mut new_pixels, mut changed_otherwise, mut differing) = (0u64, 0u64, 0u64, 0u64);
        let mut clipped_pixels = 0u64;
        let black = |i: usize| image[i * 3..i * 3 + 3] == [0, 0, 0];
        let mut broken = vec![false; differs.len()];
        for (i, &d) in differs.iter().enumerate() {
            match (d, reproduces(i)) {
                (true, true) => {
                    pixels += 1;
                    clipped_pixels += u64::from(clipped(i));
                }
                (false, false) => {
                    new_pixels += 1;
                    broken[i] = true;
                }
                (true, false) if changes(i) => changed_otherwise += 1,
                _ => {}
            }
            differing += u64::from(d);
        }
        let broken_areas = areas(&broken, w, h);
        let se = |a: &[u8]| -> f64 {
            a.iter()
                .zip(image)
                .map(|(x, y)| f64::from(x.abs_diff(*y)).powi(2))
                .sum()
        };
        let se_blocks = |m: &[f32]| -> f64 { m.iter().zip(&mi).map(|(x, y)| f64::from(x - y).powi(2)).sum() };
        // The error removed pixel for pixel, or over block averages where speckle moved.
        let removed = |before: f64, after: f64| if before > 0.0 { 1.0 - after / before } else { 0.0 };
        let removed = removed(se(ours), se(candidate)).max(removed(se_blocks(&mo), se_blocks(&mc)));
        let mut got = vec![0u64; traced.parts.len()];
        let mut got_clipped = vec![0u64; traced.parts.len()];
        let mut got_black = vec![0u64; traced.parts.len()];
        for (&i, &k) in traced.pixels.iter().zip(&traced.part_of) {
            if reproduces(i as usize) {
                got[k] += 1;
                got_clipped[k] += u64::from(clipped(i as usize));
                got_black[k] += u64::from(black(i as usize));
            }
        }
        let pct = |a: u64, b: u64| {
            if b == 0 {
                0.0
            } else {
                (1000.0 * a as f64 / b as f64).round() / 10.0
            }
        };
        Explained {
            pixels,
            percent: pct(pixels, differing),
            clipped: clipped_pixels,
            new_pixels,
            broken_areas,
            changed_otherwise,
            error_percent: (1000.0 * removed).round() / 10.0,
            parts: traced
                .parts
                .iter()
                .zip(&traced.counts)
                .zip(got.iter().zip(&got_clipped).zip(&got_black))
                .map(|((p, &n), ((&g, &c), &b))| PartExplained {
                    entity: p.entity.clone(),
                    seen_in: p.seen_in.clone(),
                    pixels: n,
                    percent: pct(g, n),
                    clipped_share: if g == 0 { 0.0 } else { c as f64 / g as f64 },
                    black_share: if g == 0 { 0.0 } else { b as f64 / g as f64 },
                })
                .collect(),
        }
    }

    /// True when the render explains a real part of the difference: most of the differing
    /// pixels, or most of one sizeable part's, while adding error nowhere it takes away,
    /// changing fewer pixels to colours the image does not have than it reproduces (a mistake
    /// that changes the whole picture matches a part of another's by chance only), and leaving
    /// the areas the image has right as they are (a mistake that is not the image's removes a
    /// shadow the image keeps). Clipped pixels count for nothing here: any mistake that
    /// brightens enough reproduces them.
    pub(crate) fn partial(&self) -> bool {
        self.shows_part() && self.broken_areas as f64 <= AREA_BREAKS_PER_FIX * self.evidence() as f64
    }

    /// True when the render explains the whole difference: [`FULL_PERCENT`] of the differing
    /// pixels, as [`Self::partial`] does.
    pub(crate) fn full(&self) -> bool {
        self.percent >= FULL_PERCENT && self.partial()
    }

    /// [`Self::partial`] for a render that shows what the picture looks like rather than a
    /// mistake (entities left out): it may change areas the image has right, as a sphere left
    /// out does where the image's sphere is only smaller.
    pub(crate) fn shows_part(&self) -> bool {
        let sizeable = |p: &PartExplained| self.sizeable(p);
        let evidence = self.evidence();
        let unclipped = |percent: f64, clipped_share: f64| percent * (1.0 - clipped_share);
        let whole = unclipped(self.percent, self.clipped as f64 / self.pixels.max(1) as f64);
        let clean = self.error_percent > 0.0
            && self.new_pixels as f64 <= BREAKS_PER_FIX * evidence as f64
            && self.new_pixels + self.changed_otherwise <= evidence;
        clean
            && (whole >= WHOLE_PERCENT
                || self
                    .parts
                    .iter()
                    .any(|p| sizeable(p) && unclipped(p.percent, p.clipped_share) >= PART_PERCENT))
    }

    /// [`Self::full`] for a render that shows what the picture looks like ([`Self::shows_part`]).
    pub(crate) fn shows_all(&self) -> bool {
        self.percent >= FULL_PERCENT && self.shows_part()
    }

    /// True for a part big enough to be explained on its own: ten traced pixels or more, and
    /// a twentieth of all those traced.
    pub(crate) fn sizeable(&self, p: &PartExplained) -> bool {
        let traced: u64 = self.parts.iter().map(|p| p.pixels).sum();
        p.pixels >= 10 && p.pixels * 20 >= traced
    }

    /// The share of the reproduced pixels (of the traced ones) that the image has black.
    pub(crate) fn black_share(&self) -> f64 {
        let (mut black, mut all) = (0.0, 0.0);
        for p in &self.parts {
            let got = p.pixels as f64 * p.percent / 100.0;
            black += got * p.black_share;
            all += got;
        }
        if all > 0.0 {
            black / all
        } else {
            0.0
        }
    }

    /// Reproduced pixels the image has not clipped: the evidence for the render.
    fn evidence(&self) -> u64 {
        self.pixels - self.clipped
    }

    /// The part it explains best, among the sizeable ones, in words: "74 % of GlassSphere's
    /// differing pixels".
    pub(crate) fn best_part(&self) -> Option<String> {
        self.parts
            .iter()
            .filter(|p| self.sizeable(p))
            .max_by(|a, b| a.percent.total_cmp(&b.percent))
            .map(|p| {
                let seen = if p.seen_in.is_empty() {
                    String::new()
                } else {
                    format!(" (seen in {})", p.seen_in.join(" in "))
                };
                format!("{:.0} % of {}{seen}'s differing pixels", p.percent, p.entity)
            })
    }
}

/// The next step for a difference nothing explains in full: the pixels to log with the
/// student's own tracer, as the logging kits' environment variables, and the commands that
/// judge that log and show rayscope's own rays at one of the pixels.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NextStep {
    /// The pixels, `[x, y]`.
    pub pixels: Vec<[u32; 2]>,
    /// The environment for a tracer with rayscope's logging kit, e.g.
    /// `RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_PIXELS="12,30 40,8"`.
    pub log_env: String,
    /// The `rayscope check` command for that log.
    pub check_command: String,
    /// The `rayscope trace` command for the first pixel.
    pub trace_command: String,
}

impl NextStep {
    /// For `pixels`, with `flags` the render flags (size, anti-aliasing, …) and `scene` the
    /// scene file as the student named it.
    pub(crate) fn new(pixels: &[(u32, u32)], flags: &str, scene: &str) -> Option<NextStep> {
        let &(x0, y0) = pixels.first()?;
        let list: Vec<String> = pixels.iter().map(|(x, y)| format!("{x},{y}")).collect();
        Some(NextStep {
            pixels: pixels.iter().map(|&(x, y)| [x, y]).collect(),
            log_env: format!("RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_PIXELS=\"{}\"", list.join(" ")),
            check_command: format!("rayscope check -f {scene} --rays rays.jsonl {flags}"),
            trace_command: format!("rayscope trace -f {scene} {flags} --pixel {x0},{y0}"),
        })
    }
}
