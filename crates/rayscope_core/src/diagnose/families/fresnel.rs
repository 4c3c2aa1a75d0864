//! The Fresnel weight of glass, fitted to the student's pixels: the course's exact unpolarised
//! weight, none (0), a half, Schlick's approximation, the reflected and refracted weights
//! exchanged (1 minus the exact weight), a constant (fitted), and a general curve
//! (fitted at knots: piecewise linear in cos θi entering the glass, in the angle's share of the
//! critical angle leaving it). Each member
//! is fitted by least squares over the channels of the glass's pixels that the weight changes by
//! at least [`SENSITIVE`] levels and that are not clipped, leaving out the [`TRIM`] worst pixels
//! (edges and rims, where two tracers' rays may meet different things), and fits when its
//! residual is within [`FIT_RMS`] levels: the bytes' own rounding is 0.29 levels.

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::fitted::Fitted;
use super::trees::{GlassHit, PixelTrees};
use crate::optics::{fresnel, schlick};

/// A pixel is fitted where the weight changes its colour: a half against none moves a channel
/// by at least this many levels.
const SENSITIVE: f64 = 1.0;

/// Share of the fitted pixels left out as the worst ones, the ones a tie may explain.
const TRIM: f64 = 0.02;

/// A fit explains the glass when its residual, root mean square over the channels fitted, is
/// at most this many levels.
const FIT_RMS: f64 = 0.6;

/// Fewest pixels a finding rests on.
const MIN_PIXELS: usize = 30;

/// Where the entering curve has its knots: cosines of the angle of incidence.
const ENTER_KNOTS: [f64; 10] = [0.0, 0.05, 0.1, 0.173_648, 0.25, 0.35, 0.5, 0.7, 0.85, 1.0];

/// Where the leaving curve has its knots: angles of incidence as shares of the critical angle.
const LEAVE_KNOTS: [f64; 9] = [0.0, 0.3, 0.5, 0.65, 0.8, 0.87, 0.93, 0.97, 1.0];

/// The leaving knot the report names beside normal incidence: 0.8 of the critical angle.
const LEAVE_SAID: usize = 4;

/// Tikhonov weight (levels² per unit of weight²) holding a curve's knots that no pixel sees at
/// the course's values.
const HOLD: f64 = 1.0;

/// A member of the family.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Member {
    /// The course's exact unpolarised weight.
    Course,
    /// No reflection: 0 at every angle.
    None,
    /// Half and half at every angle.
    Half,
    /// Schlick's approximation.
    Schlick,
    /// The reflected and refracted weights exchanged: 1 − the course's weight (1 under total
    /// internal reflection, where there is nothing to exchange it with).
    Exchanged,
    /// One share at every angle (fitted).
    Constant,
    /// Piecewise linear, entering and leaving apart (fitted at [`ENTER_KNOTS`] and
    /// [`LEAVE_KNOTS`]).
    Curve,
}

impl Member {
    /// How many parameters the member has.
    fn params(self) -> usize {
        match self {
            Member::Constant => 1,
            Member::Curve => ENTER_KNOTS.len() + LEAVE_KNOTS.len(),
            _ => 0,
        }
    }

    /// The member's code in [`Fitted::code`].
    fn code(self) -> &'static str {
        match self {
            Member::Course => "fresnel-exact",
            Member::None => "fresnel-none",
            Member::Half => "fresnel-half",
            Member::Schlick => "fresnel-schlick",
            Member::Exchanged => "fresnel-exchanged",
            Member::Constant => "fresnel-constant",
            Member::Curve => "fresnel-curve",
        }
    }

    /// The weight at `h` with parameters `p`, and its derivatives by them in `g`.
    fn weight(self, h: &GlassHit, p: &[f64], g: &mut [f64]) -> f64 {
        let (c, n1, n2) = (h.cos_i as f32, h.n1 as f32, h.n2 as f32);
        match self {
            Member::Course => h.course,
            Member::None => 0.0,
            Member::Half => 0.5,
            Member::Schlick => f64::from(schlick(c, n1, n2)),
            Member::Exchanged => {
                if h.course >= 1.0 {
                    1.0
                } else {
                    1.0 - h.course
                }
            }
            Member::Constant => {
                if let Some(d) = g.first_mut() {
                    *d = 1.0;
                }
                p[0]
            }
            Member::Curve => {
                let (base, x, knots) = if h.entering {
                    (0, h.cos_i, &ENTER_KNOTS[..])
                } else {
                    (ENTER_KNOTS.len(), leave_share(h), &LEAVE_KNOTS[..])
                };
                let (k, f) = segment(knots, x);
                if g.len() > base + k + 1 {
                    g[base + k] = 1.0 - f;
                    g[base + k + 1] = f;
                }
                p[base + k] * (1.0 - f) + p[base + k + 1] * f
            }
        }
    }
}

