//! Image comparison: PSNR, the share of differing pixels and a per-channel difference heat map
//! with a stated scale.

/// The result of comparing two 8-bit RGB images of the same size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Comparison {
    /// Peak signal-to-noise ratio in dB over the RGB channels; infinite for identical images.
    pub psnr: f64,
    /// Pixels where any channel differs.
    pub differing: u64,
    /// Pixels compared.
    pub total: u64,
    /// Largest difference of any channel.
    pub max_diff: u8,
}

/// Compares two RGB8 buffers of equal length (3 bytes a pixel).
///
/// # Panics
/// If the buffers differ in length.
#[must_use]
pub fn compare_rgb8(a: &[u8], b: &[u8]) -> Comparison {
    assert_eq!(a.len(), b.len(), "images must have the same size");
    let mut se = 0u64;
    let mut differing = 0u64;
    let mut max_diff = 0u8;
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let mut any = false;
        for (&x, &y) in pa.iter().zip(pb) {
            let d = x.abs_diff(y);
            se += u64::from(d) * u64::from(d);
            max_diff = max_diff.max(d);
            any |= d != 0;
        }
        differing += u64::from(any);
    }
    let mse = se as f64 / a.len().max(1) as f64;
    let psnr = if se == 0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    Comparison {
        psnr,
        differing,
        total: (a.len() / 3) as u64,
        max_diff,
    }
}

/// A difference heat map and the scale it was drawn with.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Heatmap {
    /// RGB8 pixels: each channel is that channel's absolute difference, scaled so that `range`
    /// levels or more are 255; black where the images agree.
    pub rgb: Vec<u8>,
    /// Difference (in 8-bit levels) shown at full brightness.
    pub range: u8,
    /// True when `range` was chosen from the images (`auto_range`).
    pub auto: bool,
    /// Pixels with a channel difference above `range` (shown at full brightness, clipped).
    pub clipped: u64,
}

/// Share of the differing pixels [`auto_range`] lets clip, so a few outliers (two surfaces tied
/// at an edge) do not dim every other difference into black.
pub(crate) const AUTO_RANGE_CLIP: f64 = 0.01;

/// The range [`heatmap`] picks by itself: the largest channel difference of all but the
/// [`AUTO_RANGE_CLIP`] most different of the differing pixels (at least 1).
#[must_use]
pub(crate) fn auto_range(a: &[u8], b: &[u8]) -> u8 {
    let mut hist = [0u64; 256];
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0);
        hist[d as usize] += 1;
    }
    let differing: u64 = hist[1..].iter().sum();
    // The number of differing pixels allowed above the range, rounded down.
    let allowed = (differing as f64 * AUTO_RANGE_CLIP) as u64;
    let mut above = 0u64;
    for d in (1..256).rev() {
        if above + hist[d] > allowed {
            return d as u8;
        }
        above += hist[d];
    }
    1
}

/// A per-channel heat map of the difference between two RGB8 buffers of equal length: each
/// output channel is |a − b| of that channel, times 255 / `range` and clipped at 255. With
/// `range` `None` it is `auto_range`; a range of 0 counts as 1.
///
/// # Panics
/// If the buffers differ in length.
#[must_use]
pub fn heatmap(a: &[u8], b: &[u8], range: Option<u8>) -> Heatmap {
    assert_eq!(a.len(), b.len(), "images must have the same size");
    let auto = range.is_none();
    let range = range.unwrap_or_else(|| auto_range(a, b)).max(1);
    let scale = |d: u8| -> u8 {
        // Rounded to nearest: d · 255 / range in integers.
        let v = (u32::from(d.min(range)) * 255 + u32::from(range) / 2) / u32::from(range);
        v as u8
    };
    let mut clipped = 0u64;
    let mut rgb = Vec::with_capacity(a.len());
    for (pa, pb) in a.chunks_exact(3).zip(b.chunks_exact(3)) {
        let d = [pa[0].abs_diff(pb[0]), pa[1].abs_diff(pb[1]), pa[2].abs_diff(pb[2])];
        clipped += u64::from(d.iter().any(|&x| x > range));
        rgb.extend(d.map(scale));
    }
    Heatmap {
        rgb,
        range,
        auto,
        clipped,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identical_and_known_psnr() {
        let a = vec![10u8; 300];
        let c = compare_rgb8(&a, &a);
        assert!(c.psnr.is_infinite() && c.differing == 0);
        let mut b = a.clone();
        b[0] = 11; // one channel off by one in 300: MSE = 1/300.
        let c = compare_rgb8(&a, &b);
        assert!((c.psnr - 10.0 * (255.0f64 * 255.0 * 300.0).log10()).abs() < 1e-9);
        assert_eq!((c.differing, c.total, c.max_diff), (1, 100, 1));
        let h = heatmap(&a, &b, Some(16));
        assert_eq!(&h.rgb[0..3], &[16, 0, 0], "1 of 16 levels, red channel only");
        assert_eq!(&h.rgb[3..6], &[0, 0, 0]);
        assert_eq!((h.range, h.auto, h.clipped), (16, false, 0));
    }

    #[test]
    fn small_errors_are_graded_not_saturated() {
        // Differences of 1, 2 and 3 levels in the green channel.
        let a = vec![100u8; 12];
        let mut b = a.clone();
        b[1] = 101;
        b[4] = 102;
        b[7] = 103;
        let h = heatmap(&a, &b, None);
        assert_eq!((h.range, h.auto, h.clipped), (3, true, 0));
        let g: Vec<u8> = h.rgb.chunks_exact(3).map(|p| p[1]).collect();
        assert_eq!(g, [85, 170, 255, 0]);
        assert!(h.rgb.chunks_exact(3).all(|p| p[0] == 0 && p[2] == 0));
    }

    #[test]
    fn auto_range_ignores_a_few_outliers() {
        // 200 pixels off by 4 levels and one off by 250: the outlier clips, the rest stay graded.
        let n = 300;
        let a = vec![0u8; n * 3];
        let mut b = a.clone();
        for p in 0..200 {
            b[p * 3] = 4;
        }
        b[250 * 3] = 250;
        assert_eq!(auto_range(&a, &b), 4);
        let h = heatmap(&a, &b, None);
        assert_eq!(h.clipped, 1);
        assert_eq!(&h.rgb[0..3], &[255, 0, 0]);
        // A single differing pixel cannot clip: it sets the range itself.
        let mut c = a.clone();
        c[5] = 7;
        assert_eq!(auto_range(&a, &c), 7);
        assert_eq!(auto_range(&a, &a), 1);
    }
}
