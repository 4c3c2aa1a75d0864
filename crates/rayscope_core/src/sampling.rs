//! Sampling routines for the stage-3 integrator: disk, cosine hemisphere, cones, spheres,
//! triangles and the GGX distribution of visible normals, each with the density it draws from;
//! the frame change to world space, the power heuristic and Russian roulette.
//!
//! Densities are in solid angle (directions) or area (points). Every routine here has a χ²
//! goodness-of-fit test in `tests/stage3_sampling.rs`. The cosine warp and the frame change
//! also have lane forms for the path-tracing wave, tested below to return the one-vector
//! forms' bits.

use std::f32::consts::{FRAC_1_PI, FRAC_PI_2, FRAC_PI_4, PI};

use glam::{Vec2, Vec3, Vec3A};

use crate::simd::{sel, LANES};

/// Uniform point on the unit disk from two uniform numbers (Shirley–Chiu concentric mapping).
#[must_use]
#[inline]
pub(crate) fn concentric_disk(u1: f32, u2: f32) -> Vec2 {
    let a = 2.0 * u1 - 1.0;
    let b = 2.0 * u2 - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    if a.abs() > b.abs() {
        let (sin, cos) = sin_cos_eighth(FRAC_PI_4 * (b / a));
        Vec2::new(a * cos, a * sin)
    } else {
        // The angle is π/2 − x, whose cosine is sin x and whose sine is cos x.
        let (sin, cos) = sin_cos_eighth(FRAC_PI_4 * (a / b));
        Vec2::new(b * sin, b * cos)
    }
}

/// `(sin x, cos x)` for `|x| ≤ π/4`, within 5e-8 of the exact values (libm's own error is 3e-8).
///
/// The polynomials are least-squares fits on that interval alone, so no range reduction is
/// needed; libm's `sincosf` had been 3.6 % of a path-traced box's time, nearly all of it from
/// sampling cosine-weighted bounces.
#[must_use]
#[inline]
pub(crate) fn sin_cos_eighth(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = x + x * z * (-0.166_666_51 + z * (0.008_331_979 + z * -0.000_194_956_35));
    // 1 − z/2 is rounded once and its rounding error added back with the small terms, which
    // keeps the cosine within one ulp near 1.
    let half = 0.5 * z;
    let head = 1.0 - half;
    let tail = z * z * (0.041_666_646 + z * (-0.001_388_736_8 + z * 0.000_024_438_45));
    (sin, head + (((1.0 - head) - half) + tail))
}

/// `(cos φ, sin φ)` for φ = 2π·u − π/4: for a uniform u in [0, 1), a uniform point on the unit
/// circle. The quarter turn u falls in is taken by swapping signs (exact), the angle within
/// it, in [−π/4, π/4), by [`sin_cos_eighth`]: no range reduction and no library call.
#[must_use]
#[inline(always)]
pub(crate) fn circle_point(u: f32) -> (f32, f32) {
    let t = 4.0 * u;
    let quarter = t.min(3.0).floor();
    let (s, c) = sin_cos_eighth((t - quarter - 0.5) * FRAC_PI_2);
    let (c, s) = if quarter >= 2.0 { (-c, -s) } else { (c, s) };
    if quarter == 1.0 || quarter == 3.0 {
        (-s, c)
    } else {
        (c, s)
    }
}

/// Cosine-weighted direction about +z (Malley's method); density `cosθ / π`.
#[must_use]
#[inline]
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3A {
    let d = concentric_disk(u1, u2);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3A::new(d.x, d.y, z)
}

/// [`cosine_hemisphere`] in lane form: the same direction with no branch, so that a loop over
/// sixteen lanes calling it vectorises (both of the disk's quotients are warped and one kept,
/// and the centre, where the quotient is 0/0, is set apart). Its loop is
/// [`crate::bsdf::lambert_sample_lanes`], whose body it is most of: a loop of the warp alone
/// is small enough for the compiler to unroll it before vectorising, and then it does not.
#[must_use]
#[inline(always)]
pub(crate) fn cosine_hemisphere_lane(u1: f32, u2: f32) -> [f32; 3] {
    let [x, y] = concentric_disk_lane(u1, u2);
    [x, y, (1.0 - (x * x + y * y)).max(0.0).sqrt()]
}

