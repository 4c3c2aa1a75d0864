//! The 4-wide BVH's layout: nodes whose four child boxes are stored structure-of-arrays, so one
//! ray is tested against four boxes with a handful of `Vec4` instructions, and leaves that are
//! packets of up to four triangles, spheres or planes in the same layout, tested together. This
//! is the layout Embree uses for single rays; with glam's `Vec4` it needs no `unsafe`. Here too
//! are the tags that name a leaf's kind and a hit's primitive, and the tie rule that orders hits.

use glam::Vec4;

use crate::geometry::PrimRef;

/// Hit tag: a plane (the index is in the low bits).
pub(super) const TAG_PLANE: u32 = 1 << 30;
/// Hit tag: a sphere.
pub(super) const TAG_SPHERE: u32 = 2 << 30;
/// Hit tag: a triangle.
pub(super) const TAG_TRI: u32 = 3 << 30;
/// The tag bits of a hit reference.
pub(super) const TAG_MASK: u32 = 3 << 30;

/// Child reference flag: the child is a leaf packet, not a node.
pub(super) const LEAF: u32 = 1 << 31;
/// Leaf flag: the packet holds spheres, not triangles.
pub(super) const SPHERES: u32 = 1 << 30;
/// Leaf field: how many triangle packets after the one referenced belong to the same leaf (a
/// run of up to [`MAX_RUN`] packets, stored one after another and tested in turn).
pub(super) const RUN: u32 = 3 << RUN_SHIFT;
pub(super) const RUN_SHIFT: u32 = 28;

/// An empty child slot.
pub(super) const EMPTY: u32 = u32::MAX;
/// Lane id of an unused packet lane.
pub(super) const NO_PRIM: u32 = u32::MAX;

/// One 4-wide node: child bounds as `[axis][min/max]` lanes, and child references.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(64))]
pub struct Node4 {
    /// `bounds[axis][0]` = min of the four children on that axis, `[1]` = max.
    pub bounds: [[Vec4; 2]; 3],
    /// Node index, `LEAF | packet` (with a `RUN` of more packets), `LEAF | SPHERES | packet`,
    /// or `EMPTY`.
    pub children: [u32; 4],
    /// Bit i set when `children[i]` is used (sits in the padding of the 128-byte node).
    pub valid: u32,
}

impl Node4 {
    pub(super) fn empty() -> Self {
        Node4 {
            bounds: [[Vec4::INFINITY, Vec4::NEG_INFINITY]; 3],
            children: [EMPTY; 4],
            valid: 0,
        }
    }

    pub(super) fn set_children(&mut self, children: [u32; 4]) {
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
    pub(super) v0: [Vec4; 3],
    pub(super) e1: [Vec4; 3],
    pub(super) e2: [Vec4; 3],
    /// e1 × e2, stored because the test needs it for every ray.
    pub(super) n: [Vec4; 3],
    /// Triangle index of each lane (`NO_PRIM` for padding).
    pub ids: [u32; 4],
}

/// Four infinite planes in structure-of-arrays layout.
#[derive(Debug, Clone, Copy)]
pub struct PlanePacket {
    pub(super) p: [Vec4; 3],
    /// Unit normals; zero in padding lanes, which therefore never hit.
    pub(super) n: [Vec4; 3],
    /// Plane index of each lane (`NO_PRIM` for padding).
    pub ids: [u32; 4],
}

/// Four spheres in structure-of-arrays layout.
#[derive(Debug, Clone, Copy)]
pub struct SpherePacket {
    pub(super) c: [Vec4; 3],
    pub(super) r2: Vec4,
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
    pub(super) fn key(&self) -> u32 {
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
    /// that is cheaper (see `Bvh4::walk_cost`): in a small room every wall's box overlaps every
    /// other, so a ray opens most of the tree anyway. Ray packets still walk the tree, whose node
    /// tests they share among sixteen rays. Empty otherwise.
    pub single: Vec<u32>,
    /// Root reference (`EMPTY` for an empty scene).
    pub root: u32,
    /// True when the tree is too deep for the fixed traversal stack (3 entries per level), as
    /// a binned SAH can build for pathological inputs: queries then use a heap stack, so no
    /// branch is ever lost, and ordinary trees pay nothing for the check.
    pub deep: bool,
    /// True when the nodes and packets outgrow the per-core cache (see `PREFETCH_BYTES`), so
    /// the walks prefetch the children they will visit.
    pub prefetch: bool,
    /// True when the tree is larger than `SPLIT_BYTES`: a pixel then usually covers several
    /// triangles, so a packet's rays part in the lower levels, and each ray finishes alone the
    /// subtrees few of the packet's rays enter.
    pub split_packets: bool,
    /// True when the tree has at least `SPLIT_SHADOW_NODES` nodes: shadow packets, whose rays
    /// part as they leave the surface, are split as [`Self::split_packets`] splits camera rays.
    pub split_shadows: bool,
}

/// Trees larger than this split packets of closest-hit rays where they part (see
/// [`Bvh4::split_packets`]). The bookkeeping (each stack entry carries its rays) costs packets
/// that never part 2–4 %; a bumpy torus rendered at 1024² with one sample a pixel broke even at
/// 300 k triangles (36 MB), and gained 4 % at 1 M (121 MB) and 17 % at 4 M.
pub(crate) const SPLIT_BYTES: usize = 64 << 20;

/// Trees with at least this many nodes split shadow packets (see [`Bvh4::split_shadows`]). The
/// course's rooms have a handful of nodes, too few levels for a packet's shadow rays to part in;
/// the bunny scene (354 nodes) renders about 1 % faster split.
pub(crate) const SPLIT_SHADOW_NODES: usize = 64;

/// Traversal stack entries kept on the machine stack. A 4-wide node pushes at most four entries
/// and pops one, so a tree of depth d needs at most 3d + 1: 64 covers 21 levels, more than any
/// reasonable mesh needs; deeper trees (see [`Bvh4::deep`]) are walked with a heap stack.
pub(super) const STACK: usize = 64;

/// Trees larger than this prefetch (about a core's L2 cache). Below it the prefetches find their
/// lines already cached and only cost instructions (the path-traced box, 8 packets: +1.5 %);
/// above it they let the misses of a node's children overlap (a 50 k-triangle torus, 4 MB:
/// incoherent rays +8 %; 1 M triangles: +25 %).
pub(super) const PREFETCH_BYTES: usize = 1 << 20;

/// The most triangle packets in one leaf (at most 4, the [`RUN`] field's range). Three measured
/// best: a run spares the node that would sit over its packets, and a longer one tests packets
/// whose own bounds would have culled them.
pub(super) const MAX_RUN: usize = 3;

impl Bvh4 {
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
}

/// True when a hit at `t` on the primitive with key `key` is preferred to the best so far at
/// `t_best` with key `key_best`: it is nearer, or exactly as near and its key is lower. With
/// `key_best` = 0 (nothing found), `t_best` is a strict bound. Ties broken this way make the
/// closest hit independent of the order primitives are visited in, so a packet walk and a
/// single-ray walk (which visit leaves in different orders) agree even where a ray meets two
/// primitives at exactly the same distance, as at the corner of two walls.
#[inline(always)]
pub(super) fn beats(t: f32, key: u32, t_best: f32, key_best: u32) -> bool {
    t < t_best || (t == t_best && key < key_best)
}
