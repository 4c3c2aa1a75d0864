//! Ray packets: sixteen rays traced together through the 4-wide BVH.
//!
//! Camera rays of one pixel (or of neighbouring pixels) and the shadow rays from their hits
//! toward one light travel almost together, so the render loop traces them as a packet: each
//! primitive is loaded once and tested against all sixteen rays with lane-parallel arithmetic,
//! and each node is opened once for the packet rather than once per ray. The per-lane
//! arithmetic is that of the single-ray tests, packet by packet, so a packet returns what
//! tracing its rays one at a time returns (in scenes without a tree bit for bit; in a tree only
//! the order leaves are visited in differs, which matters only for exact ties).
//!
//! The kernels are plain loops over `[f32; LANES]` arrays that the compiler vectorises. The
//! entry points run an AVX-512 or AVX2 build of them when the CPU has it (`crate::simd::dispatched`).

use arrayvec::ArrayVec;

use super::frustum::{ApexCull, Beam};
use super::layout::{
    Bvh4, Node4, PlanePacket, SpherePacket, TriPacket, EMPTY, LEAF, NO_PRIM, RUN, RUN_SHIFT, SPHERES, STACK, TAG_MASK,
    TAG_PLANE, TAG_SPHERE, TAG_TRI,
};
use super::single::{far, NodeConsts, RayConsts, TraversalStack, Walk, SLAB_SLACK};
use crate::geometry::{plane_hit, sphere_line, triangle_plane, PrimRef, SphereLine, TrianglePlane};
use crate::math::RayPacket;
use crate::simd::{dispatched, put, Mask, LANES};

/// Every lane of a primitive packet.
const ALL: u32 = 0xF;

/// A subtree that at most this many of a packet's rays enter is walked by each of them alone.
/// Rays that start together part where a pixel covers several triangles, and shadow rays part
/// near the surfaces they leave: below the level where they part, a packet would test all
/// sixteen lanes at every node and leaf any one of them enters. Two measured best (four: the
/// same for shadow rays, a 4 M-triangle render's camera rays 6 % slower).
const SOLO_LANES: u32 = 2;

/// One value per lane.
type F = [f32; LANES];

/// The closest hits of a packet's rays (none by default).
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct PacketHits {
    t: F,
    u: F,
    v: F,
    prim: [u32; LANES],
    /// What `u` and `v` are still to be divided by (a triangle's |d·n|; 1 once divided): the
    /// kernels divide once, after the last packet, instead of at every packet that holds a hit.
    a: F,
}

impl Default for PacketHits {
    fn default() -> Self {
        Self {
            t: [0.0; LANES],
            u: [0.0; LANES],
            v: [0.0; LANES],
            prim: [0; LANES],
            a: [1.0; LANES],
        }
    }
}

impl PacketHits {
    /// True when every lane hit the same primitive: the common case for a packet of one
    /// pixel's samples, whose shading data can then be looked up once.
    #[must_use]
    #[inline]
    pub(crate) fn one_prim(&self) -> bool {
        let p = self.prim[0];
        // A fold rather than `all`, which would stop early and keep the loop scalar.
        p & TAG_MASK != 0 && self.prim.iter().fold(true, |a, &q| a & (q == p))
    }

    /// Which lanes hit something, and their hit distances (0 in the others), as whole arrays:
    /// written lane by lane and then read as vectors, they stalled on store forwarding.
    #[must_use]
    #[inline(always)]
    pub fn distances(&self) -> (Mask, F) {
        let hit: Mask = std::array::from_fn(|i| self.prim[i] & TAG_MASK != 0);
        (hit, std::array::from_fn(|i| sel(hit[i], self.t[i], 0.0)))
    }

    /// Every lane's barycentrics (u, v) (meaningless in lanes without a hit), as whole arrays.
    #[must_use]
    #[inline(always)]
    pub(crate) fn barycentrics(&self) -> (F, F) {
        (self.u, self.v)
    }

    /// Makes `h` lane `i`'s hit, as [`Self::get`] returns it (none: no hit).
    #[inline]
    pub fn set(&mut self, i: usize, h: Option<(f32, f32, f32, PrimRef)>) {
        let Some((t, u, v, prim)) = h else {
            self.prim[i] = 0;
            return;
        };
        let key = match prim {
            PrimRef::Plane(k) => TAG_PLANE | k,
            PrimRef::Sphere(k) => TAG_SPHERE | k,
            PrimRef::Triangle(k) => TAG_TRI | k,
        };
        (self.t[i], self.u[i], self.v[i], self.prim[i], self.a[i]) = (t, u, v, key, 1.0);
    }

    /// Divides the barycentrics by what the kernels left them scaled by.
    #[inline(always)]
    pub(crate) fn divide(&mut self) {
        for i in 0..LANES {
            self.u[i] /= self.a[i];
            self.v[i] /= self.a[i];
            self.a[i] = 1.0;
        }
    }

    /// Lane `i`'s hit: (t, u, v, primitive).
    #[must_use]
    #[inline]
    pub fn get(&self, i: usize) -> Option<(f32, f32, f32, PrimRef)> {
        let p = self.prim[i];
        let id = p & !TAG_MASK;
        // Tests rather than a `match`, which compiles to a jump table whose indirect jump
        // mispredicts whenever neighbouring lanes hit different kinds of primitive.
        let tag = p & TAG_MASK;
        let prim = if tag == TAG_TRI {
            PrimRef::Triangle(id)
        } else if tag == TAG_PLANE {
            PrimRef::Plane(id)
        } else if tag == TAG_SPHERE {
            PrimRef::Sphere(id)
        } else {
            // Tag 0: no hit (the default).
            return None;
        };
        Some((self.t[i], self.u[i], self.v[i], prim))
    }
}

/// Lane `k` of a 4-wide primitive packet's vector stored per axis.
#[inline(always)]
fn lane_of(v: &[glam::Vec4; 3], k: usize) -> [f32; 3] {
    // Read through a reference: `to_array` copies the whole vector to the stack first, and the
    // lane's load then waits on that store.
    let at = |a: usize| AsRef::<[f32; 4]>::as_ref(&v[a])[k];
    [at(0), at(1), at(2)]
}