/// [`concentric_disk`] in lane form: the same point with no branch (both of the disk's
/// quotients are warped and one kept, and the centre, where the quotient is 0/0, is set apart),
/// so that a loop over lanes calling it vectorises.
#[must_use]
#[inline(always)]
pub(crate) fn concentric_disk_lane(u1: f32, u2: f32) -> [f32; 2] {
    let (a, b) = (2.0 * u1 - 1.0, 2.0 * u2 - 1.0);
    let wide = a.abs() > b.abs();
    let (sin, cos) = sin_cos_eighth(FRAC_PI_4 * if wide { b / a } else { a / b });
    let (x, y) = if wide { (a * cos, a * sin) } else { (b * sin, b * cos) };
    let (x, y) = if (a == 0.0) & (b == 0.0) { (0.0, 0.0) } else { (x, y) };
    [x, y]
}

/// Density of [`cosine_hemisphere`] for a direction with cosine `cos_theta` to +z.
#[must_use]
#[inline]
pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * FRAC_1_PI
}

/// Uniform direction about +z inside the cone whose half-angle has `1 − cosθmax = omc` (passing
/// `1 − cos` keeps small cones exact in f32); density `1 / (2π · omc)`.
#[must_use]
#[inline]
pub(crate) fn uniform_cone(u1: f32, u2: f32, omc: f32) -> Vec3A {
    let x = u1 * omc; // 1 − cosθ
    let cos = 1.0 - x;
    let sin = (x * (2.0 - x)).max(0.0).sqrt();
    let (c, s) = circle_point(u2);
    Vec3A::new(sin * c, sin * s, cos)
}

/// Density of [`uniform_cone`] inside the cone.
#[must_use]
#[inline]
pub(crate) fn uniform_cone_pdf(omc: f32) -> f32 {
    1.0 / (2.0 * PI * omc)
}

/// Uniform direction on the unit sphere; density `1 / (4π)`.
#[must_use]
#[inline]
pub fn uniform_sphere(u1: f32, u2: f32) -> Vec3A {
    let z = 1.0 - 2.0 * u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (c, s) = circle_point(u2);
    Vec3A::new(r * c, r * s, z)
}

/// Uniform barycentrics (b1, b2) on a triangle (weights of v1 and v2), the square-root mapping.
#[must_use]
#[inline]
pub(crate) fn uniform_triangle(u1: f32, u2: f32) -> (f32, f32) {
    let s = u1.sqrt();
    (s * (1.0 - u2), s * u2)
}

/// `atan r` for `|r| ≤ 1`, within 2e-7 of the exact value, without a library call (libm's
/// `atanf` may take another code path on another instruction set, and renders must not change
/// with the CPU) and without branches, so that a loop over lanes vectorises.
#[must_use]
#[inline(always)]
pub(crate) fn atan_unit(r: f32) -> f32 {
    let a = r.abs();
    // Above tan(π/8), atan a = π/4 + atan((a − 1)/(a + 1)) brings the argument within
    // ±tan(π/8), where each term of the series is at most a sixth of the one before.
    let big = a > 0.414_213_57;
    let x = sel(big, (a - 1.0) / (a + 1.0), a);
    let z = x * x;
    // The Taylor series to x^17: the first term left out is below 3e-9.
    let series = -1.0 / 3.0
        + z * (1.0 / 5.0
            + z * (-1.0 / 7.0
                + z * (1.0 / 9.0 + z * (-1.0 / 11.0 + z * (1.0 / 13.0 + z * (-1.0 / 15.0 + z * (1.0 / 17.0)))))));
    let y = x + x * z * series;
    sel(big, FRAC_PI_4 + y, y).copysign(r)
}

/// The angle of the point (x, y) with `y ≥ 0`, in [0, π], by [`atan_unit`]; NaN at the origin.
#[must_use]
#[inline(always)]
pub(crate) fn angle_upper(y: f32, x: f32) -> f32 {
    let flat = y <= x.abs();
    let at = atan_unit(sel(flat, y / x.abs(), x / y));
    sel(flat, sel(x >= 0.0, at, PI - at), FRAC_PI_2 - at)
}

