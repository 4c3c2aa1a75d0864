//! A 4-wide BVH with SIMD node tests and 4-wide triangle and sphere packets.
//!
//! Built by collapsing the binary SAH BVH of [`crate::bvh`]: each node holds up to four
//! children whose bounds are stored structure-of-arrays, so one ray is tested against four boxes
//! with a handful of `Vec4` instructions. Leaves are packets of up to four triangles (or spheres)
//! in the same layout, tested together. This is the layout Embree uses for single rays; with
//! glam's `Vec4` it needs no `unsafe`.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use arrayvec::ArrayVec;
use glam::{BVec4A, Vec3A, Vec4};
use rayon::prelude::*;

use crate::bvh::{Bvh, BvhNode, MAX_LEAF_PRIMS};
use crate::geometry::{Plane, PrimRef, Sphere, Triangle};
use crate::math::{Aabb, Ray};

mod beam;
#[cfg(test)]
mod kernel_builds;
pub(crate) mod packet;
// Interleaved walks serve `rayscope bench rays` alone; the binary enables `bench-kernels` so that
// the shipped `bench` subcommand keeps its ray-throughput mode.
#[cfg(feature = "bench-kernels")]
mod stream;
pub use crate::math::RayPacket;
pub use crate::simd::LANES;
pub use beam::ApexCull;
pub use packet::PacketHits;
#[cfg(feature = "bench-kernels")]
pub use stream::INTERLEAVE_BYTES;

/// Hit tag: a plane (the index is in the low bits).
const TAG_PLANE: u32 = 1 << 30;
/// Hit tag: a sphere.
const TAG_SPHERE: u32 = 2 << 30;
/// Hit tag: a triangle.
const TAG_TRI: u32 = 3 << 30;
/// The tag bits of a hit reference.
const TAG_MASK: u32 = 3 << 30;

/// Child reference flag: the child is a leaf packet, not a node.
const LEAF: u32 = 1 << 31;
/// Leaf flag: the packet holds spheres, not triangles.
const SPHERES: u32 = 1 << 30;
/// Leaf field: how many triangle packets after the one referenced belong to the same leaf (a
/// run of up to [`MAX_RUN`] packets, stored one after another and tested in turn).
const RUN: u32 = 3 << RUN_SHIFT;
const RUN_SHIFT: u32 = 28;

/// An empty child slot.
const EMPTY: u32 = u32::MAX;
/// Lane id of an unused packet lane.
const NO_PRIM: u32 = u32::MAX;

/// One 4-wide node: child bounds as `[axis][min/max]` lanes, and child references.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub struct Node4 {
    /// `bounds[axis][0]` = min of the four children on that axis, `[1]` = max.
    pub bounds: [[Vec4; 2]; 3],
    /// Node index, `LEAF | packet` (with a [`RUN`] of more packets), `LEAF | SPHERES | packet`,
    /// or `EMPTY`.
    pub children: [u32; 4],
    /// Bit i set when `children[i]` is used (sits in the padding of the 128-byte node).
    pub valid: u32,
}

impl Node4 {
    fn empty() -> Self {
        Node4 {
            bounds: [[Vec4::INFINITY, Vec4::NEG_INFINITY]; 3],
            children: [EMPTY; 4],
            valid: 0,
        }
    }

    fn set_children(&mut self, children: [u32; 4]) {
        self.children = children;
        self.valid = children
            .iter()
            .enumerate()
            .fold(0, |m, (i, &c)| m | (u32::from(c != EMPTY) << i));
    }
}

/// Four triangles in structure-of-arrays layout.
#[derive(Debug, Clone, Copy)]
pub struct TriPacket {
    v0: [Vec4; 3],
    e1: [Vec4; 3],
    e2: [Vec4; 3],
    /// e1 × e2, stored because the test needs it for every ray.
    n: [Vec4; 3],
    /// Triangle index of each lane (`NO_PRIM` for padding).
    pub ids: [u32; 4],
}

/// Four infinite planes in structure-of-arrays layout.
#[derive(Debug, Clone, Copy)]
pub struct PlanePacket {
    p: [Vec4; 3],
    /// Unit normals; zero in padding lanes, which therefore never hit.
    n: [Vec4; 3],
    /// Plane index of each lane (`NO_PRIM` for padding).
    pub ids: [u32; 4],
}

/// Four spheres in structure-of-arrays layout.
#[derive(Debug, Clone, Copy)]
pub struct SpherePacket {
    c: [Vec4; 3],
    r2: Vec4,
    /// Sphere index of each lane (`NO_PRIM` for padding).
    pub ids: [u32; 4],
}

/// What a wide-BVH query hit: the primitive and the ray parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideHit {
    /// Ray parameter.
    pub t: f32,
    /// Barycentric u (triangles).
    pub u: f32,
    /// Barycentric v (triangles).
    pub v: f32,
    /// The primitive.
    pub prim: PrimRef,
}

impl WideHit {
    /// The primitive's key, which breaks ties between hits at the same distance (see [`beats`]):
    /// planes, then spheres, then triangles, each by index; never 0.
    #[inline(always)]
    fn key(&self) -> u32 {
        match self.prim {
            PrimRef::Plane(i) => TAG_PLANE | i,
            PrimRef::Sphere(i) => TAG_SPHERE | i,
            PrimRef::Triangle(i) => TAG_TRI | i,
        }
    }
}

/// The 4-wide BVH.
#[derive(Debug, Clone, Default)]
pub struct Bvh4 {
    /// Nodes; the root is node 0 unless `root` is a leaf.
    pub nodes: Vec<Node4>,
    /// Triangle packets.
    pub tris: Vec<TriPacket>,
    /// Sphere packets.
    pub spheres: Vec<SpherePacket>,
    /// Infinite planes, tested before the tree (they have no bounds).
    pub planes: Vec<PlanePacket>,
    /// Packets tested one after another with no tree: the whole scene when it fits in a few
    /// packets, where every ray would open every node anyway.
    pub flat: Vec<u32>,
    /// Full packets that single rays test one after another instead of walking the tree, when
    /// that is cheaper (see [`Bvh4::walk_cost`]): in a small room every wall's box overlaps every
    /// other, so a ray opens most of the tree anyway. Ray packets still walk the tree, whose node
    /// tests they share among sixteen rays. Empty otherwise.
    pub single: Vec<u32>,
    /// Root reference (`EMPTY` for an empty scene).
    pub root: u32,
    /// True when the tree is too deep for the fixed traversal stack (3 entries per level), as
    /// a binned SAH can build for pathological inputs: queries then use a heap stack, so no
    /// branch is ever lost, and ordinary trees pay nothing for the check.
    pub deep: bool,
    /// True when the nodes and packets outgrow the per-core cache (see [`PREFETCH_BYTES`]), so
    /// the walks prefetch the children they will visit.
    pub prefetch: bool,
    /// True when the tree is larger than [`SPLIT_BYTES`]: a pixel then usually covers several
    /// triangles, so a packet's rays part in the lower levels, and each ray finishes alone the
    /// subtrees few of the packet's rays enter.
    pub split_packets: bool,
    /// True when the tree has at least [`SPLIT_SHADOW_NODES`] nodes: shadow packets, whose rays
    /// part as they leave the surface, are split as [`Self::split_packets`] splits camera rays.
    pub split_shadows: bool,
}

