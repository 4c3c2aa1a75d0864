//! The course's common mistakes as render switches: `--mistake NAME[,NAME…]` renders a scene the
//! way a tracer with those mistakes would, so a student can see what a mistake looks like and
//! `diagnose` can search for the mistakes that explain a wrong picture.
//!
//! A render with any mistake goes through the one-ray-at-a-time recursive integrator: its
//! intersector is a `crate::render::Mistaken` wrapper, which offers no wide BVH (so the packet
//! and wave engines are never chosen) and whose [`crate::scene::Intersect::MISTAKEN`] turns on the
//! integrator's few checks. Every other intersector leaves that constant false, so those checks
//! compile away from correct renders.

use std::fmt;

use glam::{Vec3, Vec3A};
use rayscope_scene::{SceneFile, Shape};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::camera::Camera;
use crate::film::Film;

/// One of the course's common mistakes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[repr(u8)]
pub enum Mistake {
    /// The field of view spans the image's height.
    FovVertical,
    /// Both image-plane axes use tan(fov/2): the aspect ratio is ignored.
    AspectIgnored,
    /// Rays through pixel corners instead of centres.
    PixelCorners,
    /// Row 0 is the bottom row.
    ImageFlipped,
    /// Shadow rays start on the surface.
    NoShadowOffset,
    /// Shadow rays start 0.1 units off the surface.
    HugeShadowOffset,
    /// Triangles hit from their back side are ignored.
    OneSidedTriangles,
    /// Triangle normals are (v2 − v0) × (v1 − v0) and never turned towards the ray.
    ReversedNormals,
    /// Leaving glass, the outward normal is used as it is.
    RefractionNoNormalFlip,
    /// Leaving glass, the indices are not swapped.
    RefractionNoIndexSwap,
    /// Total internal reflection is not handled: black.
    NoTir,
    /// Glass only refracts (no Fresnel reflection).
    NoFresnel,
    /// Glass mixes reflection and refraction half and half.
    FresnelHalf,
    /// Schlick's approximation instead of the exact Fresnel equations.
    Schlick,
    /// Recursion stops after 3 bounces.
    RecursionLimit3,
    /// Point lights fall off with the squared distance.
    LightFalloff,
    /// A constant ambient term is added at diffuse hits.
    AmbientTerm,
    /// Shadow rays are blocked by objects beyond the light.
    ShadowPastLight,
    /// Only the first light is counted.
    FirstLightOnly,
    /// Colours are rounded to bytes instead of truncated.
    RoundedColours,
    /// Colours are gamma-corrected before they are written.
    Gamma,
    /// OBJ vertices are used without negating z.
    ObjNoZFlip,
    /// OBJ triangles are shaded with their face normals.
    ObjFlatNormals,
    /// The camera's rotation angle is used as radians.
    CamAngleRadians,
    /// Hits nearer than 0.05 along a ray are ignored.
    MinHitDistance,
    /// The nearest hit is the one nearest the world's origin.
    NearestByOriginDistance,
    /// The first hit in the scene's entity order is kept, not the nearest.
    FirstHitInSceneOrder,
    /// Glass's reflected ray starts along the incident ray.
    GlassReflectionAlongRay,
    /// Glass's reflected ray starts on the outside of the surface.
    GlassReflectionOutward,
    /// The anti-aliasing sum is not reset between pixels.
    AccumulatorNotReset,
    /// Entering glass, η = n instead of 1/n.
    EtaEnteringInverted,
    /// The reflection formula without its factor 2.
    ReflectNo2,
    /// The Fresnel reflectance with cos θi and cos θt exchanged in one term.
    FresnelSwapped,
    /// The triangle's inside test rejects hits near its edges.
    StrictEdges,
    /// A sphere's normal is p − c, not divided by the radius.
    SphereNormalUnnormalised,
    /// From inside a sphere, the root behind the ray's origin is taken.
    SphereNearRootBehind,
    /// The plane test accepts hits behind the ray's origin (t < 0).
    PlaneHitsBehind,
    /// N·L is not clamped at 0: lights behind the shading normal subtract.
    NdotLUnclamped,
    /// The refracted ray starts off the surface on the side the ray came from.
    RefractionOffsetOutside,
}

/// What the catalogue says about a mistake.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct MistakeInfo {
    /// Kebab-case name, as `--mistake` takes it.
    pub name: &'static str,
    /// What the code does wrong.
    pub wrong: &'static str,
    /// What the picture looks like.
    pub looks: &'static str,
    /// The part of the course's marking the mistake costs.
    pub rubric: &'static str,
    /// The `rayscope check` verdicts a ray log of a tracer with the mistake is headed by (the
    /// `image.*` ones with the tracer's picture given to `check --image`).
    pub check: &'static [&'static str],
    /// The `rayscope probe` findings an intersector with the mistake gets, for mistakes of an
    /// intersector (empty where `probe` cannot see the mistake): each a verdict code, narrowed
    /// to a primitive and perhaps a case as `PRIMITIVE[ CASE]: VERDICT` ("triangle back-hit:
    /// missed").
    pub probe: &'static [&'static str],
}