/// Solid angles inside which a triangle emitter is sampled uniformly by solid angle
/// ([`spherical_triangle_sample`]); outside, by area. Below the lower bound the spherical
/// triangle's angles lose their precision in f32 and area sampling is as good (the triangle is
/// small and far); above the upper one (nearly the whole sphere) the same holds for its
/// complement.
pub(crate) const SPHERICAL_SAMPLING: (f32, f32) = (3e-4, 6.22);

type V3 = [f32; 3];

#[inline(always)]
fn dot3(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[inline(always)]
fn cross3(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn scaled(a: V3, k: f32) -> V3 {
    [a[0] * k, a[1] * k, a[2] * k]
}

#[inline(always)]
fn sum3(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn diff3(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[inline(always)]
fn unit3(a: V3) -> V3 {
    scaled(a, 1.0 / dot3(a, a).sqrt())
}

/// The solid angle of the triangle with corners `v0`, `v0 + e1`, `v0 + e2` seen from `p`, and
/// the unit directions to its corners (NaN when `p` is on a corner).
#[must_use]
#[inline(always)]
pub(crate) fn spherical_triangle(v0: V3, e1: V3, e2: V3, p: V3) -> (f32, [V3; 3]) {
    let a = unit3(diff3(v0, p));
    let b = unit3(diff3(sum3(v0, e1), p));
    let c = unit3(diff3(sum3(v0, e2), p));
    // tan(Ω/2) = |a · (b × c)| / (1 + a·b + b·c + c·a) (Van Oosterom and Strackee); the
    // denominator is negative for solid angles above π.
    let num = dot3(a, cross3(b, c)).abs();
    let den = 1.0 + dot3(a, b) + dot3(b, c) + dot3(c, a);
    (2.0 * angle_upper(num, den), [a, b, c])
}

/// Whether [`spherical_triangle_sample`] draws from a triangle of solid angle `area`.
#[must_use]
#[inline(always)]
pub(crate) fn spherical_sampling(area: f32) -> bool {
    (area >= SPHERICAL_SAMPLING.0) & (area <= SPHERICAL_SAMPLING.1)
}

/// A direction drawn uniformly by solid angle inside the spherical triangle with corners
/// `[a, b, c]` and solid angle `area`, from two uniform numbers (Arvo's method: `u1` picks the
/// sub-triangle of area `u1 · area` at corner a, `u2` the point on its arc from b); density
/// `1 / area`. Not finite where rounding leaves no direction (a triangle seen nearly edge-on).
/// Branch-free, so that a loop over lanes vectorises.
#[must_use]
#[inline(always)]
pub(crate) fn spherical_triangle_sample(area: f32, [a, b, c]: [V3; 3], u1: f32, u2: f32) -> V3 {
    // The angle α at corner a, between the great circles through a and b and through a and c.
    let (nab, nac) = (cross3(a, b), cross3(a, c));
    let inv = 1.0 / (dot3(nab, nab) * dot3(nac, nac)).sqrt();
    let cos_alpha = (dot3(nab, nac) * inv).clamp(-1.0, 1.0);
    let n = cross3(nab, nac);
    let sin_alpha = dot3(n, n).sqrt() * inv;
    // (cos, sin) of the sub-triangle's area u1 · Ω, as an angle: circle_point turns by
    // 2π·u − π/4, so an eighth of a turn is added (and a whole one taken off past it).
    let turn = u1 * area * (0.5 * FRAC_1_PI) + 0.125;
    let (cos_h, sin_h) = circle_point(sel(turn >= 1.0, turn - 1.0, turn));
    // sin and cos of (area − α).
    let s = sin_h * cos_alpha - cos_h * sin_alpha;
    let co = cos_h * cos_alpha + sin_h * sin_alpha;
    let u = co - cos_alpha;
    let v = s + sin_alpha * dot3(a, b);
    // The cosine of the arc from a to the sub-triangle's third corner, on the arc from a to c.
    let q = (((v * co - u * s) * cos_alpha - v) / ((v * s + u * co) * sin_alpha)).clamp(-1.0, 1.0);
    let c_perp = unit3(diff3(c, scaled(a, dot3(c, a))));
    let c_hat = sum3(scaled(a, q), scaled(c_perp, (1.0 - q * q).max(0.0).sqrt()));
    // The point on the arc from b to that corner.
    let z = (1.0 - u2 * (1.0 - dot3(c_hat, b))).clamp(-1.0, 1.0);
    let b_perp = unit3(diff3(c_hat, scaled(b, dot3(c_hat, b))));
    sum3(scaled(b, z), scaled(b_perp, (1.0 - z * z).max(0.0).sqrt()))
}

/// A point drawn uniformly by solid angle on the triangle with corners `v0`, `v0 + e1`,
/// `v0 + e2` and e1 × e2 `c`, seen from `p`: (direction, distance, density, whether the
/// triangle is drawn this way at all, whether the draw succeeded). The triangle is drawn this
/// way where its solid angle is inside [`SPHERICAL_SAMPLING`] (elsewhere the caller samples it
/// by area); the draw fails where rounding leaves no direction. Branch-free, so that a loop
/// over lanes vectorises.
#[must_use]
#[inline(always)]
pub(crate) fn spherical_triangle_point(v0: V3, e1: V3, e2: V3, c: V3, p: V3, u1: f32, u2: f32) -> SphericalPoint {
    let (area, corners) = spherical_triangle(v0, e1, e2, p);
    spherical_triangle_point_in(area, corners, v0, c, p, u1, u2)
}

/// [`spherical_triangle_point`] with the triangle's solid angle and corner directions given.
#[must_use]
#[inline(always)]
pub(crate) fn spherical_triangle_point_in(
    area: f32,
    corners: [V3; 3],
    v0: V3,
    c: V3,
    p: V3,
    u1: f32,
    u2: f32,
) -> SphericalPoint {
    let dir = spherical_triangle_sample(area, corners, u1, u2);
    // Where the direction meets the triangle's plane.
    let dist = dot3(c, diff3(v0, p)) / dot3(c, dir);
    let finite = dir[0].is_finite() & dir[1].is_finite() & dir[2].is_finite() & dist.is_finite();
    SphericalPoint {
        dir,
        dist,
        pdf: 1.0 / area,
        taken: spherical_sampling(area),
        ok: (dist > 0.0) & finite,
    }
}

/// What [`spherical_triangle_point`] draws.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SphericalPoint {
    /// Unit direction to the point.
    pub(crate) dir: V3,
    /// Distance to it.
    pub(crate) dist: f32,
    /// Solid-angle density, 1 / Ω.
    pub(crate) pdf: f32,
    /// The triangle is drawn by solid angle from here (else by area).
    pub(crate) taken: bool,
    /// The draw gave a direction.
    pub(crate) ok: bool,
}

/// The power heuristic (β = 2) weight of a strategy with density `a` against one with density `b`.
#[must_use]
#[inline]
pub(crate) fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 || !a2.is_finite() {
        return if a > 0.0 { 1.0 } else { 0.0 };
    }
    a2 / (a2 + b2)
}

/// World direction of the local direction `v` in the frame (t, b, n).
#[must_use]
#[inline]
pub fn to_world(v: Vec3A, t: Vec3A, b: Vec3A, n: Vec3A) -> Vec3A {
    t * v.x + b * v.y + n * v.z
}

/// `to_world(v, t, b, n).normalize()` of each lane: the unit world directions, per axis, of the
/// local directions `v` in the frames (t, b, n), all per axis.
#[must_use]
#[inline(always)]
pub(crate) fn to_world_unit_lanes(
    v: &[[f32; LANES]; 3],
    t: &[[f32; LANES]; 3],
    b: &[[f32; LANES]; 3],
    n: &[[f32; LANES]; 3],
) -> [[f32; LANES]; 3] {
    let mut w = [[0.0; LANES]; 3];
    for i in 0..LANES {
        let d: [f32; 3] = std::array::from_fn(|a| t[a][i] * v[0][i] + b[a][i] * v[1][i] + n[a][i] * v[2][i]);
        // glam's length: (x² + y²) + z², then its square root, which each axis is divided by.
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        for a in 0..3 {
            w[a][i] = d[a] / len;
        }
    }
    w
}

/// Russian roulette's survival probability for a path whose throughput is `beta`: its largest
/// channel, at most 0.95. The path goes on when a uniform number falls below it, and then
/// divides what it carries by it, which keeps the estimate unbiased.
#[must_use]
#[inline(always)]
pub(crate) fn russian_roulette_survival(beta: Vec3) -> f32 {
    beta.max_element().min(0.95)
}

/// Local coordinates of the world direction `v` in the frame (t, b, n).
#[must_use]
#[inline]
pub fn to_local(v: Vec3A, t: Vec3A, b: Vec3A, n: Vec3A) -> Vec3A {
    Vec3A::new(v.dot(t), v.dot(b), v.dot(n))
}

/// Isotropic GGX (Trowbridge–Reitz) normal distribution D(h) for a local half vector `h`.
#[must_use]
#[inline]
pub(crate) fn ggx_d(h: Vec3A, alpha: f32) -> f32 {
    if h.z <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = h.z * h.z;
    let k = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * k * k)
}

/// Smith's Λ for GGX, for a local direction `w`.
#[must_use]
#[inline]
pub(crate) fn ggx_lambda(w: Vec3A, alpha: f32) -> f32 {
    let c2 = w.z * w.z;
    if c2 <= 0.0 {
        return f32::INFINITY;
    }
    let t2 = ((1.0 - c2) / c2).max(0.0);
    0.5 * ((1.0 + alpha * alpha * t2).sqrt() - 1.0)
}

/// Smith's masking G1 for GGX.
#[must_use]
#[inline]
pub(crate) fn ggx_g1(w: Vec3A, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(w, alpha))
}