/// A leaving ray's angle of incidence as a share of the critical angle (of a right angle where
/// there is none).
fn leave_share(h: &GlassHit) -> f64 {
    let theta = h.cos_i.clamp(0.0, 1.0).acos();
    let critical = if h.n1 > h.n2 {
        (h.n2 / h.n1).asin()
    } else {
        std::f64::consts::FRAC_PI_2
    };
    (theta / critical).clamp(0.0, 1.0)
}

/// The segment of `knots` (ascending) that holds `x`, and where in it `x` lies (0 to 1).
fn segment(knots: &[f64], x: f64) -> (usize, f64) {
    let last = knots.len() - 2;
    let k = knots.windows(2).position(|s| x <= s[1]).unwrap_or(last).min(last);
    let f = ((x - knots[k]) / (knots[k + 1] - knots[k])).clamp(0.0, 1.0);
    (k, f)
}

/// A member's fit over some pixels.
#[derive(Debug, Clone)]
struct Fit {
    params: Vec<f64>,
    /// Root mean square residual, in levels, over the channels fitted of the pixels kept.
    rms: f64,
    /// Pixels kept (the fitted ones less the trimmed).
    pixels: usize,
    /// Each parameter's standard error: the residual times the square root of its diagonal
    /// element of (JᵀJ + [`HOLD`])⁻¹.
    sigma: Vec<f64>,
}

/// The residuals of `px` under `m` with `p`: Σ r², and with `normal`, JᵀJ and Jᵀr added to it.
fn residuals(px: &PixelTrees, m: Member, p: &[f64], normal: Option<(&mut [f64], &mut [f64])>) -> (f64, f64, usize) {
    let n = if normal.is_some() { m.params() } else { 0 };
    let mut grad = vec![[0.0; 3]; n];
    let weight = |h: &GlassHit, g: &mut [f64]| m.weight(h, p, g);
    let pred = px.eval(&weight, n, &mut grad);
    let (mut sum, mut worst, mut count) = (0.0, 0.0f64, 0);
    let mut normal = normal;
    for c in 0..3 {
        let b = px.theirs[c];
        if b == 0 || b == 255 {
            continue;
        }
        let r = f64::from(b) + 0.5 - pred[c];
        sum += r * r;
        worst = worst.max(r.abs());
        count += 1;
        if let Some((jtj, jtr)) = normal.as_mut() {
            for i in 0..n {
                jtr[i] += grad[i][c] * r;
                for j in 0..n {
                    jtj[i * n + j] += grad[i][c] * grad[j][c];
                }
            }
        }
    }
    (sum, worst, count)
}

/// Σ r² and channel count of `pixels` under `m` with `p`.
fn cost(pixels: &[&PixelTrees], m: Member, p: &[f64]) -> (f64, usize) {
    pixels
        .par_iter()
        .map(|px| {
            let (s, _, n) = residuals(px, m, p, None);
            (s, n)
        })
        .reduce(|| (0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1))
}

