//! Acceleration structures: the 4-wide BVH every ray query traverses and the binary BVH it is
//! collapsed from, cut by role as Embree cuts its kernels (each walk written once, in the file
//! named for it):
//!
//! - `builder.rs`: the binary BVH ([`Bvh`]) over the scene's finite primitives, built with
//!   binned SAH; its walk serves tests only.
//! - `layout.rs`: the 4-wide BVH ([`Bvh4`]): nodes of four child boxes stored
//!   structure-of-arrays, the triangle, sphere and plane packets of four, the flags that tag leaf
//!   references and hits, and the tie rule that orders hits at the same distance.
//! - `collapse.rs`: [`Bvh4::from_binary`], the 4-wide tree made from the binary one, with the
//!   flat packet list of tiny scenes and the single-ray list of small rooms.
//! - `single.rs`: one ray's walks (closest hit, any hit, both at once) and the 1×4 tests of a ray
//!   against a packet's primitives or a node's boxes.
//! - `packet.rs`: sixteen rays' walks through the same tree ([`PacketHits`]), which return what
//!   the single-ray walks return for each ray.
//! - `frustum.rs`: [`ApexCull`], which lets a packet whose rays share an apex (a pinhole camera's
//!   centre, a point light) skip the flat list's primitives outside the packet's cone.
//! - `stream.rs`: many independent rays' walks interleaved, for `rayscope bench rays` (feature
//!   `bench-kernels`).
//!
//! None of them knows the scene, the camera, the integrators, the render loop or the lights: they
//! see primitives (`crate::geometry`), rays (`crate::math`) and lanes (`crate::simd`) only, which
//! `tests/module_graph.rs` checks.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

mod builder;
mod collapse;
mod frustum;
mod layout;
// Crate-visible for the test that compares the kernels' instruction-set builds
// (`crate::simd`'s `kernel_builds`).
pub(crate) mod packet;
mod single;
// Interleaved walks serve `rayscope bench rays` alone; the binary enables `bench-kernels` so that
// the shipped `bench` subcommand keeps its ray-throughput mode.
#[cfg(feature = "bench-kernels")]
mod stream;

pub use builder::{BuildPrim, Bvh, BvhNode};
pub use frustum::ApexCull;
pub use layout::{Bvh4, Node4, PlanePacket, SpherePacket, TriPacket, WideHit};
pub use packet::PacketHits;
#[cfg(feature = "bench-kernels")]
pub use stream::INTERLEAVE_BYTES;