/// Height-correlated masking–shadowing G2 for GGX.
#[must_use]
#[inline]
pub(crate) fn ggx_g2(wo: Vec3A, wi: Vec3A, alpha: f32) -> f32 {
    1.0 / (1.0 + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha))
}

/// A microfacet normal drawn from GGX's distribution of normals visible from the local direction
/// `wo` (`wo.z > 0`), Heitz 2018, "Sampling the GGX Distribution of Visible Normals".
#[must_use]
#[inline]
pub fn ggx_sample_vndf(wo: Vec3A, alpha: f32, u1: f32, u2: f32) -> Vec3A {
    // Stretch to the hemisphere configuration.
    let vh = Vec3A::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let lensq = vh.x * vh.x + vh.y * vh.y;
    let t1 = if lensq > 0.0 {
        Vec3A::new(-vh.y, vh.x, 0.0) / lensq.sqrt()
    } else {
        Vec3A::X
    };
    let t2 = vh.cross(t1);
    let r = u1.sqrt();
    let (c, s) = circle_point(u2);
    let p1 = r * c;
    let mut p2 = r * s;
    let s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * p2;
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    // Unstretch.
    Vec3A::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize()
}

/// Density (solid angle of `wi`) of reflecting local `wo` about a VNDF-sampled normal:
/// `G1(wo) · D(h) / (4 · wo.z)`, with `h` the half vector of `wo` and `wi`.
#[must_use]
#[inline]
pub fn ggx_reflect_pdf(wo: Vec3A, wi: Vec3A, alpha: f32) -> f32 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize_or_zero();
    if h == Vec3A::ZERO || h.z <= 0.0 || wo.dot(h) <= 0.0 {
        return 0.0;
    }
    ggx_g1(wo, alpha) * ggx_d(h, alpha) / (4.0 * wo.z)
}