/// Trees larger than this split packets of closest-hit rays where they part (see
/// [`Bvh4::split_packets`]). The bookkeeping (each stack entry carries its rays) costs packets
/// that never part 2–4 %; a bumpy torus rendered at 1024² with one sample a pixel broke even at
/// 300 k triangles (36 MB), and gained 4 % at 1 M (121 MB) and 17 % at 4 M.
pub const SPLIT_BYTES: usize = 64 << 20;

/// Trees with at least this many nodes split shadow packets (see [`Bvh4::split_shadows`]). The
/// course's rooms have a handful of nodes, too few levels for a packet's shadow rays to part in;
/// the bunny scene (354 nodes) renders about 1 % faster split.
pub const SPLIT_SHADOW_NODES: usize = 64;

/// Per-ray constants for the packet tests.
struct RayConsts {
    o: [Vec4; 3],
    d: [Vec4; 3],
}

/// Each coordinate of `v` in all four lanes.
#[inline(always)]
fn splat3(v: Vec3A) -> [Vec4; 3] {
    [Vec4::splat(v.x), Vec4::splat(v.y), Vec4::splat(v.z)]
}

impl RayConsts {
    #[inline]
    fn new(ray: &Ray) -> Self {
        Self {
            o: splat3(ray.origin),
            d: splat3(ray.dir),
        }
    }
}

/// Per-ray constants for the node test, made only when a ray enters a tree.
struct NodeConsts {
    inv: [Vec4; 3],
    /// 0 when the direction is positive on the axis (near plane = min), else 1.
    near: [usize; 3],
}

impl NodeConsts {
    #[inline]
    fn new(ray: &Ray) -> Self {
        let inv = ray.dir.recip();
        Self {
            inv: splat3(inv),
            near: [(inv.x < 0.0) as usize, (inv.y < 0.0) as usize, (inv.z < 0.0) as usize],
        }
    }
}

/// Traversal stack entries kept on the machine stack. A 4-wide node pushes at most four entries
/// and pops one, so a tree of depth d needs at most 3d + 1: 64 covers 21 levels, more than any
/// reasonable mesh needs; deeper trees (see [`Bvh4::deep`]) are walked with a heap stack.
const STACK: usize = 64;

/// Factor on a box's exit distance that makes the slab test conservative (≈ 8 ulps).
const SLAB_SLACK: f32 = 1.0 + 1.0 / (1 << 20) as f32;

/// The bound a triangle's undivided distance is filtered against: `t_max` itself, or with
/// `ties` widened by a few ulps so a hit whose divided distance equals `t_max` (which the tie
/// rule may prefer) is not lost to the rounding of `t_max · |d·n|`.
#[inline(always)]
fn far(ties: bool, t_max: f32) -> f32 {
    if ties {
        t_max * SLAB_SLACK
    } else {
        t_max
    }
}

/// Trees larger than this prefetch (about a core's L2 cache). Below it the prefetches find their
/// lines already cached and only cost instructions (the path-traced box, 8 packets: +1.5 %);
/// above it they let the misses of a node's children overlap (a 50 k-triangle torus, 4 MB:
/// incoherent rays +8 %; 1 M triangles: +25 %).
const PREFETCH_BYTES: usize = 1 << 20;

/// `x < t_max` per lane, or with `TIES` `x <= t_max`: a closest-hit query keeps hits at exactly
/// the best distance so far for the tie rule ([`beats`]) to decide; a shadow query's bound is
/// strict. (Triangles filter their undivided distance with [`far`] instead.)
#[inline(always)]
fn below<const TIES: bool>(x: Vec4, t_max: Vec4) -> BVec4A {
    if TIES {
        x.cmple(t_max)
    } else {
        x.cmplt(t_max)
    }
}

/// The most triangle packets in one leaf (at most 4, the [`RUN`] field's range). Three measured
/// best: a run spares the node that would sit over its packets, and a longer one tests packets
/// whose own bounds would have culled them.
const MAX_RUN: usize = 3;

/// Scenes that fit in this many packets are tested flat, without a tree.
const FLAT_PACKETS: usize = 4;
/// Scenes of up to this many packets get a [`Bvh4::single`] list when it costs less than the walk.
const SINGLE_PACKETS: usize = 16;
/// What a node visit costs in the walk, in packet tests: its four box tests, and the ordering,
/// stack and branches around them that a flat list does not have. Calibrated on our scenes: the
/// emitter-lit box (7 packets, walk cost 7.7) path traces 7 % faster from a list; the ambient and
/// beer scenes (10 and 9 packets, walk costs 8.5 and 4.6) 4–9 % slower, and stay with the walk.
const NODE_COST: f32 = 2.0;

impl Bvh4 {
    /// Collapses a binary BVH whose references are `id` (triangle) or `id | sphere_bit` (sphere),
    /// and adds the infinite planes.
    #[must_use]
    pub fn from_binary(
        bvh: &Bvh,
        triangles: &[Triangle],
        spheres: &[Sphere],
        sphere_bit: u32,
        planes: &[Plane],
    ) -> Bvh4 {
        let mut out = Bvh4 {
            root: EMPTY,
            planes: planes
                .chunks(4)
                .enumerate()
                .map(|(k, c)| PlanePacket::new(c, 4 * k as u32))
                .collect(),
            ..Bvh4::default()
        };
        if bvh.nodes.is_empty() {
            return out;
        }
        let mut b = Builder {
            bvh,
            triangles,
            spheres,
            sphere_bit,
            under: prims_under(bvh, sphere_bit),
            out: &mut out,
        };
        let packets = triangles.len().div_ceil(4) + spheres.len().div_ceil(4);
        if packets <= FLAT_PACKETS {
            out.flat = b.full_packets();
            fill_tri_packets(&mut out.tris, triangles);
            return out;
        }
        let root = b.node_ref(0);
        if packets <= SINGLE_PACKETS && (packets as f32) < b.out.walk_cost(root, area(&bvh.nodes[0])) {
            out.single = b.full_packets();
        }
        fill_tri_packets(&mut out.tris, triangles);
        out.root = root;
        out.deep = 3 * out.depth() + 1 > STACK;
        out.prefetch = out.memory_bytes() > PREFETCH_BYTES;
        out.split_packets = out.memory_bytes() > SPLIT_BYTES;
        out.split_shadows = out.nodes.len() >= SPLIT_SHADOW_NODES;
        out
    }

