//! The geometry at a packet's hits and the mirror and glass rays leaving them, sixteen lanes
//! at once.
//!
//! After a packet's closest hits are found, each lane's hit point, normals and shadow-ray origin
//! are what [`crate::scene::Scene::surface`] and the single-ray shading code compute. The
//! primitives' data is gathered lane by lane (by the caller, which knows the scene); this
//! kernel then computes every lane with the same arithmetic in the same order (glam's: sums of
//! three products are `(x + y) + z`, `normalize` divides by the length), without branching on
//! the kind of primitive, so the compiler can vectorise it. A plane, a sphere and a triangle
//! side by side in one packet is the common case, and per-lane branches on it mispredict.
//! [`specular_rays`] does the same for the rays mirrors and glass send on.

use crate::math::RayPacket;
use crate::simd::{dispatched, Mask, LANES};

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
    /// Where rays leaving the surface on the ray's side start: the point moved off the surface
    /// by `offset_eps` along the facing normal.
    pub outside: [F; 3],
}

/// glam's `max` of one lane (`maxps`: the second operand when either is NaN).
#[inline(always)]
fn maxps(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// glam's `max_element` of one lane's (x, y, z), in glam's order.
#[inline(always)]
pub(crate) fn max_element(c: [f32; 3]) -> f32 {
    maxps(maxps(c[0], c[2]), maxps(c[1], c[2]))
}

/// `crate::math::offset_eps` of lane `i` of points `p` and ray origins `o`: 1e-5 × the largest
/// |coordinate| of either (glam's abs, max and max_element, in that order), at least 1e-30.
#[inline(always)]
fn offset_eps(p: &[F; 3], o: &[F; 3], i: usize) -> f32 {
    let m = max_element(std::array::from_fn(|a| maxps(p[a][i].abs(), o[a][i].abs())));
    (1e-5 * m).max(1e-30)
}

/// `a` when `c`, else `b`.
#[inline(always)]
fn sel(c: bool, a: f32, b: f32) -> f32 {
    if c {
        a
    } else {
        b
    }
}

/// The geometry at the hits of `rays` (the rays as traced, before their hits) on the
/// primitives `g`. See the module documentation.
#[inline(always)]
pub(super) fn surface_frames_impl(rays: &RayPacket, g: &HitPrims) -> SurfaceFrames {
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
        let eps = offset_eps(&point, &rays.o, i);
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

/// The rays mirrors and glass send on from a packet's hits: per lane, the arithmetic of the
/// single-ray code's `mirror`, `glass`, `fresnel` and `refract` (meaningless in other lanes).
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct SpecularRays {
    /// Unit mirror-reflection direction.
    pub reflected: [F; 3],
    /// Fresnel reflectance of glass with the lane's index of refraction.
    pub kr: F,
    /// Lanes where light also refracts (reflectance below 1, no total internal reflection).
    pub has_refracted: Mask,
    /// Unit refracted direction, in those lanes.
    pub refracted: [F; 3],
    /// Where refracted rays start: the hit point moved off the surface to the far side.
    pub inside: [F; 3],
}

/// The mirror and glass rays of the hits `f` of `rays`, glass having index of refraction `ior`.
#[inline(always)]
pub(super) fn specular_rays_impl(rays: &RayPacket, f: &SurfaceFrames, ior: &F) -> SpecularRays {
    let mut out = SpecularRays {
        reflected: [[0.0; LANES]; 3],
        kr: [0.0; LANES],
        has_refracted: [false; LANES],
        refracted: [[0.0; LANES]; 3],
        inside: [[0.0; LANES]; 3],
    };
    let (d, n, p) = (&rays.d, &f.normal, &f.point);
    for i in 0..LANES {
        let dn = d[0][i] * n[0][i] + d[1][i] * n[1][i] + d[2][i] * n[2][i];
        // reflect(d, n) = d − n·(2 d·n), normalised.
        let r: [f32; 3] = std::array::from_fn(|a| d[a][i] - n[a][i] * (2.0 * dn));
        let len = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        for a in 0..3 {
            out.reflected[a][i] = r[a] / len;
        }
        // fresnel(cos_i, n1, n2) with cos_i = clamp(−d·n, 0, 1) (NaN passes through clamp).
        let front = f.front_face[i];
        let (n1, n2) = (sel(front, 1.0, ior[i]), sel(front, ior[i], 1.0));
        let neg = -dn;
        let cos_i = sel(neg < 0.0, 0.0, sel(neg > 1.0, 1.0, neg));
        let eta = n1 / n2;
        let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
        let cos_t = (1.0 - sin2_t).sqrt();
        let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
        let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
        let kr = sel(sin2_t >= 1.0, 1.0, 0.5 * (rs * rs + rp * rp));
        out.kr[i] = kr;
        // refract(d, n, n1 / n2), tried only when kr < 1; its cosine is not clamped.
        let sin2_r = eta * eta * (1.0 - neg * neg).max(0.0);
        let cos_r = (1.0 - sin2_r).sqrt();
        out.has_refracted[i] = (kr < 1.0) & (sin2_r < 1.0);
        let t: [f32; 3] = std::array::from_fn(|a| d[a][i] * eta + n[a][i] * (eta * neg - cos_r));
        let len = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        for a in 0..3 {
            out.refracted[a][i] = t[a] / len;
        }
        // As for `SurfaceFrames::outside`, on the other side.
        let eps = offset_eps(p, &rays.o, i);
        for a in 0..3 {
            out.inside[a][i] = p[a][i] - n[a][i] * eps;
        }
    }
    out
}

dispatched!(
    /// [`specular_rays`] with the best instruction set the CPU has.
    best_specular_rays, specular_rays_avx512, specular_rays_avx2,
    (rays: &RayPacket, frames: &SurfaceFrames, ior: &[f32; LANES]) -> SpecularRays,
    specular_rays_impl(rays, frames, ior)
);

/// The rays mirrors and glass send on from the hits `frames` of `rays`; see [`SpecularRays`].
// Calls the dispatcher rather than being it (see `crate::simd::dispatched`).
#[must_use]
pub fn specular_rays(rays: &RayPacket, frames: &SurfaceFrames, ior: &[f32; LANES]) -> SpecularRays {
    best_specular_rays(rays, frames, ior)
}
