//! A bounding volume hierarchy over the scene's finite primitives, built with binned SAH.
//!
//! Nodes are stored depth-first in one flat array; a node's left child follows it directly and
//! the right child's index is stored, so traversal touches memory mostly forwards.

use glam::{Vec3, Vec3A, Vec4};
use rayon::prelude::*;

use crate::math::Aabb;
#[cfg(any(test, feature = "test-support"))]
use crate::math::Ray;

/// One BVH node: bounds plus either two children or a run of primitive references.
///
/// The corners are unpadded `Vec3`s, so a node is 32 bytes instead of 48: a build makes two
/// nodes for every few primitives, and for a large mesh this tree sits beside the wide one being
/// made from it at the peak of the load.
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct BvhNode {
    /// Lower corner of the bounds.
    pub min: Vec3,
    /// Upper corner of the bounds.
    pub max: Vec3,
    /// Interior: index of the right child. Leaf: first index into [`Bvh::prims`].
    pub offset: u32,
    /// Number of primitives; 0 for an interior node.
    pub count: u16,
    /// Split axis of an interior node (decides which child is visited first).
    pub axis: u16,
}

/// A BVH over primitives identified by `u32`s chosen by the caller.
#[derive(Debug, Clone, Default)]
pub struct Bvh {
    /// Nodes, root first; empty when there are no primitives.
    pub nodes: Vec<BvhNode>,
    /// Primitive references in leaf order.
    pub prims: Vec<u32>,
}

/// A primitive to build over: its identifier and bounds.
///
/// The identifier rides in the lower corner's fourth lane, so a primitive is 32 bytes (two
/// aligned vectors) instead of 48: the build streams its whole array from memory twice a level
/// near the root, where the array is far larger than the caches.
#[derive(Debug, Clone, Copy)]
pub struct BuildPrim {
    /// Lower corner, and the identifier's bits in `w`.
    lo: Vec4,
    /// Upper corner (`w` unused).
    hi: Vec4,
}

/// Flipped in an identifier's bits where it is stored in a float lane: the build's vector
/// arithmetic runs on that lane too, and an identifier below 2^23 read as a float is a denormal,
/// each operation on which costs a microcode assist (the build took twice as long). Flipped, any
/// identifier below 2^30 (whatever its top bit) reads as a normal float, an infinity or a NaN,
/// none of which the arithmetic slows down on.
const ID_EXPONENT: u32 = 1 << 30;

impl BuildPrim {
    /// The primitive `id` (the caller's identifier, returned by traversal) with bounds `bounds`.
    #[must_use]
    pub fn new(id: u32, bounds: Aabb) -> Self {
        Self {
            lo: bounds.min.extend(f32::from_bits(id ^ ID_EXPONENT)),
            hi: bounds.max.extend(0.0),
        }
    }

    /// The caller's identifier.
    #[must_use]
    pub fn id(&self) -> u32 {
        self.lo.w.to_bits() ^ ID_EXPONENT
    }

    /// Bounds of the primitive.
    #[must_use]
    #[inline(always)]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3A::from_vec4(self.lo),
            max: Vec3A::from_vec4(self.hi),
        }
    }
}

const BINS: usize = 16;
const MAX_LEAF: usize = 4;
/// The most primitives a leaf holds: up to [`MAX_LEAF`] always, and up to twice that where the
/// SAH finds no split worth a node.
pub(super) const MAX_LEAF_PRIMS: usize = 2 * MAX_LEAF;
/// Below this many primitives a subtree is built on the current thread.
const PARALLEL_CUTOFF: usize = 4096;
/// From this many primitives a node's passes over them are shared among the threads, in chunks
/// of [`PASS_CHUNK`].
const PARALLEL_PASS: usize = 1 << 17;
const PASS_CHUNK: usize = 1 << 14;

impl Bvh {
    /// Builds a BVH over `prims` (any order); uses all rayon threads for large inputs.
    #[must_use]
    pub fn build(mut prims: Vec<BuildPrim>) -> Bvh {
        let usable = |p: &BuildPrim| {
            let b = p.bounds();
            !b.is_empty() && b.min.is_finite() && b.max.is_finite()
        };
        // Checked on every thread first: the whole array is rewritten only when some are not.
        if !prims.par_iter().with_min_len(PASS_CHUNK).all(usable) {
            prims.retain(usable);
        }
        if prims.is_empty() {
            return Bvh::default();
        }
        // A binary tree over n primitives has at most 2n − 1 nodes. Zeroed, the buffer is
        // fresh pages that cost memory only where the build writes.
        let mut nodes: Vec<BvhNode> = bytemuck::zeroed_vec(2 * prims.len() - 1);
        let ext = Extent::of(&prims);
        let count = build_rec(&mut prims, ext, 0, &mut nodes, 0);
        nodes.truncate(count);
        nodes.shrink_to_fit();
        // The build partitions `prims` in place into leaf order, so the leaves' runs are
        // ranges of it.
        Bvh {
            nodes,
            prims: prims.iter().map(BuildPrim::id).collect(),
        }
    }