/// Solves `a x = b` (`a` n×n, row-major) by elimination with partial pivoting; `None` when
/// singular.
fn solve(mut a: Vec<f64>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i * n + col].abs().total_cmp(&a[j * n + col].abs()))?;
        if a[piv * n + col].abs() < 1e-12 {
            return None;
        }
        for k in 0..n {
            a.swap(col * n + k, piv * n + k);
        }
        b.swap(col, piv);
        for row in col + 1..n {
            let f = a[row * n + col] / a[col * n + col];
            for k in col..n {
                a[row * n + k] -= f * a[col * n + k];
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for row in (0..n).rev() {
        let s: f64 = (row + 1..n).map(|k| a[row * n + k] * x[k]).sum();
        x[row] = (b[row] - s) / a[row * n + row];
    }
    Some(x)
}

/// Least squares over `pixels` for `m`'s parameters from `p0` (Levenberg–Marquardt), holding
/// each one towards `hold` by [`HOLD`].
fn least_squares(pixels: &[&PixelTrees], m: Member, p0: &[f64], hold: &[f64]) -> Vec<f64> {
    let n = m.params();
    let mut p = p0.to_vec();
    if n == 0 {
        return p;
    }
    let penalty = |p: &[f64]| HOLD * p.iter().zip(hold).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
    let mut now = cost(pixels, m, &p).0 + penalty(&p);
    let mut mu = 1e-3;
    for _ in 0..40 {
        let (jtj, jtr) = pixels
            .par_iter()
            .fold(
                || (vec![0.0; n * n], vec![0.0; n]),
                |(mut a, mut b), px| {
                    residuals(px, m, &p, Some((&mut a, &mut b)));
                    (a, b)
                },
            )
            .reduce(
                || (vec![0.0; n * n], vec![0.0; n]),
                |(mut a, mut b), (c, d)| {
                    a.iter_mut().zip(c).for_each(|(x, y)| *x += y);
                    b.iter_mut().zip(d).for_each(|(x, y)| *x += y);
                    (a, b)
                },
            );
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            let b: Vec<f64> = (0..n).map(|i| jtr[i] - HOLD * (p[i] - hold[i])).collect();
            for i in 0..n {
                a[i * n + i] += HOLD + mu * (jtj[i * n + i] + HOLD);
            }
            let Some(step) = solve(a, b) else {
                mu *= 10.0;
                continue;
            };
            let q: Vec<f64> = p.iter().zip(&step).map(|(a, d)| a + d).collect();
            let next = cost(pixels, m, &q).0 + penalty(&q);
            if next < now {
                let small = step.iter().all(|d| d.abs() < 1e-6);
                (p, now, mu) = (q, next, (mu / 3.0).max(1e-9));
                improved = !small;
                break;
            }
            mu *= 8.0;
        }
        if !improved {
            break;
        }
    }
    p
}

/// Fits `m` to `pixels` from `p0`: over all, then again without the [`TRIM`] worst pixels.
fn fit_member(pixels: &[&PixelTrees], m: Member, p0: &[f64]) -> Fit {
    let p = least_squares(pixels, m, p0, p0);
    let mut worst: Vec<(f64, usize)> = pixels
        .par_iter()
        .enumerate()
        .map(|(i, px)| (residuals(px, m, &p, None).1, i))
        .collect();
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    let trim = (pixels.len() as f64 * TRIM).ceil() as usize;
    let mut gone = vec![false; pixels.len()];
    for &(_, i) in worst.iter().take(trim) {
        gone[i] = true;
    }
    let kept: Vec<&PixelTrees> = pixels
        .iter()
        .enumerate()
        .filter(|(i, _)| !gone[*i])
        .map(|(_, px)| *px)
        .collect();
    let params = least_squares(&kept, m, &p, p0);
    let (sum, n) = cost(&kept, m, &params);
    let rms = (sum / n.max(1) as f64).sqrt();
    let k = m.params();
    let jtj = kept
        .par_iter()
        .fold(
            || (vec![0.0; k * k], vec![0.0; k]),
            |(mut a, mut b), px| {
                residuals(px, m, &params, Some((&mut a, &mut b)));
                (a, b)
            },
        )
        .map(|(a, _)| a)
        .reduce(
            || vec![0.0; k * k],
            |a, b| a.iter().zip(b).map(|(x, y)| x + y).collect(),
        );
    let mut held = jtj;
    for i in 0..k {
        held[i * k + i] += HOLD;
    }
    // Each parameter's variance is rms² times its diagonal element of (JᵀJ + HOLD)⁻¹.
    let sigma = (0..k)
        .map(|i| {
            let unit: Vec<f64> = (0..k).map(|j| f64::from(u8::from(i == j))).collect();
            solve(held.clone(), unit).map_or(f64::INFINITY, |col| rms * col[i].max(0.0).sqrt())
        })
        .collect();
    Fit {
        sigma,
        rms,
        params,
        pixels: kept.len(),
    }
}

