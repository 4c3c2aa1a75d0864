//! The last step of a tracer: the colours its camera rays brought back, turned into the bytes of
//! its picture. With the tracer's PNG beside its log, each fully logged pixel's bytes are
//! recomputed from the logged colours by the course's rule (the samples' colours averaged, each
//! channel clamped to [0, 1], then `trunc(v · 255)`), and where the picture follows another rule
//! the one it follows is named.

use serde::Serialize;

use rayscope_core::diagnose::{next_step, NextStep};
use rayscope_core::{RenderSettings, Scene};

use crate::log::{LogError, LoggedRay, RaySource};
use crate::verdict::Code;

/// The logged colours of each pixel's camera rays, summed.
#[derive(Debug, Clone)]
pub struct PixelSums {
    width: u32,
    height: u32,
    spp: u32,
    /// Sum of the samples' colours.
    sum: Vec<[f64; 3]>,
    /// Sum of the samples' colours each turned into bytes by the course's rule.
    bytes: Vec<[u32; 3]>,
    /// Samples with a colour.
    n: Vec<u32>,
    /// The course's bytes of the colour of the pixel's first and of its last sample (by sample
    /// number, else by their order in the log).
    one: Vec<[[u8; 3]; 2]>,
    /// Pixels with a logged camera ray, coloured or not.
    logged: Vec<bool>,
}

impl PixelSums {
    /// Empty sums for a `width` × `height` image of `spp` samples a pixel (the caller bounds the
    /// size: 47 bytes a pixel).
    #[must_use]
    pub fn new(width: u32, height: u32, spp: u32) -> Self {
        let len = width as usize * height as usize;
        Self {
            width,
            height,
            spp,
            sum: vec![[0.0; 3]; len],
            bytes: vec![[0; 3]; len],
            n: vec![0; len],
            one: vec![[[0; 3]; 2]; len],
            logged: vec![false; len],
        }
    }

    /// Pixel `i`'s average logged colour, when every one of its samples logged one.
    fn average(&self, i: usize) -> Option<[f64; 3]> {
        let n = self.n[i];
        (n == self.spp && n != 0).then(|| self.sum[i].map(|v| v / f64::from(n)))
    }

    /// The pixels with a logged camera ray, row by row.
    #[must_use]
    pub fn into_logged(self) -> Vec<bool> {
        self.logged
    }

    /// Marks a camera ray's pixel as logged and adds its colour; rays without a pixel are left
    /// out, and rays without a colour add none.
    pub fn add(&mut self, r: &LoggedRay) {
        let Some([x, y]) = r.pixel else {
            return;
        };
        if x >= self.width || y >= self.height {
            return;
        }
        let i = (y * self.width + x) as usize;
        self.logged[i] = true;
        let Some(c) = r.color else {
            return;
        };
        for ((sum, bytes), v) in self.sum[i].iter_mut().zip(&mut self.bytes[i]).zip(c.to_array()) {
            *sum += v;
            *bytes += u32::from(course_byte(v));
        }
        let b = c.to_array().map(course_byte);
        let (first, last) = match r.sample {
            Some(s) => (s == 0, s + 1 == self.spp),
            None => (self.n[i] == 0, true),
        };
        if first {
            self.one[i][0] = b;
        }
        if last {
            self.one[i][1] = b;
        }
        self.n[i] += 1;
    }

    /// Reads every ray of `src`, adding those `camera` says are camera rays.
    pub fn read(&mut self, src: &mut dyn RaySource, camera: &dyn Fn(&LoggedRay) -> bool) -> Result<(), LogError> {
        let mut batch = Vec::new();
        loop {
            batch.clear();
            let more = src.next_batch(&mut batch)?;
            for r in batch.iter().filter(|r| camera(r)) {
                self.add(r);
            }
            if !more {
                return Ok(());
            }
        }
    }
}

/// The course's byte: clamped to [0, 1], times 255, truncated (the template's
/// `(byte)(Math.Min(v, 1) * 255)` on a non-negative colour).
fn course_byte(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0) as u8
}