const CAMERA: &str = "Stage 1: camera rays through the pixel grid";
const SHADOWS: &str = "Stage 2: diffuse lighting and shadow rays";
const REFRACTION: &str = "Stage 2: refraction (Snell's law, total internal reflection)";
const FRESNEL: &str = "Stage 2: Fresnel mix of reflection and refraction";
const OUTPUT: &str = "Output: the image matches the reference";
const OBJ: &str = "Stage 3 C: OBJ models";
const NEAREST: &str = "Stage 1: the nearest hit along each ray";

/// The offset [`Mistake::HugeShadowOffset`] moves shadow rays off the surface, in scene units.
pub(crate) const HUGE_OFFSET: f32 = 0.1;
/// The ambient term [`Mistake::AmbientTerm`] adds, as a fraction of the material colour.
pub(crate) const AMBIENT: f32 = 0.1;
/// The distance under which [`Mistake::MinHitDistance`] ignores hits, in scene units.
pub(crate) const MIN_HIT: f32 = 0.05;
/// The share of a triangle's altitude near each edge in which [`Mistake::StrictEdges`] rejects
/// hits (a margin of 0.02 on the barycentric coordinates).
pub(crate) const EDGE_MARGIN: f32 = 0.02;
/// The exponent [`Mistake::Gamma`] raises colours to.
pub(crate) const GAMMA: f32 = 1.0 / 2.2;

impl Mistake {
    /// Every mistake, in catalogue order.
    pub const ALL: [Mistake; 39] = [
        Mistake::FovVertical,
        Mistake::AspectIgnored,
        Mistake::PixelCorners,
        Mistake::ImageFlipped,
        Mistake::NoShadowOffset,
        Mistake::HugeShadowOffset,
        Mistake::OneSidedTriangles,
        Mistake::ReversedNormals,
        Mistake::RefractionNoNormalFlip,
        Mistake::RefractionNoIndexSwap,
        Mistake::NoTir,
        Mistake::NoFresnel,
        Mistake::FresnelHalf,
        Mistake::Schlick,
        Mistake::RecursionLimit3,
        Mistake::LightFalloff,
        Mistake::AmbientTerm,
        Mistake::ShadowPastLight,
        Mistake::FirstLightOnly,
        Mistake::RoundedColours,
        Mistake::Gamma,
        Mistake::ObjNoZFlip,
        Mistake::ObjFlatNormals,
        Mistake::CamAngleRadians,
        Mistake::MinHitDistance,
        Mistake::NearestByOriginDistance,
        Mistake::FirstHitInSceneOrder,
        Mistake::GlassReflectionAlongRay,
        Mistake::GlassReflectionOutward,
        Mistake::AccumulatorNotReset,
        Mistake::EtaEnteringInverted,
        Mistake::ReflectNo2,
        Mistake::FresnelSwapped,
        Mistake::StrictEdges,
        Mistake::SphereNormalUnnormalised,
        Mistake::SphereNearRootBehind,
        Mistake::PlaneHitsBehind,
        Mistake::NdotLUnclamped,
        Mistake::RefractionOffsetOutside,
    ];

