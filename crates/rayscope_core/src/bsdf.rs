//! Reflection models of the non-specular materials: Lambert (Diffuse), a coated Lambert base
//! under a rough dielectric GGX coat (Glossy) and the normalised Phong model (Phong).
//!
//! All directions are local: +z is the shading normal, `wo` points back along the incoming ray,
//! `wi` towards the light. Values are BRDFs (without the cosine).
//!
//! **Glossy.** `Material "M" Glossy (r, g, b) n` is a Lambert base of albedo (r, g, b) under a
//! clear dielectric coat of index 1.5 whose surface is a GGX microfacet distribution. The
//! number `n` is a glossiness: roughness ρ = 1 / (1 + max(n, 0)) and GGX α = ρ² (clamped to
//! ≥ 0.001), so `0` is very rough (α = 1), the conventional `1` is a satin gloss (α = 0.25),
//! `10` is nearly a mirror (α ≈ 0.008). The coat reflects F(wo·h) D G₂ / (4 cosθo cosθi)
//! (exact unpolarised Fresnel, height-correlated Smith G₂); the base gets what the coat
//! transmits both ways, albedo/π · (1 − F(cosθo)) (1 − F(cosθi)), so the sum never reflects
//! more than it receives and nothing is transmitted. The coat lobe is sampled with the GGX
//! distribution of visible normals, the base with cosine sampling, mixed by one-sample MIS.
//!
//! **Phong.** `Material "M" Phong (r, g, b) n` is the normalised (energy-conserving) Phong
//! model with exponent `n` (0 to 10,000): half of its albedo c = (r, g, b) reflects as Lambert
//! does, half in a lobe about the mirror direction r of `wo`,
//! f = c · (1/2 · 1/π + 1/2 · (n + 2)/(2π) · max(0, wi·r)ⁿ). The lobe's factor (n + 2)/(2π)
//! makes it reflect everything it receives at normal incidence and less elsewhere (the horizon
//! cuts it off), so the model never reflects more than a Diffuse surface of the same colour, and
//! `n = 0` is exactly that surface. The lobe is sampled about r with density
//! (n + 1)/(2π) · (wi·r)ⁿ (cos α = u^(1/(n+1))), the Lambert half with cosine sampling, each
//! with probability 1/2, and [`Bsdf::pdf`] is that mixture's exact density. The lobe is the
//! model's specular part: without indirect light the full renderer traces it on like a
//! blurred mirror, as it does a Glossy coat's reflection.
//!
//! **Lambert in lanes.** The path-tracing wave shades sixteen Lambertian vertices at once with
//! `lambert_sample_lanes`, the Lambert model's sample in lane form (tested below to return
//! [`Bsdf::sample`]'s bits), and with `lambert_f` and `lambert_pdf`, the value and density
//! [`Bsdf::Lambert`] itself is evaluated with.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3A;

use crate::math::{basis, not_at_most};
use crate::optics::fresnel;
use crate::sampling::{
    circle_point, cosine_hemisphere, cosine_hemisphere_lane, cosine_hemisphere_pdf, ggx_d, ggx_g2, ggx_reflect_pdf,
    ggx_sample_vndf, reflect_about,
};
use crate::scene::Material;
use crate::simd::LANES;
use rayscope_scene::MaterialKind;

/// Refractive index of the Glossy material's clear coat.
pub(crate) const COAT_IOR: f32 = 1.5;

/// GGX α of a Glossy material with number `n`: (1 / (1 + max(n, 0)))², at least 0.001.
#[must_use]
pub fn glossy_alpha(n: f32) -> f32 {
    let n = if n.is_nan() { 0.0 } else { n.max(0.0) };
    let r = 1.0 / (1.0 + n);
    (r * r).max(1e-3)
}

/// Largest Phong exponent ([`rayscope_scene::PHONG_MAX_EXPONENT`], which the parser enforces).
pub const PHONG_MAX_EXPONENT: f32 = rayscope_scene::PHONG_MAX_EXPONENT as f32;

/// Share of a Phong material's albedo its lobe reflects (the rest reflects as Lambert does).
const PHONG_LOBE_SHARE: f32 = 0.5;

/// The Phong exponent of a Phong material with number `n`: `n` within [0, [`PHONG_MAX_EXPONENT`]]
/// (0 for NaN).
#[must_use]
pub fn phong_exponent(n: f32) -> f32 {
    if n.is_nan() {
        0.0
    } else {
        n.clamp(0.0, PHONG_MAX_EXPONENT)
    }
}