    /// Visits leaves in near-to-far order along the ray; `leaf` gets the leaf's primitives and
    /// returns the new `t_max` (shrinking it prunes farther nodes). Returns early when `leaf`
    /// returns a negative value (any-hit queries). A cross-check of the wide BVH's walk, for tests.
    #[cfg(any(test, feature = "test-support"))]
    #[inline]
    pub(crate) fn traverse(&self, ray: &Ray, t_min: f32, t_max: f32, leaf: impl FnMut(&[u32], f32) -> f32) -> f32 {
        self.traverse_counting::<false>(ray, t_min, t_max, leaf, &mut 0)
    }

    /// [`Bvh::traverse`] that also counts, when `COUNT`, the nodes whose bounds were tested.
    #[cfg(any(test, feature = "test-support"))]
    #[inline]
    pub(crate) fn traverse_counting<const COUNT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        mut t_max: f32,
        mut leaf: impl FnMut(&[u32], f32) -> f32,
        visits: &mut u32,
    ) -> f32 {
        if self.nodes.is_empty() {
            return t_max;
        }
        let inv = ray.dir.recip();
        let neg = [inv.x < 0.0, inv.y < 0.0, inv.z < 0.0];
        // A growable stack: this walk is the cross-check of the wide one, so it must not lose a
        // branch of a pathologically deep tree, and it is not on the render path.
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        let mut idx = 0u32;
        loop {
            let node = &self.nodes[idx as usize];
            if COUNT {
                *visits += 1;
            }
            if slab(node, ray.origin, inv, t_min, t_max) {
                if node.count > 0 {
                    let r = leaf(self.leaf(node), t_max);
                    if r < 0.0 {
                        return r;
                    }
                    t_max = r;
                } else {
                    // Visit the child on the ray's near side first.
                    let (first, second) = if neg[node.axis as usize] {
                        (node.offset, idx + 1)
                    } else {
                        (idx + 1, node.offset)
                    };
                    stack.push(second);
                    idx = first;
                    continue;
                }
            }
            match stack.pop() {
                Some(next) => idx = next,
                None => return t_max,
            }
        }
    }

    /// The primitive references of leaf `node`.
    #[must_use]
    #[inline]
    pub(crate) fn leaf(&self, node: &BvhNode) -> &[u32] {
        let start = node.offset as usize;
        &self.prims[start..start + node.count as usize]
    }

    /// Bytes used by nodes and references.
    #[must_use]
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<BvhNode>() + self.prims.len() * 4
    }
}

/// Whether `ray` (origin `o`, reciprocal direction `inv`) meets `node`'s bounds within
/// `t_min..=t_max`.
#[cfg(any(test, feature = "test-support"))]
#[inline]
fn slab(node: &BvhNode, o: Vec3A, inv: Vec3A, t_min: f32, t_max: f32) -> bool {
    let t0 = (Vec3A::from(node.min) - o) * inv;
    let t1 = (Vec3A::from(node.max) - o) * inv;
    // min/max of glam ignore NaN from 0 * inf the right way for rays starting on a slab plane.
    let near = t0.min(t1).max_element().max(t_min);
    let far = t0.max(t1).min_element().min(t_max);
    near <= far
}

/// Writes a leaf over `items`, which start at index `first` of the whole build's primitives, to
/// `out[0]`; returns 1, the nodes written.
fn leaf_node(items: &[BuildPrim], first: u32, bounds: Aabb, out: &mut [BvhNode]) -> usize {
    out[0] = BvhNode {
        min: bounds.min.into(),
        max: bounds.max.into(),
        offset: first,
        count: items.len() as u16,
        axis: 0,
    };
    1
}

/// The bounds of a set of primitives and of their centres, which is what a split needs.
#[derive(Debug, Clone, Copy)]
struct Extent {
    bounds: Aabb,
    centers: Aabb,
}