/// Ray `i`'s origin.
#[inline(always)]
fn ray_o(rays: &RayPacket, i: usize) -> [f32; 3] {
    [rays.o[0][i], rays.o[1][i], rays.o[2][i]]
}

/// Ray `i`'s direction.
#[inline(always)]
fn ray_d(rays: &RayPacket, i: usize) -> [f32; 3] {
    [rays.d[0][i], rays.d[1][i], rays.d[2][i]]
}

/// `a` when `c`, else `b`: written so the compiler emits a blend.
#[inline(always)]
fn sel(c: bool, a: f32, b: f32) -> f32 {
    if c {
        a
    } else {
        b
    }
}

/// `a` when `c`, else `b`, as bit operations: a `bool` select on integers compiles to a branch.
#[inline(always)]
fn sel_u32(c: bool, a: u32, b: u32) -> u32 {
    let m = 0u32.wrapping_sub(u32::from(c));
    (a & m) | (b & !m)
}

/// The best hit found so far inside one 4-wide primitive packet, per ray. The single-ray test
/// filters all four primitives against the best hit known when the packet is entered and then
/// takes the nearest (the lowest lane on ties, which holds the lowest index: see
/// [`beats`](super::layout::beats)); this replays exactly that.
// The arrays first, each on a cache line of its own: behind the sixteen `found` flags they sat
// 16 bytes off, the compiler zeroed them with overlapping stores, and the first load of `t`
// then spanned two of those stores, which cannot be forwarded (a stall at every packet).
#[repr(C, align(64))]
struct PacketBest {
    t: F,
    u: F,
    v: F,
    prim: [u32; LANES],
    /// What `u` and `v` are to be divided by.
    a: F,
    found: [bool; LANES],
}

impl PacketBest {
    #[inline(always)]
    fn new() -> Self {
        Self {
            found: [false; LANES],
            t: [0.0; LANES],
            u: [0.0; LANES],
            v: [0.0; LANES],
            prim: [0; LANES],
            a: [1.0; LANES],
        }
    }

    /// Offers every lane the hit on primitive `key` that passed the packet's filter and beats
    /// the lane's best hit on entry where `ok`; returns where it is taken. Offers come in lane
    /// order, so on a tie the earlier stays. Written as whole arrays of bit operations and
    /// selects, which the compiler vectorises: short-circuit tests lane by lane compile to a
    /// chain of branches per ray and primitive.
    #[inline(always)]
    fn offer_lanes(&mut self, ok: &Mask, t: &F, key: u32) -> Mask {
        let take: Mask = std::array::from_fn(|i| ok[i] & (!self.found[i] | (t[i] < self.t[i])));
        self.t = std::array::from_fn(|i| sel(take[i], t[i], self.t[i]));
        self.prim = std::array::from_fn(|i| sel_u32(take[i], key, self.prim[i]));
        self.found = std::array::from_fn(|i| self.found[i] | take[i]);
        take
    }

    /// [`Self::offer_lanes`] of triangle hits, which carry their undivided barycentrics and
    /// what they are to be divided by. Sphere and plane hits have u = v = 0 and a = 1, the
    /// values [`Self::new`] holds, so they are offered without them.
    #[inline(always)]
    fn offer_lanes_uva(&mut self, ok: &Mask, t: &F, u: &F, v: &F, a: &F, key: u32) {
        let take = self.offer_lanes(ok, t, key);
        self.u = std::array::from_fn(|i| sel(take[i], u[i], self.u[i]));
        self.v = std::array::from_fn(|i| sel(take[i], v[i], self.v[i]));
        self.a = std::array::from_fn(|i| sel(take[i], a[i], self.a[i]));
    }

    /// Writes the packet's hits into the running result.
    #[inline(always)]
    fn commit(&self, rays: &mut RayPacket, hits: &mut PacketHits) {
        if !any(&self.found) {
            return;
        }
        // Whole arrays selected and stored: written as a select per lane into the same array,
        // the compiler makes each lane a branch and a conditional store.
        let f = &self.found;
        rays.t_max = std::array::from_fn(|i| sel(f[i], self.t[i], rays.t_max[i]));
        hits.t = std::array::from_fn(|i| sel(f[i], self.t[i], hits.t[i]));
        hits.u = std::array::from_fn(|i| sel(f[i], self.u[i], hits.u[i]));
        hits.v = std::array::from_fn(|i| sel(f[i], self.v[i], hits.v[i]));
        hits.prim = std::array::from_fn(|i| sel_u32(f[i], self.prim[i], hits.prim[i]));
        hits.a = std::array::from_fn(|i| sel(f[i], self.a[i], hits.a[i]));
    }
}

/// Where `ok` and the hit at `t` on primitive `key` [`beats`](super::layout::beats) the best
/// hit on entry (`entry`, `entry_key`), as bit operations, so that the loop vectorises.
#[inline(always)]
fn beats_lanes(ok: &Mask, t: &F, key: u32, entry: &F, entry_key: &[u32; LANES]) -> Mask {
    std::array::from_fn(|i| ok[i] & ((t[i] < entry[i]) | ((t[i] == entry[i]) & (key < entry_key[i]))))
}

#[inline(always)]
fn any(m: &Mask) -> bool {
    m.iter().fold(false, |a, &b| a | b)
}

/// [`any`] as one 128-bit word of the flags' bytes, for flags just made by comparisons: folded
/// flag by flag, the compiler turned the comparisons' mask register into bytes and then
/// OR-reduced those through a chain of nine shuffles (4 % of the bunny scene's samples). Used
/// everywhere in place of the fold, the word made scene 2 6 % slower (its closest-hit kernel
/// compiled worse), so it is used only for the primitive tests' fresh flags.
#[inline(always)]
fn any_fresh(m: &Mask) -> bool {
    u128::from_ne_bytes(m.map(u8::from)) != 0
}

