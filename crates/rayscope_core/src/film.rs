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
    pub fn to_rgba8(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pixels.len() * 4);
        for p in &self.pixels {
            out.extend_from_slice(&[to_byte(p.x), to_byte(p.y), to_byte(p.z), 255]);
        }
        out
    }

    /// RGB8 bytes with the course's conversion.
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.pixels
            .iter()
            .flat_map(|p| [to_byte(p.x), to_byte(p.y), to_byte(p.z)])
            .collect()
    }
}

/// The course's channel conversion: `(byte)(Math.Min(v, 1) * 255)`, with negatives and NaN as 0.
#[must_use]
#[inline]
pub fn to_byte(v: f32) -> u8 {
    // `f32::min` would turn NaN into 1.0, so NaN is caught first; `as u8` saturates negatives to
    // 0 and truncates like the C# cast.
    if v.is_nan() {
        return 0;
    }
    (v.min(1.0) * 255.0) as u8
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
}
