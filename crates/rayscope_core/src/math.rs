//! Rays, bounding boxes and small vector helpers shared by the whole core.

use glam::{Vec3, Vec3A};
use serde::{Deserialize, Serialize};

use crate::simd::{lane, max_element, maxps, LANES};

/// A ray `origin + t * dir`; `dir` is expected to have unit length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// Start point in world space.
    pub origin: Vec3A,
    /// Unit direction in world space.
    pub dir: Vec3A,
}

impl Ray {
    /// A ray from `origin` along `dir` (which must be normalised).
    #[must_use]
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A) -> Self {
        Self { origin, dir }
    }

    /// The point at parameter `t`.
    #[must_use]
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}

/// Axis-aligned bounding box; an empty box has `min > max`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3A,
    /// Upper corner.
    pub max: Vec3A,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

impl Aabb {
    /// The empty box, identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    /// The smallest box holding both boxes.
    #[must_use]
    #[inline]
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }

    /// The smallest box holding the box and a point.
    #[must_use]
    #[inline]
    pub(crate) fn grow(self, p: Vec3A) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// Half the surface area (enough for SAH ratios); 0 for an empty box.
    #[must_use]
    #[inline]
    pub(crate) fn half_area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3A::ZERO);
        d.x * d.y + d.y * d.z + d.z * d.x
    }

    /// Centre point.
    #[must_use]
    #[inline]
    pub fn center(&self) -> Vec3A {
        (self.min + self.max) * 0.5
    }

    /// True when the box holds no point.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }
}

/// Offset distance that keeps a secondary ray leaving `p` (reached by a ray from `from`) clear of
/// the surface it starts on.
///
/// The rounding error of a hit point grows with the magnitude of the coordinates involved, so the
/// offset is relative: 1e-5 of the largest coordinate, which is the course's 1e-5 at unit scale
/// and keeps scenes from 1e-4 to 1e4 units free of acne.
#[must_use]
#[inline]
pub fn offset_eps(p: Vec3A, from: Vec3A) -> f32 {
    let m = p.abs().max(from.abs()).max_element();
    (1e-5 * m).max(1e-30)
}

/// [`offset_eps`] of lane `i` of points `p` and ray origins `o`: 1e-5 × the largest
/// |coordinate| of either (glam's abs, max and max_element, in that order), at least 1e-30.
#[inline(always)]
pub(crate) fn offset_eps_lane(p: &[[f32; LANES]; 3], o: &[[f32; LANES]; 3], i: usize) -> f32 {
    let m = max_element(std::array::from_fn(|a| maxps(p[a][i].abs(), o[a][i].abs())));
    (1e-5 * m).max(1e-30)
}

/// `!(x <= y)`: true where `x > y` and where either is NaN, so lane code passes exactly the
/// values the single-ray code's `if x <= y { reject }` lets through.
#[must_use]
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub(crate) fn not_at_most(x: f32, y: f32) -> bool {
    !(x <= y)
}

/// An orthonormal basis (t, b, n) around the unit vector `n` (Duff et al. 2017).
#[must_use]
#[inline]
pub fn basis(n: Vec3A) -> (Vec3A, Vec3A) {
    let sign = 1.0_f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3A::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3A::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// [`basis`] of each lane's normal `n` (per axis): the tangents t and b, per axis, in the same
/// operations and order as the one-vector form.
#[must_use]
#[inline(always)]
pub(crate) fn basis_lanes(n: &[[f32; LANES]; 3]) -> ([[f32; LANES]; 3], [[f32; LANES]; 3]) {
    let (mut t, mut b) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3]);
    for i in 0..LANES {
        let (nx, ny, nz) = (n[0][i], n[1][i], n[2][i]);
        let sign = 1.0_f32.copysign(nz);
        let a = -1.0 / (sign + nz);
        let bxy = nx * ny * a;
        (t[0][i], t[1][i], t[2][i]) = (1.0 + sign * nx * nx * a, sign * bxy, -sign * nx);
        (b[0][i], b[1][i], b[2][i]) = (bxy, sign + ny * ny * a, -ny);
    }
    (t, b)
}