/// The normalised Phong lobe (n + 2)/(2π) · max(0, cos α)ⁿ and its sampling density
/// (n + 1)/(2π) · max(0, cos α)ⁿ, for a direction at cosine `cos_a` to the lobe's axis.
#[must_use]
#[inline]
fn phong_lobe(cos_a: f32, n: f32) -> (f32, f32) {
    if cos_a <= 0.0 {
        return (0.0, 0.0);
    }
    let p = cos_a.min(1.0).powf(n) * (0.5 * FRAC_1_PI);
    ((n + 2.0) * p, (n + 1.0) * p)
}

/// A direction about the unit axis `r` drawn with density (n + 1)/(2π) · cos ⁿα from two
/// uniform numbers: cos α = u1^(1/(n+1)), the azimuth 2π·u2 − π/4.
#[must_use]
#[inline]
fn phong_lobe_sample(r: Vec3A, n: f32, u1: f32, u2: f32) -> Vec3A {
    let cos_a = u1.powf(1.0 / (n + 1.0));
    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
    let (c, s) = circle_point(u2);
    let (t, b) = basis(r);
    (t * (sin_a * c) + b * (sin_a * s) + r * cos_a).normalize()
}

/// The mirror direction of local `wo` about the normal (+z).
#[must_use]
#[inline]
fn mirror_local(wo: Vec3A) -> Vec3A {
    Vec3A::new(-wo.x, -wo.y, wo.z)
}

/// The albedo of material `m` in light transport: its colour clamped to [0, 1].
///
/// A surface cannot reflect more light than it receives: colours above 1 (which the course's
/// point-light formula allows as "brightness") are clamped for light transport, or paths
/// between such surfaces would gain energy at every bounce and diverge.
#[must_use]
#[inline(always)]
pub(crate) fn transport_albedo(m: &Material) -> Vec3A {
    Vec3A::from(m.color).clamp(Vec3A::ZERO, Vec3A::ONE)
}

/// The Lambert BRDF of albedo `albedo` above the surface: albedo / π.
#[must_use]
#[inline(always)]
pub(crate) fn lambert_f(albedo: Vec3A) -> Vec3A {
    albedo * FRAC_1_PI
}

/// The density with which Lambert sampling draws a direction above the surface whose cosine
/// to the normal is `cos_i`: the cosine hemisphere's, cosθ / π.
#[must_use]
#[inline(always)]
pub(crate) fn lambert_pdf(cos_i: f32) -> f32 {
    cosine_hemisphere_pdf(cos_i)
}

/// Lambert samples of sixteen lanes ([`lambert_sample_lanes`]).
#[derive(Debug, Clone)]
pub(crate) struct LambertLanes {
    /// Local directions towards the light, per axis.
    pub(crate) wi: [[f32; LANES]; 3],
    /// Density of each direction ([`lambert_pdf`] of its cosine).
    pub(crate) pdf: [f32; LANES],
    /// Lanes where [`Bsdf::sample`] returns the sample rather than `None`.
    pub(crate) ok: [bool; LANES],
}

/// [`Bsdf::sample`] of a [`Bsdf::Lambert`] for each lane's `(u1, u2)`, with an outgoing
/// direction above the surface (which the integrator's shading ensures): the cosine-weighted
/// direction, its density, and whether the sample passes `sample`'s checks (direction above
/// the surface, density positive and finite). The BRDF value is [`lambert_f`].
#[must_use]
#[inline(always)]
pub(crate) fn lambert_sample_lanes(u1: &[f32; LANES], u2: &[f32; LANES]) -> LambertLanes {
    let mut s = LambertLanes {
        wi: [[0.0; LANES]; 3],
        pdf: [0.0; LANES],
        ok: [false; LANES],
    };
    for i in 0..LANES {
        let [x, y, z] = cosine_hemisphere_lane(u1[i], u2[i]);
        let p = lambert_pdf(z);
        (s.wi[0][i], s.wi[1][i], s.wi[2][i], s.pdf[i]) = (x, y, z, p);
        s.ok[i] = not_at_most(z, 0.0) & not_at_most(p, 0.0) & p.is_finite();
    }
    s
}

