//! The COMP30019 ray tracer scene format: a parser with file:line:col diagnostics and an OBJ loader.
//!
//! The parser produces a [`SceneFile`]: a faithful, validated description of what the text says,
//! in the scene's own left-handed coordinates. OBJ models are loaded (and converted from their
//! right-handed space) while parsing, so a scene that parses is a scene that can be rendered.

use std::path::PathBuf;

pub use glam::{DVec3, Vec3};

mod diagnostic;
pub mod input;
mod lexer;
mod obj;
mod parser;

pub use strum::VariantArray;

pub use diagnostic::{Diagnostic, Severity};
pub use obj::{load_obj, parse_obj, ObjOptions};
pub use parser::{load, parse_str};

/// The kind of surface a material describes, as named in the scene file.
///
/// `MaterialKind::VARIANTS` (from [`strum::VariantArray`]) lists every kind in this order: the
/// parser accepts exactly these names, so a new kind is parsed as soon as it is declared here.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, strum::VariantArray)]
pub enum MaterialKind {
    /// Lambertian surface; colour is the albedo.
    Diffuse,
    /// Perfect mirror; colour is unused by the course's renderer.
    Reflective,
    /// Dielectric; the number is the refractive index, colour is the absorbance (Beer's law).
    Refractive,
    /// Area light; colour is the emitted radiance.
    Emissive,
    /// Coloured base under a rough reflective coat; the number controls the roughness.
    Glossy,
    /// Normalised Phong reflection: half Lambertian, half a lobe about the mirror direction; the
    /// number is the lobe's exponent (0 to [`PHONG_MAX_EXPONENT`]).
    Phong,
}

/// Largest exponent a Phong material may have: its lobe is then about a degree wide, and a
/// sharper one is a mirror's business (Reflective).
pub const PHONG_MAX_EXPONENT: f64 = 10_000.0;

impl MaterialKind {
    /// The name used in the scene format.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            MaterialKind::Diffuse => "Diffuse",
            MaterialKind::Reflective => "Reflective",
            MaterialKind::Refractive => "Refractive",
            MaterialKind::Emissive => "Emissive",
            MaterialKind::Glossy => "Glossy",
            MaterialKind::Phong => "Phong",
        }
    }

    /// What the number at the end of a `Material` line means for this kind, when it means
    /// anything (the format requires one for every kind).
    #[must_use]
    pub fn number_meaning(self) -> Option<&'static str> {
        match self {
            MaterialKind::Refractive => Some("refractive index"),
            MaterialKind::Glossy => Some("roughness"),
            MaterialKind::Phong => Some("Phong exponent"),
            MaterialKind::Diffuse | MaterialKind::Reflective | MaterialKind::Emissive => None,
        }
    }
}

/// A `Material "Name" Type (r, g, b) number` line.
#[derive(Debug, Clone, PartialEq)]
pub struct MaterialDef {
    /// Unique name among materials.
    pub name: String,
    /// The material's type.
    pub kind: MaterialKind,
    /// Colour: albedo, emitted radiance or absorbance depending on `kind`.
    pub color: DVec3,
    /// The trailing number: refractive index for Refractive, roughness control for Glossy,
    /// exponent for Phong.
    pub value: f64,
    /// 1-based line of the definition in the scene file.
    pub line: usize,
}

/// A `PointLight "Name" (x, y, z) (r, g, b)` line.
#[derive(Debug, Clone, PartialEq)]
pub struct PointLightDef {
    /// Unique name among lights.
    pub name: String,
    /// Position in scene space.
    pub position: DVec3,
    /// Colour (intensity per channel).
    pub color: DVec3,
    /// 1-based line of the definition in the scene file.
    pub line: usize,
}

/// A triangle mesh loaded from an OBJ file, already in scene space (scaled, offset, z negated).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions in scene space.
    pub positions: Vec<Vec3>,
    /// Vertex normals in scene space (unit length); may be empty.
    pub normals: Vec<Vec3>,
    /// Triangles; polygons are fan-triangulated.
    pub triangles: Vec<MeshTriangle>,
}

/// One triangle of a [`Mesh`]: indices into its positions and, optionally, its normals.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MeshTriangle {
    /// Indices into [`Mesh::positions`].
    pub positions: [u32; 3],
    /// Indices into [`Mesh::normals`], when the face gave normals for all three corners.
    pub normals: Option<[u32; 3]>,
}

/// The geometry of an entity.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// Infinite plane through `point`; `normal` has unit length.
    Plane {
        /// A point on the plane.
        point: DVec3,
        /// Unit normal.
        normal: DVec3,
    },
    /// Sphere with positive radius.
    Sphere {
        /// Centre.
        center: DVec3,
        /// Radius (> 0).
        radius: f64,
    },
    /// Single triangle; its geometric normal is (v1 − v0) × (v2 − v0).
    Triangle {
        /// Corners in file order.
        vertices: [DVec3; 3],
    },
    /// An OBJ model.
    Mesh {
        /// The OBJ file that was loaded (the resolved path).
        source: PathBuf,
        /// Offset as written in the scene.
        offset: DVec3,
        /// Scale as written in the scene.
        scale: f64,
        /// The loaded, transformed mesh.
        mesh: Mesh,
    },
}

impl Shape {
    /// The scene-format command that declares this shape.
    #[must_use]
    pub fn command(&self) -> &'static str {
        match self {
            Shape::Plane { .. } => "Plane",
            Shape::Sphere { .. } => "Sphere",
            Shape::Triangle { .. } => "Triangle",
            Shape::Mesh { .. } => "ObjModel",
        }
    }
}

/// A Plane, Sphere, Triangle or ObjModel line.
#[derive(Debug, Clone, PartialEq)]
pub struct EntityDef {
    /// Unique name among entities.
    pub name: String,
    /// Geometry.
    pub shape: Shape,
    /// Index into [`SceneFile::materials`].
    pub material: usize,
    /// 1-based line of the definition in the scene file.
    pub line: usize,
}

/// A parsed scene file.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SceneFile {
    /// The path the scene was read from (as given).
    pub path: PathBuf,
    /// Materials in file order.
    pub materials: Vec<MaterialDef>,
    /// Point lights in file order.
    pub lights: Vec<PointLightDef>,
    /// Entities in file order.
    pub entities: Vec<EntityDef>,
    /// Warnings found while parsing (extra tokens, degenerate triangles, …).
    pub warnings: Vec<Diagnostic>,
}

/// Why a scene or OBJ file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("cannot read {}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file's content is invalid; the diagnostic names file, line and column.
    #[error("{0}")]
    Invalid(Box<Diagnostic>),
}