    /// The catalogue entry.
    #[must_use]
    pub fn info(self) -> MistakeInfo {
        let (name, wrong, looks, rubric) = match self {
            Mistake::FovVertical => (
                "fov-vertical",
                "spans the 60° field of view over the image's height (Unity's camera, the workshop) instead of its width",
                "a wide image shows more of the scene than it should, a tall one less; square images are unaffected",
                CAMERA,
            ),
            Mistake::AspectIgnored => (
                "aspect-ignored",
                "scales both image-plane axes by tan(fov/2), ignoring the image's width : height",
                "non-square images are stretched: spheres become ellipses; square images are unaffected",
                CAMERA,
            ),
            Mistake::PixelCorners => (
                "pixel-corners",
                "sends rays through (x/W, y/H), the pixels' top-left corners, instead of their centres ((x + 0.5)/W, (y + 0.5)/H)",
                "the whole picture moves half a pixel right and down; differences only along edges",
                CAMERA,
            ),
            Mistake::ImageFlipped => (
                "image-flipped",
                "treats image row 0 as the bottom row (y up in the image) instead of the top",
                "the picture is upside down, mirrored top to bottom",
                CAMERA,
            ),
            Mistake::NoShadowOffset => (
                "no-shadow-offset",
                "starts shadow rays exactly at the hit point, so they can hit the surface they leave",
                "shadow acne: lit surfaces are speckled or striped with dark dots",
                SHADOWS,
            ),
            Mistake::HugeShadowOffset => (
                "huge-shadow-offset",
                "starts shadow rays 0.1 units off the surface (rayscope: 1e-5 of the coordinates' size)",
                "shadows shift and shrink, and come loose where an object meets the surface it stands on",
                SHADOWS,
            ),
            Mistake::OneSidedTriangles => (
                "one-sided-triangles",
                "ignores a triangle hit from its back side (the side its normal points away from)",
                "shadows of triangles seen from behind by the light vanish; triangles seen from behind disappear",
                SHADOWS,
            ),
            Mistake::ReversedNormals => (
                "reversed-normals",
                "computes a triangle's normal as (v2 − v0) × (v1 − v0) and uses it without turning it towards the ray",
                "triangles seen from their front come out black, as if lit from behind",
                SHADOWS,
            ),
            Mistake::RefractionNoNormalFlip => (
                "refraction-no-normal-flip",
                "leaving glass, refracts about the outward normal instead of the one facing the ray (and offsets to the wrong side)",
                "the view through glass is wrong: dark or scrambled spheres",
                REFRACTION,
            ),
            Mistake::RefractionNoIndexSwap => (
                "refraction-no-index-swap",
                "leaving glass, keeps n₁ = 1, n₂ = n instead of swapping them to n₁ = n, n₂ = 1",
                "the view through glass bends the wrong amount and the dark total-internal-reflection rim is missing",
                REFRACTION,
            ),
            Mistake::NoTir => (
                "no-tir",
                "past the critical angle, gives up (black) instead of reflecting the whole ray (total internal reflection)",
                "black patches inside glass where the ray should have reflected",
                REFRACTION,
            ),
            Mistake::NoFresnel => (
                "no-fresnel",
                "ignores the Fresnel equations: glass only refracts (a fixed mix of 0 % reflection)",
                "glass shows no reflections of the room, its rim no bright edge",
                FRESNEL,
            ),
            Mistake::FresnelHalf => (
                "fresnel-half",
                "mixes reflection and refraction half and half instead of by the Fresnel equations",
                "glass looks half mirror: strong reflections over its whole face",
                FRESNEL,
            ),
            Mistake::Schlick => (
                "schlick",
                "uses Schlick's approximation instead of the exact (unpolarised) Fresnel equations",
                "glass differs by a few levels, most near its rim; invisible by eye elsewhere",
                FRESNEL,
            ),
            Mistake::RecursionLimit3 => (
                "recursion-limit-3",
                "stops mirrors and glass after 3 bounces (the course's images need 7 or more)",
                "black where a ray bounces between mirrors and glass more than 3 times",
                "Stage 2: recursive reflection and refraction",
            ),
            Mistake::LightFalloff => (
                "light-falloff",
                "divides each light's contribution by the squared distance to the light",
                "the picture is darker away from the lights (the course's lights do not fall off)",
                SHADOWS,
            ),
            Mistake::AmbientTerm => (
                "ambient-term",
                "adds an ambient term (0.1 × the material colour) at every diffuse hit",
                "shadows are not black and every surface is a little brighter",
                SHADOWS,
            ),
            Mistake::ShadowPastLight => (
                "shadow-past-light",
                "lets anything on the shadow ray block the light, even beyond the light",
                "surfaces go dark wherever something lies behind the light; in a closed room, everything",
                SHADOWS,
            ),
            Mistake::FirstLightOnly => (
                "first-light-only",
                "adds the first light only (the loop over lights returns early)",
                "darker, with the other lights' highlights and shadows missing",
                SHADOWS,
            ),
            Mistake::RoundedColours => (
                "rounded-colours",
                "rounds v · 255 to the nearest byte instead of truncating it like the template's (byte) cast",
                "about half the pixels one level brighter; invisible by eye",
                OUTPUT,
            ),
            Mistake::Gamma => (
                "gamma",
                "gamma-corrects colours (v^(1/2.2)) before writing them; the course writes linear values",
                "a brighter, washed-out picture with lighter shadows' edges",
                OUTPUT,
            ),
            Mistake::ObjNoZFlip => (
                "obj-no-z-flip",
                "places OBJ vertices without negating z (the OBJ file is right-handed, the scene left-handed)",
                "the model is mirrored front to back",
                OBJ,
            ),
            Mistake::ObjFlatNormals => (
                "obj-flat-normals",
                "shades OBJ triangles with their face normals, ignoring the file's vn normals",
                "the model looks faceted instead of smooth",
                OBJ,
            ),
            Mistake::CamAngleRadians => (
                "cam-angle-radians",
                "turns the camera by --cam-angle read as radians (e.g. passed straight to Quaternion.CreateFromAxisAngle) instead of degrees",
                "with --cam-angle the camera looks the wrong way (45 means about 2578°); without it nothing changes",
                "Stage 3 E: custom camera",
            ),
            Mistake::MinHitDistance => (
                "min-hit-distance",
                "ignores every hit nearer than 0.05 along a ray (a large minimum distance as the cure for shadow acne)",
                "shadows come loose where objects touch, and what lies within 0.05 of a surface is missing from its shadows and reflections",
                SHADOWS,
            ),
            Mistake::NearestByOriginDistance => (
                "nearest-by-origin-distance",
                "keeps the hit nearest the world's origin (its position's length) instead of the one nearest the ray's origin",
                "reflections, refractions and anything seen from a moved camera show the wrong surface; the course's camera at the origin is unaffected",
                NEAREST,
            ),
            Mistake::FirstHitInSceneOrder => (
                "first-hit-in-scene-order",
                "keeps the first hit in the scene file's order instead of the nearest (e.g. comparing the lengths of unit incident directions, all 1)",
                "entities listed early cover those listed later, even when they are behind them",
                NEAREST,
            ),
            Mistake::GlassReflectionAlongRay => (
                "glass-reflection-along-ray",
                "starts the glass's reflected ray a little along the incident ray (inside the glass) instead of off the surface on the ray's side",
                "glass shows its inside instead of reflections: its rim and highlights of the room are wrong",
                FRESNEL,
            ),
            Mistake::GlassReflectionOutward => (
                "glass-reflection-outward",
                "starts the glass's reflected ray off the surface along the outward normal, also when it reflects inside the glass",
                "inside glass, rays that should reflect leave it: the dark rims and inner reflections of glass change",
                FRESNEL,
            ),
            Mistake::AccumulatorNotReset => (
                "accumulator-not-reset",
                "never resets the anti-aliasing sum between pixels, so each pixel adds all the pixels before it",
                "from the first lit pixels on, the picture climbs to full brightness: mostly white, or one saturated colour",
                "Anti-aliasing: each pixel the mean of its own samples",
            ),
            Mistake::EtaEnteringInverted => (
                "eta-entering-inverted",
                "entering glass, bends rays with η = n₂ / n₁ = n instead of n₁ / n₂ = 1/n",
                "glass bends light the wrong way: what it shows is shrunk or scrambled, with wide dark rims",
                REFRACTION,
            ),
            Mistake::ReflectNo2 => (
                "reflect-no-2",
                "reflects with d − (d · n) n, the factor 2 forgotten, for mirrors and glass",
                "mirrors and glass reflect along the surface: they show a smeared band of what lies beside them",
                "Stage 2: recursive reflection and refraction",
            ),
            Mistake::FresnelSwapped => (
                "fresnel-swapped",
                "writes one Fresnel term with cos θi and cos θt exchanged, so that the reflected share is rs² or rp² instead of their mean",
                "glass reflects a little too much or too little, most near its rim",
                FRESNEL,
            ),
            Mistake::StrictEdges => (
                "strict-edges",
                "rejects triangle hits within 0.02 of an edge in barycentric coordinates (u > ε, u + v < 1 − ε)",
                "thin cracks along every triangle's edges, through which what lies behind shows",
                NEAREST,
            ),
            Mistake::SphereNormalUnnormalised => (
                "sphere-normal-unnormalised",
                "takes a sphere's normal as p − c without dividing by the radius r, and shades, offsets, reflects and refracts with it; with r = 1 that changes nothing",
                "diffuse spheres of radius under 1 are lit too dimly (N·L times r), over 1 too brightly; mirror and glass spheres of radius under 1 turn black, their rays bent back into the sphere; spheres of radius 1 are unaffected",
                SHADOWS,
            ),
            Mistake::SphereNearRootBehind => (
                "sphere-near-root-behind",
                "returns a sphere's near root t₀ whenever its far root t₁ lies ahead, also when t₀ < 0: a ray starting inside the sphere hits it behind its origin",
                "glass spheres go dark, showing only faint reflections of the room: a ray inside meets the sphere again where it entered, until the recursion limit",
                NEAREST,
            ),
            Mistake::PlaneHitsBehind => (
                "plane-hits-behind",
                "accepts a plane hit at any t (it only checks that d · n ≠ 0), also behind the ray's origin; the nearest hit is then the most negative one",
                "an entirely black image wherever the scene has a plane: camera rays stop on a plane behind the camera, and every shadow ray is blocked by one",
                NEAREST,
            ),
            Mistake::NdotLUnclamped => (
                "n-dot-l-unclamped",
                "adds albedo × light × N·L without the clamp at 0, so a light behind the shading normal whose shadow ray gets through subtracts",
                "smooth models darken in a band where the interpolated normal turns from a light the face still sees while another light shines; elsewhere a light behind a surface is blocked by the surface itself and nothing changes",
                SHADOWS,
            ),
            Mistake::RefractionOffsetOutside => (
                "refraction-offset-outside",
                "starts the refracted ray off the surface on the side the ray came from (p + n·ε, as for a reflection) instead of past it (p − n·ε)",
                "glass goes dark, showing only faint reflections of the room: the refracted ray meets the glass again where it entered, until the recursion limit",
                REFRACTION,
            ),
        };
        MistakeInfo {
            name,
            wrong,
            looks,
            rubric,
            check: self.check_codes(),
            probe: self.probe_codes(),
        }
    }