/// A non-specular reflection model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bsdf {
    /// Lambertian reflection, BRDF = albedo / π.
    Lambert {
        /// Albedo.
        albedo: Vec3A,
    },
    /// Lambert base under a rough dielectric coat (the Glossy material).
    Coated {
        /// Albedo of the base.
        base: Vec3A,
        /// GGX α of the coat.
        alpha: f32,
        /// Sample only the coat lobe (when the base's bounce would carry nothing).
        coat_only: bool,
    },
    /// The normalised Phong model (the Phong material): half Lambert, half a lobe of exponent
    /// `exponent` about the mirror direction, both of albedo `albedo`.
    Phong {
        /// Albedo.
        albedo: Vec3A,
        /// The lobe's exponent.
        exponent: f32,
        /// Sample only the lobe (when the Lambert half's bounce would carry nothing).
        lobe_only: bool,
    },
}

/// A direction drawn from a [`Bsdf`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BsdfSample {
    /// Local direction towards the light.
    pub wi: Vec3A,
    /// Whole BRDF value for `wi`.
    pub f: Vec3A,
    /// The specular part of `f` (a coat's reflection): what the full renderer traces on
    /// without indirect light.
    pub(crate) f_specular: Vec3A,
    /// Density of `wi` (solid angle) over every lobe the model samples.
    pub pdf: f32,
}

impl Bsdf {
    /// The model of a material whose lobe is [`Lambert`](crate::scene::Lobe::Lambert) or
    /// [`Bsdf`](crate::scene::Lobe::Bsdf); `None` for the other kinds. With `specular_only` the
    /// model samples only its specular part (when the rest's bounce would carry nothing).
    #[must_use]
    pub fn of(m: &Material, specular_only: bool) -> Option<Bsdf> {
        let albedo = transport_albedo(m);
        match m.kind {
            MaterialKind::Diffuse => Some(Bsdf::Lambert { albedo }),
            MaterialKind::Glossy => Some(Bsdf::Coated {
                base: albedo,
                alpha: glossy_alpha(m.value),
                coat_only: specular_only,
            }),
            MaterialKind::Phong => Some(Bsdf::Phong {
                albedo,
                exponent: phong_exponent(m.value),
                lobe_only: specular_only,
            }),
            // Mirrors and glass send rays on (`crate::optics`); emitters are not shaded.
            MaterialKind::Reflective | MaterialKind::Refractive | MaterialKind::Emissive => None,
        }
    }

    /// True when the model has a specular part ([`BsdfSample::f_specular`]): every model but
    /// Lambert's, which the full renderer lights by point lights with the whole BRDF and
    /// samples even without indirect light.
    #[must_use]
    #[inline]
    pub(crate) fn has_specular(&self) -> bool {
        !matches!(self, Bsdf::Lambert { .. })
    }

    /// Probability of sampling the specular lobe (a coat's, Phong's) for `wo`.
    #[must_use]
    #[inline]
    pub(crate) fn coat_prob(&self, wo: Vec3A) -> f32 {
        match *self {
            Bsdf::Lambert { .. } => 0.0,
            Bsdf::Coated { coat_only: true, .. } | Bsdf::Phong { lobe_only: true, .. } => 1.0,
            Bsdf::Phong { .. } => PHONG_LOBE_SHARE,
            Bsdf::Coated { base, .. } => {
                let f = fresnel(wo.z.clamp(0.0, 1.0), 1.0, COAT_IOR);
                let lum = base.dot(Vec3A::new(0.2126, 0.7152, 0.0722)).max(0.0);
                (f / (f + (1.0 - f) * lum + 1e-6)).clamp(0.25, 0.9)
            }
        }
    }