/// A rule that turns a pixel's logged colours into its bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Conversion {
    /// The course's: colours averaged, clamped, `trunc(v · 255)`.
    Course,
    /// Rounded to the nearest byte.
    Rounded,
    /// Times 256 rather than 255, cut at 255: `(byte)Math.Min(v * 256, 255)`.
    Times256,
    /// Gamma-corrected, `v^(1/2.2)`, before the conversion.
    Gamma,
    /// Not clamped: a value over 1 wraps around a byte.
    Unclamped,
    /// Each sample turned into bytes, then the bytes averaged.
    ByteAverage,
    /// Rows upside down.
    Flipped,
    /// Columns right to left.
    Mirrored,
    /// Rows and columns both reversed: half a turn.
    Rotated,
    /// Rows and columns exchanged (a square picture only).
    Transposed,
    /// Red and blue exchanged.
    Bgr,
    /// Each pixel the sum of its own colour and every pixel's before it, row by row: an
    /// anti-aliasing sum never reset between pixels.
    Accumulated,
    /// The samples' colours added up and not divided by their number.
    Summed,
    /// The samples' average times one factor for every pixel ([`ImageCheck::factor`]), then
    /// the course's conversion.
    Scaled,
    /// Each pixel the sum of its own colour and every pixel's before it in its row: the sum
    /// reset at the start of each row instead of each pixel.
    AccumulatedRow,
    /// The first sample's colour alone, not the samples' average.
    FirstSample,
    /// The last sample's colour alone: each sample's colour written over the one before.
    LastSample,
}

impl Conversion {
    const ALL: [Conversion; 16] = [
        Conversion::Course,
        Conversion::Rounded,
        Conversion::Times256,
        Conversion::Gamma,
        Conversion::Unclamped,
        Conversion::ByteAverage,
        Conversion::Flipped,
        Conversion::Mirrored,
        Conversion::Rotated,
        Conversion::Transposed,
        Conversion::Bgr,
        Conversion::Accumulated,
        Conversion::Summed,
        Conversion::AccumulatedRow,
        Conversion::FirstSample,
        Conversion::LastSample,
    ];

    /// The verdict a picture following this rule gets.
    fn code(self) -> Option<Code> {
        match self {
            Conversion::Course => None,
            Conversion::Rounded => Some(Code::ImageRounded),
            Conversion::Times256 => Some(Code::ImageTimes256),
            Conversion::Gamma => Some(Code::ImageGamma),
            Conversion::Unclamped => Some(Code::ImageUnclamped),
            Conversion::ByteAverage => Some(Code::ImageByteAverage),
            Conversion::Flipped => Some(Code::ImageFlipped),
            Conversion::Mirrored => Some(Code::ImageMirrored),
            Conversion::Rotated => Some(Code::ImageRotated),
            Conversion::Transposed => Some(Code::ImageTransposed),
            Conversion::Bgr => Some(Code::ImageChannels),
            Conversion::Accumulated | Conversion::AccumulatedRow => Some(Code::ImageAccumulated),
            Conversion::Summed => Some(Code::ImageSummed),
            Conversion::Scaled => Some(Code::ImageScaled),
            Conversion::FirstSample | Conversion::LastSample => Some(Code::ImageOneSample),
        }
    }

    /// The logged pixel whose colours this rule writes at (x, y); `None` for a transposed
    /// picture that is not square.
    fn source(self, s: &PixelSums, x: u32, y: u32) -> Option<(u32, u32)> {
        Some(match self {
            Conversion::Flipped => (x, s.height - 1 - y),
            Conversion::Mirrored => (s.width - 1 - x, y),
            Conversion::Rotated => (s.width - 1 - x, s.height - 1 - y),
            Conversion::Transposed if s.width == s.height => (y, x),
            Conversion::Transposed => return None,
            _ => (x, y),
        })
    }

    /// Pixel (x, y)'s bytes under this rule; `None` when the rule needs a pixel not fully logged.
    fn bytes(self, s: &PixelSums, x: u32, y: u32) -> Option<[u8; 3]> {
        let (x, y) = self.source(s, x, y)?;
        if matches!(
            self,
            Conversion::Accumulated | Conversion::AccumulatedRow | Conversion::Scaled
        ) {
            return None;
        }
        let i = (y * s.width + x) as usize;
        let avg = s.average(i)?;
        let n = s.spp;
        match self {
            Conversion::FirstSample => return Some(s.one[i][0]),
            Conversion::LastSample => return Some(s.one[i][1]),
            _ => {}
        }
        let one = |v: f64| -> u8 {
            match self {
                Conversion::Course
                | Conversion::Flipped
                | Conversion::Mirrored
                | Conversion::Rotated
                | Conversion::Transposed
                | Conversion::Bgr => course_byte(v),
                Conversion::Rounded => (v.clamp(0.0, 1.0) * 255.0).round() as u8,
                Conversion::Times256 => (v.max(0.0) * 256.0).min(255.0) as u8,
                Conversion::Gamma => (v.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8,
                // A C# `(byte)` of a double past 255 keeps the low 8 bits of its integer part.
                Conversion::Unclamped => ((v.max(0.0) * 255.0) as i64).rem_euclid(256) as u8,
                Conversion::Summed => course_byte(v * f64::from(n)),
                Conversion::ByteAverage
                | Conversion::Accumulated
                | Conversion::AccumulatedRow
                | Conversion::Scaled
                | Conversion::FirstSample
                | Conversion::LastSample => 0,
            }
        };
        let mut b = if self == Conversion::ByteAverage {
            s.bytes[i].map(|v| (v / n) as u8)
        } else {
            avg.map(one)
        };
        if self == Conversion::Bgr {
            b.swap(0, 2);
        }
        Some(b)
    }
}

/// One pixel whose bytes are not the course's conversion of its logged colours.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PixelExample {
    /// The pixel.
    pub pixel: [u32; 2],
    /// The picture's bytes.
    pub yours: [u8; 3],
    /// The course's conversion of the logged colours.
    pub expected: [u8; 3],
    /// The logged colour, averaged over the pixel's samples.
    pub colour: [f64; 3],
}