    /// The expected number of tests, in packet tests, of a ray that enters the tree under `root`,
    /// whose bounds have surface area ∝ `root_area` (surface area heuristic: a box is entered
    /// with a probability proportional to its area). A node visit counts as [`NODE_COST`] packet
    /// tests.
    fn walk_cost(&self, root: u32, root_area: f32) -> f32 {
        fn area(node: &Node4, i: usize) -> f32 {
            let d = |a: usize| (node.bounds[a][1][i] - node.bounds[a][0][i]).max(0.0);
            d(0) * d(1) + d(1) * d(2) + d(2) * d(0)
        }
        fn cost(b: &Bvh4, r: u32, a: f32) -> f32 {
            if r & LEAF != 0 {
                let packets = if r & SPHERES != 0 {
                    1
                } else {
                    1 + ((r & RUN) >> RUN_SHIFT)
                };
                return a * packets as f32;
            }
            let node = &b.nodes[r as usize];
            let children: f32 = (0..4)
                .filter(|&i| node.valid & (1 << i) != 0)
                .map(|i| cost(b, node.children[i], area(node, i)))
                .sum();
            a * NODE_COST + children
        }
        if root_area <= 0.0 {
            return 1.0;
        }
        cost(self, root, root_area) / root_area
    }

    /// The closest hit among the packets of `list`.
    #[inline(always)]
    fn closest_flat<const COUNT: bool>(
        &self,
        list: &[u32],
        rc: &RayConsts,
        t_min: f32,
        w: &mut Walk,
        visits: &mut u32,
    ) {
        for &r in list {
            if COUNT {
                *visits += 1;
            }
            if let Some(h) = self.packet_closest::<true>(r, rc, t_min, w.t_best, w.key) {
                w.take(h);
            }
        }
    }

    /// The closest hit in packet `r` (a flat-list entry, never a run): with `TIES`, one that
    /// [`beats`] (`t_max`, `key_max`), else one with `t < t_max`.
    #[inline(always)]
    fn packet_closest<const TIES: bool>(
        &self,
        r: u32,
        rc: &RayConsts,
        t_min: f32,
        t_max: f32,
        key_max: u32,
    ) -> Option<WideHit> {
        if r & SPHERES != 0 {
            self.spheres[(r & !(LEAF | SPHERES)) as usize].closest::<TIES>(rc, t_min, t_max, key_max)
        } else {
            self.tris[(r & !LEAF) as usize].closest::<TIES>(rc, t_min, t_max, key_max)
        }
    }

    /// True when [`Self::packet_closest`] without ties finds a hit in packet `r`.
    #[inline(always)]
    fn packet_occludes(&self, r: u32, rc: &RayConsts, t_min: f32, t_max: f32) -> bool {
        if r & SPHERES != 0 {
            self.spheres[(r & !(LEAF | SPHERES)) as usize].occludes(rc, t_min, t_max)
        } else {
            self.tris[(r & !LEAF) as usize].occludes(rc, t_min, t_max)
        }
    }

    /// The primitive [`Self::leaf_closest`] without ties reports in leaf `r`, if any. Each packet
    /// is first asked only whether it holds a hit, which spares the search for the nearest lane
    /// in the packets that do not; the one that does is then searched as `leaf_closest` would.
    #[inline(always)]
    fn leaf_occluder(&self, r: u32, rc: &RayConsts, t_min: f32, t_max: f32) -> Option<PrimRef> {
        if r & SPHERES != 0 {
            let p = &self.spheres[(r & !(LEAF | SPHERES)) as usize];
            if !p.occludes(rc, t_min, t_max) {
                return None;
            }
            return p.closest::<false>(rc, t_min, t_max, 0).map(|h| h.prim);
        }
        let first = (r & !(LEAF | RUN)) as usize;
        let run = &self.tris[first..=first + ((r & RUN) >> RUN_SHIFT) as usize];
        let p = run.iter().find(|p| p.occludes(rc, t_min, t_max))?;
        p.closest::<false>(rc, t_min, t_max, 0).map(|h| h.prim)
    }

    /// [`Self::packet_closest`] for a tree leaf `r`, which may be a [`RUN`] of packets.
    #[inline(always)]
    fn leaf_closest<const TIES: bool>(
        &self,
        r: u32,
        rc: &RayConsts,
        t_min: f32,
        t_max: f32,
        key_max: u32,
    ) -> Option<WideHit> {
        if r & SPHERES != 0 {
            return self.packet_closest::<TIES>(r, rc, t_min, t_max, key_max);
        }
        let i = (r & !(LEAF | RUN)) as usize;
        let (mut best, mut t, mut key) = (None, t_max, key_max);
        for p in &self.tris[i..=i + ((r & RUN) >> RUN_SHIFT) as usize] {
            if let Some(h) = p.closest::<TIES>(rc, t_min, t, key) {
                if !TIES {
                    return Some(h);
                }
                (t, key) = (h.t, h.key());
                best = Some(h);
            }
        }
        best
    }

    /// Node levels on the longest root-to-leaf path (0 without a tree).
    #[must_use]
    pub fn depth(&self) -> usize {
        fn level(b: &Bvh4, r: u32) -> usize {
            if r == EMPTY || r & LEAF != 0 {
                return 0;
            }
            1 + b.nodes[r as usize]
                .children
                .iter()
                .map(|&c| level(b, c))
                .max()
                .unwrap_or(0)
        }
        level(self, self.root)
    }

    /// Where sphere `k` sits among the sphere packets: (packet, lane), if it is in the tree.
    #[must_use]
    pub fn sphere_slot(&self, k: u32) -> Option<(u32, u32)> {
        self.spheres.iter().enumerate().find_map(|(p, sp)| {
            let lane = sp.ids.iter().position(|&id| id == k)?;
            Some((p as u32, lane as u32))
        })
    }

