//! The scene view's frame buffer and its 2D/3D drawing primitives: anti-aliased, depth-tested
//! lines and dots over a colour + depth + id buffer, and a tiny bitmap font for the axis gizmo.
//!
//! Lines are rasterised by coverage: every pixel within half a line width (+ half a pixel) of
//! the projected segment gets `clamp(w/2 + 0.5 − distance, 0, 1)` of the line's colour. Depth is
//! interpolated as 1/z in screen space (perspective-correct) and tested against the depth buffer
//! the scene pass wrote; hidden parts are drawn at `hidden_alpha` of their opacity ("x-ray").

use glam::{Vec2, Vec3, Vec4};

/// No object at this pixel.
pub const ID_NONE: u32 = u32::MAX;

/// A linear RGB frame with camera-space depth and an object id per pixel.
#[derive(Debug, Clone)]
pub struct Canvas {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Colours, row-major from the top-left.
    pub color: Vec<Vec3>,
    /// Camera-space depth (distance along the view direction); infinity where nothing was hit.
    pub depth: Vec<f32>,
    /// Object id per pixel ([`ID_NONE`] for the sky).
    pub id: Vec<u32>,
    /// Opacity multiplier of occluded line parts (0 hides them).
    pub hidden_alpha: f32,
}

/// A point projected to the screen: pixel position, and 1/z for depth interpolation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScreenPoint {
    /// Pixel position (continuous; pixel centres at +0.5).
    pub p: Vec2,
    /// Reciprocal of the camera-space depth.
    pub inv_z: f32,
}

impl Canvas {
    /// A canvas of `width` × `height` with the given buffers already filled by the scene pass.
    #[must_use]
    pub fn new(width: u32, height: u32, color: Vec<Vec3>, depth: Vec<f32>, id: Vec<u32>) -> Self {
        Self {
            width,
            height,
            color,
            depth,
            id,
            hidden_alpha: 0.0,
        }
    }

    #[inline]
    fn blend(&mut self, i: usize, c: Vec3, a: f32) {
        let d = &mut self.color[i];
        *d = *d * (1.0 - a) + c * a;
    }

    /// Alpha for a fragment at depth `z` over pixel `i` (depth test with a relative bias).
    #[inline]
    fn depth_factor(&self, i: usize, z: f32, bias: f32) -> f32 {
        if z <= self.depth[i] * (1.0 + bias) + bias {
            1.0
        } else {
            self.hidden_alpha
        }
    }

