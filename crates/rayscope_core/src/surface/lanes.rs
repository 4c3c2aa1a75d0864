//! The surface at a packet's hits, sixteen lanes at once.
//!
//! After a packet's closest hits are found, each lane's hit point, normals and shadow-ray origin
//! are what [`Scene::surface`](crate::scene::Scene::surface) and
//! [`Surface::outside`](super::Surface::outside) compute for one ray. The primitives' data is
//! gathered lane by lane (by `PacketSurfaces`, which knows the scene); this kernel then computes
//! every lane with the same arithmetic in the same order (glam's: sums of three products are
//! `(x + y) + z`, `normalize` divides by the length), without branching on the kind of
//! primitive, so the compiler can vectorise it. A plane, a sphere and a triangle side by side in
//! one packet is the common case, and per-lane branches on it mispredict. The rays mirrors and
//! glass send on from these frames are `crate::optics::specular_rays`.

use crate::math::{offset_eps_lane, RayPacket};
use crate::simd::{dispatched, sel, Mask, LANES};

/// One value per lane.
type F = [f32; LANES];

/// Per-lane data of the primitives a packet's rays hit, gathered for [`surface_frames`].
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct HitPrims {
    /// Lanes with a hit.
    pub hit: Mask,
    /// Hit distance.
    pub t: F,
    /// Lanes whose hit is on a sphere.
    pub sphere: Mask,
    /// Lanes whose hit is on a triangle.
    pub triangle: Mask,
    /// A plane's unit normal, a sphere's centre or a triangle's first edge (v1 − v0).
    pub a: [F; 3],
    /// A triangle's second edge (v2 − v0).
    pub b: [F; 3],
    /// A sphere's radius (1 elsewhere).
    pub radius: F,
    /// Vertex normals of the lanes on smooth triangles, when there are any.
    pub smooth: Option<SmoothNormals>,
}

impl Default for HitPrims {
    fn default() -> Self {
        Self {
            hit: [false; LANES],
            t: [0.0; LANES],
            sphere: [false; LANES],
            triangle: [false; LANES],
            a: [[0.0; LANES]; 3],
            b: [[0.0; LANES]; 3],
            radius: [1.0; LANES],
            smooth: None,
        }
    }
}

/// The vertex normals of a packet's hits on triangles that have them.
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct SmoothNormals {
    /// Lanes whose triangle has vertex normals.
    pub on: Mask,
    /// The normals, in vertex order.
    pub vn: [[F; 3]; 3],
    /// Barycentric u of the hit (weight of the second vertex).
    pub bu: F,
    /// Barycentric v of the hit (weight of the third vertex).
    pub bv: F,
}

impl Default for SmoothNormals {
    fn default() -> Self {
        Self {
            on: [false; LANES],
            vn: [[[0.0; LANES]; 3]; 3],
            bu: [0.0; LANES],
            bv: [0.0; LANES],
        }
    }
}

/// The local geometry at each lane's hit (meaningless in lanes without one).
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct SurfaceFrames {
    /// Hit point.
    pub point: [F; 3],
    /// Unit geometric normal, flipped to face the ray.
    pub normal: [F; 3],
    /// Unit shading normal (interpolated on smooth triangles), on the same side as `normal`.
    pub shading_normal: [F; 3],
    /// The ray hit the side the primitive's own normal points to.
    pub front_face: Mask,
    /// Where rays leaving the surface on the ray's side start:
    /// [`Surface::outside`](super::Surface::outside) of each lane.
    pub outside: [F; 3],
}