    /// Bytes used by nodes and packets.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node4>()
            + self.tris.len() * std::mem::size_of::<TriPacket>()
            + self.spheres.len() * std::mem::size_of::<SpherePacket>()
            + self.planes.len() * std::mem::size_of::<PlanePacket>()
    }

    /// The closest hit with `t_min < t < t_max`. When `COUNT`, adds the node and packet tests
    /// made to `visits` (a plane counts as one test).
    #[inline(always)]
    pub fn closest<const COUNT: bool>(&self, ray: &Ray, t_min: f32, t_max: f32, visits: &mut u32) -> Option<WideHit> {
        let rc = RayConsts::new(ray);
        // Key 0: nothing found yet, so a hit at exactly `t_max` does not count.
        let mut walk = Walk {
            best: None,
            t_best: t_max,
            key: 0,
            visits: 0,
        };
        // Planes first: their hit bounds the tree walk, and for rays inside a room most hits are
        // on a floor or a wall.
        for p in &self.planes {
            if COUNT {
                *visits += p.ids.iter().filter(|&&id| id != NO_PRIM).count() as u32;
            }
            if let Some(h) = p.closest::<true>(&rc, t_min, walk.t_best, walk.key) {
                walk.take(h);
            }
        }
        if !self.single.is_empty() {
            self.closest_flat::<COUNT>(&self.single, &rc, t_min, &mut walk, visits);
            return walk.best;
        }
        self.closest_flat::<COUNT>(&self.flat, &rc, t_min, &mut walk, visits);
        if self.root == EMPTY {
            return walk.best;
        }
        let nc = NodeConsts::new(ray);
        if self.deep {
            self.walk_closest_deep::<COUNT>(&rc, &nc, t_min, &mut walk);
        } else {
            self.walk_closest::<COUNT, ArrayVec<(u32, f32), STACK>>(self.root, &rc, &nc, t_min, &mut walk);
        }
        if COUNT {
            *visits += walk.visits;
        }
        walk.best
    }

    /// [`Self::walk_closest`] on the heap, kept out of line so the common walk stays compact.
    #[inline(never)]
    fn walk_closest_deep<const COUNT: bool>(&self, rc: &RayConsts, nc: &NodeConsts, t_min: f32, w: &mut Walk) {
        self.walk_closest::<COUNT, Vec<(u32, f32)>>(self.root, rc, nc, t_min, w);
    }

    /// [`Self::walk_any`] on the heap, kept out of line so the common walk stays compact.
    #[inline(never)]
    fn walk_any_deep(&self, rc: &RayConsts, nc: &NodeConsts, t_min: f32, t_max: f32) -> Option<PrimRef> {
        self.walk_any::<Vec<u32>>(self.root, rc, nc, t_min, t_max)
    }

    /// The closest-hit walk of the subtree `root` (a node or leaf reference) on a stack of type
    /// `S`, which must hold 3 × depth + 1 entries.
    #[inline(always)]
    fn walk_closest<const COUNT: bool, S: TraversalStack<(u32, f32)> + Default>(
        &self,
        root: u32,
        rc: &RayConsts,
        nc: &NodeConsts,
        t_min: f32,
        w: &mut Walk,
    ) {
        // Locals, not fields behind a reference, so the loop keeps them in registers.
        let mut stack = S::default();
        let (mut best, mut t_best, mut key, mut visits) = (w.best, w.t_best, w.key, 0);
        // Stack entries are culled against the best distance widened like box exits (see
        // `node_test`), recomputed only when a hit is found. The widening also keeps boxes that
        // hold a hit at exactly the best distance, which the tie rule may still prefer.
        let mut t_cull = t_best * SLAB_SLACK;
        stack.put((root, t_min));
        while let Some((r, t_near)) = stack.take() {
            if t_near > t_cull {
                continue;
            }
            if COUNT {
                visits += 1;
            }
            if r & LEAF != 0 {
                if let Some(h) = self.leaf_closest::<true>(r, rc, t_min, t_best, key) {
                    (t_best, key) = (h.t, h.key());
                    t_cull = t_best * SLAB_SLACK;
                    best = Some(h);
                }
                continue;
            }
            let node = &self.nodes[r as usize];
            let (mask, tn) = node_test(node, rc, nc, t_min, t_best);
            self.push_children(node, mask, tn, &mut stack);
        }
        *w = Walk {
            best,
            t_best,
            key,
            visits,
        };
    }

    /// Pushes the children of `node` in `mask` (entry distances `tn`), far first, so the nearest
    /// is popped first, prefetching each (see [`Self::prefetch_child`]).
    #[inline(always)]
    fn push_children<S: TraversalStack<(u32, f32)>>(&self, node: &Node4, mask: u32, tn: Vec4, stack: &mut S) {
        if mask == 0 {
            return;
        }
        let tn = tn.to_array();
        if mask & (mask - 1) == 0 {
            // One child hit: no ordering needed.
            let i = mask.trailing_zeros() as usize;
            self.prefetch_child(node.children[i]);
            stack.put((node.children[i], tn[i]));
            return;
        }
        // Several: insertion-sort by entry distance (at most four).
        let mut hits: [(u32, f32); 4] = [(EMPTY, 0.0); 4];
        let mut n = 0;
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            self.prefetch_child(node.children[i]);
            let item = (node.children[i], tn[i]);
            let mut j = n;
            while j > 0 && hits[j - 1].1 < item.1 {
                hits[j] = hits[j - 1];
                j -= 1;
            }
            hits[j] = item;
            n += 1;
        }
        for &h in &hits[..n] {
            stack.put(h);
        }
    }

    /// In trees with [`Self::prefetch`], starts loading the node or packet `r` refers to, so the
    /// cache misses of a node's children overlap instead of coming one after another as the
    /// walk reaches them.
    #[inline(always)]
    pub(crate) fn prefetch_child(&self, r: u32) {
        if !self.prefetch {
            return;
        }
        if r & LEAF == 0 {
            let p = std::ptr::from_ref(&self.nodes[r as usize]).cast::<u8>();
            crate::simd::prefetch(p);
            crate::simd::prefetch(p.wrapping_add(64));
        } else if r & SPHERES == 0 {
            let p = std::ptr::from_ref(&self.tris[(r & !(LEAF | RUN)) as usize]).cast::<u8>();
            for k in 0..4 {
                crate::simd::prefetch(p.wrapping_add(64 * k));
            }
            if r & RUN != 0 {
                let bytes = (1 + ((r & RUN) >> RUN_SHIFT) as usize) * std::mem::size_of::<TriPacket>();
                for k in 4..bytes.div_ceil(64) {
                    crate::simd::prefetch(p.wrapping_add(64 * k));
                }
            }
        }
    }

    /// Some primitive with `t_min < t < t_max` (any hit).
    #[inline]
    pub fn any(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        let rc = RayConsts::new(ray);
        for p in &self.planes {
            if let Some(h) = p.closest::<false>(&rc, t_min, t_max, 0) {
                return Some(h.prim);
            }
        }
        let list = if self.single.is_empty() {
            &self.flat
        } else {
            &self.single
        };
        for &r in list {
            if let Some(p) = self.leaf_occluder(r, &rc, t_min, t_max) {
                return Some(p);
            }
        }
        if self.root == EMPTY || !self.single.is_empty() {
            return None;
        }
        let nc = NodeConsts::new(ray);
        if self.deep {
            self.walk_any_deep(&rc, &nc, t_min, t_max)
        } else {
            self.walk_any::<ArrayVec<u32, STACK>>(self.root, &rc, &nc, t_min, t_max)
        }
    }

    /// [`Self::closest`] for `ray` (`0 < t`) together with whether [`Self::any`] finds
    /// something on `shadow` with `0 < t < shadow_t_max`: the same two answers as the two
    /// queries. In small scenes (a flat list, or a room's single-ray list) both rays go through
    /// the list in one loop, so the two independent tests overlap in the core instead of one
    /// query waiting for the other; in trees the two walks run one after the other.
    #[inline(always)]
    pub fn closest_and_occluded(&self, ray: &Ray, shadow: &Ray, shadow_t_max: f32) -> (Option<WideHit>, bool) {
        let list = if !self.single.is_empty() {
            &self.single
        } else if self.root == EMPTY {
            &self.flat
        } else {
            let blocked = self.any(shadow, 0.0, shadow_t_max).is_some();
            return (self.closest::<false>(ray, 0.0, f32::INFINITY, &mut 0), blocked);
        };
        let (rc, sc) = (RayConsts::new(ray), RayConsts::new(shadow));
        let mut walk = Walk {
            best: None,
            t_best: f32::INFINITY,
            key: 0,
            visits: 0,
        };
        let mut blocked = false;
        for p in &self.planes {
            if let Some(h) = p.closest::<true>(&rc, 0.0, walk.t_best, walk.key) {
                walk.take(h);
            }
            blocked |= p.closest::<false>(&sc, 0.0, shadow_t_max, 0).is_some();
        }
        for &r in list {
            blocked = blocked || self.packet_occludes(r, &sc, 0.0, shadow_t_max);
            if let Some(h) = self.packet_closest::<true>(r, &rc, 0.0, walk.t_best, walk.key) {
                walk.take(h);
            }
        }
        (walk.best, blocked)
    }

    /// The any-hit walk of the subtree `root` on a stack of type `S`, which must hold
    /// 3 × depth + 1 entries.
    #[inline(always)]
    fn walk_any<S: TraversalStack<u32> + Default>(
        &self,
        root: u32,
        rc: &RayConsts,
        nc: &NodeConsts,
        t_min: f32,
        t_max: f32,
    ) -> Option<PrimRef> {
        let mut stack = S::default();
        stack.put(root);
        while let Some(r) = stack.take() {
            if r & LEAF != 0 {
                if let Some(p) = self.leaf_occluder(r, rc, t_min, t_max) {
                    return Some(p);
                }
                continue;
            }
            let node = &self.nodes[r as usize];
            let (mut mask, _) = node_test(node, rc, nc, t_min, t_max);
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                self.prefetch_child(node.children[i]);
                stack.put(node.children[i]);
            }
        }
        None
    }
}

