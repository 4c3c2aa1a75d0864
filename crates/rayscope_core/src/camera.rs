//! The course's pinhole/thin-lens camera: left-handed, looking along +z, image plane at 1.

use glam::{Mat3A, Vec2, Vec3, Vec3A};
use serde::{Deserialize, Serialize};

use crate::math::Ray;
use crate::simd::{dispatched, LANES};

/// Which field of view the `fov` angle spans.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum FovAxis {
    /// The angle spans the image's width (the course's spec).
    #[default]
    Horizontal,
    /// The angle spans the image's height (the Unity workshop).
    Vertical,
}

/// Camera placement and lens, in the course's terms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CameraSettings {
    /// Camera position (`--cam-pos`).
    pub position: Vec3,
    /// Rotation axis (`--cam-axis`); any non-zero length.
    pub axis: Vec3,
    /// Rotation angle in degrees (`--cam-angle`).
    pub angle_deg: f32,
    /// Field of view in degrees.
    pub fov_deg: f32,
    /// Which image side the field of view spans.
    pub fov_axis: FovAxis,
    /// Lens radius (`--aperture-radius`); 0 is a pinhole.
    pub aperture_radius: f32,
    /// Distance to the plane in focus (`--focal-length`).
    pub focal_length: f32,
}

impl Default for CameraSettings {
    fn default() -> Self {
        Self {
            position: Vec3::ZERO,
            axis: Vec3::Z,
            angle_deg: 0.0,
            fov_deg: 60.0,
            fov_axis: FovAxis::Horizontal,
            aperture_radius: 0.0,
            focal_length: 1.0,
        }
    }
}