impl TriPacket {
    /// Lane `k`'s triangle tested against every ray ([`triangle_plane`], as in
    /// [`TriPacket::closest`]). Returns (hit, t, u, v, |d·n|) per ray, undivided; `None` when no
    /// ray meets the triangle's plane inside its interval (checked before the edge tests, as the
    /// single-ray test does, so shadow rays that end before a wall cost a third).
    #[inline(always)]
    fn lane_vs_rays(&self, k: usize, rays: &RayPacket, t_min: f32, t_max: &F) -> Option<(Mask, F, F, F, F)> {
        let (v0, n) = (lane_of(&self.v0, k), lane_of(&self.n, k));
        let (mut ok, mut t, mut s, mut a) = ([false; LANES], [0.0; LANES], [0.0; LANES], [0.0; LANES]);
        let mut c = [[0.0; LANES]; 3];
        for i in 0..LANES {
            let plane = triangle_plane(&v0, &n, &ray_o(rays, i), &ray_d(rays, i), t_min, t_max[i]);
            put(&mut c, i, plane.c);
            (ok[i], t[i], s[i], a[i]) = (plane.hit, plane.t, plane.s, plane.a);
        }
        if !any_fresh(&ok) {
            return None;
        }
        let (e1, e2) = (lane_of(&self.e1, k), lane_of(&self.e2, k));
        // The plane half is kept per ray in arrays, so the loop above stays vectorised and the
        // edge half runs only when some ray meets the plane.
        let (mut u, mut v, mut hit) = ([0.0; LANES], [0.0; LANES], [false; LANES]);
        for i in 0..LANES {
            let plane = TrianglePlane {
                c: [c[0][i], c[1][i], c[2][i]],
                s: s[i],
                a: a[i],
                t: t[i],
                hit: ok[i],
            };
            (u[i], v[i], hit[i]) = plane.edges(&e1, &e2, &ray_d(rays, i));
        }
        Some((hit, t, u, v, a))
    }

    #[inline(always)]
    fn closest_rays(&self, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits, live: u32) {
        let mut best = PacketBest::new();
        let (entry, entry_key) = (rays.t_max, hits.prim);
        // The single-ray test's filter bound (see `far`).
        let bound = entry.map(|t| far(true, t));
        for k in 0..4 {
            let id = self.ids[k];
            if id == NO_PRIM || live & (1 << k) == 0 {
                continue;
            }
            let Some((ok, t, u, v, a)) = self.lane_vs_rays(k, rays, t_min, &bound) else {
                continue;
            };
            if !any_fresh(&ok) {
                continue;
            }
            let key = TAG_TRI | id;
            // As in the single-ray test: the divided distance decides. The barycentrics are
            // divided for the nearest hit only (as the single-ray test does), once the last
            // packet is tested (`PacketHits::divide`).
            let t: F = std::array::from_fn(|i| t[i] / a[i]);
            let ok = beats_lanes(&ok, &t, key, &entry, &entry_key);
            best.offer_lanes_uva(&ok, &t, &u, &v, &a, key);
        }
        best.commit(rays, hits);
    }

    #[inline(always)]
    fn occlude_rays(&self, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask, live: u32) {
        for k in 0..4 {
            if self.ids[k] == NO_PRIM || live & (1 << k) == 0 {
                continue;
            }
            if let Some((ok, ..)) = self.lane_vs_rays(k, rays, t_min, &rays.t_max) {
                block(rays, blocked, &ok);
            }
        }
    }
}

/// Marks the rays in `ok` as blocked and closes their intervals, so nothing tests them again.
#[inline(always)]
fn block(rays: &mut RayPacket, blocked: &mut Mask, ok: &Mask) {
    for i in 0..LANES {
        blocked[i] |= ok[i];
        rays.t_max[i] = sel(ok[i], f32::NEG_INFINITY, rays.t_max[i]);
    }
}

impl SpherePacket {
    /// Lane `k`'s sphere against every ray ([`sphere_line`], as in [`SpherePacket::closest`]);
    /// `None` when no ray's line meets the sphere (no ray can hit it), checked before the
    /// second half of the test, as the single-ray test does: most packets pass most spheres by.
    #[inline(always)]
    fn lane_vs_rays<const TIES: bool>(&self, k: usize, rays: &RayPacket, t_min: f32, t_max: &F) -> Option<(Mask, F)> {
        let c = lane_of(&self.c, k);
        let r2 = AsRef::<[f32; 4]>::as_ref(&self.r2)[k];
        // The first half is kept per ray in arrays, so both loops stay vectorised.
        let (mut f, mut b, mut disc, mut meets) = ([[0.0; LANES]; 3], [0.0; LANES], [0.0; LANES], [false; LANES]);
        for i in 0..LANES {
            let line = sphere_line(&c, r2, &ray_o(rays, i), &ray_d(rays, i));
            put(&mut f, i, line.f);
            (b[i], disc[i], meets[i]) = (line.b, line.disc, line.disc >= 0.0);
        }
        if !any_fresh(&meets) {
            return None;
        }
        let (mut ok, mut t) = ([false; LANES], [0.0; LANES]);
        for i in 0..LANES {
            let line = SphereLine {
                f: [f[0][i], f[1][i], f[2][i]],
                b: b[i],
                disc: disc[i],
            };
            (ok[i], t[i]) = line.hit::<TIES>(r2, t_min, t_max[i]);
        }
        Some((ok, t))
    }

    #[inline(always)]
    fn closest_rays(&self, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits, live: u32) {
        let test = |k, r: &RayPacket, t_max: &F| self.lane_vs_rays::<true>(k, r, t_min, t_max);
        lanes_closest_rays(&self.ids, live, TAG_SPHERE, test, rays, hits);
    }

    #[inline(always)]
    fn occlude_rays(&self, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask, live: u32) {
        let test = |k, r: &RayPacket, t_max: &F| self.lane_vs_rays::<false>(k, r, t_min, t_max);
        lanes_occlude_rays(&self.ids, live, test, rays, blocked);
    }
}

