//! Optics at an interface: mirror reflection, Snell refraction and the Fresnel reflectance
//! (exact, and Schlick's approximation a tracer with that mistake uses), and the rays mirrors and
//! glass send on, for one ray (`mirror_ray`, `glass_rays`) and for the sixteen lanes of a
//! packet ([`specular_rays`], the same arithmetic in the same order, tested bit for bit below).
//!
//! The BSDFs (`bsdf`), the integrators and the packet kernels all take these rules from here.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::Vec3A;

use crate::math::{offset_eps_lane, Ray, RayPacket};
use crate::simd::{dispatched, sel, Mask, LANES};
use crate::surface::SurfaceFrames;

/// One value per lane.
type F = [f32; LANES];

/// Mirror reflection of `d` about the unit normal `n`.
#[must_use]
#[inline]
pub fn reflect(d: Vec3A, n: Vec3A) -> Vec3A {
    d - n * (2.0 * d.dot(n))
}

/// Exact unpolarised Fresnel reflectance for a ray meeting an interface with `cos_i` = cos of
/// the incidence angle (≥ 0), going from index `n1` to `n2`; 1 under total internal reflection.
#[must_use]
#[inline]
pub fn fresnel(cos_i: f32, n1: f32, n2: f32) -> f32 {
    fresnel_terms(cos_i, n1, n2, false)
}

