//! The film: linear RGB pixels, and the course's 8-bit conversion.

use glam::Vec3;

/// A linear-light RGB image, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixels, row-major from the top-left.
    pub pixels: Vec<Vec3>,
}

impl Film {
    /// A black film.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            pixels: vec![Vec3::ZERO; width as usize * height as usize],
        }
    }

    /// The pixel at (`x`, `y`).
    #[must_use]
    pub fn get(&self, x: u32, y: u32) -> Vec3 {
        self.pixels[y as usize * self.width as usize + x as usize]
    }

    /// RGBA8 bytes with the course's conversion: clamp to [0, 1], then `trunc(v · 255)`.
    #[must_use]
    pub(crate) fn to_rgba8(&self) -> Vec<u8> {
        // Into a buffer of the final size: pushed pixel by pixel, the conversion was 4 ns a
        // pixel, most of a millisecond of a small render's wall time.
        let mut out = vec![255; self.pixels.len() * 4];
        for (o, p) in out.chunks_exact_mut(4).zip(&self.pixels) {
            o[..3].copy_from_slice(&[to_byte(p.x), to_byte(p.y), to_byte(p.z)]);
        }
        out
    }

    /// RGB8 bytes with the course's conversion.
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        let mut out = vec![0; self.pixels.len() * 3];
        for (o, p) in out.chunks_exact_mut(3).zip(&self.pixels) {
            o.copy_from_slice(&[to_byte(p.x), to_byte(p.y), to_byte(p.z)]);
        }
        out
    }
}

/// The course's channel conversion: `(byte)(Math.Min(v, 1) * 255)`, with negatives and NaN as 0.
#[must_use]
#[inline]
pub(crate) fn to_byte(v: f32) -> u8 {
    // NaN and negatives fail the first test (`f32::min` would turn NaN into 1.0); `as u8`
    // truncates like the C# cast. Selects rather than an early return, so loops over pixels
    // compile without a branch per channel.
    let c = if v >= 0.0 {
        if v < 1.0 {
            v
        } else {
            1.0
        }
    } else {
        0.0
    };
    (c * 255.0) as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn course_conversion_truncates() {
        assert_eq!(to_byte(1.0), 255);
        assert_eq!(to_byte(2.0), 255);
        assert_eq!(to_byte(0.5), 127);
        assert_eq!(to_byte(-1.0), 0);
        assert_eq!(to_byte(f32::NAN), 0);
        assert_eq!(to_byte(0.999), 254);
    }

    #[test]
    fn byte_images_convert_every_pixel() {
        let mut film = Film::new(3, 1);
        film.pixels = vec![
            Vec3::new(0.5, 2.0, f32::NAN),
            Vec3::new(-0.0, 1.0, 0.25),
            Vec3::splat(f32::INFINITY),
        ];
        assert_eq!(film.to_rgba8(), [127, 255, 0, 255, 0, 255, 63, 255, 255, 255, 255, 255]);
        assert_eq!(film.to_rgb8(), [127, 255, 0, 0, 255, 63, 255, 255, 255]);
        assert_eq!(to_byte(f32::NEG_INFINITY), 0);
        assert_eq!(to_byte(f32::MIN_POSITIVE), 0);
    }
}