    /// (whole BRDF, specular part) for the pair of local directions.
    #[must_use]
    #[inline]
    pub fn eval(&self, wo: Vec3A, wi: Vec3A) -> (Vec3A, Vec3A) {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return (Vec3A::ZERO, Vec3A::ZERO);
        }
        match *self {
            Bsdf::Lambert { albedo } => (lambert_f(albedo), Vec3A::ZERO),
            Bsdf::Coated { base, alpha, .. } => {
                let h = (wo + wi).normalize();
                let f = fresnel(wo.dot(h).clamp(0.0, 1.0), 1.0, COAT_IOR);
                let spec = f * ggx_d(h, alpha) * ggx_g2(wo, wi, alpha) / (4.0 * wo.z * wi.z);
                let t = (1.0 - fresnel(wo.z.min(1.0), 1.0, COAT_IOR)) * (1.0 - fresnel(wi.z.min(1.0), 1.0, COAT_IOR));
                let coat = Vec3A::splat(spec);
                (coat + base * (FRAC_1_PI * t), coat)
            }
            Bsdf::Phong { albedo, exponent, .. } => {
                let (lobe, _) = phong_lobe(wi.dot(mirror_local(wo)), exponent);
                let spec = albedo * (PHONG_LOBE_SHARE * lobe);
                (spec + albedo * ((1.0 - PHONG_LOBE_SHARE) * FRAC_1_PI), spec)
            }
        }
    }

    /// Density with which [`Bsdf::sample`] draws `wi` given `wo`.
    #[must_use]
    #[inline]
    pub fn pdf(&self, wo: Vec3A, wi: Vec3A) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        match *self {
            Bsdf::Lambert { .. } => lambert_pdf(wi.z),
            Bsdf::Coated { alpha, .. } => {
                let p = self.coat_prob(wo);
                let mut pdf = p * ggx_reflect_pdf(wo, wi, alpha);
                if p < 1.0 {
                    pdf += (1.0 - p) * cosine_hemisphere_pdf(wi.z);
                }
                pdf
            }
            Bsdf::Phong { exponent, .. } => {
                let p = self.coat_prob(wo);
                let (_, lobe_pdf) = phong_lobe(wi.dot(mirror_local(wo)), exponent);
                let mut pdf = p * lobe_pdf;
                if p < 1.0 {
                    pdf += (1.0 - p) * cosine_hemisphere_pdf(wi.z);
                }
                pdf
            }
        }
    }

    /// Whether [`Self::sample`] chooses between lobes with its `u0` (a Lambert BRDF has one
    /// lobe and ignores it).
    #[must_use]
    #[inline]
    pub fn has_lobes(&self) -> bool {
        !matches!(self, Bsdf::Lambert { .. })
    }

    /// Draws a direction from three uniform numbers; `None` when it falls below the surface.
    #[must_use]
    #[inline]
    pub fn sample(&self, wo: Vec3A, u0: f32, u1: f32, u2: f32) -> Option<BsdfSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let wi = match *self {
            Bsdf::Lambert { .. } => cosine_hemisphere(u1, u2),
            Bsdf::Coated { alpha, .. } => {
                if u0 < self.coat_prob(wo) {
                    reflect_about(wo, ggx_sample_vndf(wo, alpha, u1, u2))
                } else {
                    cosine_hemisphere(u1, u2)
                }
            }
            Bsdf::Phong { exponent, .. } => {
                if u0 < self.coat_prob(wo) {
                    phong_lobe_sample(mirror_local(wo), exponent, u1, u2)
                } else {
                    cosine_hemisphere(u1, u2)
                }
            }
        };
        if wi.z <= 0.0 {
            return None;
        }
        let pdf = self.pdf(wo, wi);
        if pdf <= 0.0 || !pdf.is_finite() {
            return None;
        }
        let (f, f_specular) = self.eval(wo, wi);
        Some(BsdfSample { wi, f, f_specular, pdf })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    fn albedo(b: &Bsdf, wo: Vec3A, n: u32) -> Vec3A {
        let mut rng = Rng::for_sample(7, 0, 0);
        let mut sum = Vec3A::ZERO;
        for _ in 0..n {
            if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32()) {
                sum += s.f * s.wi.z / s.pdf;
            }
        }
        sum / n as f32
    }

    #[test]
    fn lambert_albedo_is_its_colour() {
        let b = Bsdf::Lambert {
            albedo: Vec3A::new(0.2, 0.5, 0.9),
        };
        let a = albedo(&b, Vec3A::new(0.3, 0.1, 0.9).normalize(), 1000);
        assert!((a - Vec3A::new(0.2, 0.5, 0.9)).abs().max_element() < 1e-5, "{a}");
    }

    #[test]
    fn lambert_lanes_are_bsdf_sample_bit_for_bit() {
        let mut rng = Rng::for_sample(11, 12, 13);
        let albedo = Vec3A::new(0.3, 0.0, 1.0);
        let b = Bsdf::Lambert { albedo };
        for round in 0..64 {
            let mut u1: [f32; LANES] = std::array::from_fn(|_| rng.next_f32());
            let mut u2: [f32; LANES] = std::array::from_fn(|_| rng.next_f32());
            if round == 0 {
                // The disk's centre, its rim (a direction in the plane: rejected), points next
                // to the rim (tiny densities) and a corner.
                let edges = [
                    (0.5, 0.5),
                    (0.0, 0.5),
                    (0.5, 1.0),
                    (0.999_999_94, 0.5),
                    (0.5, 6e-8),
                    (0.0, 0.0),
                ];
                for (i, (a, c)) in edges.into_iter().enumerate() {
                    (u1[i], u2[i]) = (a, c);
                }
            }
            let s = lambert_sample_lanes(&u1, &u2);
            assert!(
                round > 0 || (s.ok[0] && !s.ok[1]),
                "the centre is kept and the rim rejected"
            );
            for i in 0..LANES {
                // Outgoing directions from grazing (shade's 1e-4 floor) to the normal.
                let wo = Vec3A::new(rng.next_f32() - 0.5, 0.3, [1e-4, 1.0, rng.next_f32()][i % 3]).normalize();
                let want = b.sample(wo, rng.next_f32(), u1[i], u2[i]);
                assert_eq!(s.ok[i], want.is_some(), "u = ({}, {})", u1[i], u2[i]);
                let Some(want) = want else { continue };
                let wi = Vec3A::new(s.wi[0][i], s.wi[1][i], s.wi[2][i]);
                let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
                assert_eq!(bits(wi), bits(want.wi), "u = ({}, {})", u1[i], u2[i]);
                assert_eq!(s.pdf[i].to_bits(), want.pdf.to_bits(), "u = ({}, {})", u1[i], u2[i]);
                assert_eq!(bits(lambert_f(albedo)), bits(want.f));
                assert_eq!(lambert_pdf(wi.z).to_bits(), b.pdf(wo, wi).to_bits());
            }
        }
    }

    #[test]
    fn transport_albedo_is_the_lambert_models() {
        let m = Material {
            kind: MaterialKind::Diffuse,
            color: glam::Vec3::new(2.0, 0.5, -1.0),
            value: 0.0,
        };
        assert_eq!(
            Bsdf::of(&m, false),
            Some(Bsdf::Lambert {
                albedo: transport_albedo(&m)
            })
        );
        assert_eq!(transport_albedo(&m), Vec3A::new(1.0, 0.5, 0.0));
    }

    #[test]
    fn glossy_conserves_energy_and_keeps_most_of_it() {
        for n in [0.0, 1.0, 4.0, 30.0] {
            let b = Bsdf::Coated {
                base: Vec3A::ONE,
                alpha: glossy_alpha(n),
                coat_only: false,
            };
            for cos in [1.0f32, 0.7, 0.3, 0.05] {
                let wo = Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let a = albedo(&b, wo, 200_000).x;
                assert!(a <= 1.0 + 0.01, "n {n} cos {cos}: albedo {a}");
                if cos > 0.2 {
                    assert!(a > 0.7, "n {n} cos {cos}: albedo {a}");
                }
            }
        }
    }

    /// ∫ f cosθi dωi over the hemisphere for `wo` (of the specular part alone with
    /// `specular`), by `n` directions drawn uniformly over it, not by the model's own sampling.
    fn albedo_uniform(b: &Bsdf, wo: Vec3A, specular: bool, n: u32) -> Vec3A {
        let mut rng = Rng::for_sample(9, 1, 2);
        let mut sum = Vec3A::ZERO;
        for _ in 0..n {
            let mut wi = crate::sampling::uniform_sphere(rng.next_f32(), rng.next_f32());
            wi.z = wi.z.abs();
            let (f, f_specular) = b.eval(wo, wi);
            sum += if specular { f_specular } else { f } * wi.z;
        }
        sum * (2.0 * std::f32::consts::PI / n as f32)
    }

    /// The same integral by the model's own sampling, `n` samples weighted by f cos / pdf.
    fn albedo_sampled(b: &Bsdf, wo: Vec3A, specular: bool, n: u32) -> Vec3A {
        let mut rng = Rng::for_sample(7, 0, 0);
        let mut sum = Vec3A::ZERO;
        for _ in 0..n {
            if let Some(s) = b.sample(wo, rng.next_f32(), rng.next_f32(), rng.next_f32()) {
                sum += if specular { s.f_specular } else { s.f } * s.wi.z / s.pdf;
            }
        }
        sum / n as f32
    }

    fn phong(exponent: f32, lobe_only: bool) -> Bsdf {
        Bsdf::Phong {
            albedo: Vec3A::new(0.9, 0.5, 0.2),
            exponent,
            lobe_only,
        }
    }

    #[test]
    fn phong_reflects_no_more_than_a_diffuse_surface_of_its_colour() {
        for n in [0.0, 1.0, 8.0, 64.0, 1000.0] {
            let b = phong(n, false);
            for cos in [1.0f32, 0.7, 0.3, 0.05] {
                let wo = Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let a = albedo(&b, wo, 100_000);
                assert!(
                    a.cmple(Vec3A::new(0.9, 0.5, 0.2) * 1.01).all(),
                    "n {n} cos {cos}: albedo {a}"
                );
                // At normal incidence the lobe lies whole above the surface: all of it comes back.
                if cos == 1.0 {
                    assert!((a.x - 0.9).abs() < 0.01, "n {n}: albedo {a} at normal incidence");
                }
            }
        }
    }

    #[test]
    fn phong_density_is_the_sampling_density() {
        // The model's own estimate converges to the integral that uniform directions estimate
        // only if `pdf` is the density `sample` draws with, lobe alone (which estimates the
        // lobe's part, as the renderer uses it) and mixed (the whole model).
        for (n, lobe_only) in [(0.0, false), (3.0, false), (20.0, false), (20.0, true), (60.0, true)] {
            let b = phong(n, lobe_only);
            for cos in [0.9f32, 0.4] {
                let wo = Vec3A::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let own = albedo_sampled(&b, wo, lobe_only, 200_000).x;
                let uniform = albedo_uniform(&b, wo, lobe_only, 1_000_000).x;
                assert!(
                    (own - uniform).abs() < 0.02 * uniform,
                    "n {n} lobe only {lobe_only} cos {cos}: {own} by its sampling, {uniform} uniformly"
                );
            }
        }
    }

    #[test]
    fn phong_of_exponent_zero_is_lambert() {
        let wo = Vec3A::new(0.3, -0.2, 0.9).normalize();
        let lambert = Bsdf::Lambert {
            albedo: Vec3A::new(0.9, 0.5, 0.2),
        };
        for wi in [
            Vec3A::Z,
            Vec3A::new(0.5, 0.5, 0.7).normalize(),
            Vec3A::new(-0.9, 0.0, 0.1).normalize(),
        ] {
            let (f, _) = phong(0.0, false).eval(wo, wi);
            assert!((f - lambert.eval(wo, wi).0).abs().max_element() < 1e-6, "{wi}: {f}");
        }
    }

    #[test]
    fn phong_highlight_peaks_in_the_mirror_direction() {
        let wo = Vec3A::new(0.6, 0.0, 0.8);
        let b = phong(50.0, false);
        let (peak, spec) = b.eval(wo, mirror_local(wo));
        let (off, _) = b.eval(wo, Vec3A::new(-0.4, 0.3, 0.866).normalize());
        assert!(peak.x > 5.0 * off.x, "{peak} against {off}");
        assert!(
            (spec.x - 0.9 * 0.5 * 52.0 / (2.0 * std::f32::consts::PI)).abs() < 1e-4,
            "{spec}"
        );
    }

    #[test]
    fn phong_number_mapping() {
        assert_eq!(phong_exponent(-1.0), 0.0);
        assert_eq!(phong_exponent(f32::NAN), 0.0);
        assert_eq!(phong_exponent(32.0), 32.0);
        assert_eq!(phong_exponent(1e9), PHONG_MAX_EXPONENT);
        let m = Material {
            kind: MaterialKind::Phong,
            color: glam::Vec3::new(2.0, 0.5, 0.25),
            value: 40.0,
        };
        assert_eq!(
            Bsdf::of(&m, true),
            Some(Bsdf::Phong {
                albedo: Vec3A::new(1.0, 0.5, 0.25),
                exponent: 40.0,
                lobe_only: true
            })
        );
    }

    #[test]
    fn glossy_number_mapping() {
        assert!((glossy_alpha(1.0) - 0.25).abs() < 1e-6);
        assert_eq!(glossy_alpha(0.0), 1.0);
        assert_eq!(glossy_alpha(-3.0), 1.0);
        assert!(glossy_alpha(1e9) >= 1e-3);
    }
}
