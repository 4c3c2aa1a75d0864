//! The geometry at a packet's hits, sixteen lanes at once (`wide/surface.rs`).

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

pub(crate) mod surface;
pub use surface::{surface_frames, HitPrims, SmoothNormals, SurfaceFrames};
#[cfg(all(test, target_arch = "x86_64"))]
pub(crate) use surface::{surface_frames_avx2, surface_frames_avx512};

/// The surface kernel's baseline build, for the test that compares its instruction-set builds.
#[cfg(test)]
pub(crate) fn surface_frames_impl(rays: &crate::math::RayPacket, g: &HitPrims) -> SurfaceFrames {
    surface::surface_frames_impl(rays, g)
}
