//! Reflection models of the non-specular materials: Lambert (Diffuse) and a coated Lambert base
//! under a rough dielectric GGX coat (Glossy).
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
//! **Lambert in lanes.** The path-tracing wave shades sixteen Lambertian vertices at once with
//! `lambert_sample_lanes`, the Lambert model's sample in lane form (tested below to return
//! [`Bsdf::sample`]'s bits), and with `lambert_f` and `lambert_pdf`, the value and density
//! [`Bsdf::Lambert`] itself is evaluated with.

use std::f32::consts::FRAC_1_PI;

use glam::Vec3A;

use crate::math::not_at_most;
use crate::optics::fresnel;
use crate::sampling::{
    cosine_hemisphere, cosine_hemisphere_lane, cosine_hemisphere_pdf, ggx_d, ggx_g2, ggx_reflect_pdf, ggx_sample_vndf,
    reflect_about,
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
    /// The model of a material whose lobe is [`Lambert`](crate::material::Lobe::Lambert) or
    /// [`Bsdf`](crate::material::Lobe::Bsdf); `None` for the other kinds. With `specular_only` the model samples only its specular part (when
    /// the rest's bounce would carry nothing).
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

    /// Probability of sampling the coat lobe for `wo`.
    #[must_use]
    #[inline]
    pub(crate) fn coat_prob(&self, wo: Vec3A) -> f32 {
        match *self {
            Bsdf::Lambert { .. } => 0.0,
            Bsdf::Coated { coat_only: true, .. } => 1.0,
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
        }
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

    #[test]
    fn glossy_number_mapping() {
        assert!((glossy_alpha(1.0) - 0.25).abs() < 1e-6);
        assert_eq!(glossy_alpha(0.0), 1.0);
        assert_eq!(glossy_alpha(-3.0), 1.0);
        assert!(glossy_alpha(1e9) >= 1e-3);
    }
}
