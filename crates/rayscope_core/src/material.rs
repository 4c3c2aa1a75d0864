//! Materials as the renderer uses them: each [`MaterialKind`] is one [`Lobe`], the way light
//! leaves its surface, and every decision the renderer takes on a material is taken on its lobe.
//!
//! [`Material::lobe`] is the one exhaustive `match` on [`MaterialKind`] (no wildcard arm), so a
//! new kind is a compile error here until its lobe is chosen. The engines (`integrator.rs`'s
//! `trace_hit`, `integrator/packets.rs`'s `trace_packet`, `integrator/wave.rs`'s `wave_step`)
//! switch on the lobe; a [`Lobe::Bsdf`] material is shaded through [`crate::bsdf::Bsdf::of`] and
//! the light-sampling code, so a new reflection model needs a lobe here, its model in
//! `bsdf.rs` and its name in the scene format, and nothing in an engine.

use glam::{Vec3, Vec3A};
use rayscope_scene::{MaterialDef, MaterialKind};
use serde::Serialize;

use crate::settings::{Edition, Stage};

/// How light leaves a surface: what an engine does at a hit on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lobe {
    /// An area light (Emissive): shows its radiance in the full renderer, shaded like a diffuse
    /// surface at stage 2.
    Emitter,
    /// A perfect mirror (Reflective): one reflected ray.
    Mirror,
    /// A smooth dielectric (Refractive): Fresnel glass, a reflected and a refracted ray.
    Dielectric,
    /// Lambertian reflection (Diffuse): [`crate::bsdf::Bsdf::Lambert`], which the wave engine
    /// also shades sixteen lanes at a time.
    Lambert,
    /// Any other non-specular reflection model ([`crate::bsdf::Bsdf::of`]): point lights, emitter
    /// sampling and BSDF sampling in the full renderer, the course's diffuse formula at stage 2.
    Bsdf,
}

/// A material as the integrators use it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Material {
    /// The material's type.
    #[serde(serialize_with = "ser_kind")]
    pub kind: MaterialKind,
    /// Albedo, emitted radiance or absorbance, by kind.
    pub color: Vec3,
    /// Refractive index (Refractive), roughness control (Glossy) or exponent (Phong).
    pub value: f32,
}

fn ser_kind<S: serde::Serializer>(k: &MaterialKind, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(k.name())
}

impl Material {
    /// The renderer's form of a scene file's material: its colour and number in f32.
    #[must_use]
    pub(crate) fn from_def(m: &MaterialDef) -> Material {
        Material {
            kind: m.kind,
            color: m.color.as_vec3(),
            value: m.value as f32,
        }
    }

    /// The way light leaves a surface of this material.
    #[must_use]
    #[inline(always)]
    pub fn lobe(&self) -> Lobe {
        match self.kind {
            MaterialKind::Emissive => Lobe::Emitter,
            MaterialKind::Reflective => Lobe::Mirror,
            MaterialKind::Refractive => Lobe::Dielectric,
            MaterialKind::Diffuse => Lobe::Lambert,
            MaterialKind::Glossy | MaterialKind::Phong => Lobe::Bsdf,
        }
    }

    /// The radiance a surface of this material emits, when it emits any (the full renderer's
    /// area lights).
    #[must_use]
    pub(crate) fn emission(&self) -> Option<Vec3A> {
        (self.is_emitter() && self.color.max_element() > 0.0).then(|| self.color.into())
    }

    /// True when this kind can emit at all, whatever its colour.
    #[must_use]
    pub(crate) fn is_emitter(&self) -> bool {
        self.lobe() == Lobe::Emitter
    }

    /// True when light leaves a surface of this material in a randomly sampled direction even
    /// without indirect light (a reflection model other than Lambert's, whose specular part the
    /// full renderer traces on), so a render that shows it is stochastic (`-q` multiplies its
    /// paths).
    #[must_use]
    pub(crate) fn scatters_at_random(&self) -> bool {
        self.lobe() == Lobe::Bsdf
    }

    /// True when light passing through this material is absorbed along the way (Beer's law,
    /// from the colour) at `stage` in `edition`: coloured glass in the full renderer, from the
    /// 2022 course on (in 2021 the glass colour played no part).
    #[must_use]
    pub(crate) fn absorbs(&self, stage: Stage, edition: Edition) -> bool {
        self.is_glass() && stage == Stage::Full && edition != Edition::Y2021 && self.color != Vec3::ZERO
    }

    /// True when this is glass: a ray that refracts into it starts inside the primitive it hit.
    #[must_use]
    pub fn is_glass(&self) -> bool {
        self.lobe() == Lobe::Dielectric
    }