impl PlanePacket {
    /// Lane `k`'s plane against every ray ([`plane_hit`], as in [`PlanePacket::closest`]).
    #[inline(always)]
    fn lane_vs_rays<const TIES: bool>(&self, k: usize, rays: &RayPacket, t_min: f32, t_max: &F) -> Option<(Mask, F)> {
        let (p, n) = (lane_of(&self.p, k), lane_of(&self.n, k));
        let (mut ok, mut t) = ([false; LANES], [0.0; LANES]);
        for i in 0..LANES {
            (ok[i], t[i]) = plane_hit::<_, TIES>(&p, &n, &ray_o(rays, i), &ray_d(rays, i), t_min, t_max[i]);
        }
        Some((ok, t))
    }

    #[inline(always)]
    fn closest_rays(&self, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits, live: u32) {
        let test = |k, r: &RayPacket, t_max: &F| self.lane_vs_rays::<true>(k, r, t_min, t_max);
        lanes_closest_rays(&self.ids, live, TAG_PLANE, test, rays, hits);
    }

    #[inline(always)]
    fn occlude_rays(&self, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask, live: u32) {
        let test = |k, r: &RayPacket, t_max: &F| self.lane_vs_rays::<false>(k, r, t_min, t_max);
        lanes_occlude_rays(&self.ids, live, test, rays, blocked);
    }
}

/// The closest hits among a packet's four spheres or planes, `test(k, rays, t_max)` giving lane
/// `k`'s (hit, t) per ray, or `None` where no ray can hit it: all four filtered against the
/// distances known on entry, then each ray takes its nearest, as the single-ray test does packet
/// by packet.
#[inline(always)]
fn lanes_closest_rays(
    ids: &[u32; 4],
    live: u32,
    tag: u32,
    test: impl Fn(usize, &RayPacket, &F) -> Option<(Mask, F)>,
    rays: &mut RayPacket,
    hits: &mut PacketHits,
) {
    let mut best = PacketBest::new();
    let (entry, entry_key) = (rays.t_max, hits.prim);
    for (k, &id) in ids.iter().enumerate() {
        if id == NO_PRIM || live & (1 << k) == 0 {
            continue;
        }
        let Some((ok, t)) = test(k, rays, &entry) else {
            continue;
        };
        let ok = beats_lanes(&ok, &t, tag | id, &entry, &entry_key);
        best.offer_lanes(&ok, &t, tag | id);
    }
    best.commit(rays, hits);
}

/// [`lanes_closest_rays`] for shadow rays: marks the rays some lane blocks.
#[inline(always)]
fn lanes_occlude_rays(
    ids: &[u32; 4],
    live: u32,
    test: impl Fn(usize, &RayPacket, &F) -> Option<(Mask, F)>,
    rays: &mut RayPacket,
    blocked: &mut Mask,
) {
    for (k, &id) in ids.iter().enumerate() {
        if id == NO_PRIM || live & (1 << k) == 0 {
            continue;
        }
        if let Some((ok, _)) = test(k, rays, &rays.t_max) {
            block(rays, blocked, &ok);
        }
    }
}

/// Per-packet constants of the node test.
#[repr(align(64))]
struct PacketNodeConsts {
    inv: [F; 3],
}

impl PacketNodeConsts {
    #[inline(always)]
    fn new(rays: &RayPacket) -> Self {
        let mut inv = [[0.0; LANES]; 3];
        for a in 0..3 {
            for i in 0..LANES {
                inv[a][i] = 1.0 / rays.d[a][i];
            }
        }
        Self { inv }
    }
}

/// Which of a node's children some ray of the packet enters (bit per child), the nearest entry
/// distance of each child over the rays that enter it, and with `lanes_of` which rays enter
/// each child (bit per lane; zero without). Always inlined with a constant `lanes_of`.
#[inline(always)]
fn node_test(
    node: &Node4,
    rays: &RayPacket,
    nc: &PacketNodeConsts,
    t_min: f32,
    lanes_of: bool,
) -> (u32, [f32; 4], [u32; 4]) {
    let mut mask = 0;
    let mut near = [f32::INFINITY; 4];
    let mut lanes = [0; 4];
    for c in 0..4 {
        if node.valid & (1 << c) == 0 {
            continue;
        }
        let lo = [node.bounds[0][0][c], node.bounds[1][0][c], node.bounds[2][0][c]];
        let hi = [node.bounds[0][1][c], node.bounds[1][1][c], node.bounds[2][1][c]];
        let mut hit = [false; LANES];
        let mut entry = [f32::INFINITY; LANES];
        for i in 0..LANES {
            let mut t0 = t_min;
            let mut t1 = rays.t_max[i];
            for a in 0..3 {
                // Near and far planes by the direction's sign, as in the single-ray test (not
                // by comparing the distances, which a NaN would confuse).
                let neg = nc.inv[a][i] < 0.0;
                let tn = (sel(neg, hi[a], lo[a]) - rays.o[a][i]) * nc.inv[a][i];
                let tf = (sel(neg, lo[a], hi[a]) - rays.o[a][i]) * nc.inv[a][i];
                // A NaN from 0·∞ (origin on a slab of an axis-parallel ray) leaves the interval
                // unchanged, as in the single-ray test.
                t0 = sel(tn > t0, tn, t0);
                t1 = sel(tf < t1, tf, t1);
            }
            hit[i] = t0 <= t1 * SLAB_SLACK;
            entry[i] = sel(hit[i], t0, f32::INFINITY);
        }
        // Without `lanes_of` the walk needs only whether any ray enters, which the fold gives
        // without assembling the mask.
        let entered = if lanes_of {
            lanes[c] = bits(&hit);
            lanes[c] != 0
        } else {
            any(&hit)
        };
        if entered {
            mask |= 1 << c;
            near[c] = min_lane(entry);
        }
    }
    (mask, near, lanes)
}