    /// Draws the screen-space segment `a`→`b` with per-end colours (RGBA, straight alpha),
    /// `width` pixels wide, depth-tested. `persp` interpolates colours in world space.
    #[allow(clippy::too_many_arguments)]
    pub fn segment(&mut self, a: ScreenPoint, b: ScreenPoint, ca: Vec4, cb: Vec4, width: f32, bias: f32, fade_z: f32) {
        let hw = (width * 0.5).max(0.35);
        let reach = hw + 1.0;
        // Clip against the screen rectangle grown by the reach (Liang–Barsky), in f64: an end
        // near the view's near plane projects very far off screen.
        let (w, h) = (self.width as f32, self.height as f32);
        let (ax, ay) = (f64::from(a.p.x), f64::from(a.p.y));
        let (dx, dy) = (f64::from(b.p.x) - ax, f64::from(b.p.y) - ay);
        let r = f64::from(reach);
        let mut s0 = 0.0f64;
        let mut s1 = 1.0f64;
        for (p, q) in [
            (-dx, ax + r),
            (dx, f64::from(w) + r - ax),
            (-dy, ay + r),
            (dy, f64::from(h) + r - ay),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    return;
                }
            } else {
                let t = q / p;
                if p < 0.0 {
                    s0 = s0.max(t);
                } else {
                    s1 = s1.min(t);
                }
            }
        }
        if s0 > s1 || !s0.is_finite() || !s1.is_finite() {
            return;
        }
        // Re-base the segment on its visible part (colours perspective-correct at the cuts).
        let at = |s: f64| {
            let inv_z = a.inv_z + (b.inv_z - a.inv_z) * s as f32;
            let sw = if inv_z > 0.0 && b.inv_z != a.inv_z {
                (s as f32 * b.inv_z / inv_z).clamp(0.0, 1.0)
            } else {
                s as f32
            };
            (
                ScreenPoint {
                    p: Vec2::new((ax + dx * s) as f32, (ay + dy * s) as f32),
                    inv_z,
                },
                ca + (cb - ca) * sw,
            )
        };
        let ((a, ca), (b, cb)) = (at(s0), at(s1));
        let (s0, s1) = (0.0f32, 1.0f32);
        let d = b.p - a.p;
        let (pa, pb) = (a.p, b.p);
        let len2 = d.length_squared();
        let steep = d.y.abs() > d.x.abs();
        // Walk the major axis one pixel at a time; cover a band across the minor axis.
        let (lo, hi) = if steep {
            (pa.y.min(pb.y) - reach, pa.y.max(pb.y) + reach)
        } else {
            (pa.x.min(pb.x) - reach, pa.x.max(pb.x) + reach)
        };
        let lim_major = if steep { h } else { w };
        let lim_minor = if steep { w } else { h };
        let i0 = lo.floor().max(0.0) as i64;
        let i1 = (hi.ceil().min(lim_major) as i64) - 1;
        let slope = if steep {
            if d.y != 0.0 {
                d.x / d.y
            } else {
                0.0
            }
        } else if d.x != 0.0 {
            d.y / d.x
        } else {
            0.0
        };
        let band = reach * (1.0 + slope.abs()) + 1.0;
        for i in i0..=i1 {
            let m = i as f32 + 0.5;
            // Minor coordinate of the line at this major coordinate.
            let c = if steep {
                a.p.x + (m - a.p.y) * slope
            } else {
                a.p.y + (m - a.p.x) * slope
            };
            let j0 = (c - band).floor().max(0.0) as i64;
            let j1 = ((c + band).ceil().min(lim_minor) as i64) - 1;
            for j in j0..=j1 {
                let (x, y) = if steep { (j, i) } else { (i, j) };
                let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let s = if len2 > 0.0 {
                    ((q - a.p).dot(d) / len2).clamp(s0, s1)
                } else {
                    0.0
                };
                let dist = (q - (a.p + d * s)).length();
                let cov = (hw + 0.5 - dist).clamp(0.0, 1.0);
                if cov <= 0.0 {
                    continue;
                }
                let inv_z = a.inv_z + (b.inv_z - a.inv_z) * s;
                if inv_z <= 0.0 {
                    continue;
                }
                let z = 1.0 / inv_z;
                // World-space parameter for colour interpolation (perspective-correct).
                let sw = if (b.inv_z - a.inv_z).abs() > 0.0 {
                    (s * b.inv_z) / inv_z
                } else {
                    s
                };
                let col = ca + (cb - ca) * sw.clamp(0.0, 1.0);
                let idx = y as usize * self.width as usize + x as usize;
                let mut alpha = cov * col.w * self.depth_factor(idx, z, bias);
                if fade_z > 0.0 {
                    alpha *= (1.0 - z / fade_z).clamp(0.0, 1.0);
                }
                if alpha > 0.0 {
                    self.blend(idx, col.truncate(), alpha.min(1.0));
                }
            }
        }
    }

    /// A filled, anti-aliased disc of `radius` pixels with a `ring` outline, depth-tested at `z`.
    pub fn dot(&mut self, at: ScreenPoint, radius: f32, fill: Vec4, ring: Vec4, bias: f32) {
        let z = 1.0 / at.inv_z;
        let r = radius + 1.0;
        let x0 = (at.p.x - r).floor().max(0.0) as i64;
        let x1 = ((at.p.x + r).ceil().min(self.width as f32) as i64) - 1;
        let y0 = (at.p.y - r).floor().max(0.0) as i64;
        let y1 = ((at.p.y + r).ceil().min(self.height as f32) as i64) - 1;
        for y in y0..=y1 {
            for x in x0..=x1 {
                let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let d = (q - at.p).length();
                let cov = (radius + 0.5 - d).clamp(0.0, 1.0);
                if cov <= 0.0 {
                    continue;
                }
                let idx = y as usize * self.width as usize + x as usize;
                let k = self.depth_factor(idx, z, bias);
                let inner = (radius - 1.3 - d + 0.5).clamp(0.0, 1.0);
                let col = ring + (fill - ring) * inner;
                let a = cov * col.w * k;
                if a > 0.0 {
                    self.blend(idx, col.truncate(), a);
                }
            }
        }
    }

    /// An undepth-tested 2D line (for the gizmo), `width` pixels wide.
    pub fn line_2d(&mut self, a: Vec2, b: Vec2, color: Vec4, width: f32) {
        let pa = ScreenPoint { p: a, inv_z: 1.0 };
        let pb = ScreenPoint { p: b, inv_z: 1.0 };
        let saved = std::mem::replace(&mut self.hidden_alpha, 1.0);
        self.segment(pa, pb, color, color, width, f32::INFINITY, 0.0);
        self.hidden_alpha = saved;
    }

    /// Draws `text` (letters x, y, z, digits and a few symbols) with its top-left corner at
    /// `at`, `scale` pixels per font cell.
    pub fn text(&mut self, at: Vec2, text: &str, scale: u32, color: Vec4) {
        let mut x = at.x as i64;
        for ch in text.chars() {
            let rows = glyph(ch);
            for (r, bits) in rows.iter().enumerate() {
                for c in 0..3 {
                    if bits & (0b100 >> c) != 0 {
                        for dy in 0..scale as i64 {
                            for dx in 0..scale as i64 {
                                let px = x + c * scale as i64 + dx;
                                let py = at.y as i64 + r as i64 * scale as i64 + dy;
                                if px >= 0 && py >= 0 && (px as u32) < self.width && (py as u32) < self.height {
                                    let idx = py as usize * self.width as usize + px as usize;
                                    self.blend(idx, color.truncate(), color.w);
                                }
                            }
                        }
                    }
                }
            }
            x += 4 * scale as i64;
        }
    }

    /// The frame as 8-bit sRGB-ish RGB (values are already display values; clamped).
    #[must_use]
    pub fn to_rgb8(&self) -> Vec<u8> {
        self.color
            .iter()
            .flat_map(|c| {
                let c = c.clamp(Vec3::ZERO, Vec3::ONE) * 255.0 + Vec3::splat(0.5);
                [c.x as u8, c.y as u8, c.z as u8]
            })
            .collect()
    }
}

