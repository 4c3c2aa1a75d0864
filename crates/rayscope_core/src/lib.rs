//! rayscope's renderer: geometry, BVH, camera, materials, integrators and the parallel render loop.
//!
//! Data flows one way: a parsed [`rayscope_scene::SceneFile`] becomes a [`Scene`], which
//! [`render()`] turns into a [`Film`] under [`RenderSettings`].

pub mod accel;
pub mod animation;
pub mod bsdf;
pub mod camera;
pub mod compare;
pub mod contents;
pub mod diagnose;
pub mod edition;
pub mod farm;
pub(crate) mod film;
pub mod geometry;
pub mod integrator;
pub mod lights;
pub(crate) mod material;
pub mod math;
pub mod mistakes;
pub mod observer;
pub mod optics;
pub mod output;
pub mod reference;
pub mod render;
pub mod rng;
pub mod sampling;
pub mod scene;
pub mod settings;
pub mod simd;
pub mod sobol;
pub mod surface;

pub use camera::{Camera, CameraSettings, FovAxis};
pub use film::Film;
pub use math::Ray;
pub use mistakes::{Mistake, Mistakes};
pub use observer::{
    BranchFate, GlassBranch, GlassDecision, NoObserver, RayHitInfo, RayKind, RayNode, RayObserver, RayRecorder, RayTree,
};
pub use render::{render, render_tiles_of, render_with, trace_pixel, trace_pixel_with, Cancelled, RenderOutput};
pub use scene::Scene;
pub use settings::{Channel, DepthLimit, Edition, RenderSettings, Stage};
