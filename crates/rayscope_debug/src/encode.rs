//! PNG and JPEG encoding of RGB frames.

use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder};

use crate::view::RgbImage;

/// Encodes an RGB image as PNG (fast compression: frames are sent often).
///
/// # Panics
/// If `img.rgb` does not hold `width × height × 3` bytes.
#[must_use]
pub fn png(img: &RgbImage) -> Vec<u8> {
    png_with(img, CompressionType::Fast, FilterType::Sub)
}

/// Encodes an RGB image as small a PNG as the encoder manages (for files).
///
/// # Panics
/// If `img.rgb` does not hold `width × height × 3` bytes.
#[must_use]
pub fn png_small(img: &RgbImage) -> Vec<u8> {
    png_with(img, CompressionType::Best, FilterType::Adaptive)
}

fn png_with(img: &RgbImage, compression: CompressionType, filter: FilterType) -> Vec<u8> {
    let mut out = Vec::new();
    PngEncoder::new_with_quality(&mut out, compression, filter)
        .write_image(&img.rgb, img.width, img.height, ExtendedColorType::Rgb8)
        .expect("encoding a PNG into memory cannot fail for a well-formed image");
    out
}

/// Encodes an RGB image as JPEG at `quality` (1–100).
///
/// # Panics
/// If `img.rgb` does not hold `width × height × 3` bytes.
#[must_use]
pub fn jpeg(img: &RgbImage, quality: u8) -> Vec<u8> {
    let mut out = Vec::new();
    JpegEncoder::new_with_quality(&mut out, quality.clamp(1, 100))
        .write_image(&img.rgb, img.width, img.height, ExtendedColorType::Rgb8)
        .expect("encoding a JPEG into memory cannot fail for a well-formed image");
    out
}