/// The flags as a bit mask, lane `i` in bit `i`.
#[inline(always)]
fn bits(m: &Mask) -> u32 {
    // Each half's eight flag bytes (0 or 1) are gathered into its top byte by one
    // multiplication: the constant's byte 7 - i is 2^i, which moves flag i (at bit 8i) to bit
    // 56 + i, and no two partial products share a bit, so nothing carries. Folded flag by flag,
    // the compiler kept the lanes apart (12 % of a packet walk's samples).
    let b = u128::from_le_bytes(m.map(u8::from));
    let gather = |h: u64| (h.wrapping_mul(0x0102_0408_1020_4080) >> 56) as u32;
    gather(b as u64) | (gather((b >> 64) as u64) << 8)
}

/// The lanes whose interval is still open past `t_min` (bit per lane).
#[inline(always)]
fn open_lanes(rays: &RayPacket, t_min: f32) -> u32 {
    bits(&std::array::from_fn(|i| rays.t_max[i] > t_min))
}

/// A packet walk's stack entry: a node or leaf reference with the nearest entry distance of the
/// packet's rays (closest-hit walks), or the reference alone (shadow walks), and wrapped in
/// [`Split`] the lanes whose rays entered it.
trait Entry: Copy {
    /// Whether entries carry their lanes, and the walk splits packets where the rays part.
    const SPLIT: bool;
    fn new(r: u32, near: f32, lanes: u32) -> Self;
    fn node(self) -> u32;
    /// The entry distance (0 for entries without one).
    fn near(self) -> f32;
    /// The lanes that entered (every lane for entries without them).
    fn lanes(self) -> u32;
}

impl Entry for u32 {
    const SPLIT: bool = false;
    #[inline(always)]
    fn new(r: u32, _: f32, _: u32) -> Self {
        r
    }
    #[inline(always)]
    fn node(self) -> u32 {
        self
    }
    #[inline(always)]
    fn near(self) -> f32 {
        0.0
    }
    #[inline(always)]
    fn lanes(self) -> u32 {
        u32::MAX
    }
}

impl Entry for (u32, f32) {
    const SPLIT: bool = false;
    #[inline(always)]
    fn new(r: u32, near: f32, _: u32) -> Self {
        (r, near)
    }
    #[inline(always)]
    fn node(self) -> u32 {
        self.0
    }
    #[inline(always)]
    fn near(self) -> f32 {
        self.1
    }
    #[inline(always)]
    fn lanes(self) -> u32 {
        u32::MAX
    }
}

/// An [`Entry`] `E` with the lanes that entered it.
#[derive(Clone, Copy)]
struct Split<E> {
    entry: E,
    lanes: u32,
}

impl<E: Entry> Entry for Split<E> {
    const SPLIT: bool = true;
    #[inline(always)]
    fn new(r: u32, near: f32, lanes: u32) -> Self {
        Split {
            entry: E::new(r, near, lanes),
            lanes,
        }
    }
    #[inline(always)]
    fn node(self) -> u32 {
        self.entry.node()
    }
    #[inline(always)]
    fn near(self) -> f32 {
        self.entry.near()
    }
    #[inline(always)]
    fn lanes(self) -> u32 {
        self.lanes
    }
}

/// Calls `walk(i, rays, ray constants, node constants)` for each lane `i` in `lanes` (bit per
/// lane), with the constants a single-ray query makes for lane `i`'s ray.
#[inline(always)]
fn alone(lanes: u32, rays: &mut RayPacket, mut walk: impl FnMut(usize, &mut RayPacket, &RayConsts, &NodeConsts)) {
    let mut m = lanes;
    while m != 0 {
        let i = m.trailing_zeros() as usize;
        m &= m - 1;
        let ray = rays.ray(i);
        walk(i, rays, &RayConsts::new(&ray), &NodeConsts::new(&ray));
    }
}

/// The smallest of sixteen values, none NaN (entry distances start at `t_min` and only take
/// values that compare greater), by halving: a fold compiles to a chain of dependent minima.
#[inline(always)]
fn min_lane(mut m: F) -> f32 {
    let mut w = LANES / 2;
    while w > 0 {
        for i in 0..w {
            m[i] = if m[i + w] < m[i] { m[i + w] } else { m[i] };
        }
        w /= 2;
    }
    m[0]
}

/// The largest interval end over the packet: a child entered beyond it cannot matter.
#[inline(always)]
fn max_t(rays: &RayPacket) -> f32 {
    // Halving rather than a fold: `f32::max` treats NaN specially, so a fold compiles to a
    // chain of sixteen dependent scalar maxima. Interval ends are never NaN (a NaN distance
    // fails every comparison that would store it), so the order does not matter.
    let mut m = rays.t_max;
    let mut w = LANES / 2;
    while w > 0 {
        for i in 0..w {
            m[i] = if m[i + w] > m[i] { m[i + w] } else { m[i] };
        }
        w /= 2;
    }
    m[0]
}

/// True when every ray of the packet is closed (blocked, or unused).
#[inline(always)]
fn all_closed(rays: &RayPacket) -> bool {
    rays.t_max.iter().fold(true, |a, &t| a & (t == f32::NEG_INFINITY))
}

impl Bvh4 {
    /// Tests leaf `r`; only tree leaves (`RUNS`) can be a [`RUN`] of packets.
    /// `live` (bit per lane) says which primitives of a single packet to test (see [`Beam`]).
    #[inline(always)]
    fn leaf_closest_rays<const RUNS: bool>(
        &self,
        r: u32,
        rays: &mut RayPacket,
        t_min: f32,
        hits: &mut PacketHits,
        live: u32,
    ) {
        if live == 0 {
            return;
        }
        if r & SPHERES != 0 {
            self.spheres[(r & !(LEAF | SPHERES)) as usize].closest_rays(rays, t_min, hits, live);
        } else if !RUNS {
            self.tris[(r & !LEAF) as usize].closest_rays(rays, t_min, hits, live);
        } else {
            let i = (r & !(LEAF | RUN)) as usize;
            for p in &self.tris[i..=i + ((r & RUN) >> RUN_SHIFT) as usize] {
                p.closest_rays(rays, t_min, hits, live);
            }
        }
    }