/// The closest-hit walk's running result.
struct Walk {
    best: Option<WideHit>,
    t_best: f32,
    /// The best hit's [`WideHit::key`], 0 while there is none.
    key: u32,
    visits: u32,
}

impl Walk {
    /// Makes `h` the best hit.
    #[inline(always)]
    fn take(&mut self, h: WideHit) {
        (self.t_best, self.key) = (h.t, h.key());
        self.best = Some(h);
    }
}

/// True when a hit at `t` on the primitive with key `key` is preferred to the best so far at
/// `t_best` with key `key_best`: it is nearer, or exactly as near and its key is lower. With
/// `key_best` = 0 (nothing found), `t_best` is a strict bound. Ties broken this way make the
/// closest hit independent of the order primitives are visited in, so a packet walk and a
/// single-ray walk (which visit leaves in different orders) agree even where a ray meets two
/// primitives at exactly the same distance, as at the corner of two walls.
#[inline(always)]
pub(crate) fn beats(t: f32, key: u32, t_best: f32, key_best: u32) -> bool {
    t < t_best || (t == t_best && key < key_best)
}

/// A traversal stack: the fixed-size one, or a heap one for trees too deep for it.
trait TraversalStack<T> {
    /// Pushes `x` (the caller has checked that the tree fits).
    fn put(&mut self, x: T);
    /// Pops the top entry.
    fn take(&mut self) -> Option<T>;
}

impl<T, const N: usize> TraversalStack<T> for ArrayVec<T, N> {
    #[inline(always)]
    fn put(&mut self, x: T) {
        // Cannot fail: trees too deep for this stack use the heap one (`Bvh4::deep`).
        let _ = self.try_push(x);
    }
    #[inline(always)]
    fn take(&mut self) -> Option<T> {
        self.pop()
    }
}

impl<T> TraversalStack<T> for Vec<T> {
    #[inline(always)]
    fn put(&mut self, x: T) {
        self.push(x);
    }
    #[inline(always)]
    fn take(&mut self) -> Option<T> {
        self.pop()
    }
}

/// Slab test of the ray against a node's four child boxes: hit mask and entry distances.
#[inline(always)]
fn node_test(node: &Node4, rc: &RayConsts, nc: &NodeConsts, t_min: f32, t_max: f32) -> (u32, Vec4) {
    let mut t0 = Vec4::splat(t_min);
    let mut t1 = Vec4::splat(t_max);
    for a in 0..3 {
        let n = nc.near[a];
        let tn = (node.bounds[a][n] - rc.o[a]) * nc.inv[a];
        let tf = (node.bounds[a][1 - n] - rc.o[a]) * nc.inv[a];
        // SSE max/min return their second operand when either is NaN, so with the running interval
        // second a NaN from 0·∞ (origin on a slab plane of
        // an axis-parallel ray) then leaves the interval unchanged instead of poisoning it.
        t0 = tn.max(t0);
        t1 = tf.min(t1);
    }
    // The exit distance is widened by a few ulps: slab distances are rounded differently from a
    // primitive's own distance, and a primitive lying on its box's face (a wall) must not be
    // culled by that rounding while a farther hit is kept. Empty slots have inverted bounds and
    // never pass, except for degenerate rays; mask them out explicitly so traversal can never
    // follow one.
    (t0.cmple(t1 * Vec4::splat(SLAB_SLACK)).bitmask() & node.valid, t0)
}

