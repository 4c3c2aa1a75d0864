//! The state only the engines that trace ray packets use (`packets.rs`, `camera_packets.rs`,
//! `wave.rs`), which the integrator holds for them; `packets.rs` fills it in.

use crate::accel::ApexCull;

/// What only the engines that trace ray packets use, set up with the integrator.
#[derive(Debug, Clone, Default)]
pub(crate) struct PacketSetup {
    /// Per material: a hit on it is shaded by point lights alone (see `point_lit_only`).
    pub(crate) point_lit: Vec<bool>,
    /// The flat list seen from the pinhole camera's centre and from each point light, for ray
    /// packets that leave or reach those points (see [`ApexCull`]).
    pub(crate) beams: Beams,
    /// Per sphere: where it sits among the BVH's sphere packets, when it is glass and no other
    /// primitive comes near it ([`crate::scene::Scene::sphere_alone`]), so packets of rays that
    /// refracted into it test it alone.
    pub(crate) lone_spheres: Vec<Option<(u32, u32)>>,
}

/// [`ApexCull`]s of the points many packets' rays share.
#[derive(Debug, Clone, Default)]
pub(crate) struct Beams {
    /// From the camera's centre (pinhole cameras only).
    pub(crate) camera: Option<ApexCull>,
    /// From each point light, in the scene's order.
    pub(crate) lights: Vec<Option<ApexCull>>,
}