    /// True when a ray that hits this material may go on as a reflection ray at `stage`: mirrors
    /// and glass at every stage, and in the full renderer a non-Lambertian reflection model's
    /// (and an emitter's, which a tracer may treat as a coated surface).
    #[must_use]
    pub fn sends_reflection_rays(&self, stage: Stage) -> bool {
        match self.lobe() {
            Lobe::Mirror | Lobe::Dielectric => true,
            Lobe::Bsdf | Lobe::Emitter => stage == Stage::Full,
            Lobe::Lambert => false,
        }
    }

    /// True when a hit on this material is shaded at `stage` by point lights alone, with the
    /// course's formula, so its shadow rays can be traced as packets. `lambert_point_lit` says
    /// whether the full renderer's Lambertian vertices are (no emitters, no ambient light).
    #[must_use]
    pub(crate) fn point_lit_only(&self, stage: Stage, lambert_point_lit: bool) -> bool {
        match (stage, self.lobe()) {
            (Stage::One, _) => false,
            (Stage::Two, Lobe::Lambert | Lobe::Bsdf | Lobe::Emitter) => true,
            (Stage::Two, Lobe::Mirror | Lobe::Dielectric) => false,
            (Stage::Full, Lobe::Lambert) => lambert_point_lit,
            (Stage::Full, Lobe::Mirror | Lobe::Dielectric | Lobe::Emitter | Lobe::Bsdf) => false,
        }
    }
}

#[cfg(test)]
mod tests {
    use rayscope_scene::VariantArray;

    use super::*;

    fn material(kind: MaterialKind, color: Vec3) -> Material {
        Material {
            kind,
            color,
            value: 1.5,
        }
    }

    #[test]
    fn the_scattering_lobes_are_exactly_the_kinds_with_a_reflection_model() {
        // The engines shade a Lambert or Bsdf hit through `Bsdf::of`, and only a Lambert one in
        // lanes: a kind with either lobe must have a model, Lambert's for the Lambert lobe.
        for kind in MaterialKind::VARIANTS.iter().copied() {
            let m = material(kind, Vec3::new(0.5, 0.25, 1.0));
            let model = crate::bsdf::Bsdf::of(&m, false);
            let lobe = m.lobe();
            assert_eq!(
                model.is_some(),
                matches!(lobe, Lobe::Lambert | Lobe::Bsdf),
                "{kind:?}: {lobe:?}"
            );
            let lambert = matches!(model, Some(crate::bsdf::Bsdf::Lambert { .. }));
            assert_eq!(lambert, lobe == Lobe::Lambert, "{kind:?}: {lobe:?}");
            assert_eq!(model.is_some_and(|b| b.has_specular()), lobe == Lobe::Bsdf, "{kind:?}");
            assert_eq!(m.scatters_at_random(), lobe == Lobe::Bsdf, "{kind:?}");
        }
    }

    #[test]
    fn only_lit_emissive_materials_emit() {
        for kind in MaterialKind::VARIANTS.iter().copied() {
            let lit = material(kind, Vec3::new(0.0, 2.0, 0.0)).emission();
            assert_eq!(lit.is_some(), kind == MaterialKind::Emissive, "{kind:?}");
            assert_eq!(
                material(kind, Vec3::ZERO).emission(),
                None,
                "{kind:?} in black emits nothing"
            );
        }
    }

    #[test]
    fn only_coloured_glass_absorbs_and_only_in_the_full_renderer() {
        let tinted = material(MaterialKind::Refractive, Vec3::new(0.5, 0.0, 0.0));
        let now = Edition::Y2022;
        assert!(tinted.absorbs(Stage::Full, now));
        assert!(!tinted.absorbs(Stage::Two, now), "stage 2 glass is the course's, clear");
        assert!(
            !tinted.absorbs(Stage::Full, Edition::Y2021),
            "the 2021 course's glass colour plays no part"
        );
        assert!(!material(MaterialKind::Refractive, Vec3::ZERO).absorbs(Stage::Full, now));
        assert!(!material(MaterialKind::Diffuse, Vec3::ONE).absorbs(Stage::Full, now));
    }

    #[test]
    fn stage_two_shades_every_non_specular_kind_with_point_lights() {
        let lit: Vec<_> = (MaterialKind::VARIANTS.iter().copied())
            .filter(|&k| material(k, Vec3::ONE).point_lit_only(Stage::Two, false))
            .collect();
        assert_eq!(
            lit,
            [
                MaterialKind::Diffuse,
                MaterialKind::Emissive,
                MaterialKind::Glossy,
                MaterialKind::Phong
            ]
        );
        assert!(material(MaterialKind::Diffuse, Vec3::ONE).point_lit_only(Stage::Full, true));
        assert!(!material(MaterialKind::Diffuse, Vec3::ONE).point_lit_only(Stage::Full, false));
        assert!(!material(MaterialKind::Glossy, Vec3::ONE).point_lit_only(Stage::Full, true));
        assert!(!material(MaterialKind::Phong, Vec3::ONE).point_lit_only(Stage::Full, true));
    }
}