    /// The `rayscope probe` findings the mistake shows as (see [`MistakeInfo::probe`]).
    fn probe_codes(self) -> &'static [&'static str] {
        match self {
            Mistake::OneSidedTriangles => &["triangle back-hit: missed"],
            // Never turned towards the ray, the reversed normal faces the ray on back-face hits
            // only: most answers follow neither convention the same way, and the front-face
            // hits break the one the back-face hits set.
            Mistake::ReversedNormals => &["triangle: normal-flipped"],
            Mistake::SphereNormalUnnormalised => &["sphere: normal-not-unit"],
            // From the centre, too, the near root lies behind the origin.
            Mistake::SphereNearRootBehind => &["sphere inside: behind-origin", "sphere centre: behind-origin"],
            Mistake::PlaneHitsBehind => &["plane away: behind-origin"],
            _ => &[],
        }
    }

    /// The `rayscope check` verdicts the mistake shows as (see [`MistakeInfo::check`]).
    fn check_codes(self) -> &'static [&'static str] {
        match self {
            Mistake::FovVertical => &["camera.fov-axis"],
            Mistake::AspectIgnored => &["camera.aspect"],
            Mistake::PixelCorners => &["camera.pixel-corner"],
            Mistake::ImageFlipped => &["camera.flipped"],
            Mistake::NoShadowOffset => &["shadow.acne"],
            Mistake::HugeShadowOffset => &["secondary.origin-not-at-hit"],
            Mistake::OneSidedTriangles => &["shadow.one-sided-triangle", "hit.one-sided-triangle"],
            Mistake::ReversedNormals => &["hit.normal-reversed-winding"],
            Mistake::RefractionNoNormalFlip => &["refraction.normal-not-flipped"],
            Mistake::RefractionNoIndexSwap => &["refraction.indices-not-swapped"],
            Mistake::NoTir => &["missing.secondary"],
            Mistake::NoFresnel => &["missing.reflection", "shading.fresnel-none"],
            Mistake::FresnelHalf => &["shading.fresnel-half"],
            Mistake::Schlick => &["shading.fresnel-schlick"],
            Mistake::RecursionLimit3 => &["missing.secondary", "shading.depth-limit"],
            Mistake::LightFalloff | Mistake::AmbientTerm | Mistake::ObjFlatNormals => &["shading.diffuse"],
            Mistake::ShadowPastLight => &["shadow.blocked-beyond-light"],
            Mistake::FirstLightOnly => &["missing.shadow-ray"],
            Mistake::RoundedColours => &["image.rounded"],
            Mistake::Gamma => &["image.gamma"],
            Mistake::ObjNoZFlip => &["hit.surface-wrong"],
            Mistake::CamAngleRadians => &["camera.rotation"],
            Mistake::MinHitDistance => &["hit.near-skipped"],
            Mistake::NearestByOriginDistance => &["hit.origin-distance"],
            Mistake::FirstHitInSceneOrder => &["hit.scene-order"],
            Mistake::GlassReflectionAlongRay => &["secondary.offset-wrong-side"],
            Mistake::GlassReflectionOutward => &["secondary.offset-wrong-side"],
            Mistake::AccumulatorNotReset => &["image.accumulated"],
            Mistake::EtaEnteringInverted => &["refraction.indices-not-swapped"],
            Mistake::ReflectNo2 => &["reflection.not-mirror"],
            Mistake::FresnelSwapped => &["shading.fresnel-swapped-cosines"],
            Mistake::StrictEdges => &["hit.triangle-edge"],
            Mistake::SphereNormalUnnormalised => &["hit.normal-not-unit"],
            Mistake::SphereNearRootBehind | Mistake::PlaneHitsBehind => &["hit.behind-origin"],
            Mistake::NdotLUnclamped => &["shading.diffuse"],
            Mistake::RefractionOffsetOutside => &["secondary.offset-wrong-side"],
        }
    }

    /// The kinds of ray (`reflection`, `refraction`) the mistake's `check` verdicts fall on,
    /// where a verdict it shares with other mistakes falls on other rays for them; empty for any.
    #[must_use]
    pub fn check_ray_kinds(self) -> &'static [&'static str] {
        match self {
            Mistake::GlassReflectionAlongRay | Mistake::GlassReflectionOutward => &["reflection"],
            Mistake::RefractionOffsetOutside => &["refraction"],
            _ => &[],
        }
    }

    /// The kebab-case name.
    #[must_use]
    pub fn name(self) -> &'static str {
        self.info().name
    }

    /// The mistake called `name`.
    #[must_use]
    pub(crate) fn from_name(name: &str) -> Option<Mistake> {
        Mistake::ALL.into_iter().find(|m| m.name() == name)
    }

    fn bit(self) -> u64 {
        1 << self as u8
    }
}