/// The geometry at the hits of `rays` (the rays as traced, before their hits) on the
/// primitives `g`. See the module documentation.
#[inline(always)]
pub(crate) fn surface_frames_impl(rays: &RayPacket, g: &HitPrims) -> SurfaceFrames {
    let dot = |x: &[F; 3], y: &[F; 3], i: usize| x[0][i] * y[0][i] + x[1][i] * y[1][i] + x[2][i] * y[2][i];
    // Ray::at.
    let mut point = [[0.0; LANES]; 3];
    for (ax, p) in point.iter_mut().enumerate() {
        for i in 0..LANES {
            p[i] = rays.o[ax][i] + rays.d[ax][i] * g.t[i];
        }
    }
    // Sphere::normal is ((p − c) / r).normalize(); Triangle::geometric_normal is
    // (e1 × e2).normalize(); a plane stores its normal. Each kind is computed only when some
    // lane has it (packets of mirror and glass rays are often sparse and of one kind).
    let mut n = g.a;
    if g.sphere.iter().any(|&s| s) {
        let mut q = [[0.0; LANES]; 3];
        for (ax, q) in q.iter_mut().enumerate() {
            for i in 0..LANES {
                q[i] = (point[ax][i] - g.a[ax][i]) / g.radius[i];
            }
        }
        for i in 0..LANES {
            let len = dot(&q, &q, i).sqrt();
            for ax in 0..3 {
                n[ax][i] = sel(g.sphere[i], q[ax][i] / len, n[ax][i]);
            }
        }
    }
    if g.triangle.iter().any(|&t| t) {
        let (a, b) = (&g.a, &g.b);
        let mut x = [[0.0; LANES]; 3];
        for i in 0..LANES {
            x[0][i] = a[1][i] * b[2][i] - a[2][i] * b[1][i];
            x[1][i] = a[2][i] * b[0][i] - a[0][i] * b[2][i];
            x[2][i] = a[0][i] * b[1][i] - a[1][i] * b[0][i];
        }
        for i in 0..LANES {
            let len = dot(&x, &x, i).sqrt();
            for ax in 0..3 {
                n[ax][i] = sel(g.triangle[i], x[ax][i] / len, n[ax][i]);
            }
        }
    }
    // Scene::surface's shading normal: the vertex normals interpolated and normalised with
    // glam's normalize_or_zero (times the reciprocal length, zero unless that is finite and
    // positive), the geometric normal where that gives zero.
    let mut ns = n;
    if let Some(sm) = &g.smooth {
        let mut s = [[0.0; LANES]; 3];
        for (ax, s) in s.iter_mut().enumerate() {
            for i in 0..LANES {
                let w = 1.0 - sm.bu[i] - sm.bv[i];
                s[i] = sm.vn[0][ax][i] * w + sm.vn[1][ax][i] * sm.bu[i] + sm.vn[2][ax][i] * sm.bv[i];
            }
        }
        for i in 0..LANES {
            let rcp = 1.0 / dot(&s, &s, i).sqrt();
            let usable = sm.on[i] & rcp.is_finite() & (rcp > 0.0);
            let v = [s[0][i] * rcp, s[1][i] * rcp, s[2][i] * rcp];
            let nonzero = (v[0] != 0.0) | (v[1] != 0.0) | (v[2] != 0.0);
            for ax in 0..3 {
                ns[ax][i] = sel(usable & nonzero, v[ax], n[ax][i]);
            }
        }
    }
    let mut out = SurfaceFrames {
        point,
        normal: [[0.0; LANES]; 3],
        shading_normal: [[0.0; LANES]; 3],
        front_face: [false; LANES],
        outside: [[0.0; LANES]; 3],
    };
    for i in 0..LANES {
        let front = dot(&n, &rays.d, i) < 0.0;
        out.front_face[i] = front;
        for ax in 0..3 {
            out.normal[ax][i] = sel(front, n[ax][i], -n[ax][i]);
        }
    }
    for i in 0..LANES {
        let flip = dot(&ns, &out.normal, i) < 0.0;
        for ax in 0..3 {
            out.shading_normal[ax][i] = sel(flip, -ns[ax][i], ns[ax][i]);
        }
        // The shadow-ray origin: the point moved off the surface along the facing normal.
        let eps = offset_eps_lane(&point, &rays.o, i);
        for ax in 0..3 {
            out.outside[ax][i] = point[ax][i] + out.normal[ax][i] * eps;
        }
    }
    out
}

dispatched!(
    /// [`surface_frames`] with the best instruction set the CPU has.
    best_surface_frames, surface_frames_avx512, surface_frames_avx2,
    (rays: &RayPacket, prims: &HitPrims) -> SurfaceFrames,
    surface_frames_impl(rays, prims)
);

/// The geometry at the hits of `rays` on the primitives `prims`: per lane, the hit point, the
/// normals and the offset origin that the single-ray code computes (see the module docs).
// Calls the dispatcher rather than being it (see `crate::simd::dispatched`).
#[must_use]
pub fn surface_frames(rays: &RayPacket, prims: &HitPrims) -> SurfaceFrames {
    best_surface_frames(rays, prims)
}