    /// Tests leaf `r`; only tree leaves (`RUNS`) can be a [`RUN`] of packets.
    /// `live` (bit per lane) says which primitives of a single packet to test (see [`Beam`]).
    #[inline(always)]
    fn leaf_occlude_rays<const RUNS: bool>(
        &self,
        r: u32,
        rays: &mut RayPacket,
        t_min: f32,
        blocked: &mut Mask,
        live: u32,
    ) {
        if live == 0 {
            return;
        }
        if r & SPHERES != 0 {
            self.spheres[(r & !(LEAF | SPHERES)) as usize].occlude_rays(rays, t_min, blocked, live);
        } else if !RUNS {
            self.tris[(r & !LEAF) as usize].occlude_rays(rays, t_min, blocked, live);
        } else {
            let i = (r & !(LEAF | RUN)) as usize;
            for p in &self.tris[i..=i + ((r & RUN) >> RUN_SHIFT) as usize] {
                p.occlude_rays(rays, t_min, blocked, live);
            }
        }
    }

    /// The packet tree walk for closest hits, on a stack of type `S` (see [`Bvh4::deep`]). With
    /// entries that carry their lanes ([`Entry::SPLIT`]), a subtree that at most [`SOLO_LANES`]
    /// rays entered is walked by each of them alone (see [`Bvh4::split_packets`]).
    #[inline(always)]
    fn walk_closest_rays<E: Entry, S: TraversalStack<E> + Default>(
        &self,
        rays: &mut RayPacket,
        t_min: f32,
        hits: &mut PacketHits,
    ) {
        let nc = PacketNodeConsts::new(rays);
        let mut stack = S::default();
        stack.put(E::new(self.root, t_min, open_lanes(rays, t_min)));
        let mut far = max_t(rays);
        while let Some(e) = stack.take() {
            let r = e.node();
            if e.near() > far * SLAB_SLACK {
                continue;
            }
            if E::SPLIT && e.lanes().count_ones() <= SOLO_LANES {
                self.solo_closest(r, e.lanes(), rays, t_min, hits);
                far = max_t(rays);
                continue;
            }
            if r & LEAF != 0 {
                self.leaf_closest_rays::<true>(r, rays, t_min, hits, ALL);
                far = max_t(rays);
                continue;
            }
            let node = &self.nodes[r as usize];
            let (mask, near, lanes) = node_test(node, rays, &nc, t_min, E::SPLIT);
            // Far children first, so the nearest is taken first.
            let mut order: ArrayVec<E, 4> = ArrayVec::new();
            let mut m = mask;
            while m != 0 {
                let i = m.trailing_zeros() as usize;
                m &= m - 1;
                self.prefetch_child(node.children[i]);
                let item = E::new(node.children[i], near[i], lanes[i]);
                let mut j = order.len();
                order.push(item);
                while j > 0 && order[j - 1].near() < item.near() {
                    order[j] = order[j - 1];
                    j -= 1;
                }
                order[j] = item;
            }
            for &e in &order {
                stack.put(e);
            }
        }
    }

    /// The closest-hit walk that splits packets, on the fixed stack (the caller has checked that
    /// there is a tree and that it is not [`Bvh4::deep`]).
    #[inline(always)]
    pub(crate) fn closest_rays_split_impl(&self, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits) {
        self.walk_closest_rays::<Split<(u32, f32)>, ArrayVec<_, STACK>>(rays, t_min, hits);
    }

    /// The shadow walk that splits packets, on the fixed stack (the caller has checked that
    /// there is a tree and that it is not [`Bvh4::deep`]).
    #[inline(always)]
    pub(crate) fn occluded_rays_split_impl(&self, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask) {
        self.walk_occlude_rays::<Split<u32>, ArrayVec<_, STACK>>(rays, t_min, blocked);
    }

    /// The closest hits in subtree `r` of the rays in `lanes`, each walked alone, as
    /// [`Bvh4::closest`] walks it: the same arithmetic and tie rule, so the same hits.
    #[inline(never)]
    fn solo_closest(&self, r: u32, lanes: u32, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits) {
        alone(lanes, rays, |i, rays, rc, nc| {
            let mut walk = Walk {
                best: None,
                t_best: rays.t_max[i],
                key: hits.prim[i],
                visits: 0,
            };
            if self.deep {
                self.walk_closest::<false, Vec<(u32, f32)>>(r, rc, nc, t_min, &mut walk);
            } else {
                self.walk_closest::<false, ArrayVec<(u32, f32), STACK>>(r, rc, nc, t_min, &mut walk);
            }
            if let Some(h) = walk.best {
                // Divided already (`a` = 1), as `PacketHits::divide` leaves the other lanes.
                (rays.t_max[i], hits.t[i], hits.u[i], hits.v[i], hits.a[i]) = (h.t, h.t, h.u, h.v, 1.0);
                hits.prim[i] = h.key();
            }
        });
    }