impl Extent {
    const EMPTY: Extent = Extent {
        bounds: Aabb::EMPTY,
        centers: Aabb::EMPTY,
    };

    #[inline(always)]
    fn add(self, p: &BuildPrim) -> Extent {
        Extent {
            bounds: self.bounds.union(p.bounds()),
            centers: self.centers.grow(p.bounds().center()),
        }
    }

    #[inline(always)]
    fn union(self, o: Extent) -> Extent {
        Extent {
            bounds: self.bounds.union(o.bounds),
            centers: self.centers.union(o.centers),
        }
    }

    /// The extent of `items`, in one pass (shared among the threads for many).
    fn of(items: &[BuildPrim]) -> Extent {
        if items.len() >= PARALLEL_PASS {
            return items
                .par_chunks(PASS_CHUNK)
                .map(|c| c.iter().fold(Extent::EMPTY, Extent::add))
                .reduce(|| Extent::EMPTY, Extent::union);
        }
        items.iter().fold(Extent::EMPTY, Extent::add)
    }
}

/// Each bin's extent and how many primitives fell in it.
type Bins = ([Extent; BINS], [usize; BINS]);

/// Writes the subtree over `items` (index `first` onwards of the whole build's primitives, whose
/// extent is `ext`) depth-first from `out[0]`, which is node `base` of the tree; returns how many
/// nodes it wrote. `out` holds at least 2 × `items.len()` − 1 nodes, as many as any binary tree
/// over them needs. Subtrees are written where they end up instead of built apart and joined:
/// joining copied every node once per level above it and allocated two vectors per leaf, nearly
/// a quarter of a large mesh's build time.
///
/// The binning keeps each bin's centre bounds beside its box, so both sides' extents are known
/// from the bins once a split is chosen: each node then reads its primitives twice (binning and
/// partition) instead of four times.
///
/// Centroids are recomputed where they are needed rather than stored beside the primitives: a
/// stored copy made the build's working array a third larger, and for a 4 M-triangle mesh that
/// array and the centroids copied into it were 320 MB of fresh memory.
fn build_rec(items: &mut [BuildPrim], ext: Extent, first: u32, out: &mut [BvhNode], base: u32) -> usize {
    let bounds = ext.bounds;
    if items.len() <= MAX_LEAF {
        return leaf_node(items, first, bounds, out);
    }
    let cb = ext.centers;
    let extent = cb.max - cb.min;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let lo = cb.min[axis];
    let width = extent[axis];
    if width.is_nan() || width <= 0.0 {
        // All centroids coincide: split in the middle of the list (small lists returned above).
        return join_at_middle(items, first, bounds, axis, out, base);
    }
    // Binned SAH on the axis of largest centroid extent.
    let scale = BINS as f32 / width;
    let bin_of = |c: Vec3A| (((c[axis] - lo) * scale) as usize).min(BINS - 1);
    let bin = |items: &[BuildPrim]| {
        let mut bins: Bins = ([Extent::EMPTY; BINS], [0; BINS]);
        for p in items {
            let b = bin_of(p.bounds().center());
            bins.0[b] = bins.0[b].add(p);
            bins.1[b] += 1;
        }
        bins
    };
    // Near the root, where a node's primitives are a large part of the mesh and the levels
    // below have not yet split the work among the threads, the binning is shared out too.
    let (bins, bin_count) = if items.len() >= PARALLEL_PASS {
        let merge = |(mut e, mut n): Bins, (e2, n2): Bins| {
            for b in 0..BINS {
                e[b] = e[b].union(e2[b]);
                n[b] += n2[b];
            }
            (e, n)
        };
        items
            .par_chunks(PASS_CHUNK)
            .map(bin)
            .reduce(|| ([Extent::EMPTY; BINS], [0; BINS]), merge)
    } else {
        bin(items)
    };
    let mut right_area = [0.0f32; BINS];
    let mut acc = Aabb::EMPTY;
    let mut cnt = 0;
    let mut right_count = [0usize; BINS];
    for i in (1..BINS).rev() {
        acc = acc.union(bins[i].bounds);
        cnt += bin_count[i];
        right_area[i] = acc.half_area();
        right_count[i] = cnt;
    }
    let mut best = (f32::INFINITY, 0usize);
    let mut acc = Aabb::EMPTY;
    let mut cnt = 0;
    for i in 0..BINS - 1 {
        acc = acc.union(bins[i].bounds);
        cnt += bin_count[i];
        if cnt == 0 || right_count[i + 1] == 0 {
            continue;
        }
        let cost = acc.half_area() * cnt as f32 + right_area[i + 1] * right_count[i + 1] as f32;
        if cost < best.0 {
            best = (cost, i);
        }
    }
    let leaf_cost = bounds.half_area() * items.len() as f32;
    // Traversal cost ≈ one primitive test, relative to the parent's area.
    let split_cost = bounds.half_area() + best.0;
    if items.len() <= MAX_LEAF_PRIMS && split_cost >= leaf_cost {
        return leaf_node(items, first, bounds, out);
    }
    if best.0 == f32::INFINITY {
        // No split leaves primitives on both sides (every centre in one bin).
        return join_at_middle(items, first, bounds, axis, out, base);
    }
    let split_bin = best.1;
    let mid = partition(items, |p| bin_of(p.bounds().center()) <= split_bin);
    let left = bins[..=split_bin].iter().fold(Extent::EMPTY, |a, &b| a.union(b));
    let right = bins[split_bin + 1..].iter().fold(Extent::EMPTY, |a, &b| a.union(b));
    join(items, first, mid, [left, right], bounds, axis, out, base)
}

