//! The 4-wide BVH made from the binary one: up to four children gathered under each node by
//! opening the largest interior child (as Embree does), small subtrees turned into leaf packets
//! (or runs of them), the infinite planes packed apart, and for small scenes the flat list and the
//! rooms' single-ray list.

use arrayvec::ArrayVec;
use glam::Vec4;
use rayon::prelude::*;

use super::builder::{Bvh, BvhNode, MAX_LEAF_PRIMS};
use super::layout::{
    Bvh4, Node4, PlanePacket, SpherePacket, TriPacket, EMPTY, LEAF, MAX_RUN, NO_PRIM, PREFETCH_BYTES, RUN, RUN_SHIFT,
    SPHERES, SPLIT_BYTES, SPLIT_SHADOW_NODES, STACK,
};
use crate::geometry::{cross, Plane, Sphere, Triangle};
use crate::math::Aabb;

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
/// holds the lowest index (the tie rule, see [`beats`](super::layout::beats)).
fn sorted(ids: &[u32]) -> impl Iterator<Item = u32> {
    let mut v: ArrayVec<u32, 4> = ids.iter().copied().collect();
    v.sort_unstable();
    v.into_iter()
}

fn area(n: &BvhNode) -> f32 {
    let d = (n.max - n.min).max(glam::Vec3::ZERO);
    d.x * d.y + d.y * d.z + d.z * d.x
}
