//! Image comparison: PSNR, the share of differing pixels and a difference heat map.

use crate::integrator::heat;

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

/// A heat map of per-pixel differences (RGB8): black where equal, blue→red as the largest
/// channel difference grows to `scale` or more.
#[must_use]
pub fn heatmap_rgb8(a: &[u8], b: &[u8], scale: u8) -> Vec<u8> {
    let scale = f32::from(scale.max(1));
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .flat_map(|(pa, pb)| {
            let d = pa.iter().zip(pb).map(|(x, y)| x.abs_diff(*y)).max().unwrap_or(0);
            if d == 0 {
                [0, 0, 0]
            } else {
                let c = heat(f32::from(d) / scale);
                [(c.x * 255.0) as u8, (c.y * 255.0) as u8, (c.z * 255.0) as u8]
            }
        })
        .collect()
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
        let h = heatmap_rgb8(&a, &b, 16);
        assert_ne!(&h[0..3], &[0, 0, 0]);
        assert_eq!(&h[3..6], &[0, 0, 0]);
    }
}