/// [`join`] at the middle of `items`, with both halves' extents found by a pass over them.
fn join_at_middle(
    items: &mut [BuildPrim],
    first: u32,
    bounds: Aabb,
    axis: usize,
    out: &mut [BvhNode],
    base: u32,
) -> usize {
    let mid = items.len() / 2;
    let halves = [Extent::of(&items[..mid]), Extent::of(&items[mid..])];
    join(items, first, mid, halves, bounds, axis, out, base)
}

/// Writes an interior node splitting `items` at `mid` (the halves' extents `halves`) to
/// `out[0]`, then its two subtrees (see [`build_rec`]); returns the nodes written.
///
/// The left subtree follows its parent. Above [`PARALLEL_CUTOFF`] the right one is built at the
/// same time, on another thread, from `out[2 × mid]` on (the left one cannot reach that far), and
/// then moved down to follow the left one with its interior offsets moved with it. Building it
/// in a vector of its own instead left about 85 MB of a 4 M-triangle build in glibc's per-thread
/// arenas once those vectors were freed, on top of the peak of the load.
#[allow(clippy::too_many_arguments)]
fn join(
    items: &mut [BuildPrim],
    first: u32,
    mid: usize,
    halves: [Extent; 2],
    bounds: Aabb,
    axis: usize,
    out: &mut [BvhNode],
    base: u32,
) -> usize {
    let n = items.len();
    let (l, r) = items.split_at_mut(mid);
    let right_first = first + mid as u32;
    let (left, right) = if n > PARALLEL_CUTOFF {
        let (head, tail) = out.split_at_mut(2 * mid);
        let right_base = base + 2 * mid as u32;
        let (left, right) = rayon::join(
            || build_rec(l, halves[0], first, &mut head[1..], base + 1),
            || build_rec(r, halves[1], right_first, tail, right_base),
        );
        let (from, to) = (2 * mid, 1 + left);
        if to < from {
            out.copy_within(from..from + right, to);
            let shift = (from - to) as u32;
            for nd in &mut out[to..to + right] {
                if nd.count == 0 {
                    nd.offset -= shift;
                }
            }
        }
        (left, right)
    } else {
        let left = build_rec(l, halves[0], first, &mut out[1..], base + 1);
        let right = build_rec(r, halves[1], right_first, &mut out[1 + left..], base + 1 + left as u32);
        (left, right)
    };
    out[0] = BvhNode {
        min: bounds.min.into(),
        max: bounds.max.into(),
        offset: base + 1 + left as u32,
        count: 0,
        axis: axis as u16,
    };
    1 + left + right
}