/// A set of [`Mistake`]s, an offset of the student's own where one is given — for shadow
/// rays (`shadow-offset=E`) or for every ray leaving a surface (`ray-offset=E`) — and a factor
/// every colour is multiplied by where one is given (`colour-scale=K`); empty for a correct
/// render. Serialised as a list of names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Mistakes(u64, u32, bool, u32);

/// The name a shadow-ray offset of the student's own goes by: `shadow-offset=0.02`.
const SHADOW_OFFSET: &str = "shadow-offset";

/// The name an offset of the student's own for every ray leaving a surface goes by:
/// `ray-offset=0.02`.
const RAY_OFFSET: &str = "ray-offset";

/// The name a factor every colour is multiplied by goes by: `colour-scale=0.5`.
const COLOUR_SCALE: &str = "colour-scale";

/// The bit of a set's mistakes that loses every glass's refracted light (see
/// [`Mistakes::with_refraction_lost`]); no catalogued mistake has it.
const REFRACTION_LOST: u64 = 1 << 63;

/// The bit of a set's mistakes that loses every glass's reflected light (see
/// [`Mistakes::with_reflection_lost`]); no catalogued mistake has it.
const REFLECTION_LOST: u64 = 1 << 62;

/// The entity kinds whose shadows [`Mistakes::with_shadowless`] takes away, each by its bit
/// from [`SHADOWLESS_BIT`]; no catalogued mistake has them.
const SHADOWLESS_KINDS: [&str; 4] = ["Sphere", "Plane", "Triangle", "ObjModel"];

/// The bit of a set's mistakes for the first of [`SHADOWLESS_KINDS`], the others above it.
const SHADOWLESS_BIT: u32 = 58;

/// The largest colour scale `colour-scale=K` takes: at 256 every lit byte is already 255.
const MAX_COLOUR_SCALE: f32 = 256.0;