/// The course's weight at the curve's knots for glass of index `ior` in air.
fn course_knots(ior: f64) -> Vec<f64> {
    let enter = ENTER_KNOTS
        .iter()
        .map(|&c| f64::from(fresnel(c as f32, 1.0, ior as f32)));
    let critical = (1.0 / ior).min(1.0).asin();
    let leave = LEAVE_KNOTS
        .iter()
        .map(|&s| f64::from(fresnel((s * critical).cos() as f32, ior as f32, 1.0)));
    enter.chain(leave).collect()
}

/// The index of the glass most of the entering hits meet.
fn common_ior(pixels: &[&PixelTrees]) -> f64 {
    let mut counts: BTreeMap<u64, usize> = BTreeMap::new();
    for h in pixels.iter().flat_map(|p| &p.hits).filter(|h| h.entering) {
        *counts.entry(h.n2.to_bits()).or_default() += 1;
    }
    counts
        .into_iter()
        .max_by_key(|&(_, n)| n)
        .map_or(1.5, |(b, _)| f64::from_bits(b))
}

/// The Fresnel finding for the glass `pixels`, if the course's weight does not explain them and
/// a member of the family does.
pub(super) fn fit(all: &[PixelTrees]) -> Option<Fitted> {
    // Pixels whose colour the weight changes.
    let pixels: Vec<&PixelTrees> = all
        .par_iter()
        .filter(|px| {
            let mut g = [];
            let none = px.eval(&|h, g| Member::None.weight(h, &[], g), 0, &mut g);
            let half = px.eval(&|h, g| Member::Half.weight(h, &[], g), 0, &mut g);
            (0..3).any(|c| (none[c] - half[c]).abs() >= SENSITIVE && !matches!(px.theirs[c], 0 | 255))
        })
        .collect();
    if pixels.len() < MIN_PIXELS {
        return None;
    }
    let course = fit_member(&pixels, Member::Course, &[]);
    if course.rms <= FIT_RMS {
        return None;
    }
    let ior = common_ior(&pixels);
    let start = |m: Member| match m {
        Member::Constant => vec![f64::from(fresnel(1.0, 1.0, ior as f32))],
        Member::Curve => course_knots(ior),
        _ => Vec::new(),
    };
    [
        Member::None,
        Member::Half,
        Member::Schlick,
        Member::Exchanged,
        Member::Constant,
        Member::Curve,
    ]
    .into_iter()
    .map(|m| (m, fit_member(&pixels, m, &start(m))))
    .find(|(_, f)| f.rms <= FIT_RMS && f.pixels >= MIN_PIXELS)
    .map(|(m, f)| finding(m, &f, &course, ior))
}

/// A weight as a percentage for a sentence.
/// The weights at normal incidence, 60° and 80°, as "a, b, c".
fn pcts(v: [f64; 3]) -> String {
    v.map(pct).join(", ")
}

fn pct(v: f64) -> String {
    if v.abs() < 0.1 {
        format!("{:.1} %", 100.0 * v)
    } else {
        format!("{:.0} %", 100.0 * v)
    }
}

