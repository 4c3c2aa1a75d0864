//! Which of the catalogue's mistakes can show in a picture of a scene: `diagnose` tries only
//! those, and `check` names only those beside a verdict.

use crate::material::Material;
use crate::mistakes::Mistake;
use crate::scene::Scene;
use crate::settings::{RenderSettings, Stage};

/// What a scene contains, as far as it decides which mistakes can show in its pictures.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SceneContents {
    glass: bool,
    /// Mirrors or glass: what sends reflection rays at stage 2.
    pub specular: bool,
    /// Emissive or Glossy surfaces: in the full renderer their hits send rays of their own.
    pub sampled: bool,
    triangles: bool,
    single_triangles: bool,
    meshes: bool,
    mesh_normals: bool,
    /// Spheres, and spheres whose radius is not 1.
    spheres: bool,
    spheres_not_unit: bool,
    planes: bool,
    lights: usize,
}

impl SceneContents {
    /// What `scene` contains.
    #[must_use]
    pub fn of(scene: &Scene) -> SceneContents {
        let used = |f: fn(&Material) -> bool| {
            (scene.entities.iter()).any(|e| f(&scene.materials[e.material as usize]) && e.primitives > 0)
        };
        let kind = |k: &str| scene.entities.iter().any(|e| e.kind == k && e.primitives > 0);
        SceneContents {
            glass: used(Material::is_glass),
            specular: used(|m| m.sends_reflection_rays(Stage::Two)),
            sampled: used(|m| m.emission().is_some() || m.scatters_at_random()),
            single_triangles: kind("Triangle"),
            triangles: kind("Triangle") || kind("ObjModel"),
            meshes: kind("ObjModel"),
            // Only meshes carry vertex normals.
            mesh_normals: !scene.normals.is_empty(),
            spheres: !scene.spheres.is_empty(),
            spheres_not_unit: scene.spheres.iter().any(|s| s.radius != 1.0),
            planes: !scene.planes.is_empty(),
            lights: scene.lights.len(),
        }
    }

    /// True when mistake `m` can change a picture of this scene under settings `s`.
    #[must_use]
    pub fn can_show(&self, m: Mistake, s: &RenderSettings) -> bool {
        use Mistake as M;
        match m {
            M::FovVertical => s.width != s.height,
            M::RecursionLimit3 => self.specular,
            M::AspectIgnored => s.width != s.height,
            M::PixelCorners | M::ImageFlipped | M::RoundedColours | M::Gamma => true,
            M::NoShadowOffset | M::HugeShadowOffset | M::LightFalloff | M::ShadowPastLight | M::AmbientTerm => {
                self.lights > 0
            }
            M::FirstLightOnly => self.lights > 1,
            M::OneSidedTriangles => self.triangles,
            M::ReversedNormals => self.single_triangles,
            M::RefractionNoNormalFlip
            | M::RefractionNoIndexSwap
            | M::NoTir
            | M::NoFresnel
            | M::FresnelHalf
            | M::Schlick
            | M::GlassReflectionAlongRay
            | M::GlassReflectionOutward
            | M::RefractionOffsetOutside
            | M::EtaEnteringInverted
            | M::FresnelSwapped => self.glass,
            M::ReflectNo2 => self.specular,
            M::StrictEdges => self.triangles,
            M::ObjNoZFlip => self.meshes,
            M::ObjFlatNormals => self.mesh_normals,
            M::SphereNormalUnnormalised => self.spheres_not_unit,
            M::SphereNearRootBehind => self.spheres,
            M::PlaneHitsBehind => self.planes,
            // Elsewhere a light behind the surface is blocked by the surface itself.
            M::NdotLUnclamped => self.mesh_normals && self.lights > 0,
            M::CamAngleRadians => s.camera.angle_deg != 0.0 && s.camera.axis != glam::Vec3::ZERO,
            M::MinHitDistance | M::FirstHitInSceneOrder | M::AccumulatorNotReset => true,
            // With the camera at the origin, only rays from other points choose differently.
            M::NearestByOriginDistance => self.specular || s.camera.position != glam::Vec3::ZERO,
        }
    }
}
