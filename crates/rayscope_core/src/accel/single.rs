//! One ray through the 4-wide BVH: the closest-hit walk, the any-hit walk, and both at once for
//! a ray and its shadow ray; the 1×4 tests of one ray against a packet's four primitives or a
//! node's four boxes. A scene without a tree (the flat list, a room's single-ray list) is tested
//! packet by packet in the same loops.

use arrayvec::ArrayVec;
use glam::{BVec4A, Vec3A, Vec4};

use super::layout::{
    beats, Bvh4, Node4, PlanePacket, SpherePacket, TriPacket, WideHit, EMPTY, LEAF, NO_PRIM, RUN, RUN_SHIFT, SPHERES,
    STACK, TAG_PLANE, TAG_SPHERE, TAG_TRI,
};
use crate::geometry::{plane_hit, sphere_line, triangle_plane, PrimRef};
use crate::math::Ray;

/// Per-ray constants for the packet tests.
pub(super) struct RayConsts {
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
    pub(super) fn new(ray: &Ray) -> Self {
        Self {
            o: splat3(ray.origin),
            d: splat3(ray.dir),
        }
    }
}

/// Per-ray constants for the node test, made only when a ray enters a tree.
pub(super) struct NodeConsts {
    inv: [Vec4; 3],
    /// 0 when the direction is positive on the axis (near plane = min), else 1.
    near: [usize; 3],
}

impl NodeConsts {
    #[inline]
    pub(super) fn new(ray: &Ray) -> Self {
        let inv = ray.dir.recip();
        Self {
            inv: splat3(inv),
            near: [(inv.x < 0.0) as usize, (inv.y < 0.0) as usize, (inv.z < 0.0) as usize],
        }
    }
}

/// Factor on a box's exit distance that makes the slab test conservative (≈ 8 ulps).
pub(super) const SLAB_SLACK: f32 = 1.0 + 1.0 / (1 << 20) as f32;

/// The bound a triangle's undivided distance is filtered against: `t_max` itself, or with
/// `ties` widened by a few ulps so a hit whose divided distance equals `t_max` (which the tie
/// rule may prefer) is not lost to the rounding of `t_max · |d·n|`.
#[inline(always)]
pub(super) fn far(ties: bool, t_max: f32) -> f32 {
    if ties {
        t_max * SLAB_SLACK
    } else {
        t_max
    }
}

impl Bvh4 {
    /// The closest hit among the packets of `list`.
    #[inline(always)]
    pub(super) fn closest_flat<const COUNT: bool>(
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
    pub(super) fn leaf_closest<const TIES: bool>(
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
    pub(super) fn walk_closest<const COUNT: bool, S: TraversalStack<(u32, f32)> + Default>(
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
    pub(super) fn push_children<S: TraversalStack<(u32, f32)>>(
        &self,
        node: &Node4,
        mask: u32,
        tn: Vec4,
        stack: &mut S,
    ) {
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
    pub(super) fn prefetch_child(&self, r: u32) {
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
    pub(crate) fn closest_and_occluded(&self, ray: &Ray, shadow: &Ray, shadow_t_max: f32) -> (Option<WideHit>, bool) {
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
    pub(super) fn walk_any<S: TraversalStack<u32> + Default>(
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
pub(super) struct Walk {
    pub(super) best: Option<WideHit>,
    pub(super) t_best: f32,
    /// The best hit's [`WideHit::key`], 0 while there is none.
    pub(super) key: u32,
    pub(super) visits: u32,
}

impl Walk {
    /// Makes `h` the best hit.
    #[inline(always)]
    pub(super) fn take(&mut self, h: WideHit) {
        (self.t_best, self.key) = (h.t, h.key());
        self.best = Some(h);
    }
}

/// A traversal stack: the fixed-size one, or a heap one for trees too deep for it.
pub(super) trait TraversalStack<T> {
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
pub(super) fn node_test(node: &Node4, rc: &RayConsts, nc: &NodeConsts, t_min: f32, t_max: f32) -> (u32, Vec4) {
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

/// The nearest of a sphere or plane packet's lanes in `mask` as a hit on `prim(id)`; with `TIES`
/// only when it beats the best hit so far (`t_max`, `key_max`) by the tie rule ([`beats`]).
#[inline(always)]
fn nearest_hit<const TIES: bool>(
    mask: BVec4A,
    t: Vec4,
    ids: &[u32; 4],
    tag: u32,
    prim: fn(u32) -> PrimRef,
    t_max: f32,
    key_max: u32,
) -> Option<WideHit> {
    let i = nearest_lane(mask, t)?;
    let ti = t.to_array()[i];
    if TIES && !beats(ti, tag | ids[i], t_max, key_max) {
        return None;
    }
    Some(WideHit {
        t: ti,
        u: 0.0,
        v: 0.0,
        prim: prim(ids[i]),
    })
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
    /// The triangle test ([`triangle_plane`]) on four triangles at once, up to the division: the
    /// lanes whose triangle the ray meets with `t_min < t < t_far` (compared undivided, so the
    /// caller decides on the divided distance), or `None` when there are none.
    #[inline(always)]
    fn undivided(&self, rc: &RayConsts, t_min: f32, t_far: f32) -> Option<Undivided> {
        let plane = triangle_plane(&self.v0, &self.n, &rc.o, &rc.d, Vec4::splat(t_min), Vec4::splat(t_far));
        // The supporting planes first: a shadow ray that ends before every plane (a wall behind
        // the light) is done after a third of the work.
        if !plane.hit.any() {
            return None;
        }
        let (u, v, mask) = plane.edges(&self.e1, &self.e2, &rc.d);
        mask.any().then_some(Undivided {
            mask,
            t: plane.t,
            u,
            v,
            a: plane.a,
        })
    }

    /// The closest hit in the packet (the test of [`Triangle`](crate::geometry::Triangle), the
    /// division made only when some lane hits).
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
    /// The sphere test ([`sphere_line`]) on four spheres at once: the lanes whose sphere the ray
    /// meets with `t_min < t` and `t` below `t_max` (`t <= t_max` with `TIES`), with each lane's
    /// nearer such distance, or `None` when the ray's line misses all four.
    #[inline(always)]
    fn hits<const TIES: bool>(&self, rc: &RayConsts, t_min: f32, t_max: f32) -> Option<(BVec4A, Vec4)> {
        let line = sphere_line(&self.c, self.r2, &rc.o, &rc.d);
        if !line.disc.cmpge(Vec4::ZERO).any() {
            return None;
        }
        Some(line.hit::<TIES>(self.r2, Vec4::splat(t_min), Vec4::splat(t_max)))
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
        nearest_hit::<TIES>(mask, t, &self.ids, TAG_SPHERE, PrimRef::Sphere, t_max, key_max)
    }
}

impl PlanePacket {
    /// [`Plane`](crate::geometry::Plane)'s test on four planes at once.
    #[inline(always)]
    pub(super) fn closest<const TIES: bool>(
        &self,
        rc: &RayConsts,
        t_min: f32,
        t_max: f32,
        key_max: u32,
    ) -> Option<WideHit> {
        let (mask, t) = plane_hit::<_, TIES>(&self.p, &self.n, &rc.o, &rc.d, Vec4::splat(t_min), Vec4::splat(t_max));
        nearest_hit::<TIES>(mask, t, &self.ids, TAG_PLANE, PrimRef::Plane, t_max, key_max)
    }
}