/// How a picture's bytes follow from the logged colours.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ImageCheck {
    /// Pixels whose every sample logged a colour, compared.
    pub compared: u64,
    /// Of those, pixels whose bytes are the course's conversion (each channel within 1).
    pub course: u64,
    /// The rule most pixels follow, and how many.
    pub best: (Conversion, u64),
    /// The verdict: the rule the picture follows instead of the course's, or `image.differs`.
    pub verdict: Option<Code>,
    /// The factor of [`Conversion::Scaled`], when the picture follows it.
    pub factor: Option<f64>,
    /// The exponent of [`Conversion::Gamma`] when the picture follows a power other than 1/2.2.
    pub exponent: Option<f64>,
    /// The verdict on the bytes when the picture follows two rules at once, one that moves its
    /// pixels (the verdict) and one that changes their bytes (this one).
    pub also: Option<Code>,
    /// What differs, in words.
    pub detail: String,
    /// The first pixels that differ from the course's conversion, by row.
    pub examples: Vec<PixelExample>,
}

/// Share of compared pixels a rule must fit to be the one a picture follows.
const FOLLOWS: f64 = 0.98;

/// Compares `image` (RGB bytes, row by row, the sums' size) with the logged colours.
#[must_use]
pub fn judge(s: &PixelSums, image: &[u8], keep: usize) -> ImageCheck {
    let mut fits = [0u64; Conversion::ALL.len()];
    let mut exact = [0u64; Conversion::ALL.len()];
    let mut compared = 0;
    let mut examples = Vec::new();
    // The running sum of the logged colours, row by row, while every pixel so far is logged.
    let mut sum = Some([0.0f64; 3]);
    let running: Vec<Option<[u8; 3]>> = (0..s.n.len())
        .map(|i| {
            sum = sum
                .zip(s.average(i))
                .map(|(t, avg)| [t[0] + avg[0], t[1] + avg[1], t[2] + avg[2]]);
            sum.map(|t| t.map(course_byte))
        })
        .collect();
    for y in 0..s.height {
        // The running sum of the row so far, while every pixel of it so far is logged.
        let mut row_sum = Some([0.0f64; 3]);
        for x in 0..s.width {
            row_sum = row_sum
                .zip(s.average((y * s.width + x) as usize))
                .map(|(t, avg)| [t[0] + avg[0], t[1] + avg[1], t[2] + avg[2]]);
            let Some(expected) = Conversion::Course.bytes(s, x, y) else {
                continue;
            };
            let o = 3 * (y * s.width + x) as usize;
            let Some(yours) = image.get(o..o + 3).map(|b| [b[0], b[1], b[2]]) else {
                continue;
            };
            compared += 1;
            for (k, c) in Conversion::ALL.iter().enumerate() {
                let b = match c {
                    Conversion::Accumulated => running[(y * s.width + x) as usize],
                    Conversion::AccumulatedRow => row_sum.map(|t| t.map(course_byte)),
                    _ => c.bytes(s, x, y),
                };
                fits[k] += u64::from(b.is_some_and(|b| within_a_level(b, yours)));
                exact[k] += u64::from(b == Some(yours));
            }
            if !within_a_level(expected, yours) && examples.len() < keep {
                let i = (y * s.width + x) as usize;
                examples.push(PixelExample {
                    pixel: [x, y],
                    yours,
                    expected,
                    colour: s.average(i).unwrap_or_default(),
                });
            }
        }
    }
    let share = |n: u64| n as f64 / compared.max(1) as f64;
    let top = |f: &[u64]| {
        let (k, &n) = f
            .iter()
            .enumerate()
            .max_by_key(|(k, &n)| (n, std::cmp::Reverse(*k)))
            .unwrap_or((0, &0));
        (k, n)
    };
    // Bytes a tracer computed from the colour it logged are exact; within one level they allow
    // for a colour logged with fewer digits than it was computed with. Exact fits decide first,
    // so rounding (at most one level off) is told from truncation.
    let (ek, en) = top(&exact);
    let (bk, bn, course) = if share(en) >= FOLLOWS {
        (ek, en, exact[0])
    } else {
        let (k, n) = top(&fits);
        (k, n, fits[0])
    };
    let mut best = (Conversion::ALL[bk], bn);
    let mut factor = None;
    let mut exponent = None;
    let mut also = None;
    let (verdict, detail) = if compared == 0 {
        (
            None,
            "no pixel had a colour logged for every sample, so the picture was not compared".to_string(),
        )
    } else if course == compared || (fits[0] == compared && best.0 == Conversion::Course) {
        (
            None,
            format!("{course} of {compared} pixels are your logged colours turned into bytes as the course does"),
        )
    } else if best.0 != Conversion::Course && share(bn) >= FOLLOWS {
        let which = match best.0 {
            Conversion::FirstSample => format!(": each pixel is its first sample's colour alone, not the average of its {}", s.spp),
            Conversion::AccumulatedRow => {
                ": each pixel is the sum of its own colour and those before it in its row, the sum set to black at the start of each row instead of each pixel".to_string()
            }
            Conversion::LastSample => format!(
                ": each pixel is its last sample's colour alone, not the average of its {} (a pixel written inside the sample loop, each sample over the one before)",
                s.spp
            ),
            _ => String::new(),
        };
        (
            best.0.code(),
            format!(
                "{bn} of {compared} pixels are your logged colours converted that way{which}; {course} as the course converts them"
            ),
        )
    } else if let Some((moved, value, n)) = two_rules(s, image).filter(|&(_, _, n)| share(n) >= FOLLOWS) {
        best = (moved, n);
        also = value.code();
        let code = |c: Conversion| c.code().unwrap_or(Code::ImageDiffers);
        (
            moved.code(),
            format!(
                "{n} of {compared} pixels are your logged colours written with two mistakes at once: {} ({}) and {} ({}); {course} as the course converts them",
                code(moved).summary(),
                code(moved).as_str(),
                code(value).summary(),
                code(value).as_str()
            ),
        )
    } else if let Some((k, n)) = plain_factor(s, image).filter(|&(_, n)| share(n) >= FOLLOWS) {
        best = (Conversion::Scaled, n);
        factor = Some(k);
        let side = f64::from(s.spp).sqrt().round() as u32;
        let why = if s.spp > 1 && side * side == s.spp && k == f64::from(side) {
            format!(
                ": the sum of each pixel's {side}×{side} samples divided by {side}, not by {}",
                s.spp
            )
        } else {
            String::new()
        };
        (
            Some(Code::ImageScaled),
            format!(
                "{n} of {compared} pixels are your logged colours' average times {}, then turned into bytes as the course does{why}; {course} as the course converts them",
                factor_words(k)
            ),
        )
    } else if let Some((g, n)) = plain_exponent(s, image).filter(|&(_, n)| share(n) >= FOLLOWS) {
        best = (Conversion::Gamma, n);
        exponent = Some(g);
        (
            Some(Code::ImageGamma),
            format!(
                "{n} of {compared} pixels are your logged colours raised to the power {}, then turned into bytes as the course does; {course} as the course converts them",
                exponent_words(g)
            ),
        )
    } else if share(course) >= FOLLOWS {
        // A few pixels only: no rule for the whole picture, but those pixels' bytes came from
        // something other than their own samples.
        (
            Some(Code::ImageDiffers),
            format!(
                "{} of {compared} pixels are not your logged colours turned into bytes, though the other {} are: those pixels were written from something other than their own samples' colours (a colour or sum shared by the threads of a parallel loop does this)",
                compared - fits[0],
                fits[0]
            ),
        )
    } else {
        (
            Some(Code::ImageDiffers),
            format!(
                "only {course} of {compared} pixels are your logged colours turned into bytes as the course does, and no usual mistake explains the rest: the picture is not made from the colours your camera rays logged"
            ),
        )
    };
    ImageCheck {
        compared,
        course,
        best,
        verdict,
        factor,
        exponent,
        also,
        detail,
        examples,
    }
}