/// The unpolarised reflectance, with rp's cosines exchanged when `swapped`.
#[inline(always)]
fn fresnel_terms(cos_i: f32, n1: f32, n2: f32, swapped: bool) -> f32 {
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let (ci, ct) = if swapped { (cos_t, cos_i) } else { (cos_i, cos_t) };
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// [`fresnel`] as a tracer that writes rp with cos θi and cos θt exchanged computes it: the
/// mean of rs² and rs², that is rs² (a catalogued mistake).
#[must_use]
pub(crate) fn fresnel_swapped(cos_i: f32, n1: f32, n2: f32) -> f32 {
    fresnel_terms(cos_i, n1, n2, true)
}

/// Refracted direction of unit `d` through unit normal `n` (facing `d`'s origin side) with
/// `eta = n1 / n2`; `None` under total internal reflection.
#[must_use]
#[inline]
pub fn refract(d: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

/// Schlick's approximation of the Fresnel reflectance, from `n1` into `n2` at `cos_i`; 1 under
/// total internal reflection.
#[must_use]
pub fn schlick(cos_i: f32, n1: f32, n2: f32) -> f32 {
    let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    // Going into the denser medium the incident angle is the larger one; leaving it, the
    // transmitted one is.
    let c = if n1 <= n2 { cos_i } else { (1.0 - sin2_t).sqrt() };
    r0 + (1.0 - r0) * (1.0 - c).powi(5)
}

/// The mirror ray of a ray with unit direction `d` meeting a surface at `point`, whose unit normal
/// `n` faces the ray: `d` reflected about `n`, starting `eps` off the surface on the ray's side.
#[must_use]
#[inline]
pub(crate) fn mirror_ray(d: Vec3A, n: Vec3A, point: Vec3A, eps: f32) -> Ray {
    Ray::new(point + n * eps, reflect(d, n).normalize())
}

/// What glass of index of refraction `ior` makes of a ray with unit direction `d` meeting it at
/// `point`, whose unit normal `n` faces the ray (`front_face`: the ray comes from outside): the
/// Fresnel reflectance, the mirror ray, and the refracted ray starting `eps` off the surface on
/// the far side, none under total internal reflection.
#[must_use]
#[inline]
pub(crate) fn glass_rays(
    d: Vec3A,
    n: Vec3A,
    point: Vec3A,
    eps: f32,
    front_face: bool,
    ior: f32,
) -> (f32, Ray, Option<Ray>) {
    let (n1, n2) = if front_face { (1.0, ior) } else { (ior, 1.0) };
    let cos_i = (-d.dot(n)).clamp(0.0, 1.0);
    let kr = fresnel(cos_i, n1, n2);
    let refracted = if kr < 1.0 { refract(d, n, n1 / n2) } else { None };
    (
        kr,
        mirror_ray(d, n, point, eps),
        refracted.map(|t| Ray::new(point - n * eps, t)),
    )
}

/// The rays mirrors and glass send on from a packet's hits: per lane, what `mirror_ray` and
/// `glass_rays` return (meaningless in lanes without a hit).
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct SpecularRays {
    /// Unit mirror-reflection direction.
    pub reflected: [F; 3],
    /// Fresnel reflectance of glass with the lane's index of refraction.
    pub kr: F,
    /// Lanes where light also refracts (reflectance below 1, no total internal reflection).
    pub(crate) has_refracted: Mask,
    /// Unit refracted direction, in those lanes.
    pub refracted: [F; 3],
    /// Where refracted rays start: the hit point moved off the surface to the far side.
    pub inside: [F; 3],
}

/// The mirror and glass rays of the hits `f` of `rays`, glass having index of refraction `ior`.
#[inline(always)]
pub(crate) fn specular_rays_impl(rays: &RayPacket, f: &SurfaceFrames, ior: &F) -> SpecularRays {
    let mut out = SpecularRays {
        reflected: [[0.0; LANES]; 3],
        kr: [0.0; LANES],
        has_refracted: [false; LANES],
        refracted: [[0.0; LANES]; 3],
        inside: [[0.0; LANES]; 3],
    };
    let (d, n, p) = (&rays.d, &f.normal, &f.point);
    for i in 0..LANES {
        let dn = d[0][i] * n[0][i] + d[1][i] * n[1][i] + d[2][i] * n[2][i];
        // reflect(d, n) = d − n·(2 d·n), normalised.
        let r: [f32; 3] = std::array::from_fn(|a| d[a][i] - n[a][i] * (2.0 * dn));
        let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        for a in 0..3 {
            out.reflected[a][i] = r[a] / len;
        }
        // fresnel(cos_i, n1, n2) with cos_i = clamp(−d·n, 0, 1) (NaN passes through clamp).
        let front = f.front_face[i];
        let (n1, n2) = (sel(front, 1.0, ior[i]), sel(front, ior[i], 1.0));
        let neg = -dn;
        let cos_i = sel(neg < 0.0, 0.0, sel(neg > 1.0, 1.0, neg));
        let eta = n1 / n2;
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
        let cos_t = (1.0 - sin2_t).sqrt();
        let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
        let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
        let kr = sel(sin2_t >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp));
        out.kr[i] = kr;
        // refract(d, n, n1 / n2), tried only when kr < 1; its cosine is not clamped.
        let sin2_r = eta * eta * (1.0 - neg * neg).max(0.0);
        let cos_r = (1.0 - sin2_r).sqrt();
        out.has_refracted[i] = (kr < 1.0) & (sin2_r < 1.0);
        let t: [f32; 3] = std::array::from_fn(|a| d[a][i] * eta + n[a][i] * (eta * neg - cos_r));
        let len = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        for a in 0..3 {
            out.refracted[a][i] = t[a] / len;
        }
        // As for `SurfaceFrames::outside`, on the other side.
        let eps = offset_eps_lane(p, &rays.o, i);
        for a in 0..3 {
            out.inside[a][i] = p[a][i] - n[a][i] * eps;
        }
    }
    out
}

dispatched!(
    /// [`specular_rays`] with the best instruction set the CPU has.
    best_specular_rays, specular_rays_avx512, specular_rays_avx2,
    (rays: &RayPacket, frames: &SurfaceFrames, ior: &[f32; LANES]) -> SpecularRays,
    specular_rays_impl(rays, frames, ior)
);

/// The rays mirrors and glass send on from the hits `frames` of `rays`; see [`SpecularRays`].
// Calls the dispatcher rather than being it (see `crate::simd::dispatched`).
#[must_use]
pub fn specular_rays(rays: &RayPacket, frames: &SurfaceFrames, ior: &[f32; LANES]) -> SpecularRays {
    best_specular_rays(rays, frames, ior)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        // Normal incidence air→glass 1.5: ((1−1.5)/(1+1.5))² = 0.04.
        assert!((fresnel(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing: total reflection.
        assert!((fresnel(0.0, 1.0, 1.5) - 1.0).abs() < 1e-6);
        // Inside glass past the critical angle (41.8° for 1.5): TIR.
        assert_eq!(fresnel(50f32.to_radians().cos(), 1.5, 1.0), 1.0);
        assert!(fresnel(30f32.to_radians().cos(), 1.5, 1.0) < 1.0);
    }

    #[test]
    fn refraction_obeys_snell() {
        let d = Vec3A::new(1.0, -1.0, 0.0).normalize();
        let n = Vec3A::Y;
        let t = refract(d, n, 1.0 / 1.4).unwrap();
        let sin_i = d.x;
        let sin_t = t.x;
        assert!((sin_i - 1.4 * sin_t).abs() < 1e-6);
        assert!(
            refract(Vec3A::new(0.9, -0.1, 0.0).normalize(), n, 1.4).is_none(),
            "TIR from inside"
        );
    }

    #[test]
    fn schlick_is_close_to_fresnel_but_not_equal() {
        for k in 0..=20 {
            let c = k as f32 / 20.0;
            let (s, f) = (schlick(c, 1.0, 1.5), fresnel(c, 1.0, 1.5));
            assert!((s - f).abs() < 0.06, "{c}: {s} vs {f}");
        }
        assert!((schlick(0.5, 1.0, 1.5) - fresnel(0.5, 1.0, 1.5)).abs() > 1e-4);
        assert_eq!(schlick(0.1, 1.5, 1.0), 1.0, "TIR");
    }

    #[test]
    fn specular_rays_are_mirror_and_glass_rays_bit_for_bit() {
        use crate::math::offset_eps;
        let mut rng = crate::rng::Rng::for_sample(11, 2, 3);
        let mut r = move || rng.next_f32();
        let mut unit = || Vec3A::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0).normalize();
        let (mut refracting, mut reflecting_only) = (0, 0);
        for round in 0..64 {
            let mut rays = RayPacket::default();
            let mut f = SurfaceFrames {
                point: [[0.0; LANES]; 3],
                normal: [[0.0; LANES]; 3],
                shading_normal: [[0.0; LANES]; 3],
                front_face: [false; LANES],
                outside: [[0.0; LANES]; 3],
            };
            let mut ior = [1.0; LANES];
            for i in 0..LANES {
                let d = unit();
                let n = unit();
                // The normal faces the ray, as the frames' normals do.
                let n = if d.dot(n) > 0.0 { -n } else { n };
                let p = unit() * (1.0 + (round % 7) as f32 * 3.0);
                let o = p - d * (0.5 + 4.0 * (i as f32 / LANES as f32));
                rays.set(i, &Ray::new(o, d), f32::INFINITY);
                for a in 0..3 {
                    f.point[a][i] = p[a];
                    f.normal[a][i] = n[a];
                }
                f.front_face[i] = (i + round) % 3 != 0;
                ior[i] = 1.0 + (i % 5) as f32 * 0.35;
            }
            let sp = specular_rays(&rays, &f, &ior);
            for i in 0..LANES {
                let (d, o) = (rays.ray(i).dir, rays.ray(i).origin);
                let (p, n) = (crate::simd::lane(&f.point, i), crate::simd::lane(&f.normal, i));
                let eps = offset_eps(p, o);
                let (kr, mirror, refracted) = glass_rays(d, n, p, eps, f.front_face[i], ior[i]);
                let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
                let lane_bits = |v: &[[f32; LANES]; 3]| bits(crate::simd::lane(v, i));
                assert_eq!(
                    lane_bits(&sp.reflected),
                    bits(mirror.dir),
                    "round {round} lane {i}: mirror direction"
                );
                assert_eq!(mirror_ray(d, n, p, eps).dir, mirror.dir);
                assert_eq!(sp.kr[i].to_bits(), kr.to_bits(), "round {round} lane {i}: reflectance");
                assert_eq!(
                    sp.has_refracted[i],
                    refracted.is_some(),
                    "round {round} lane {i}: refracts"
                );
                if refracted.is_some() {
                    refracting += 1;
                } else {
                    reflecting_only += 1;
                }
                if let Some(t) = refracted {
                    assert_eq!(
                        lane_bits(&sp.refracted),
                        bits(t.dir),
                        "round {round} lane {i}: refracted direction"
                    );
                    assert_eq!(
                        lane_bits(&sp.inside),
                        bits(t.origin),
                        "round {round} lane {i}: refracted origin"
                    );
                }
            }
        }
        assert!(
            refracting > 100 && reflecting_only > 20,
            "{refracting} {reflecting_only}"
        );
    }
}