/// Mirror reflection of local `wo` about `h`.
#[must_use]
#[inline]
pub fn reflect_about(wo: Vec3A, h: Vec3A) -> Vec3A {
    h * (2.0 * wo.dot(h)) - wo
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atan_without_libm_is_within_2e_7_of_the_exact_angle() {
        let mut worst = 0.0f64;
        for k in 0..=200_000 {
            let r = -1.0 + 2.0 * k as f32 / 200_000.0;
            worst = worst.max((f64::from(atan_unit(r)) - f64::from(r).atan()).abs());
        }
        assert!(worst < 2e-7, "atan_unit is {worst} off");
        let mut worst = 0.0f64;
        for k in 0..=720 {
            let phi = std::f64::consts::PI * f64::from(k) / 720.0;
            for len in [1e-3f64, 1.0, 7.5] {
                let (y, x) = ((len * phi.sin()) as f32, (len * phi.cos()) as f32);
                let exact = f64::from(y).atan2(f64::from(x));
                worst = worst.max((f64::from(angle_upper(y, x)) - exact).abs());
            }
        }
        assert!(worst < 4e-7, "angle_upper is {worst} off");
        assert!(angle_upper(0.0, 0.0).is_nan());
    }

    #[test]
    fn a_spherical_triangle_has_the_solid_angle_of_its_triangle() {
        // Half of one face of the cube [−1, 1]³ seen from its centre: a twelfth of the sphere,
        // π/3; the triangle (1,0,0) (0,1,0) (0,0,1) from the origin: an octant, π/2.
        let (v0, e1, e2) = ([-1.0, -1.0, 1.0], [2.0, 0.0, 0.0], [2.0, 2.0, 0.0]);
        let (area, _) = spherical_triangle(v0, e1, e2, [0.0; 3]);
        assert!((area - PI / 3.0).abs() < 1e-6, "{area}");
        let (area, _) = spherical_triangle([1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0], [0.0; 3]);
        assert!((area - FRAC_PI_2).abs() < 1e-6, "{area}");
        // Nearly a hemisphere from just above a large triangle; tiny from far away.
        let (area, _) = spherical_triangle(
            [-100.0, -100.0, 0.0],
            [300.0, 0.0, 0.0],
            [0.0, 300.0, 0.0],
            [0.0, 0.0, 1.0],
        );
        assert!(area > 6.0 && area < 2.0 * PI, "{area}");
        let (area, _) = spherical_triangle([0.0, 0.0, 1000.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0; 3]);
        assert!((area - 5e-7).abs() < 1e-8 && !spherical_sampling(area), "{area}");
    }

    #[test]
    fn cone_small_angles_stay_inside() {
        let omc = 1e-7;
        for i in 0..16 {
            let d = uniform_cone(i as f32 / 15.0, 0.3, omc);
            assert!(1.0 - d.z <= omc * 1.0001 + 1e-7);
            assert!((d.length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn sin_cos_eighth_is_as_close_as_libm() {
        let steps = 200_000;
        let (mut worst, mut worst_libm) = (0.0f64, 0.0f64);
        for i in 0..=steps {
            let x = FRAC_PI_4 * (2.0 * i as f32 / steps as f32 - 1.0);
            let (s, c) = sin_cos_eighth(x);
            let exact = (x as f64).sin_cos();
            worst = worst.max((s as f64 - exact.0).abs()).max((c as f64 - exact.1).abs());
            worst_libm = worst_libm
                .max((x.sin() as f64 - exact.0).abs())
                .max((x.cos() as f64 - exact.1).abs());
        }
        assert!(worst < 1e-7, "{worst}");
        assert!(worst < 2.0 * worst_libm, "{worst} against libm's {worst_libm}");
        // The disk's points keep the radius max(|a|, |b|) the exact mapping gives them.
        for (u1, u2) in [(0.9, 0.6), (0.2, 0.95), (0.5, 0.0), (0.0, 0.5), (1.0, 1.0)] {
            let p = concentric_disk(u1, u2);
            let r = (2.0 * u1 - 1.0f32).abs().max((2.0 * u2 - 1.0f32).abs());
            assert!((p.length() - r).abs() < 1e-6, "{u1} {u2}: {p}");
        }
    }

    #[test]
    fn circle_points_are_the_angle_2_pi_u_less_an_eighth_turn() {
        let steps = 100_000;
        for i in 0..steps {
            // Every quarter's ends included: u = k/4 and the float just below.
            let u = match i % 3 {
                0 => i as f32 / steps as f32,
                1 => ((i % 4) as f32 * 0.25).max(f32::MIN_POSITIVE),
                _ => f32::from_bits(((i % 4 + 1) as f32 * 0.25).to_bits() - 1),
            };
            let (c, s) = circle_point(u);
            let phi = std::f64::consts::TAU * f64::from(u) - std::f64::consts::FRAC_PI_4;
            let err = (f64::from(c) - phi.cos()).abs().max((f64::from(s) - phi.sin()).abs());
            assert!(err < 1e-6, "u = {u}: ({c}, {s}) against angle {phi}");
        }
    }

    /// Sixteen lanes of uniform numbers from `rng`, the first lanes replaced by `edges`.
    fn lanes_with(rng: &mut crate::rng::Rng, edges: &[f32]) -> [f32; LANES] {
        let mut u: [f32; LANES] = std::array::from_fn(|_| rng.next_f32());
        u[..edges.len()].copy_from_slice(edges);
        u
    }

    #[test]
    fn cosine_hemisphere_lane_is_cosine_hemisphere_bit_for_bit() {
        let mut rng = crate::rng::Rng::for_sample(3, 1, 4);
        // The disk's centre, its edges (z = 0), its diagonals and the axes through the centre.
        let u1 = lanes_with(&mut rng, &[0.5, 0.5, 0.2, 0.0, 1.0, 0.0, 0.999_999_94, 0.75, 0.5, 0.25]);
        let u2 = lanes_with(&mut rng, &[0.5, 0.9, 0.5, 0.5, 1.0, 0.0, 0.5, 0.75, 0.0, 0.75]);
        for round in 0..64 {
            let (u1, u2) = if round == 0 {
                (u1, u2)
            } else {
                (lanes_with(&mut rng, &[]), lanes_with(&mut rng, &[]))
            };
            for i in 0..LANES {
                let want = cosine_hemisphere(u1[i], u2[i]).to_array().map(f32::to_bits);
                let got = cosine_hemisphere_lane(u1[i], u2[i]).map(f32::to_bits);
                assert_eq!(got, want, "u = ({}, {})", u1[i], u2[i]);
                let disk = concentric_disk(u1[i], u2[i]).to_array().map(f32::to_bits);
                let disk_lane = concentric_disk_lane(u1[i], u2[i]).map(f32::to_bits);
                assert_eq!(disk_lane, disk, "u = ({}, {})", u1[i], u2[i]);
            }
        }
    }

    #[test]
    fn to_world_unit_lanes_is_to_world_normalised_bit_for_bit() {
        let mut rng = crate::rng::Rng::for_sample(2, 7, 1);
        let mut r = move || rng.next_f32() - 0.5;
        let (mut v, mut t, mut b, mut n) = (
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
        );
        for i in 0..LANES {
            // Frames of random normals and of the poles, and a local direction near the plane.
            let normal = match i {
                0 => Vec3A::Z,
                1 => Vec3A::NEG_Z,
                2 => Vec3A::new(1e-4, -2e-4, -0.999_999_94),
                _ => Vec3A::new(r(), r(), r()).normalize(),
            };
            let (tt, bb) = crate::math::basis(normal);
            let local = if i == 3 {
                Vec3A::new(0.6, 0.8, 1e-7)
            } else {
                cosine_hemisphere(r() + 0.5, r() + 0.5)
            };
            for (dst, x) in [(&mut v, local), (&mut t, tt), (&mut b, bb), (&mut n, normal)] {
                for a in 0..3 {
                    dst[a][i] = x[a];
                }
            }
        }
        let w = to_world_unit_lanes(&v, &t, &b, &n);
        for i in 0..LANES {
            let at = |x: &[[f32; LANES]; 3]| Vec3A::new(x[0][i], x[1][i], x[2][i]);
            let want = to_world(at(&v), at(&t), at(&b), at(&n)).normalize();
            assert_eq!(
                at(&w).to_array().map(f32::to_bits),
                want.to_array().map(f32::to_bits),
                "lane {i}"
            );
        }
    }

    #[test]
    fn russian_roulette_keeps_the_brightest_channel_up_to_095() {
        assert_eq!(russian_roulette_survival(Vec3::new(0.2, 0.5, 0.1)), 0.5);
        assert_eq!(russian_roulette_survival(Vec3::new(0.2, 0.5, 3.0)), 0.95);
        assert_eq!(russian_roulette_survival(Vec3::ZERO), 0.0);
    }

    #[test]
    fn power_heuristic_is_a_partition() {
        for (a, b) in [(1.0, 2.0), (0.5, 0.0), (3.0, 3.0)] {
            assert!((power_heuristic(a, b) + power_heuristic(b, a) - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn ggx_d_normalised_over_projected_area() {
        // ∫ D(h) cosθh dω = 1.
        for alpha in [0.1f32, 0.5, 1.0] {
            let n = 2000;
            let mut sum = 0.0f64;
            for i in 0..n {
                let c = (i as f32 + 0.5) / n as f32;
                let h = Vec3A::new((1.0 - c * c).sqrt(), 0.0, c);
                sum += (ggx_d(h, alpha) * c) as f64 * 2.0 * std::f64::consts::PI / n as f64;
            }
            assert!((sum - 1.0).abs() < 0.01, "alpha {alpha}: {sum}");
        }
    }
}