/// The pair of a rule that moves pixels and one that changes their bytes that the most pixels
/// of `image` follow (each channel within one level), with that number of pixels: a picture
/// written with two mistakes at once.
fn two_rules(s: &PixelSums, image: &[u8]) -> Option<(Conversion, Conversion, u64)> {
    const MOVES: [Conversion; 4] = [
        Conversion::Flipped,
        Conversion::Mirrored,
        Conversion::Rotated,
        Conversion::Transposed,
    ];
    const VALUES: [Conversion; 7] = [
        Conversion::Rounded,
        Conversion::Times256,
        Conversion::Gamma,
        Conversion::Unclamped,
        Conversion::ByteAverage,
        Conversion::Bgr,
        Conversion::Summed,
    ];
    // The pixels a pair fits among every `step`-th pixel.
    let fits = |m: Conversion, v: Conversion, step: usize| -> u64 {
        (0..s.n.len())
            .step_by(step)
            .filter(|&i| {
                let (x, y) = (i as u32 % s.width, i as u32 / s.width);
                let yours = image.get(3 * i..3 * i + 3).map(|b| [b[0], b[1], b[2]]);
                let b = m.source(s, x, y).and_then(|(sx, sy)| v.bytes(s, sx, sy));
                b.zip(yours).is_some_and(|(b, yours)| within_a_level(b, yours))
            })
            .count() as u64
    };
    // The pair is chosen on an even spread of at most about 2^16 pixels, then counted on all.
    let step = (s.n.len() >> 16).max(1);
    let (m, v, _) = MOVES
        .iter()
        .flat_map(|&m| VALUES.iter().map(move |&v| (m, v)))
        .map(|(m, v)| (m, v, fits(m, v, step)))
        // On a tie the simpler pair, earlier in the lists (a picture symmetric left to right is
        // flipped as well as turned).
        .reduce(|a, b| if b.2 > a.2 { b } else { a })?;
    Some((m, v, fits(m, v, 1)))
}