fn partition<T>(v: &mut [T], pred: impl Fn(&T) -> bool) -> usize {
    let mut i = 0;
    for j in 0..v.len() {
        if pred(&v[j]) {
            v.swap(i, j);
            i += 1;
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_and_single() {
        let b = Bvh::build(vec![]);
        assert!(b.nodes.is_empty());
        let r = Ray::new(Vec3A::ZERO, Vec3A::Z);
        assert_eq!(b.traverse(&r, 0.0, 5.0, |_, _| 1.0), 5.0);
        let one = Bvh::build(vec![BuildPrim::new(
            7,
            Aabb {
                min: Vec3A::splat(-1.0),
                max: Vec3A::splat(1.0),
            },
        )]);
        let mut seen = vec![];
        one.traverse(&r, 0.0, 5.0, |p, t| {
            seen.extend_from_slice(p);
            t
        });
        assert_eq!(seen, vec![7]);
    }

    #[test]
    fn identifiers_survive_their_float_lane() {
        // Small ones (denormal bits), ones whose flipped bits read as a NaN (quiet and
        // signalling) or an infinity, and ones with the top bit the scene marks spheres with.
        let ids = [
            0,
            1,
            7,
            0x007F_FFFF,
            0x3F80_0000,
            0x3F80_0001,
            0x3FC0_0000,
            1 << 31 | 3,
            u32::MAX,
        ];
        let prims: Vec<BuildPrim> = ids
            .iter()
            .enumerate()
            .map(|(k, &id)| {
                let c = Vec3A::splat(k as f32);
                let p = BuildPrim::new(id, Aabb { min: c, max: c + 0.5 });
                assert_eq!(p.id(), id);
                assert_eq!((p.bounds().min, p.bounds().max), (c, c + 0.5));
                p
            })
            .collect();
        let mut built = Bvh::build(prims).prims;
        built.sort_unstable();
        let mut want = ids.to_vec();
        want.sort_unstable();
        assert_eq!(built, want);
    }

    #[test]
    fn every_primitive_reachable_once() {
        let prims: Vec<BuildPrim> = (0..1000)
            .map(|i| {
                let c = Vec3A::new((i % 10) as f32, ((i / 10) % 10) as f32, (i / 100) as f32);
                BuildPrim::new(
                    i,
                    Aabb {
                        min: c,
                        max: c + Vec3A::splat(0.5),
                    },
                )
            })
            .collect();
        let b = Bvh::build(prims);
        let mut ids = b.prims.clone();
        ids.sort_unstable();
        assert_eq!(ids, (0..1000).collect::<Vec<_>>());
        // Leaf offsets must be consistent with the reference array.
        let total: usize = b.nodes.iter().map(|n| n.count as usize).sum();
        assert_eq!(total, 1000);
    }

    /// Walks the tree from the root, checking each child lies within its parent, and returns
    /// the leaves (node, first of `prims`, count) in walk order.
    fn leaf_ranges(b: &Bvh, i: usize, out: &mut Vec<(usize, usize, usize)>) {
        let n = &b.nodes[i];
        if n.count > 0 {
            out.push((i, n.offset as usize, n.count as usize));
            return;
        }
        let right = n.offset as usize;
        assert!(right > i + 1 && right < b.nodes.len(), "node {i}: right child {right}");
        for c in [i + 1, right] {
            let k = &b.nodes[c];
            assert!(
                k.min.cmpge(n.min).all() && k.max.cmple(n.max).all(),
                "node {c} outside node {i}"
            );
            leaf_ranges(b, c, out);
        }
    }

    #[test]
    fn large_builds_are_whole_trees() {
        // Enough primitives that the top of the tree is built on several threads.
        let n = 40_000u32;
        let mut seed = 12345u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f32 / u32::MAX as f32
        };
        let prims: Vec<BuildPrim> = (0..n)
            .map(|id| {
                let c = Vec3A::new(next(), next(), next()) * 100.0;
                BuildPrim::new(
                    id,
                    Aabb {
                        min: c,
                        max: c + Vec3A::new(next(), next(), next()),
                    },
                )
            })
            .collect();
        let b = Bvh::build(prims.clone());
        let mut ranges = vec![];
        leaf_ranges(&b, 0, &mut ranges);
        // Depth first: the leaves take consecutive runs of `prims`, covering it once.
        let mut next_start = 0;
        for &(node, start, count) in &ranges {
            assert_eq!(start, next_start);
            next_start += count;
            let leaf = &b.nodes[node];
            for &id in &b.prims[start..start + count] {
                let p = prims[id as usize].bounds();
                assert!(
                    p.min.cmpge(leaf.min.into()).all() && p.max.cmple(leaf.max.into()).all(),
                    "prim {id} outside its leaf"
                );
            }
        }
        assert_eq!(next_start, n as usize);
        let mut ids = b.prims.clone();
        ids.sort_unstable();
        assert_eq!(ids, (0..n).collect::<Vec<_>>());
        // Every node is reached by the walk: none is left over from the parallel parts.
        assert_eq!(b.nodes.len(), 2 * ranges.len() - 1);
    }
}