impl Mistakes {
    /// No mistakes: the correct render.
    pub const NONE: Mistakes = Mistakes(0, 0, false, 0);

    /// True for the correct render.
    #[must_use]
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.0 == 0 && self.1 == 0 && self.3 == 0
    }

    /// The set with shadow rays started `offset` scene units off the surface along its normal
    /// (the light's direction still taken from the hit point), a student's own epsilon.
    #[must_use]
    pub fn with_shadow_offset(self, offset: f32) -> Mistakes {
        Mistakes(self.0, offset.to_bits(), false, self.3)
    }

    /// The set with every ray leaving a surface — shadow, mirror, glass's reflected and
    /// refracted — started `offset` scene units off it along its normal, to the side it
    /// travels: a student's own epsilon used everywhere.
    #[must_use]
    pub fn with_ray_offset(self, offset: f32) -> Mistakes {
        Mistakes(self.0, offset.to_bits(), true, self.3)
    }

    /// The offset of the student's own that shadow rays start at, where one is given (by
    /// `shadow-offset=E` or `ray-offset=E`).
    #[must_use]
    #[inline]
    pub fn shadow_offset(self) -> Option<f32> {
        (self.1 != 0).then(|| f32::from_bits(self.1))
    }

    /// The offset of the student's own that every ray leaving a surface starts at, where one
    /// is given (`ray-offset=E`).
    #[must_use]
    #[inline]
    pub fn ray_offset(self) -> Option<f32> {
        (self.1 != 0 && self.2).then(|| f32::from_bits(self.1))
    }

    /// The set with every colour multiplied by `k` before it is written as bytes: a student's
    /// lights divided by their count, samples divided by the wrong count, any one factor.
    #[must_use]
    pub fn with_colour_scale(self, k: f32) -> Mistakes {
        Mistakes(self.0, self.1, self.2, k.to_bits())
    }

    /// The factor every colour is multiplied by, where one is given (`colour-scale=K`).
    #[must_use]
    #[inline]
    pub fn colour_scale(self) -> Option<f32> {
        (self.3 != 0).then(|| f32::from_bits(self.3))
    }

    /// The set with every glass's refracted ray bringing back nothing, its reflection kept:
    /// what many different mistakes reduce to (a refracted ray that starts outside, leaves at
    /// once or is never traced), which `diagnose` renders to tell whether a picture can name
    /// one of them. It has no name and is never offered as a mistake.
    #[must_use]
    pub fn with_refraction_lost(self) -> Mistakes {
        Mistakes(self.0 | REFRACTION_LOST, self.1, self.2, self.3)
    }

    /// True when every glass's refracted light is lost ([`Self::with_refraction_lost`]).
    #[must_use]
    #[inline]
    pub fn refraction_lost(self) -> bool {
        self.0 & REFRACTION_LOST != 0
    }

    /// The set with every glass's reflected ray bringing back nothing, its refraction kept:
    /// what many different mistakes reduce to (a reflected ray never traced, started inside
    /// the glass, weighted 0), which `diagnose` renders to tell whether a picture can name one
    /// of them. It has no name and is never offered as a mistake.
    #[must_use]
    pub fn with_reflection_lost(self) -> Mistakes {
        Mistakes(self.0 | REFLECTION_LOST, self.1, self.2, self.3)
    }

    /// True when every glass's reflected light is lost ([`Self::with_reflection_lost`]).
    #[must_use]
    #[inline]
    pub fn reflection_lost(self) -> bool {
        self.0 & REFLECTION_LOST != 0
    }

    /// The set with every entity declared by `command` (`Sphere`, `Plane`, `Triangle`,
    /// `ObjModel`) casting no shadow: shadow rays pass through them, which many different
    /// mistakes reduce to (a shadow test that tries only some kinds of entity, or skips the
    /// entity the ray leaves), and which `diagnose` renders to tell whether a picture can name
    /// one of them. It has no name and is never offered as a mistake. Another command leaves
    /// the set as it is.
    #[must_use]
    pub fn with_shadowless(self, command: &str) -> Mistakes {
        let bit = SHADOWLESS_KINDS
            .iter()
            .position(|&k| k == command)
            .map_or(0, |k| 1 << (SHADOWLESS_BIT + k as u32));
        Mistakes(self.0 | bit, self.1, self.2, self.3)
    }

    /// True when entities declared by `command` cast no shadow ([`Self::with_shadowless`]).
    #[must_use]
    #[inline]
    pub fn shadowless(self, command: &str) -> bool {
        SHADOWLESS_KINDS
            .iter()
            .position(|&k| k == command)
            .is_some_and(|k| self.0 & (1 << (SHADOWLESS_BIT + k as u32)) != 0)
    }

    /// True when entities of some kind cast no shadow ([`Self::with_shadowless`]).
    #[must_use]
    #[inline]
    pub fn any_shadowless(self) -> bool {
        self.0 & (0b1111 << SHADOWLESS_BIT) != 0
    }

    /// True when `m` is in the set.
    #[must_use]
    #[inline(always)]
    pub fn has(self, m: Mistake) -> bool {
        self.0 & m.bit() != 0
    }

    /// The set with `m` added.
    #[must_use]
    pub fn with(self, m: Mistake) -> Mistakes {
        Mistakes(self.0 | m.bit(), self.1, self.2, self.3)
    }

    /// The mistakes in catalogue order.
    pub fn iter(self) -> impl Iterator<Item = Mistake> {
        Mistake::ALL.into_iter().filter(move |&m| self.has(m))
    }

    /// Number of mistakes in the set, an offset of the student's own included.
    #[must_use]
    pub fn len(&self) -> usize {
        self.0.count_ones() as usize + usize::from(self.1 != 0) + usize::from(self.3 != 0)
    }

    /// The set's names in catalogue order, then the offset of the student's own
    /// (`shadow-offset=0.02`, `ray-offset=0.02`).
    fn names(self) -> Vec<String> {
        let mut out: Vec<String> = self.iter().map(|m| m.name().to_string()).collect();
        if let Some(e) = self.shadow_offset() {
            out.push(format!("{}={e}", if self.2 { RAY_OFFSET } else { SHADOW_OFFSET }));
        }
        if let Some(k) = self.colour_scale() {
            out.push(format!("{COLOUR_SCALE}={k}"));
        }
        out
    }

    /// Parses comma-separated names (`no-tir,gamma`; `shadow-offset=E` for shadow rays and
    /// `ray-offset=E` for every ray leaving a surface started that far off it, a positive number
    /// below 1; `colour-scale=K` for every colour multiplied by K); the error names the unknown
    /// one and lists the valid names.
    pub fn parse(s: &str) -> Result<Mistakes, String> {
        let mut set = Mistakes::NONE;
        for name in s.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            for (key, every) in [(SHADOW_OFFSET, false), (RAY_OFFSET, true)] {
                let Some(v) = name.strip_prefix(key).and_then(|r| r.strip_prefix('=')) else {
                    continue;
                };
                match v.parse::<f32>() {
                    Ok(e) if e > 0.0 && e < 1.0 && every => set = set.with_ray_offset(e),
                    Ok(e) if e > 0.0 && e < 1.0 => set = set.with_shadow_offset(e),
                    _ => {
                        return Err(format!(
                            "'{name}': expected {key}=E with E a number greater than 0 and less than 1"
                        ))
                    }
                }
            }
            if let Some(v) = name.strip_prefix(COLOUR_SCALE).and_then(|r| r.strip_prefix('=')) {
                match v.parse::<f32>() {
                    Ok(k) if k > 0.0 && k <= MAX_COLOUR_SCALE && k != 1.0 => set = set.with_colour_scale(k),
                    _ => {
                        return Err(format!(
                            "'{name}': expected {COLOUR_SCALE}=K with K a number greater than 0, at most {MAX_COLOUR_SCALE} and not 1"
                        ))
                    }
                }
                continue;
            }
            if name.starts_with(&format!("{SHADOW_OFFSET}=")) || name.starts_with(&format!("{RAY_OFFSET}=")) {
                continue;
            }
            match Mistake::from_name(name) {
                Some(m) => set = set.with(m),
                None => {
                    let names: Vec<&str> = Mistake::ALL.iter().map(|m| m.name()).collect();
                    return Err(format!(
                        "unknown mistake '{name}'; expected one of: {}, {SHADOW_OFFSET}=E, {RAY_OFFSET}=E or {COLOUR_SCALE}=K (`rayscope mistakes` describes them)",
                        names.join(", ")
                    ));
                }
            }
        }
        Ok(set)
    }

    /// Makes the OBJ mistakes in a parsed scene: meshes mirrored back along z about their
    /// offset, or stripped of their vertex normals.
    pub fn apply_to_file(self, file: &mut SceneFile) {
        for e in &mut file.entities {
            let Shape::Mesh { offset, mesh, .. } = &mut e.shape else {
                continue;
            };
            if self.has(Mistake::ObjNoZFlip) {
                // The loader placed z at −s·z + oz; the student's s·z + oz is its mirror image.
                for p in &mut mesh.positions {
                    p.z = (2.0 * offset.z - f64::from(p.z)) as f32;
                }
                for n in &mut mesh.normals {
                    n.z = -n.z;
                }
            }
            if self.has(Mistake::ObjFlatNormals) {
                mesh.normals.clear();
                for t in &mut mesh.triangles {
                    t.normals = None;
                }
            }
        }
    }

    /// Makes the camera mistakes that change the image plane.
    pub(crate) fn adjust_camera(self, cam: &mut Camera) {
        if self.has(Mistake::AspectIgnored) {
            let t = (cam.settings.fov_deg.to_radians() * 0.5).tan();
            cam.half = glam::Vec2::splat(t);
        }
        if self.has(Mistake::CamAngleRadians) {
            let k = cam.settings.axis.normalize_or_zero();
            if k != Vec3::ZERO {
                cam.rotation = glam::Mat3A::from_axis_angle(k, cam.settings.angle_deg);
            }
        }
    }

    /// A linear colour as the student's output code would write it, in a form the course's
    /// truncating conversion (`crate::film::to_byte`) turns into the student's bytes.
    #[must_use]
    #[inline]
    pub fn output(self, v: Vec3) -> Vec3 {
        let mut v = v;
        if let Some(k) = self.colour_scale() {
            v *= k;
        }
        if self.has(Mistake::Gamma) {
            v = Vec3::new(gamma(v.x), gamma(v.y), gamma(v.z));
        }
        if self.has(Mistake::RoundedColours) {
            v = Vec3::new(rounded(v.x), rounded(v.y), rounded(v.z));
        }
        v
    }

    /// True when [`Self::output`] changes colours.
    #[must_use]
    pub(crate) fn changes_output(self) -> bool {
        self.has(Mistake::Gamma) || self.has(Mistake::RoundedColours) || self.3 != 0
    }

    /// Applies the film-wide mistakes to `film`: the never-reset sum, which makes each pixel the
    /// sum of itself and every pixel before it in the order the student's loops visit them (row
    /// by row from the top-left), then [`Self::output`] to every pixel.
    pub(crate) fn apply_to_film(self, film: &mut Film) {
        if self.has(Mistake::AccumulatorNotReset) {
            let mut sum = Vec3::ZERO;
            for p in &mut film.pixels {
                sum += *p;
                *p = sum;
            }
        }
        if self.changes_output() {
            for p in &mut film.pixels {
                *p = self.output(*p);
            }
        }
    }
}