/// The one factor that the average of each fully logged pixel's colours is multiplied by before
/// the course's conversion, when the picture has one, with the number of pixels it fits (each
/// channel within one level). Estimated as the median of the channels' ratios where neither the
/// clamp nor the byte's rounding hides it, then taken as a whole number, the reciprocal of one
/// or the side of the sample grid when within 1 % of it.
fn plain_factor(s: &PixelSums, image: &[u8]) -> Option<(f64, u64)> {
    let pixels = || logged_pixels(s, image);
    // The median of an even spread of at most about 2^16 pixels: the same factor, in bounded
    // memory whatever the picture's size.
    let every = (s.n.len() >> 16).max(1);
    let mut ratios: Vec<f64> = pixels()
        .step_by(every)
        .flat_map(|(avg, yours)| {
            (0..3).filter_map(move |c| {
                let (v, b) = (avg[c], yours[c]);
                (v * 255.0 >= 8.0 && (1..255).contains(&b)).then(|| (f64::from(b) + 0.5) / (v * 255.0))
            })
        })
        .collect();
    if ratios.len() < 16 {
        return None;
    }
    let mid = ratios.len() / 2;
    let (_, &mut k, _) = ratios.select_nth_unstable_by(mid, f64::total_cmp);
    let near = |a: f64| ((k - a) / a).abs() < 0.01;
    let (k, snapped) = if near(k.round()) && k.round() >= 1.0 {
        (k.round(), true)
    } else if k < 1.0 && near(1.0 / (1.0 / k).round()) {
        (1.0 / (1.0 / k).round(), true)
    } else {
        (k, false)
    };
    if near(1.0) || !k.is_finite() {
        return None;
    }
    let fit = |k: f64| fits_with_levels(s, image, |v| v * k);
    // A factor a person wrote has few digits: two decimals where they fit as many pixels.
    let (mut n, mut levels) = fit(k);
    let mut k = k;
    let short = (k * 100.0).round() / 100.0;
    if !snapped && short != k && short > 0.0 {
        let (sn, sl) = fit(short);
        if sn >= n {
            (k, n, levels) = (short, sn, sl);
        }
    }
    // One colour everywhere fits any factor: the fit needs colours of several levels to say the
    // picture is a factor of them.
    (levels >= 8).then_some((k, n))
}

/// The one exponent each fully logged pixel's average colour is raised to before the course's
/// conversion, when the picture has one other than 1, with the number of pixels it fits (each
/// channel within one level). Estimated as the median of the channels' log ratios where neither
/// the clamp nor the byte's rounding hides it, then taken as 1/2.2, 1/2.4, 1/2, 2, 2.2 or a
/// whole number where within 1 % of one.
fn plain_exponent(s: &PixelSums, image: &[u8]) -> Option<(f64, u64)> {
    let pixels = || logged_pixels(s, image);
    // As in `plain_factor`: an even spread of at most about 2^16 pixels.
    let every = (s.n.len() >> 16).max(1);
    let mut logs: Vec<f64> = pixels()
        .step_by(every)
        .flat_map(|(avg, yours)| {
            (0..3).filter_map(move |c| {
                let (v, b) = (avg[c], yours[c]);
                ((0.02..0.9).contains(&v) && (8..247).contains(&b))
                    .then(|| ((f64::from(b) + 0.5) / 255.0).ln() / v.ln())
            })
        })
        .collect();
    if logs.len() < 16 {
        return None;
    }
    let mid = logs.len() / 2;
    let (_, &mut g, _) = logs.select_nth_unstable_by(mid, f64::total_cmp);
    let g = [1.0 / 2.2, 1.0 / 2.4, 0.5, 2.0, 2.2, g.round()]
        .into_iter()
        .find(|&a| a > 0.0 && ((g - a) / a).abs() < 0.01)
        .unwrap_or(g);
    if ((g - 1.0).abs() < 0.01) || !g.is_finite() || g <= 0.0 {
        return None;
    }
    let (n, levels) = fits_with_levels(s, image, |v| v.max(0.0).powf(g));
    // As for a factor, colours of several levels are needed to say the picture is a power of them.
    (levels >= 8).then_some((g, n))
}