#[inline(always)]
fn cross(a: &[Vec4; 3], b: &[Vec4; 3]) -> [Vec4; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

#[inline(always)]
fn dot(a: &[Vec4; 3], b: &[Vec4; 3]) -> Vec4 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The lane with the smallest `t` among `mask`; of lanes at exactly the same `t`, the lowest,
/// which holds the lowest primitive index (packets keep their ids in ascending order), as the
/// tie rule ([`beats`]) wants.
#[inline(always)]
fn nearest_lane(mask: BVec4A, t: Vec4) -> Option<usize> {
    if !mask.any() {
        return None;
    }
    let t = Vec4::select(mask, t, Vec4::INFINITY);
    let m = t.min_element();
    Some((t.cmpeq(Vec4::splat(m)) & mask).bitmask().trailing_zeros() as usize)
}

/// The lanes of a triangle packet a ray meets, before the division: the hit mask, and per lane
/// the distance, u and v, each still multiplied by `a` = |d · n|.
struct Undivided {
    mask: BVec4A,
    t: Vec4,
    u: Vec4,
    v: Vec4,
    a: Vec4,
}

impl TriPacket {
    /// Möller–Trumbore on four triangles at once up to the division, rearranged around the
    /// stored normal: the lanes whose triangle the ray meets with `t_min < t < t_far` (compared
    /// undivided, so the caller decides on the divided distance), or `None` when there are none.
    #[inline(always)]
    fn undivided(&self, rc: &RayConsts, t_min: f32, t_far: f32) -> Option<Undivided> {
        let c = [self.v0[0] - rc.o[0], self.v0[1] - rc.o[1], self.v0[2] - rc.o[2]];
        let den = dot(&rc.d, &self.n);
        let s = Vec4::ONE.copysign(den);
        let a = den.abs();
        let t = dot(&c, &self.n) * s;
        // The supporting planes first: a shadow ray that ends before every plane (a wall behind
        // the light) is done after a third of the work.
        let in_range = den.cmpne(Vec4::ZERO) & t.cmpgt(Vec4::splat(t_min) * a) & t.cmplt(Vec4::splat(t_far) * a);
        if !in_range.any() {
            return None;
        }
        let r = cross(&rc.d, &c);
        let u = dot(&self.e2, &r) * -s;
        let v = dot(&self.e1, &r) * s;
        let zero = Vec4::ZERO;
        let mask = in_range & u.cmpge(zero) & v.cmpge(zero) & (u + v).cmple(a);
        mask.any().then_some(Undivided { mask, t, u, v, a })
    }

    /// The closest hit in the packet (same arithmetic as [`Triangle`]'s routine, the division
    /// made only when some lane hits).
    #[inline(always)]
    fn closest<const TIES: bool>(&self, rc: &RayConsts, t_min: f32, t_max: f32, key_max: u32) -> Option<WideHit> {
        let h = self.undivided(rc, t_min, far(TIES, t_max))?;
        let t = h.t / h.a;
        let i = nearest_lane(h.mask, t)?;
        let ti = t.to_array()[i];
        // The numerator test can pass by a rounding error (or, with `TIES`, by its slack) for a
        // hit that, divided, is no nearer than `t_max`; the divided distance decides.
        if !beats(ti, TAG_TRI | self.ids[i], t_max, key_max) {
            return None;
        }
        let a = h.a.to_array()[i];
        Some(WideHit {
            t: ti,
            u: h.u.to_array()[i] / a,
            v: h.v.to_array()[i] / a,
            prim: PrimRef::Triangle(self.ids[i]),
        })
    }

    /// True when [`Self::closest`] without ties would find a hit: some lane's triangle meets
    /// the ray with `t_min < t < t_max`, without choosing the nearest.
    #[inline(always)]
    fn occludes(&self, rc: &RayConsts, t_min: f32, t_max: f32) -> bool {
        // As in `closest`, the divided distance decides; the nearest lane is below `t_max`
        // exactly when some lane is.
        self.undivided(rc, t_min, far(false, t_max))
            .is_some_and(|h| (h.mask & (h.t / h.a).cmplt(Vec4::splat(t_max))).any())
    }
}

impl SpherePacket {
    /// The numerically careful sphere test of [`Sphere`] on four spheres at once: the lanes
    /// whose sphere the ray meets with `t_min < t` and `t` below `t_max` (see [`below`]), with
    /// each lane's nearer such distance, or `None` when no lane's ray meets its sphere at all.
    #[inline(always)]
    fn hits<const TIES: bool>(&self, rc: &RayConsts, t_min: f32, t_max: f32) -> Option<(BVec4A, Vec4)> {
        let f = [rc.o[0] - self.c[0], rc.o[1] - self.c[1], rc.o[2] - self.c[2]];
        let b = -dot(&f, &rc.d);
        let l = [f[0] + rc.d[0] * b, f[1] + rc.d[1] * b, f[2] + rc.d[2] * b];
        let disc = self.r2 - dot(&l, &l);
        let ok = disc.cmpge(Vec4::ZERO);
        if !ok.any() {
            return None;
        }
        let c = dot(&f, &f) - self.r2;
        let sq = Vec4::from_array(disc.max(Vec4::ZERO).to_array().map(f32::sqrt));
        let q = b + sq.copysign(b);
        let t0 = c / q;
        let t1 = q;
        let lo = t0.min(t1);
        let hi = t0.max(t1);
        let (tmin, tmax) = (Vec4::splat(t_min), Vec4::splat(t_max));
        let ok = ok & q.cmpne(Vec4::ZERO);
        let lo_ok = lo.cmpgt(tmin) & below::<TIES>(lo, tmax);
        let hi_ok = hi.cmpgt(tmin) & below::<TIES>(hi, tmax);
        Some((ok & (lo_ok | hi_ok), Vec4::select(lo_ok, lo, hi)))
    }

    /// True when [`Self::closest`] without ties would find a hit: some lane's sphere meets the
    /// ray with `t_min < t < t_max`, without choosing the nearest.
    #[inline(always)]
    fn occludes(&self, rc: &RayConsts, t_min: f32, t_max: f32) -> bool {
        self.hits::<false>(rc, t_min, t_max).is_some_and(|(mask, _)| mask.any())
    }

    /// The nearest hit among the packet's spheres.
    #[inline(always)]
    fn closest<const TIES: bool>(&self, rc: &RayConsts, t_min: f32, t_max: f32, key_max: u32) -> Option<WideHit> {
        let (mask, t) = self.hits::<TIES>(rc, t_min, t_max)?;
        let i = nearest_lane(mask, t)?;
        if TIES && !beats(t.to_array()[i], TAG_SPHERE | self.ids[i], t_max, key_max) {
            return None;
        }
        Some(WideHit {
            t: t.to_array()[i],
            u: 0.0,
            v: 0.0,
            prim: PrimRef::Sphere(self.ids[i]),
        })
    }
}

impl PlanePacket {
    /// Packs up to four planes whose indices start at `first`.
    fn new(planes: &[Plane], first: u32) -> Self {
        let (mut p, mut n) = ([[0f32; 4]; 3], [[0f32; 4]; 3]);
        let mut ids = [NO_PRIM; 4];
        for (l, pl) in planes.iter().enumerate() {
            for a in 0..3 {
                p[a][l] = pl.point[a];
                n[a][l] = pl.normal[a];
            }
            ids[l] = first + l as u32;
        }
        PlanePacket {
            p: p.map(Vec4::from),
            n: n.map(Vec4::from),
            ids,
        }
    }

    /// [`Plane`]'s routine on four planes at once (same arithmetic).
    #[inline(always)]
    fn closest<const TIES: bool>(&self, rc: &RayConsts, t_min: f32, t_max: f32, key_max: u32) -> Option<WideHit> {
        let den = dot(&self.n, &rc.d);
        let w = [self.p[0] - rc.o[0], self.p[1] - rc.o[1], self.p[2] - rc.o[2]];
        let t = dot(&w, &self.n) / den;
        let tmax = Vec4::splat(t_max);
        let mask = den.cmpne(Vec4::ZERO) & t.cmpgt(Vec4::splat(t_min)) & below::<TIES>(t, tmax);
        let i = nearest_lane(mask, t)?;
        if TIES && !beats(t.to_array()[i], TAG_PLANE | self.ids[i], t_max, key_max) {
            return None;
        }
        Some(WideHit {
            t: t.to_array()[i],
            u: 0.0,
            v: 0.0,
            prim: PrimRef::Plane(self.ids[i]),
        })
    }
}

/// The references under a subtree small enough for one leaf (at most four triangles and four
/// spheres), or a binary leaf's.
type Refs = ArrayVec<u32, MAX_LEAF_PRIMS>;
/// Up to four triangles that make one packet.
type Group = ArrayVec<u32, 4>;
/// The packets of a leaf's run.
type Groups = ArrayVec<Group, MAX_RUN>;

/// A [`Group`] of `ids` (at most four).
fn group(ids: &[u32]) -> Group {
    ids.iter().copied().collect()
}

struct Builder<'a> {
    bvh: &'a Bvh,
    triangles: &'a [Triangle],
    spheres: &'a [Sphere],
    sphere_bit: u32,
    /// Per binary node: the triangles and spheres under it (see [`prims_under`]).
    under: Vec<[u8; 2]>,
    out: &'a mut Bvh4,
}