fn gamma(v: f32) -> f32 {
    if v > 0.0 {
        v.powf(GAMMA)
    } else {
        0.0
    }
}

/// The value whose truncated byte is `round(clamp(v) · 255)`: the middle of that byte's range.
fn rounded(v: f32) -> f32 {
    let c = if v >= 0.0 { v.min(1.0) } else { 0.0 };
    ((c * 255.0).round() + 0.5) / 255.0
}

impl fmt::Display for Mistakes {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.names().join(","))
    }
}

impl Serialize for Mistakes {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.names())
    }
}

impl<'de> Deserialize<'de> for Mistakes {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let names = Vec::<String>::deserialize(d)?;
        Mistakes::parse(&names.join(",")).map_err(serde::de::Error::custom)
    }
}

/// The catalogue as text, for `rayscope mistakes` and `--mistake help`.
#[must_use]
pub fn catalogue_text() -> String {
    let mut out = String::from(
        "The course's common mistakes; render one with --mistake NAME[,NAME…], find them with `rayscope diagnose`.\n\n",
    );
    for m in Mistake::ALL {
        let i = m.info();
        out.push_str(&format!(
            "{}\n  wrong: {}\n  looks: {}\n  costs: {}\n  check: {}\n",
            i.name,
            i.wrong,
            i.looks,
            i.rubric,
            i.check.join(", ")
        ));
        if !i.probe.is_empty() {
            out.push_str(&format!("  probe: {}\n", i.probe.join(", ")));
        }
    }
    out
}