/// The finding for member `m` fitted as `f`, against the course's fit `course`, for glass of
/// index `ior`.
fn finding(m: Member, f: &Fit, course: &Fit, ior: f64) -> Fitted {
    let angles = [0.0f64, 60.0, 80.0];
    let at = |m: Member, p: &[f64], deg: f64, entering: bool| {
        let cos_i = deg.to_radians().cos();
        let (n1, n2) = if entering { (1.0, ior) } else { (ior, 1.0) };
        let h = GlassHit {
            entering,
            cos_i,
            n1,
            n2,
            course: f64::from(fresnel(cos_i as f32, n1 as f32, n2 as f32)),
        };
        m.weight(&h, p, &mut [])
    };
    let yours = angles.map(|a| at(m, &f.params, a, true));
    let exact = angles.map(|a| at(Member::Course, &[], a, true));
    let mut numbers: BTreeMap<&'static str, f64> = BTreeMap::new();
    numbers.insert("pixels", f.pixels as f64);
    numbers.insert("rms_levels", f.rms);
    numbers.insert("course_rms_levels", course.rms);
    numbers.insert("ior", ior);
    for (k, key) in ["fitted_0", "fitted_60", "fitted_80"].into_iter().enumerate() {
        numbers.insert(key, yours[k]);
    }
    for (k, key) in ["exact_0", "exact_60", "exact_80"].into_iter().enumerate() {
        numbers.insert(key, exact[k]);
    }
    let range = format!(
        "the exact Fresnel weight goes from {} at normal incidence to 100 % at grazing angles",
        pct(exact[0])
    );
    let n = f.pixels;
    let text = match m {
        Member::None => format!("Your glass reflects nothing at any angle (fitted from {n} pixels); {range}."),
        Member::Half => format!("Your glass reflects 50 % at every angle (fitted from {n} pixels); {range}."),
        Member::Constant => {
            numbers.insert("constant", f.params[0]);
            format!(
                "Your glass reflects {} at every angle (fitted from {n} pixels); {range}.",
                pct(f.params[0])
            )
        }
        Member::Schlick => format!(
            "Your glass's Fresnel weight is Schlick's approximation (fitted from {n} pixels): {}, {} and {} at normal incidence, 60° and 80°; the exact Fresnel weight: {}.",
            pct(yours[0]),
            pct(yours[1]),
            pct(yours[2]),
            pcts(exact)
        ),
        Member::Exchanged => format!(
            "Your glass's reflected and refracted weights are exchanged (fitted from {n} pixels): it reflects {}, {} and {} at normal incidence, 60° and 80°, which is 1 minus the exact Fresnel weight ({}). Where you mix the two colours, the reflected colour takes kr and the refracted one 1 − kr.",
            pct(yours[0]),
            pct(yours[1]),
            pct(yours[2]),
            pcts(exact)
        ),
        Member::Course | Member::Curve => curve_text(f, n, yours, exact, ior, &mut numbers),
    };
    Fitted {
        code: m.code(),
        text,
        numbers,
        allowed: false,
    }
}

/// The sentence for a fitted curve, with the leaving weight where it differs from the course's.
fn curve_text(
    f: &Fit,
    n: usize,
    yours: [f64; 3],
    exact: [f64; 3],
    ior: f64,
    numbers: &mut BTreeMap<&'static str, f64>,
) -> String {
    let mut text = format!(
        "Your glass's reflected share, fitted from {n} pixels: {} at normal incidence, {} at 60°, {} at 80°; the exact Fresnel weight: {}",
        pct(yours[0]),
        pct(yours[1]),
        pct(yours[2]),
        pcts(exact)
    );
    let course = course_knots(ior);
    let leave = ENTER_KNOTS.len();
    // Leaving: at normal incidence and at 0.8 of the critical angle.
    let (k0, k1) = (leave, leave + LEAVE_SAID);
    // Said where the fit tells it from the course's: by more than 2 % and 3 standard errors.
    let differs = [k0, k1].iter().any(|&k| {
        let d = (f.params[k] - course[k]).abs();
        d > 0.02 && d > 3.0 * f.sigma[k]
    });
    if differs {
        let critical = (1.0 / ior).min(1.0).asin().to_degrees();
        let deg = (LEAVE_KNOTS[LEAVE_SAID] * critical).round();
        numbers.insert("leaving_0", f.params[k0]);
        numbers.insert("leaving_at", f.params[k1]);
        numbers.insert("leaving_at_degrees", deg);
        text.push_str(&format!(
            "; leaving the glass: {} at normal incidence, {} at {deg:.0}° (exact: {}, {})",
            pct(f.params[k0]),
            pct(f.params[k1]),
            pct(course[k0]),
            pct(course[k1])
        ));
    }
    text.push('.');
    text
}