/// Each fully logged pixel's average colour beside the picture's bytes for it.
fn logged_pixels<'a>(s: &'a PixelSums, image: &'a [u8]) -> impl Iterator<Item = ([f64; 3], [u8; 3])> + 'a {
    (0..s.n.len()).filter_map(move |i| {
        let yours = image.get(3 * i..3 * i + 3)?;
        Some((s.average(i)?, [yours[0], yours[1], yours[2]]))
    })
}

/// The pixels whose bytes are their average colour changed by `v`, then turned into bytes as the
/// course does (each channel within one level), and how many byte levels above black they show.
fn fits_with_levels(s: &PixelSums, image: &[u8], v: impl Fn(f64) -> f64) -> (u64, usize) {
    let mut levels = [false; 256];
    let mut n = 0u64;
    for (avg, yours) in logged_pixels(s, image) {
        if within_a_level(avg.map(|c| course_byte(v(c))), yours) {
            n += 1;
            for b in yours {
                levels[usize::from(b)] = b > 0;
            }
        }
    }
    (n, levels.iter().filter(|&&l| l).count())
}

/// An exponent as a report words it: 1/2.2 and the like as a fraction, else three decimals.
fn exponent_words(g: f64) -> String {
    let inv = 1.0 / g;
    if g < 1.0 && ((inv * 10.0).round() - inv * 10.0).abs() < 1e-9 {
        let name = if inv == 2.0 { " (a square root)" } else { "" };
        format!("1/{}{name}", (inv * 10.0).round() / 10.0)
    } else if g == g.round() {
        format!("{g}")
    } else {
        format!("{g:.3}")
    }
}

/// True when each channel of `a` is within one level of `b`'s: bytes computed from a colour
/// logged with fewer digits than it was computed with.
fn within_a_level(a: [u8; 3], b: [u8; 3]) -> bool {
    a.iter().zip(b).all(|(&p, q)| p.abs_diff(q) <= 1)
}

/// A factor as a report words it: a whole number, 1/n, or three decimals.
fn factor_words(k: f64) -> String {
    if k == k.round() {
        format!("{k}")
    } else if k < 1.0 && (1.0 / k) == (1.0 / k).round() {
        format!("1/{}", 1.0 / k)
    } else {
        format!("{k:.3}")
    }
}

/// Pixels about as many as a log of [`LogNext::Sparse`]'s grid covers: enough to meet every
/// entity of a course scene, few enough to log in seconds.
const GRID_PIXELS: u64 = 1500;

/// What to log next when a log holds no mistake but does not show the whole picture.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum LogNext {
    /// The tracer's picture against rayscope's render of the same settings.
    Picture {
        /// Pixels where the picture differs from rayscope's render by two levels or more.
        differing: u64,
        /// Of those, pixels without a logged camera ray.
        unlogged: u64,
        /// A few of the unlogged ones to log next, and the commands for them.
        next: Option<NextStep>,
    },
    /// No picture to compare, and camera rays for only part of it.
    Sparse {
        /// Camera rays logged.
        camera_rays: u64,
        /// Camera rays of the whole picture (pixels × samples).
        all: u64,
        /// The logging kits' environment for an even grid of about 1,500 pixels.
        grid_env: String,
        /// The `rayscope check` command for that log together with the picture.
        check_command: String,
    },
}

impl LogNext {
    /// The tracer's `image` against rayscope's render `ours` (RGB bytes, `settings`' size) where
    /// `logged` (row by row) marks the pixels the log has camera rays for; `flags` reproduce
    /// `settings`, `scene_path` names the scene and `image_path` the picture as the student does.
    #[must_use]
    pub fn picture(
        scene: &Scene,
        settings: &RenderSettings,
        (ours, image): (&[u8], &[u8]),
        logged: &[bool],
        flags: &str,
        (scene_path, image_path): (&str, &str),
    ) -> LogNext {
        // Off by one level is rounding (a tracer in double precision against rayscope's single).
        let differing: Vec<u32> = ours
            .chunks_exact(3)
            .zip(image.chunks_exact(3))
            .enumerate()
            .filter(|(_, (a, b))| a.iter().zip(*b).any(|(x, y)| x.abs_diff(*y) >= 2))
            .map(|(i, _)| i as u32)
            .collect();
        let unlogged: Vec<u32> = differing
            .iter()
            .copied()
            .filter(|&i| !logged.get(i as usize).copied().unwrap_or(false))
            .collect();
        let next = next_step(scene, settings, &unlogged, flags, scene_path).map(|mut n| {
            n.check_command.push_str(&format!(" --image {image_path}"));
            n
        });
        LogNext::Picture {
            differing: differing.len() as u64,
            unlogged: unlogged.len() as u64,
            next,
        }
    }