/// The shadow-ray origin a tracer with `mistakes` uses at `point` with normal `normal` (facing
/// the ray), given rayscope's own offset `eps`.
#[must_use]
#[inline]
pub(crate) fn shadow_origin(mistakes: Mistakes, point: Vec3A, normal: Vec3A, eps: f32) -> Vec3A {
    if mistakes.has(Mistake::NoShadowOffset) {
        point
    } else if let Some(e) = mistakes.shadow_offset() {
        point + normal * e
    } else if mistakes.has(Mistake::HugeShadowOffset) {
        point + normal * HUGE_OFFSET
    } else {
        point + normal * eps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_printed_catalogue_says_how_check_and_probe_show_each_mistake() {
        let text = catalogue_text();
        for m in Mistake::ALL {
            let i = m.info();
            let mut entry = format!(
                "{}\n  wrong: {}\n  looks: {}\n  costs: {}\n  check: {}\n",
                i.name,
                i.wrong,
                i.looks,
                i.rubric,
                i.check.join(", ")
            );
            if !i.probe.is_empty() {
                entry.push_str(&format!("  probe: {}\n", i.probe.join(", ")));
            }
            assert!(text.contains(&entry), "{entry}");
            assert!(!text.contains(&format!("{entry}  probe:")), "{entry}");
        }
        assert!(text.contains("  probe: triangle back-hit: missed\n"));
    }

    #[test]
    fn names_round_trip_and_are_kebab_case() {
        for m in Mistake::ALL {
            assert_eq!(Mistake::from_name(m.name()), Some(m));
            assert!(m
                .name()
                .chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'));
        }
        let set = Mistakes::parse("no-tir, gamma").unwrap();
        assert_eq!(set.iter().collect::<Vec<_>>(), [Mistake::NoTir, Mistake::Gamma]);
        assert_eq!(set.to_string(), "no-tir,gamma");
        let err = Mistakes::parse("no-tir,nope").unwrap_err();
        assert!(err.contains("'nope'") && err.contains("fresnel-half"), "{err}");
    }

    #[test]
    fn rounding_and_gamma_reach_the_bytes_the_student_writes() {
        use crate::film::to_byte;
        let r = Mistakes::NONE.with(Mistake::RoundedColours);
        for k in 0..=2550 {
            let v = k as f32 / 2550.0;
            assert_eq!(to_byte(r.output(Vec3::splat(v)).x), (v * 255.0).round() as u8, "{v}");
        }
        let g = Mistakes::NONE.with(Mistake::Gamma);
        assert_eq!(
            to_byte(g.output(Vec3::splat(0.5)).x),
            (0.5f32.powf(GAMMA) * 255.0) as u8
        );
        assert_eq!(g.output(Vec3::splat(-1.0)).x, 0.0);
    }
}