    /// The packet tree walk for shadow rays, on a stack of type `S`; with entries that carry
    /// their lanes it splits packets as [`Self::walk_closest_rays`] does.
    #[inline(always)]
    fn walk_occlude_rays<E: Entry, S: TraversalStack<E> + Default>(
        &self,
        rays: &mut RayPacket,
        t_min: f32,
        blocked: &mut Mask,
    ) {
        let nc = PacketNodeConsts::new(rays);
        let mut stack = S::default();
        stack.put(E::new(self.root, t_min, open_lanes(rays, t_min)));
        while let Some(e) = stack.take() {
            let r = e.node();
            if E::SPLIT {
                // Rays blocked since the entry was pushed need nothing more from it.
                let lanes = e.lanes() & open_lanes(rays, t_min);
                if lanes == 0 {
                    continue;
                }
                if lanes.count_ones() <= SOLO_LANES {
                    self.solo_occlude(r, lanes, rays, t_min, blocked);
                    if all_closed(rays) {
                        return;
                    }
                    continue;
                }
            }
            if r & LEAF != 0 {
                self.leaf_occlude_rays::<true>(r, rays, t_min, blocked, ALL);
                if all_closed(rays) {
                    return;
                }
                continue;
            }
            let node = &self.nodes[r as usize];
            let (mut mask, near, lanes) = node_test(node, rays, &nc, t_min, E::SPLIT);
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                self.prefetch_child(node.children[i]);
                stack.put(E::new(node.children[i], near[i], lanes[i]));
            }
        }
    }

    /// Whether anything in subtree `r` blocks each ray in `lanes`, each walked alone as
    /// [`Bvh4::any`] walks it; blocked rays are closed.
    #[inline(never)]
    fn solo_occlude(&self, r: u32, lanes: u32, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask) {
        alone(lanes, rays, |i, rays, rc, nc| {
            let hit = if self.deep {
                self.walk_any::<Vec<u32>>(r, rc, nc, t_min, rays.t_max[i])
            } else {
                self.walk_any::<ArrayVec<u32, STACK>>(r, rc, nc, t_min, rays.t_max[i])
            };
            if hit.is_some() {
                blocked[i] = true;
                rays.t_max[i] = f32::NEG_INFINITY;
            }
        });
    }

    /// Lane `lane` of sphere packet `packet` alone against the rays; see
    /// [`Self::closest_rays_inside`].
    #[inline(always)]
    pub(super) fn inside_closest_rays_impl(
        &self,
        rays: &mut RayPacket,
        t_min: f32,
        hits: &mut PacketHits,
        packet: u32,
        lane: u32,
    ) {
        self.spheres[packet as usize].closest_rays(rays, t_min, hits, 1 << lane);
    }

    /// With `cull` (the view from the rays' common origin), the list skips the primitives no
    /// ray can meet.
    #[inline(always)]
    pub(crate) fn closest_rays_impl(
        &self,
        rays: &mut RayPacket,
        t_min: f32,
        hits: &mut PacketHits,
        cull: Option<&ApexCull>,
    ) {
        let beam = cull.and_then(|c| Some((c, Beam::leaving(rays, t_min, c)?)));
        for (k, p) in self.planes.iter().enumerate() {
            let live = beam.map_or(ALL, |(c, b)| c.plane_lanes(k, &b));
            if live != 0 {
                p.closest_rays(rays, t_min, hits, live);
            }
        }
        for (k, &r) in self.flat.iter().enumerate() {
            self.leaf_closest_rays::<false>(r, rays, t_min, hits, beam.map_or(ALL, |(c, b)| c.flat_lanes(k, &b)));
        }
        if self.root == EMPTY {
            return;
        }
        if self.deep {
            self.walk_closest_rays::<(u32, f32), Vec<_>>(rays, t_min, hits);
        } else if self.split_packets {
            closest_rays_split(self, rays, t_min, hits);
        } else {
            self.walk_closest_rays::<(u32, f32), ArrayVec<_, STACK>>(rays, t_min, hits);
        }
    }

    /// [`Self::closest_rays_impl`] for rays that part at once (a wave of paths' bounces): in
    /// a scene with a single-ray list the list's packets are tested one after another, as a
    /// single ray tests them, instead of walking the tree, whose every node such rays open.
    #[inline(always)]
    pub(super) fn scattered_closest_rays_impl(&self, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits) {
        if self.single.is_empty() {
            return self.closest_rays_impl(rays, t_min, hits, None);
        }
        for p in &self.planes {
            p.closest_rays(rays, t_min, hits, ALL);
        }
        for &r in &self.single {
            self.leaf_closest_rays::<false>(r, rays, t_min, hits, ALL);
        }
    }

    /// [`Self::occluded_rays_impl`] for rays that part at once; see
    /// [`Self::scattered_closest_rays_impl`].
    #[inline(always)]
    pub(super) fn scattered_occluded_rays_impl(&self, rays: &mut RayPacket, t_min: f32) -> Mask {
        if self.single.is_empty() {
            return self.occluded_rays_impl(rays, t_min, None);
        }
        let mut blocked = [false; LANES];
        for p in &self.planes {
            p.occlude_rays(rays, t_min, &mut blocked, ALL);
        }
        for &r in &self.single {
            if all_closed(rays) {
                break;
            }
            self.leaf_occlude_rays::<false>(r, rays, t_min, &mut blocked, ALL);
        }
        blocked
    }

    /// With `beam` (and the view from its apex), the list skips the primitives no ray can meet.
    #[inline(always)]
    pub(crate) fn occluded_rays_impl(&self, rays: &mut RayPacket, t_min: f32, beam: Option<(&ApexCull, Beam)>) -> Mask {
        let mut blocked = [false; LANES];
        for (k, p) in self.planes.iter().enumerate() {
            let live = beam.map_or(ALL, |(c, b)| c.plane_lanes(k, &b));
            if live != 0 {
                p.occlude_rays(rays, t_min, &mut blocked, live);
            }
        }
        for (k, &r) in self.flat.iter().enumerate() {
            // Every ray blocked: nothing left to test.
            if all_closed(rays) {
                return blocked;
            }
            self.leaf_occlude_rays::<false>(
                r,
                rays,
                t_min,
                &mut blocked,
                beam.map_or(ALL, |(c, b)| c.flat_lanes(k, &b)),
            );
        }
        if self.root == EMPTY || all_closed(rays) {
            return blocked;
        }
        if self.deep {
            self.walk_occlude_rays::<u32, Vec<_>>(rays, t_min, &mut blocked);
        } else if self.split_shadows {
            occluded_rays_split(self, rays, t_min, &mut blocked);
        } else {
            self.walk_occlude_rays::<u32, ArrayVec<_, STACK>>(rays, t_min, &mut blocked);
        }
        blocked
    }

    /// Which of the `traced` rays of `shadow` are blocked before their `t_max`; with `cull` (the
    /// view from the point every traced ray ends at, a point light's position), the flat list
    /// skips the primitives no ray can meet. [`crate::lights::point_light_rays`] makes the rays.
    #[inline(always)]
    pub(crate) fn occluded_toward_apex(&self, shadow: &mut RayPacket, traced: &Mask, cull: Option<&ApexCull>) -> Mask {
        let beam = cull.and_then(|c| Some((c, Beam::reaching(shadow, traced, c)?)));
        self.occluded_rays_impl(shadow, 0.0, beam)
    }

    /// The closest hit of every ray in the packet with `t_min < t < t_max` (the lane's own
    /// `t_max`). The packet's `t_max` is left at each lane's hit distance.
    pub fn closest_rays(&self, rays: &mut RayPacket, t_min: f32) -> PacketHits {
        let mut hits = PacketHits::default();
        closest_rays(self, rays, t_min, &mut hits, None);
        hits.divide();
        hits
    }

    /// [`Self::closest_rays`] into `hits`, for rays that may all leave the apex of `cull`, when
    /// given (a pinhole camera's centre): the same hits, found without testing what lies
    /// outside the rays' cone.
    // The hits are written in place: returned by value, they were copied on the way (a `memcpy`
    // per packet in the packet tracer).
    #[inline(always)]
    pub fn closest_rays_from(&self, rays: &mut RayPacket, t_min: f32, cull: Option<&ApexCull>, hits: &mut PacketHits) {
        *hits = PacketHits::default();
        closest_rays(self, rays, t_min, hits, cull);
        hits.divide();
    }

    /// [`Self::closest_rays`] into `hits` for rays that all start inside one sphere that no
    /// other primitive reaches into, the sphere in lane `lane` of sphere packet `packet` (see
    /// [`Self::sphere_slot`]): only that sphere is tested, since each ray leaves through it
    /// before it can meet anything else. Returns false, with `rays` as they were, when a ray in
    /// use finds no hit on the sphere (one that starts just outside it, grazing), whose hit must
    /// then be looked for everywhere.
    #[inline(always)]
    pub fn closest_rays_inside(
        &self,
        rays: &mut RayPacket,
        t_min: f32,
        (packet, lane): (u32, u32),
        hits: &mut PacketHits,
    ) -> bool {
        let entry = rays.t_max;
        *hits = PacketHits::default();
        inside_closest_rays(self, rays, t_min, hits, packet, lane);
        hits.divide();
        let missed = (0..LANES).fold(false, |m, i| m | ((entry[i] > t_min) & (hits.prim[i] & TAG_MASK == 0)));
        if missed {
            rays.t_max = entry;
        }
        !missed
    }

    /// [`Self::closest_rays`] for rays that share little of their way through the scene, such
    /// as a wave of paths' bounce rays: the same hits, found by whichever walk suits such rays.
    pub fn scattered_closest_rays(&self, rays: &mut RayPacket, t_min: f32) -> PacketHits {
        let mut hits = PacketHits::default();
        scattered_closest_rays(self, rays, t_min, &mut hits);
        hits.divide();
        hits
    }

    /// [`Self::occluded_rays`] for rays that share little of their way through the scene.
    pub fn scattered_occluded_rays(&self, rays: &mut RayPacket, t_min: f32) -> [bool; LANES] {
        scattered_occluded_rays(self, rays, t_min)
    }

    /// For every ray in the packet, whether anything lies on it with `t_min < t < t_max`.
    /// The packet's `t_max` is consumed (blocked lanes are closed).
    pub fn occluded_rays(&self, rays: &mut RayPacket, t_min: f32) -> [bool; LANES] {
        occluded_rays(self, rays, t_min)
    }
}