/// A plain RGB triple for files and JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Default)]
pub struct Rgb(pub [f32; 3]);

impl From<Vec3> for Rgb {
    fn from(v: Vec3) -> Self {
        Rgb(v.to_array())
    }
}

/// Sixteen rays in structure-of-arrays layout. Unused lanes have `t_max = −∞` and never hit.
#[derive(Debug, Clone)]
// Aligned to a cache line, like the packet code's other sixteen-lane structs: the kernels load
// each sixteen-lane array as 512-bit (or 256-bit) vectors, and a vector that straddles two lines
// costs two loads. Left to the compiler, where such a struct lands on the stack depends on
// unrelated code, and direct-lighting renders move by 4-7 % with it (`rayscope bench render -f
// SCENE -x 4 --stage 2 --threads 1` on course scenes 1 and 2 and `scenes/whitted.txt`).
#[repr(align(64))]
pub struct RayPacket {
    /// Origins, per axis.
    pub o: [[f32; LANES]; 3],
    /// Unit directions, per axis.
    pub d: [[f32; LANES]; 3],
    /// Far end of each ray's interval (the running closest distance during a closest-hit query).
    pub t_max: [f32; LANES],
}

impl Default for RayPacket {
    fn default() -> Self {
        Self {
            o: [[0.0; LANES]; 3],
            d: [[0.0; LANES], [0.0; LANES], [1.0; LANES]],
            t_max: [f32::NEG_INFINITY; LANES],
        }
    }
}

impl RayPacket {
    /// Puts `ray` with interval end `t_max` in lane `i`.
    #[inline]
    pub fn set(&mut self, i: usize, ray: &Ray, t_max: f32) {
        for a in 0..3 {
            self.o[a][i] = ray.origin[a];
            self.d[a][i] = ray.dir[a];
        }
        self.t_max[i] = t_max;
    }

    /// The ray in lane `i`.
    #[inline]
    pub fn ray(&self, i: usize) -> Ray {
        Ray::new(lane(&self.o, i), lane(&self.d, i))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::put;

    #[test]
    fn offset_eps_lane_is_offset_eps_bit_for_bit() {
        let mut rng = crate::rng::Rng::for_sample(5, 6, 7);
        let mut r = move || (rng.next_f32() - 0.5) * 10f32.powi((rng.next_f32() * 10.0) as i32 - 5);
        let (mut p, mut o) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3]);
        for i in 0..LANES {
            for a in 0..3 {
                (p[a][i], o[a][i]) = (r(), r());
            }
        }
        // A NaN coordinate and zero points, where glam's max picks a side.
        p[1][3] = f32::NAN;
        (p[0][5], p[1][5], p[2][5], o[0][5], o[1][5], o[2][5]) = (0.0, -0.0, 0.0, 0.0, 0.0, -0.0);
        for i in 0..LANES {
            let want = offset_eps(lane(&p, i), lane(&o, i));
            assert_eq!(offset_eps_lane(&p, &o, i).to_bits(), want.to_bits(), "lane {i}");
        }
    }

    #[test]
    fn basis_lanes_is_basis_bit_for_bit() {
        let mut rng = crate::rng::Rng::for_sample(8, 9, 10);
        let mut n = [[0.0; LANES]; 3];
        for i in 0..LANES {
            let v = Vec3A::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5);
            put(&mut n, i, v.normalize().to_array());
        }
        // The poles, the pole the frame is singular next to, and signed zeros in z.
        let edges = [
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1e-4, -2e-4, -0.999_999_94],
            [3e-4, 1e-4, -0.999_999_9],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, -0.0],
            [-0.6, 0.8, 0.0],
        ];
        for (i, e) in edges.into_iter().enumerate() {
            put(&mut n, i, e);
        }
        let (t, b) = basis_lanes(&n);
        for i in 0..LANES {
            let (want_t, want_b) = basis(lane(&n, i));
            let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
            assert_eq!(bits(lane(&t, i)), bits(want_t), "lane {i}: t");
            assert_eq!(bits(lane(&b, i)), bits(want_b), "lane {i}: b");
        }
    }
}