/// Per node of `bvh`: how many triangles and spheres its subtree holds, saturating at 255 (what
/// matters is whether they fit one packet of each, see [`Builder::small`]). Counted once for
/// every node, bottom up: the collapse asks it of the same subtrees again and again while it
/// gathers a node's children.
fn prims_under(bvh: &Bvh, sphere_bit: u32) -> Vec<[u8; 2]> {
    let mut counts = vec![[0u8; 2]; bvh.nodes.len()];
    // A node's children come after it, so walking backwards meets them first.
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        counts[i] = if n.count > 0 {
            let leaf = bvh.leaf(n);
            let spheres = leaf.iter().filter(|&&r| r & sphere_bit != 0).count();
            [(leaf.len() - spheres).min(255) as u8, spheres.min(255) as u8]
        } else {
            let (l, r) = (counts[i + 1], counts[n.offset as usize]);
            [l[0].saturating_add(r[0]), l[1].saturating_add(r[1])]
        };
    }
    counts
}

impl Builder<'_> {
    /// The reference for binary node `i`: a 4-wide node, or a packet for a small leaf.
    fn node_ref(&mut self, i: usize) -> u32 {
        if let Some(r) = self.leaf_of(i) {
            return r;
        }
        let idx = self.out.nodes.len();
        self.out.nodes.push(Node4::empty());
        self.fill_node(i, idx);
        idx as u32
    }

    /// A leaf reference when binary node `i` is a leaf or a subtree small enough for one.
    fn leaf_of(&mut self, i: usize) -> Option<u32> {
        let n = &self.bvh.nodes[i];
        if n.count > 0 {
            return Some(self.leaf_ref(n));
        }
        // A subtree of at most four triangles and four spheres becomes one leaf of full packets:
        // a packet tests four primitives for the price of one, so small binary leaves would
        // waste lanes and add node tests.
        let mut refs = Refs::new();
        if self.collect_small(i, &mut refs) {
            return Some(self.leaf_ref_of(&refs));
        }
        // A few small triangle-only subtrees: a run of packets, so no node is spent on them.
        let mut groups = Groups::new();
        self.tri_groups(i, &mut groups).then(|| self.tri_run(&groups))
    }

    /// Makes 4-wide node `idx` from interior binary node `i`. A node's interior children are
    /// stored next to each other (and its leaf packets too), so the cache lines a ray needs after
    /// a node test are adjacent in memory.
    fn fill_node(&mut self, i: usize, idx: usize) {
        let n = &self.bvh.nodes[i];
        // Gather up to four children by opening the largest interior child, as Embree does.
        let mut kids: Vec<usize> = vec![i + 1, n.offset as usize];
        loop {
            if kids.len() >= 4 {
                break;
            }
            let pick = kids
                .iter()
                .enumerate()
                .filter(|(_, &k)| self.bvh.nodes[k].count == 0 && !self.small(k))
                .max_by(|a, b| area(&self.bvh.nodes[*a.1]).total_cmp(&area(&self.bvh.nodes[*b.1])))
                .map(|(j, _)| j);
            let Some(j) = pick else { break };
            let k = kids.swap_remove(j);
            kids.push(k + 1);
            kids.push(self.bvh.nodes[k].offset as usize);
        }
        let mut bounds = [[[f32::INFINITY; 4], [f32::NEG_INFINITY; 4]]; 3];
        let mut children = [EMPTY; 4];
        let mut interior = Vec::with_capacity(4);
        for (slot, &k) in kids.iter().enumerate() {
            let kn = self.bvh.nodes[k];
            for a in 0..3 {
                bounds[a][0][slot] = kn.min[a];
                bounds[a][1][slot] = kn.max[a];
            }
            match self.leaf_of(k) {
                Some(r) => children[slot] = r,
                None => interior.push((slot, k)),
            }
        }
        let base = self.out.nodes.len();
        for (j, &(slot, _)) in interior.iter().enumerate() {
            self.out.nodes.push(Node4::empty());
            children[slot] = (base + j) as u32;
        }
        for (j, &(_, k)) in interior.iter().enumerate() {
            self.fill_node(k, base + j);
        }
        let node = &mut self.out.nodes[idx];
        for a in 0..3 {
            node.bounds[a] = [Vec4::from(bounds[a][0]), Vec4::from(bounds[a][1])];
        }
        node.set_children(children);
    }

    /// Appends the references under node `i` to `out` when they fit in one triangle packet and
    /// one sphere packet; false when they do not.
    fn collect_small(&self, i: usize, out: &mut Refs) -> bool {
        if !self.small(i) {
            return false;
        }
        self.gather(i, out);
        true
    }

    /// True when binary node `i`'s subtree fits one triangle packet and one sphere packet.
    fn small(&self, i: usize) -> bool {
        let [tris, spheres] = self.under[i];
        tris <= 4 && spheres <= 4
    }

    /// Appends the references under node `i` (a small subtree) to `out`.
    fn gather(&self, i: usize, out: &mut Refs) {
        let n = &self.bvh.nodes[i];
        if n.count > 0 {
            out.extend(self.bvh.leaf(n).iter().copied());
        } else {
            self.gather(i + 1, out);
            self.gather(n.offset as usize, out);
        }
    }

    fn leaf_ref(&mut self, n: &BvhNode) -> u32 {
        let bvh = self.bvh;
        self.leaf_ref_of(bvh.leaf(n))
    }

    /// A leaf: one packet, a run of triangle packets, or a small node over triangle and sphere
    /// packets when the leaf mixes them.
    fn leaf_ref_of(&mut self, refs: &[u32]) -> u32 {
        let tris: Refs = refs.iter().copied().filter(|r| r & self.sphere_bit == 0).collect();
        let sph: Refs = refs
            .iter()
            .filter(|r| *r & self.sphere_bit != 0)
            .map(|r| r & !self.sphere_bit)
            .collect();
        if sph.is_empty() && tris.len() <= 4 * MAX_RUN {
            let groups: Groups = tris.chunks(4).map(group).collect();
            return self.tri_run(&groups);
        }
        let mut parts = Vec::new();
        for chunk in tris.chunks(4) {
            parts.push(self.tri_packet(chunk));
        }
        for chunk in sph.chunks(4) {
            parts.push(self.sphere_packet(chunk));
        }
        if parts.len() == 1 {
            return parts[0];
        }
        // Mixed leaf: a node over the packets, each with its own bounds so a ray that misses
        // the spheres skips their packet.
        let idx = self.out.nodes.len();
        let mut node = Node4::empty();
        let mut lo = [[f32::INFINITY; 4]; 3];
        let mut hi = [[f32::NEG_INFINITY; 4]; 3];
        let tri_groups = tris.chunks(4).map(|c| {
            c.iter()
                .fold(Aabb::EMPTY, |b, &t| b.union(self.triangles[t as usize].bounds()))
        });
        let sph_groups = sph.chunks(4).map(|c| {
            c.iter()
                .fold(Aabb::EMPTY, |b, &t| b.union(self.spheres[t as usize].bounds()))
        });
        for (slot, b) in tri_groups.chain(sph_groups).take(4).enumerate() {
            for a in 0..3 {
                lo[a][slot] = b.min[a];
                hi[a][slot] = b.max[a];
            }
        }
        for a in 0..3 {
            node.bounds[a] = [Vec4::from(lo[a]), Vec4::from(hi[a])];
        }
        let mut children = [EMPTY; 4];
        for (s, p) in parts.iter().take(4).enumerate() {
            children[s] = *p;
        }
        node.set_children(children);
        self.out.nodes.push(node);
        idx as u32
    }

    /// Appends the triangles under node `i` to `groups`, one group per subtree small enough for a
    /// packet; false when the subtree holds spheres or needs more than [`MAX_RUN`] packets.
    fn tri_groups(&self, i: usize, groups: &mut Groups) -> bool {
        let n = &self.bvh.nodes[i];
        let mut refs = Refs::new();
        if n.count > 0 {
            let leaf = self.bvh.leaf(n);
            if refs.try_extend_from_slice(leaf).is_err() {
                // Too many for a run of packets under one node.
                return false;
            }
        } else if !self.collect_small(i, &mut refs) {
            return self.tri_groups(i + 1, groups) && self.tri_groups(n.offset as usize, groups);
        }
        if refs.iter().any(|r| r & self.sphere_bit != 0) {
            return false;
        }
        if groups.len() + refs.len().div_ceil(4) > MAX_RUN {
            return false;
        }
        groups.extend(refs.chunks(4).map(group));
        true
    }

    /// A leaf of consecutive triangle packets, one per group (at most [`MAX_RUN`]).
    fn tri_run(&mut self, groups: &[Group]) -> u32 {
        let first = self.tri_packet(&groups[0]);
        for g in &groups[1..] {
            self.tri_packet(g);
        }
        first | ((groups.len() as u32 - 1) << RUN_SHIFT)
    }

    /// The whole scene as full packets, spheres first: in a room of walls they are what casts
    /// shadows, so shadow rays stop sooner.
    fn full_packets(&mut self) -> Vec<u32> {
        let tri_ids: Vec<u32> = (0..self.triangles.len() as u32).collect();
        let sphere_ids: Vec<u32> = (0..self.spheres.len() as u32).collect();
        let mut list: Vec<u32> = sphere_ids.chunks(4).map(|c| self.sphere_packet(c)).collect();
        list.extend(tri_ids.chunks(4).map(|c| self.tri_packet(c)));
        list
    }

    /// A triangle packet over `ids`, its geometry left for [`TriPacket::fill`].
    fn tri_packet(&mut self, ids: &[u32]) -> u32 {
        let mut lane_ids = [NO_PRIM; 4];
        for (l, id) in sorted(ids).enumerate() {
            lane_ids[l] = id;
        }
        self.out.tris.push(TriPacket {
            v0: [Vec4::ZERO; 3],
            e1: [Vec4::ZERO; 3],
            e2: [Vec4::ZERO; 3],
            n: [Vec4::ZERO; 3],
            ids: lane_ids,
        });
        // 2^28 packets would be a billion triangles, far beyond memory.
        debug_assert!(self.out.tris.len() <= 1 << RUN_SHIFT);
        LEAF | (self.out.tris.len() - 1) as u32
    }

    fn sphere_packet(&mut self, ids: &[u32]) -> u32 {
        // Padding lanes get r² = −1: the discriminant is negative and they never hit.
        let (mut c, mut r2) = ([[0f32; 4]; 3], [-1f32; 4]);
        let mut lane_ids = [NO_PRIM; 4];
        for (l, id) in sorted(ids).enumerate() {
            let s = &self.spheres[id as usize];
            for a in 0..3 {
                c[a][l] = s.center[a];
            }
            r2[l] = s.radius * s.radius;
            lane_ids[l] = id;
        }
        self.out.spheres.push(SpherePacket {
            c: [Vec4::from(c[0]), Vec4::from(c[1]), Vec4::from(c[2])],
            r2: Vec4::from(r2),
            ids: lane_ids,
        });
        LEAF | SPHERES | (self.out.spheres.len() - 1) as u32
    }
}