    /// For a log of `camera_rays` camera rays of a `width`×`height` picture of `spp` samples a
    /// pixel, when it lacks some: a grid of about `GRID_PIXELS` pixels to log instead, or the
    /// picture to give; `None` for a log of every sample.
    #[must_use]
    pub fn sparse(
        camera_rays: u64,
        (width, height, spp): (u32, u32, u32),
        flags: &str,
        scene_path: &str,
    ) -> Option<LogNext> {
        let pixels = u64::from(width) * u64::from(height);
        let all = pixels * u64::from(spp.max(1));
        if camera_rays >= all {
            return None;
        }
        let step = ((pixels as f64 / GRID_PIXELS as f64).sqrt().ceil() as u64).max(1);
        Some(LogNext::Sparse {
            camera_rays,
            all,
            grid_env: format!("RAYSCOPE_LOG=rays.jsonl RAYSCOPE_LOG_STEP={step}"),
            check_command: format!("rayscope check -f {scene_path} --rays rays.jsonl --image YOUR_PICTURE.png {flags}"),
        })
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    fn sums(colours: &[[f64; 3]], w: u32, h: u32) -> PixelSums {
        let mut s = PixelSums::new(w, h, 1);
        for (i, c) in colours.iter().enumerate() {
            let mut r = LoggedRay::for_tests([i as u32 % w, i as u32 / w], 0, 1);
            r.color = Some(DVec3::from_array(*c));
            s.add(&r);
        }
        s
    }

    fn picture(s: &PixelSums, c: Conversion) -> Vec<u8> {
        let mut out = Vec::new();
        let mut sum = [0.0f64; 3];
        for y in 0..s.height {
            if c == Conversion::AccumulatedRow {
                sum = [0.0; 3];
            }
            for x in 0..s.width {
                if matches!(c, Conversion::Accumulated | Conversion::AccumulatedRow) {
                    let i = (y * s.width + x) as usize;
                    for (t, v) in sum.iter_mut().zip(s.sum[i]) {
                        *t += v / f64::from(s.n[i]);
                    }
                    out.extend(sum.map(course_byte));
                } else {
                    out.extend(c.bytes(s, x, y).unwrap_or([0; 3]));
                }
            }
        }
        out
    }

    /// An 8×8 picture's sums with one sample a factor: pixel `i`'s colour times each factor.
    fn samples(colours: &[[f64; 3]], factors: &[f64]) -> PixelSums {
        let mut s = PixelSums::new(8, 8, factors.len() as u32);
        for (i, c) in colours.iter().enumerate() {
            for (k, f) in factors.iter().enumerate() {
                let mut r = LoggedRay::for_tests([i as u32 % 8, i as u32 / 8], k as u32, 1);
                r.color = Some(DVec3::from_array(*c) * *f);
                s.add(&r);
            }
        }
        s
    }

    /// 64 colours rising in red and green and falling in blue: channel values i / `div`, blue
    /// from `blue`.
    fn ramp(div: f64, blue: f64) -> Vec<[f64; 3]> {
        (0..64)
            .map(|i| {
                let v = f64::from(i) / div;
                [v, 0.3 * v + 0.05, blue - v / 2.0]
            })
            .collect()
    }

    #[test]
    fn a_picture_raised_to_a_power_gives_the_power() {
        let s = sums(&ramp(80.0, 0.9), 8, 8);
        for (g, said) in [(0.5, "the power 1/2 (a square root)"), (2.0, "the power 2,")] {
            let bytes: Vec<u8> = (0..64)
                .flat_map(|i| s.average(i).unwrap_or_default().map(|v| course_byte(v.powf(g))))
                .collect();
            let j = judge(&s, &bytes, 3);
            assert_eq!(
                (j.verdict, j.exponent),
                (Some(Code::ImageGamma), Some(g)),
                "{}",
                j.detail
            );
            assert!(j.detail.contains(said), "{}", j.detail);
        }
        // The course's own bytes are no power.
        let j = judge(&s, &picture(&s, Conversion::Course), 3);
        assert_eq!((j.verdict, j.exponent), (None, None), "{}", j.detail);
    }

    #[test]
    fn each_rule_is_recognised_and_the_courses_gets_no_verdict() {
        let colours = ramp(40.0, 1.2);
        let s = sums(&colours, 8, 8);
        for c in Conversion::ALL {
            let j = judge(&s, &picture(&s, c), 3);
            // One sample a pixel: averaging bytes is averaging colours, the sum is the mean, and
            // the one sample is the first and the last.
            let want = if matches!(
                c,
                Conversion::ByteAverage | Conversion::Summed | Conversion::FirstSample | Conversion::LastSample
            ) {
                None
            } else {
                c.code()
            };
            assert_eq!(j.verdict, want, "{c:?}: {}", j.detail);
        }
        // Two samples a pixel, one dark and one bright: the bytes' average is not the colours'.
        let two = samples(&colours, &[0.37, 1.63]);
        let j = judge(&two, &picture(&two, Conversion::ByteAverage), 3);
        assert_eq!(j.verdict, Some(Code::ImageByteAverage), "{}", j.detail);
        let j = judge(&two, &picture(&two, Conversion::Summed), 3);
        assert_eq!(j.verdict, Some(Code::ImageSummed), "{}", j.detail);
        for (c, which) in [(Conversion::FirstSample, "first"), (Conversion::LastSample, "last")] {
            let j = judge(&two, &picture(&two, c), 3);
            assert_eq!(j.verdict, Some(Code::ImageOneSample), "{}", j.detail);
            assert!(
                j.detail.contains(&format!("its {which} sample's colour alone")),
                "{}",
                j.detail
            );
        }
    }

    #[test]
    fn a_picture_scaled_by_one_factor_gives_the_factor() {
        let colours = ramp(140.0, 0.45);
        // Four samples a pixel, their sum divided by 2: the picture twice as bright.
        let four = samples(&colours, &[0.5, 1.5, 0.8, 1.2]);
        let twice: Vec<u8> = (0..64)
            .flat_map(|i| four.sum[i].map(|v| course_byte(v / 2.0)))
            .collect();
        let j = judge(&four, &twice, 3);
        assert_eq!(j.verdict, Some(Code::ImageScaled), "{}", j.detail);
        assert_eq!(j.factor, Some(2.0));
        assert!(j.detail.contains("divided by 2, not by 4"), "{}", j.detail);
        // An older run's picture, every colour at 0.9 of the logged one.
        let s = sums(&colours, 8, 8);
        let dim: Vec<u8> = colours.iter().flat_map(|c| c.map(|v| course_byte(v * 0.9))).collect();
        let j = judge(&s, &dim, 3);
        assert_eq!(j.verdict, Some(Code::ImageScaled), "{}", j.detail);
        assert_eq!(j.factor, Some(0.9));
        assert!(j.detail.contains("times 0.900"), "{}", j.detail);
        // Half as bright is 1/2; a factor plus an offset is no factor.
        let half: Vec<u8> = colours.iter().flat_map(|c| c.map(|v| course_byte(v / 2.0))).collect();
        assert!(judge(&s, &half, 3).detail.contains("times 1/2"));
        let shifted: Vec<u8> = colours
            .iter()
            .flat_map(|c| c.map(|v| course_byte(v * 0.9 + 0.03)))
            .collect();
        assert_eq!(judge(&s, &shifted, 3).verdict, Some(Code::ImageDiffers));
    }

    #[test]
    fn a_picture_with_two_mistakes_names_the_move_and_the_bytes() {
        let colours = ramp(70.0, 0.95);
        let s = sums(&colours, 8, 8);
        let gamma = picture(&s, Conversion::Gamma);
        // The gamma-corrected picture written mirrored: each row's bytes in reverse order.
        let mirrored: Vec<u8> = gamma
            .chunks(24)
            .flat_map(|row| row.chunks(3).rev().flatten().copied().collect::<Vec<u8>>())
            .collect();
        let j = judge(&s, &mirrored, 3);
        assert_eq!(j.verdict, Some(Code::ImageMirrored), "{}", j.detail);
        assert_eq!(j.also, Some(Code::ImageGamma), "{}", j.detail);
        assert!(
            j.detail.contains("two mistakes") && j.detail.contains("(image.gamma)"),
            "{}",
            j.detail
        );
    }

    #[test]
    fn a_picture_from_other_colours_is_said_to_differ() {
        let s = sums(&[[0.5, 0.5, 0.5]; 16], 4, 4);
        let j = judge(&s, &[200; 48], 3);
        assert_eq!(j.verdict, Some(Code::ImageDiffers));
        assert_eq!(j.examples[0].expected, [127; 3]);
    }
}
