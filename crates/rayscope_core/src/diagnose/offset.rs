//! The offset of shadow rays, or of every ray leaving a surface, a picture was rendered with,
//! fitted to its pixels.
//!
//! A student's epsilon is a number of their own: 0.001, 0.01, 0.05. Too large, it moves
//! shadows where objects touch or come close; the course's is 1e-5 or less. The fit scans the
//! offset in quarter decades on the pixels that differ and a sparse grid of the rest (so an
//! offset that breaks pixels the picture has right is penalised), refines the best by
//! golden-section search on its logarithm, and leaves the confirmation at full size, round
//! values first, to the caller.

use rayon::prelude::*;

use crate::mistakes::Mistakes;

/// The bytes of some pixels rendered with rays started this far off the surface.
pub(crate) type RenderWith<'a> = dyn Fn(f32, &[(u32, u32)]) -> Vec<u8> + Sync + 'a;

/// Most differing pixels the fit compares (evenly spread over them).
const DIFFERING: usize = 3_000;

/// Pixels of the sparse grid over the whole picture the fit compares beside them.
const GRID: f64 = 2_000.0;

/// The scan: 10^(−4 + k/4) for k = 0..16, 1e-4 to about 0.56 scene units.
const SCAN: std::ops::Range<i32> = 0..16;

/// Golden-section steps on log₁₀ of the offset after the scan.
const REFINE_STEPS: usize = 14;

/// How many times closer than rayscope's own offset the fitted one must be.
const GAIN: f64 = 4.0;

/// The offset whose render of the `differing` pixels (row-major indices) and a sparse grid of
/// the `w`×`h` picture is closest to `image`, and its squared distance there, when it is at
/// least [`GAIN`] times closer than `ours` (rayscope's render, RGB8); `render(e, pixels)` gives
/// those pixels' bytes with rays started `e` off the surface.
pub(crate) fn fit(
    (w, h): (u32, u32),
    image: &[u8],
    ours: &[u8],
    differing: &[u32],
    render: &RenderWith<'_>,
) -> Option<(f32, f64)> {
    if differing.is_empty() {
        return None;
    }
    let step = differing.len().div_ceil(DIFFERING);
    let grid_step = ((f64::from(w) * f64::from(h) / GRID).sqrt() as u32).max(1);
    let mut pixels: Vec<(u32, u32)> = differing.iter().step_by(step).map(|&i| (i % w, i / w)).collect();
    for y in (grid_step / 2..h).step_by(grid_step as usize) {
        for x in (grid_step / 2..w).step_by(grid_step as usize) {
            pixels.push((x, y));
        }
    }
    let bytes_at = |b: &[u8]| -> Vec<u8> {
        pixels
            .iter()
            .flat_map(|&(x, y)| {
                let p = ((y * w + x) * 3) as usize;
                b[p..p + 3].iter().copied()
            })
            .collect()
    };
    let theirs = bytes_at(image);
    let distance = |bytes: &[u8]| -> f64 {
        bytes
            .iter()
            .zip(&theirs)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).powi(2))
            .sum()
    };
    let error = |log_e: f32| distance(&render(10f32.powf(log_e), &pixels));
    let logs: Vec<f32> = SCAN.map(|k| -4.0 + k as f32 / 4.0).collect();
    let errors: Vec<f64> = logs.par_iter().map(|&l| error(l)).collect();
    let k = (0..logs.len()).min_by(|&a, &b| errors[a].total_cmp(&errors[b]))?;
    let (mut a, mut b) = (logs[k] - 0.25, logs[k] + 0.25);
    let ratio = (5f32.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut ec, mut ed) = (error(c), error(d));
    for _ in 0..REFINE_STEPS {
        if ec <= ed {
            (b, d, ed) = (d, c, ec);
            c = b - ratio * (b - a);
            ec = error(c);
        } else {
            (a, c, ec) = (c, d, ed);
            d = a + ratio * (b - a);
            ed = error(d);
        }
    }
    let (best, e_best) = if ec <= ed { (c, ec) } else { (d, ed) };
    let e_best = e_best.min(errors[k]);
    let best = if e_best == errors[k] { logs[k] } else { best };
    (e_best * GAIN < distance(&bytes_at(ours))).then(|| (10f32.powf(best), e_best))
}

/// The offsets to confirm for a fitted `e`, roundest first: one significant digit (0.02), two
/// (0.025), then `e` itself.
pub(crate) fn round_first(e: f32) -> Vec<f32> {
    let mut out: Vec<f32> = Vec::new();
    let scale = 10f32.powf(e.log10().floor());
    for v in [
        (e / scale).round() * scale,
        (e / scale * 10.0).round() * scale / 10.0,
        e,
    ] {
        let v = format!("{v:.6}").parse::<f32>().unwrap_or(v);
        if v > 0.0 && !out.contains(&v) {
            out.push(v);
        }
    }
    out
}

/// `mistakes` with shadow rays (`every` false) or every ray leaving a surface started `e` off it.
pub(crate) fn with(mistakes: Mistakes, e: f32, every: bool) -> Mistakes {
    if every {
        mistakes.with_ray_offset(e)
    } else {
        mistakes.with_shadow_offset(e)
    }
}

/// Words for shadow rays (`every` false) or every ray leaving a surface started `e` off it.
pub(crate) fn words(e: f32, every: bool) -> String {
    if every {
        format!(
            "every ray leaving a surface (shadow, mirror, glass) started {e} off it along its normal, where the course's start 1e-5 or less off it: shadows shrink or come loose where objects touch or come close, and what mirrors and glass show shifts"
        )
    } else {
        format!(
            "shadow rays started {e} off the surface along its normal, where the course's start 1e-5 or less off it: shadows shrink or come loose where objects touch or come close"
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_values_come_first() {
        assert_eq!(round_first(0.020_13), [0.02, 0.020_13]);
        assert_eq!(round_first(0.004_7), [0.005, 0.004_7]);
        assert_eq!(round_first(0.004_73), [0.005, 0.004_7, 0.004_73]);
    }

    #[test]
    fn a_fit_finds_the_offset_a_render_was_made_with() {
        // A one-pixel "render" whose colour is the offset's logarithm, scaled: the fit finds
        // the planted 0.03 to within the golden-section steps.
        let planted = 0.03f32;
        let px = |e: f32| (128.0 + 60.0 * (e.log10() - planted.log10())).clamp(0.0, 255.0) as u8;
        let image = vec![128u8, 128, 128];
        let ours = vec![px(1e-5); 3];
        let render = |e: f32, pixels: &[(u32, u32)]| pixels.iter().flat_map(|_| [px(e); 3]).collect::<Vec<u8>>();
        let (e, _) = fit((1, 1), &image, &ours, &[0], &render).expect("fitted");
        assert!((e.log10() - planted.log10()).abs() < 0.02, "{e}");
    }
}