impl TriPacket {
    /// Sets the geometry of the triangles the packet's lanes name (zero in padding lanes).
    fn fill(&mut self, triangles: &[Triangle]) {
        let mut lanes = [[[0f32; 4]; 3]; 3];
        for (l, &id) in self.ids.iter().enumerate().filter(|&(_, &id)| id != NO_PRIM) {
            let t = &triangles[id as usize];
            for (k, v) in [t.v0(), t.e1(), t.e2()].iter().enumerate() {
                for a in 0..3 {
                    lanes[k][a][l] = v[a];
                }
            }
        }
        let v = |k: usize| {
            [
                Vec4::from(lanes[k][0]),
                Vec4::from(lanes[k][1]),
                Vec4::from(lanes[k][2]),
            ]
        };
        (self.v0, self.e1, self.e2) = (v(0), v(1), v(2));
        self.n = cross(&self.e1, &self.e2);
    }
}

/// Fills every packet's geometry (see [`TriPacket::fill`]): the collapse, which decides what goes
/// in each packet, walks the tree on one thread, and gathering and computing the packets was
/// half of its time.
fn fill_tri_packets(packets: &mut [TriPacket], triangles: &[Triangle]) {
    packets
        .par_iter_mut()
        .with_min_len(1 << 12)
        .for_each(|p| p.fill(triangles));
}

/// A packet's primitive indices in ascending order, so the lowest lane among equal distances
/// holds the lowest index (the tie rule, see [`beats`]).
fn sorted(ids: &[u32]) -> impl Iterator<Item = u32> {
    let mut v: ArrayVec<u32, 4> = ids.iter().copied().collect();
    v.sort_unstable();
    v.into_iter()
}

fn area(n: &BvhNode) -> f32 {
    let d = (n.max - n.min).max(glam::Vec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}