/// A 3×5 bitmap glyph, one row per entry, bit 2 is the left column.
fn glyph(ch: char) -> [u8; 5] {
    match ch.to_ascii_lowercase() {
        'x' => [0b101, 0b101, 0b010, 0b101, 0b101],
        'y' => [0b101, 0b101, 0b010, 0b010, 0b010],
        'z' => [0b111, 0b001, 0b010, 0b100, 0b111],
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        ',' => [0b000, 0b000, 0b000, 0b010, 0b100],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        '(' => [0b010, 0b100, 0b100, 0b100, 0b010],
        ')' => [0b010, 0b001, 0b001, 0b001, 0b010],
        _ => [0; 5],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blank(w: u32, h: u32) -> Canvas {
        let n = (w * h) as usize;
        Canvas::new(w, h, vec![Vec3::ZERO; n], vec![f32::INFINITY; n], vec![ID_NONE; n])
    }

    fn sp(x: f32, y: f32) -> ScreenPoint {
        ScreenPoint {
            p: Vec2::new(x, y),
            inv_z: 1.0,
        }
    }

    #[test]
    fn horizontal_line_covers_its_row_only() {
        let mut c = blank(20, 10);
        let white = Vec4::ONE;
        c.segment(sp(2.0, 5.5), sp(18.0, 5.5), white, white, 1.0, 0.0, 0.0);
        for x in 3..17 {
            assert!(c.color[5 * 20 + x].x > 0.99, "x={x}");
            assert!(c.color[3 * 20 + x].x < 0.01);
            assert!(c.color[7 * 20 + x].x < 0.01);
        }
        assert!(c.color[5 * 20].x < 0.01, "nothing left of the start");
    }

    #[test]
    fn depth_test_hides_lines_behind_surfaces() {
        let mut c = blank(10, 10);
        for d in &mut c.depth {
            *d = 0.5;
        }
        let a = ScreenPoint {
            p: Vec2::new(0.0, 5.5),
            inv_z: 1.0,
        };
        let b = ScreenPoint {
            p: Vec2::new(10.0, 5.5),
            inv_z: 1.0,
        };
        c.segment(a, b, Vec4::ONE, Vec4::ONE, 1.0, 1e-3, 0.0);
        assert!(c.color[55].x < 0.01, "line at z = 1 is behind the surface at 0.5");
        c.hidden_alpha = 0.5;
        c.segment(a, b, Vec4::ONE, Vec4::ONE, 1.0, 1e-3, 0.0);
        assert!((c.color[55].x - 0.5).abs() < 0.02);
    }

    #[test]
    fn steep_and_offscreen_lines_do_not_panic() {
        let mut c = blank(16, 16);
        c.segment(sp(-100.0, -50.0), sp(300.0, 900.0), Vec4::ONE, Vec4::ONE, 3.0, 0.0, 0.0);
        c.segment(sp(8.5, -1e9), sp(8.5, 1e9), Vec4::ONE, Vec4::ONE, 1.0, 0.0, 0.0);
        c.segment(sp(5.0, 5.0), sp(5.0, 5.0), Vec4::ONE, Vec4::ONE, 2.0, 0.0, 0.0);
        c.dot(sp(-3.0, 8.0), 4.0, Vec4::ONE, Vec4::ONE, 0.0);
        c.text(Vec2::new(14.0, 14.0), "xyz", 2, Vec4::ONE);
        assert!(c.color[8 * 16 + 8].x > 0.9);
    }
}
