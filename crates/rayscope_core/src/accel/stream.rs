//! Closest hits of many independent rays, their tree walks interleaved.
//!
//! In a tree far larger than the caches, a single ray's walk is a chain of dependent loads: each
//! node's children are known only once the node has arrived from memory, so the core spends most
//! of the walk waiting. Walking several rays in turn, one node each, gives every load the time
//! the other rays' steps take to arrive: a child is prefetched when it is pushed and is needed
//! only when its ray's turn comes round again. Each ray still takes exactly the steps of
//! [`Bvh4::closest`], in the same order, so the hits are the same bit for bit.
//!
//! Interleaving has a cost of its own (each step reloads its ray's state, and the branch
//! predictor sees the rays' walks mixed), so it is used only where it pays: for rays in
//! scattered directions in trees beyond [`INTERLEAVE_BYTES`] (the 4 M-triangle torus's
//! incoherent rays about 1.8× as fast, `rayscope bench rays --rays-file FILE` against
//! `--no-interleave`). Rays that mostly point the same way as the ray before them (camera rays,
//! shadow rays toward one light) are walked one after another in any tree: each finds what the
//! one before it loaded still cached, which interleaving would only disturb.

use arrayvec::ArrayVec;

use super::layout::{Bvh4, WideHit, EMPTY, LEAF, STACK};
use super::single::{node_test, NodeConsts, RayConsts, Walk, SLAB_SLACK};
use crate::math::Ray;

/// Walks in flight at once on one thread: enough to cover a miss to memory with the other
/// walks' steps (with 16 the 4 M-triangle torus ran 12 % slower, with 8 slower still), few
/// enough that their state stays in the first-level cache (about 18 KB).
const IN_FLIGHT: usize = 24;

/// Trees whose nodes and packets exceed this (half of a 32 MiB shared L3 cache)
/// interleave scattered rays. Below it their misses mostly hit the L3, too short a wait to
/// repay the interleaving: a 100 k-triangle torus (8.5 MB) was 5 % slower interleaved, a
/// 200 k one (17 MB) 20 % faster.
pub const INTERLEAVE_BYTES: usize = 16 << 20;

/// Two consecutive rays whose unit directions have at least this dot product (about 2.6°
/// apart) count as pointing the same way.
const SAME_WAY: f32 = 0.999;

/// One ray's walk in progress.
struct Lane {
    rc: RayConsts,
    nc: NodeConsts,
    stack: ArrayVec<(u32, f32), STACK>,
    walk: Walk,
    /// `walk.t_best` widened as in [`Bvh4::closest`]'s walk, which stack entries are culled by.
    t_cull: f32,
    /// The ray's index in the batch.
    index: usize,
}

impl Bvh4 {
    /// Calls `each(i, hit)` once for every ray `rays[i]`, with its closest hit with
    /// `t_min < t < t_max`: what [`Self::closest`] returns for it. Where the tree is far larger
    /// than the caches and the rays are scattered, their walks are interleaved (see
    /// [`Self::interleaves`]) and the calls come in the order the walks end, not in ray order.
    #[inline]
    pub fn closest_many(&self, rays: &[Ray], t_min: f32, t_max: f32, mut each: impl FnMut(usize, Option<WideHit>)) {
        if self.interleaves(rays) {
            self.closest_interleaved(rays, t_min, t_max, &mut each);
        } else {
            for (i, ray) in rays.iter().enumerate() {
                each(i, self.closest::<false>(ray, t_min, t_max, &mut 0));
            }
        }
    }

    /// True when [`Self::closest_many`] interleaves the walks of `rays`: the tree is larger than
    /// [`INTERLEAVE_BYTES`] and fits the fixed traversal stack, and fewer than half of the rays
    /// point the same way as the ray before them.
    #[must_use]
    pub fn interleaves(&self, rays: &[Ray]) -> bool {
        if self.root == EMPTY || self.deep || self.memory_bytes() <= INTERLEAVE_BYTES || rays.len() < 2 {
            return false;
        }
        let same_way = rays.windows(2).filter(|w| w[0].dir.dot(w[1].dir) >= SAME_WAY).count();
        2 * same_way < rays.len() - 1
    }