/// A camera ready to generate rays for a `width` × `height` image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Settings it was made from.
    pub settings: CameraSettings,
    /// world_from_camera rotation (Rodrigues about the axis).
    pub rotation: Mat3A,
    /// Position.
    pub origin: Vec3A,
    /// Half extent of the image plane at distance 1, (x, y).
    pub half: Vec2,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Camera {
    /// A camera for an image of `width` × `height` pixels.
    #[must_use]
    pub fn new(settings: CameraSettings, width: u32, height: u32) -> Self {
        let t = (settings.fov_deg.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        let half = match settings.fov_axis {
            FovAxis::Horizontal => Vec2::new(t, t / aspect),
            FovAxis::Vertical => Vec2::new(t * aspect, t),
        };
        Self {
            settings,
            rotation: rodrigues(settings.axis, settings.angle_deg),
            origin: settings.position.into(),
            half,
            width,
            height,
        }
    }

    /// The point on the image plane (camera space, z = 1) at normalised image coordinates
    /// (`u`, `v`) ∈ [0, 1]², origin top-left, +v down.
    #[must_use]
    #[inline]
    pub(crate) fn plane_point_camera(&self, u: f32, v: f32) -> Vec3A {
        Vec3A::new((2.0 * u - 1.0) * self.half.x, (1.0 - 2.0 * v) * self.half.y, 1.0)
    }

    /// The same point in world space.
    #[must_use]
    #[inline]
    pub fn plane_point_world(&self, u: f32, v: f32) -> Vec3A {
        self.origin + self.rotation * self.plane_point_camera(u, v)
    }

    /// The pinhole ray through normalised image coordinates (`u`, `v`).
    #[must_use]
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> Ray {
        Ray::new(self.origin, (self.rotation * self.plane_point_camera(u, v)).normalize())
    }

    /// The directions of [`Self::ray`] through `N` image positions at once, per axis: the
    /// same arithmetic in the same order, laid out so the compiler can vectorise it.
    #[must_use]
    #[inline]
    pub(crate) fn ray_dirs<const N: usize>(&self, u: &[f32; N], v: &[f32; N]) -> [[f32; N]; 3] {
        let r = [
            self.rotation.x_axis.to_array(),
            self.rotation.y_axis.to_array(),
            self.rotation.z_axis.to_array(),
        ];
        let mut d = [[0.0; N]; 3];
        for i in 0..N {
            let c = [(2.0 * u[i] - 1.0) * self.half.x, (1.0 - 2.0 * v[i]) * self.half.y, 1.0];
            // glam's matrix × vector: the columns scaled by x, y and z, summed in that order.
            let mut w = [0.0; 3];
            for a in 0..3 {
                w[a] = r[0][a] * c[0] + r[1][a] * c[1] + r[2][a] * c[2];
            }
            // glam's normalize: divided by the length, x² + y² + z² summed in that order.
            let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            for a in 0..3 {
                d[a][i] = w[a] / len;
            }
        }
        d
    }

    /// The thin-lens ray through (`u`, `v`) from lens sample `lens` ∈ unit disk.
    ///
    /// The surface in focus is the plane z = focal length in camera space, so straight lines stay
    /// straight and the image matches the pinhole's framing at that distance.
    #[must_use]
    #[inline]
    pub fn lens_ray(&self, u: f32, v: f32, lens: Vec2) -> Ray {
        let r = self.settings.aperture_radius;
        if r <= 0.0 {
            return self.ray(u, v);
        }
        let p = self.plane_point_camera(u, v) * self.settings.focal_length;
        let o = Vec3A::new(lens.x * r, lens.y * r, 0.0);
        Ray::new(self.origin + self.rotation * o, (self.rotation * (p - o)).normalize())
    }

    /// The rays of [`Self::lens_ray`] through `N` image positions (`u`, `v`) from the points
    /// `lens` of the unit disk, per axis: origins and directions, the same arithmetic in the
    /// same order, laid out so the compiler can vectorise it. For a camera with an aperture
    /// (where `lens_ray` gives the pinhole's ray, this does not).
    #[must_use]
    #[inline]
    pub(crate) fn lens_rays<const N: usize>(
        &self,
        u: &[f32; N],
        v: &[f32; N],
        lens: &[[f32; N]; 2],
    ) -> ([[f32; N]; 3], [[f32; N]; 3]) {
        let (r, f) = (self.settings.aperture_radius, self.settings.focal_length);
        let m = [
            self.rotation.x_axis.to_array(),
            self.rotation.y_axis.to_array(),
            self.rotation.z_axis.to_array(),
        ];
        let origin = self.origin.to_array();
        let (mut o, mut d) = ([[0.0; N]; 3], [[0.0; N]; 3]);
        for i in 0..N {
            let p = [
                (2.0 * u[i] - 1.0) * self.half.x * f,
                (1.0 - 2.0 * v[i]) * self.half.y * f,
                1.0 * f,
            ];
            let l = [lens[0][i] * r, lens[1][i] * r, 0.0];
            let q = [p[0] - l[0], p[1] - l[1], p[2] - l[2]];
            // glam's matrix × vector: the columns scaled by x, y and z, summed in that order.
            let mut w = [0.0; 3];
            for a in 0..3 {
                o[a][i] = origin[a] + (m[0][a] * l[0] + m[1][a] * l[1] + m[2][a] * l[2]);
                w[a] = m[0][a] * q[0] + m[1][a] * q[1] + m[2][a] * q[2];
            }
            // glam's normalize: divided by the length, x² + y² + z² summed in that order.
            let len = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
            for a in 0..3 {
                d[a][i] = w[a] / len;
            }
        }
        (o, d)
    }

    /// Normalised image coordinates of the centre of pixel (`x`, `y`).
    #[must_use]
    #[inline]
    pub fn pixel_center(&self, x: u32, y: u32) -> (f32, f32) {
        (
            (x as f32 + 0.5) / self.width as f32,
            (y as f32 + 0.5) / self.height as f32,
        )
    }

    /// Projects a world point onto the image plane: normalised (u, v) and camera-space depth.
    #[must_use]
    pub fn project(&self, p: Vec3A) -> Option<(f32, f32, f32)> {
        let c = self.rotation.transpose() * (p - self.origin);
        if c.z <= 0.0 {
            return None;
        }
        let x = c.x / c.z / self.half.x;
        let y = c.y / c.z / self.half.y;
        Some(((x + 1.0) * 0.5, (1.0 - y) * 0.5, c.z))
    }
}

/// The rotation by `angle_deg` degrees about `axis` (Rodrigues' formula); identity for a zero axis.
#[must_use]
pub fn rodrigues(axis: Vec3, angle_deg: f32) -> Mat3A {
    let k = axis.normalize_or_zero();
    if k == Vec3::ZERO || angle_deg == 0.0 {
        return Mat3A::IDENTITY;
    }
    // glam's from_axis_angle is the same formula: R v = v cosθ + (k × v) sinθ + k (k·v)(1 − cosθ).
    Mat3A::from_axis_angle(k, angle_deg.to_radians())
}

/// The centre of cell `cell` of the `n` × `n` grid of `-x n` inside its pixel, as an offset in
/// pixels from the pixel's top-left corner: cell (i, j) = (`cell` mod n, `cell` / n) is centred
/// at ((i + 0.5)/n, (j + 0.5)/n).
#[must_use]
#[inline]
pub(crate) fn cell_centre(cell: u32, n: u32) -> [f32; 2] {
    let (i, j) = (cell % n, cell / n);
    [(i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32]
}

/// A coordinate `centre` of a cell of an `n` × `n` grid moved across the cell by the uniform
/// random number `r` ∈ [0, 1): stratified jitter, for one ray or lane by lane.
#[must_use]
#[inline(always)]
pub(crate) fn jittered(centre: f32, r: f32, n: f32) -> f32 {
    centre + (r - 0.5) / n
}

dispatched!(
    /// [`camera_dirs`] with the best instruction set the CPU has.
    best_camera_dirs, camera_dirs_avx512, camera_dirs_avx2,
    (camera: &Camera, px: &[f32; LANES], py: &[f32; LANES], w: f32, h: f32) -> [[f32; LANES]; 3],
    {
        let (mut u, mut v) = ([0.0; LANES], [0.0; LANES]);
        for i in 0..LANES {
            (u[i], v[i]) = (px[i] / w, py[i] / h);
        }
        camera.ray_dirs(&u, &v)
    }
);

/// Directions of the pinhole camera rays through pixel positions (`px`, `py`) (pixels, not
/// normalised) of a `w` × `h` image: `Camera::ray_dirs` of (`px`/`w`, `py`/`h`), sixteen lanes
/// at once.
// Calls the dispatcher rather than being it (see `crate::simd::dispatched`).
#[must_use]
pub fn camera_dirs(camera: &Camera, px: &[f32; LANES], py: &[f32; LANES], w: f32, h: f32) -> [[f32; LANES]; 3] {
    best_camera_dirs(camera, px, py, w, h)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_is_forward_and_corners_span_fov() {
        let cam = Camera::new(CameraSettings::default(), 400, 200);
        let r = cam.ray(0.5, 0.5);
        assert!((r.dir - Vec3A::Z).length() < 1e-6);
        let left = cam.ray(0.0, 0.5).dir;
        let right = cam.ray(1.0, 0.5).dir;
        let angle = left.angle_between(right).to_degrees();
        assert!((angle - 60.0).abs() < 1e-3, "horizontal FOV {angle}");
        // Top edge: half of the horizontal extent for a 2:1 image.
        assert!((cam.plane_point_camera(0.5, 0.0).y - (30f32.to_radians().tan() / 2.0)).abs() < 1e-6);
        assert!(cam.plane_point_camera(0.0, 0.0).y > 0.0, "row 0 is the top");
    }

    #[test]
    fn jittered_cells_tile_the_pixel() {
        for n in 1..5u32 {
            let nf = n as f32;
            for cell in 0..n * n {
                let [cx, cy] = cell_centre(cell, n);
                let (i, j) = ((cell % n) as f32, (cell / n) as f32);
                assert_eq!([cx, cy], [(i + 0.5) / nf, (j + 0.5) / nf]);
                for r in [0.0, 0.25, 0.5, 0.999_999] {
                    let (x, y) = (jittered(cx, r, nf), jittered(cy, r, nf));
                    assert!(x >= i / nf - 1e-6 && x < (i + 1.0) / nf + 1e-6, "{n} {cell} {r}: {x}");
                    assert!(y >= j / nf - 1e-6 && y < (j + 1.0) / nf + 1e-6, "{n} {cell} {r}: {y}");
                }
                assert_eq!(jittered(cx, 0.5, nf), cx, "the middle of the range is the centre");
            }
        }
    }

    #[test]
    fn ray_dirs_are_ray_bit_for_bit() {
        let s = CameraSettings {
            axis: Vec3::new(0.3, -1.0, 0.2),
            angle_deg: 37.0,
            position: Vec3::new(0.5, 1.0, -2.0),
            ..CameraSettings::default()
        };
        for cam in [
            Camera::new(s, 640, 360),
            Camera::new(CameraSettings::default(), 97, 211),
        ] {
            let u: [f32; 8] = std::array::from_fn(|i| (i as f32 + 0.37) / 8.0);
            let v: [f32; 8] = std::array::from_fn(|i| 1.0 - (i as f32 * 0.61) / 5.0);
            let d = cam.ray_dirs(&u, &v);
            for i in 0..8 {
                let r = cam.ray(u[i], v[i]).dir;
                for a in 0..3 {
                    assert_eq!(d[a][i].to_bits(), r[a].to_bits(), "lane {i} axis {a}");
                }
            }
        }
    }

    #[test]
    fn lens_rays_are_lens_ray_bit_for_bit() {
        let s = CameraSettings {
            axis: Vec3::new(0.3, -1.0, 0.2),
            angle_deg: 37.0,
            position: Vec3::new(0.5, 1.0, -2.0),
            aperture_radius: 0.1,
            focal_length: 3.6,
            ..CameraSettings::default()
        };
        for cam in [
            Camera::new(s, 640, 360),
            Camera::new(
                CameraSettings {
                    aperture_radius: 0.7,
                    focal_length: 12.5,
                    ..CameraSettings::default()
                },
                97,
                211,
            ),
        ] {
            let u: [f32; 8] = std::array::from_fn(|i| (i as f32 + 0.37) / 8.0);
            let v: [f32; 8] = std::array::from_fn(|i| 1.0 - (i as f32 * 0.61) / 5.0);
            // The lens's centre, its rim and points inside.
            let lx = [0.0, 1.0, -0.3, 0.6, -0.707, 0.05, 0.0, -1.0];
            let ly = [0.0, 0.0, 0.4, -0.6, -0.707, 0.9, -1.0, 0.0];
            let (o, d) = cam.lens_rays(&u, &v, &[lx, ly]);
            for i in 0..8 {
                let r = cam.lens_ray(u[i], v[i], Vec2::new(lx[i], ly[i]));
                for a in 0..3 {
                    assert_eq!(o[a][i].to_bits(), r.origin[a].to_bits(), "lane {i} axis {a}");
                    assert_eq!(d[a][i].to_bits(), r.dir[a].to_bits(), "lane {i} axis {a}");
                }
            }
        }
    }

    #[test]
    fn vertical_fov_axis() {
        let s = CameraSettings {
            fov_axis: FovAxis::Vertical,
            ..CameraSettings::default()
        };
        let cam = Camera::new(s, 400, 200);
        let a = cam.ray(0.5, 0.0).dir.angle_between(cam.ray(0.5, 1.0).dir).to_degrees();
        assert!((a - 60.0).abs() < 1e-3);
    }

    #[test]
    fn rodrigues_matches_the_course() {
        // Axis (1,0,0), +45°: (0,0,1) → (0, −0.707, 0.707): the camera looks down.
        let r = rodrigues(Vec3::X, 45.0) * Vec3A::Z;
        assert!(
            (r - Vec3A::new(0.0, -std::f32::consts::FRAC_1_SQRT_2, std::f32::consts::FRAC_1_SQRT_2)).length() < 1e-6
        );
        // Axis is normalised.
        let r2 = rodrigues(Vec3::X * 7.0, 45.0) * Vec3A::Z;
        assert!((r - r2).length() < 1e-6);
    }

    #[test]
    fn projection_inverts_ray() {
        let s = CameraSettings {
            position: Vec3::new(1.0, 2.0, -3.0),
            axis: Vec3::new(0.3, 1.0, 0.2),
            angle_deg: 33.0,
            ..Default::default()
        };
        let cam = Camera::new(s, 320, 240);
        let r = cam.ray(0.2, 0.7);
        let (u, v, z) = cam.project(r.at(5.0)).unwrap();
        assert!((u - 0.2).abs() < 1e-5 && (v - 0.7).abs() < 1e-5 && z > 0.0);
    }
}