dispatched!(
    /// Closest hits of a ray packet.
    closest_rays, closest_rays_avx512, closest_rays_avx2,
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits, cull: Option<&ApexCull>) -> (),
    bvh.closest_rays_impl(rays, t_min, hits, cull)
);

dispatched!(
    /// Closest hits of a ray packet whose rays may part (see [`Bvh4::split_packets`]). Its builds
    /// stay out of line: inlined into [`closest_rays`], they changed how that kernel compiled
    /// for the scenes that never split.
    closest_rays_split, closest_rays_split_avx512, closest_rays_split_avx2, #[inline(never)]
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits) -> (),
    bvh.closest_rays_split_impl(rays, t_min, hits)
);

dispatched!(
    /// Which rays of a shadow packet are blocked, in trees with [`Bvh4::split_shadows`] (out
    /// of line, as [`closest_rays_split`]).
    occluded_rays_split, occluded_rays_split_avx512, occluded_rays_split_avx2, #[inline(never)]
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32, blocked: &mut Mask) -> (),
    bvh.occluded_rays_split_impl(rays, t_min, blocked)
);

dispatched!(
    /// Closest hits of a ray packet on one sphere.
    inside_closest_rays, inside_closest_rays_avx512, inside_closest_rays_avx2,
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits, packet: u32, lane: u32) -> (),
    bvh.inside_closest_rays_impl(rays, t_min, hits, packet, lane)
);

dispatched!(
    /// Which rays of a packet are blocked.
    occluded_rays, occluded_rays_avx512, occluded_rays_avx2,
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32) -> Mask,
    bvh.occluded_rays_impl(rays, t_min, None)
);

dispatched!(
    /// Closest hits of a packet of scattered rays.
    scattered_closest_rays, scattered_closest_rays_avx512, scattered_closest_rays_avx2,
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32, hits: &mut PacketHits) -> (),
    bvh.scattered_closest_rays_impl(rays, t_min, hits)
);

dispatched!(
    /// Which rays of a packet of scattered rays are blocked.
    scattered_occluded_rays, scattered_occluded_rays_avx512, scattered_occluded_rays_avx2,
    (bvh: &Bvh4, rays: &mut RayPacket, t_min: f32) -> Mask,
    bvh.scattered_occluded_rays_impl(rays, t_min)
);