    /// [`Self::closest_many`] with [`IN_FLIGHT`] walks interleaved; the tree must fit the fixed
    /// traversal stack (not [`Self::deep`]).
    fn closest_interleaved(&self, rays: &[Ray], t_min: f32, t_max: f32, each: &mut impl FnMut(usize, Option<WideHit>)) {
        debug_assert!(!self.deep);
        let mut lanes: ArrayVec<Lane, IN_FLIGHT> = ArrayVec::new();
        let mut next = 0;
        while lanes.len() < IN_FLIGHT && next < rays.len() {
            lanes.push(self.start(&rays[next], next, t_min, t_max));
            next += 1;
        }
        // Round robin: each walk takes one step, then the next walk does. A walk that ends
        // hands its slot to the next ray, so consecutive rays (often neighbours) walk together.
        let mut k = 0;
        while !lanes.is_empty() {
            if k >= lanes.len() {
                k = 0;
            }
            if !self.step(&mut lanes[k], t_min) {
                k += 1;
                continue;
            }
            each(lanes[k].index, lanes[k].walk.best);
            if next < rays.len() {
                self.restart(&mut lanes[k], &rays[next], next, t_min, t_max);
                next += 1;
                k += 1;
            } else {
                lanes.swap_remove(k);
            }
        }
    }

    /// A walk for `ray` (number `index`), with the planes and flat packets already tested, as
    /// [`Self::closest`] tests them before the tree.
    #[inline(always)]
    fn start(&self, ray: &Ray, index: usize, t_min: f32, t_max: f32) -> Lane {
        let mut lane = Lane {
            rc: RayConsts::new(ray),
            nc: NodeConsts::new(ray),
            stack: ArrayVec::new(),
            walk: Walk {
                best: None,
                t_best: t_max,
                key: 0,
                visits: 0,
            },
            t_cull: 0.0,
            index,
        };
        self.restart(&mut lane, ray, index, t_min, t_max);
        lane
    }

    /// Makes `lane` the walk for `ray` (number `index`) in place: a lane is several hundred bytes,
    /// mostly stack, that need not be copied for each ray.
    #[inline(always)]
    fn restart(&self, lane: &mut Lane, ray: &Ray, index: usize, t_min: f32, t_max: f32) {
        lane.rc = RayConsts::new(ray);
        lane.nc = NodeConsts::new(ray);
        lane.walk = Walk {
            best: None,
            t_best: t_max,
            key: 0,
            visits: 0,
        };
        for p in &self.planes {
            if let Some(h) = p.closest::<true>(&lane.rc, t_min, lane.walk.t_best, lane.walk.key) {
                lane.walk.take(h);
            }
        }
        self.closest_flat::<false>(&self.flat, &lane.rc, t_min, &mut lane.walk, &mut 0);
        lane.t_cull = lane.walk.t_best * SLAB_SLACK;
        lane.stack.clear();
        lane.stack.push((self.root, t_min));
        lane.index = index;
    }

    /// Takes `lane`'s walk one node or leaf further (skipping culled entries, which need no
    /// memory); true when the walk is over.
    #[inline(always)]
    fn step(&self, lane: &mut Lane, t_min: f32) -> bool {
        while let Some((r, t_near)) = lane.stack.pop() {
            if t_near > lane.t_cull {
                continue;
            }
            if r & LEAF != 0 {
                if let Some(h) = self.leaf_closest::<true>(r, &lane.rc, t_min, lane.walk.t_best, lane.walk.key) {
                    lane.walk.take(h);
                    lane.t_cull = lane.walk.t_best * SLAB_SLACK;
                }
                return false;
            }
            let node = &self.nodes[r as usize];
            let (mask, tn) = node_test(node, &lane.rc, &lane.nc, t_min, lane.walk.t_best);
            self.push_children(node, mask, tn, &mut lane.stack);
            return false;
        }
        true
    }
}
