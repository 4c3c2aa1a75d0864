//! Beams: the primitives of a flat list that a packet of rays leaving (or reaching) one point can
//! skip, because no ray of the packet passes through them.
//!
//! A pinhole camera's rays all leave its centre, and every shadow ray toward a point light ends
//! at the light. Seen from such a point (the apex), each primitive of the scene's flat list (the
//! whole of a small scene, such as course scene 2's planes, walls and spheres) covers a fixed
//! set of directions, so [`ApexCull`] precomputes, once per render and apex, the planes that bound
//! those directions. A packet's rays from the apex lie in a narrow cone (one pixel's samples, or
//! the shadow rays of one pixel's hits), and a primitive whose directions lie wholly outside the
//! cone is skipped with a few 4-wide operations instead of being tested with every ray.
//!
//! Every test is conservative: a primitive is skipped only when it lies outside the cone by a
//! margin ([`SLACK`]) far above the rounding of the rays and of the ray tests, and never when it
//! comes near the apex ([`NEAR`]), where an angle says little. So the hits are exactly those
//! found without beams (the tests `beams_skip_only_what_no_ray_hits` and `packet_render`).

use glam::{DVec3, Vec4};

use super::layout::{Bvh4, PlanePacket, SpherePacket, TriPacket, LEAF, NO_PRIM, SPHERES};
use crate::math::RayPacket;
use crate::simd::{Mask, LANES};

/// Margin, as the sine of an angle, by which a primitive must lie outside a packet's cone.
const SLACK: f32 = 1e-2;
/// Primitives nearer the apex than this, times [`ApexCull::scale`], are never skipped.
const NEAR: f64 = 1e-3;
/// The widest cone worth testing against (the cosine of its half-angle).
const MIN_COS: f32 = 0.9;
/// Shadow rays longer than this, times the apex's scale, get no beam: the rounding of their
/// directions moves them off the apex by more than [`NEAR`] allows for.
const MAX_REACH: f32 = 8.0;

/// Per lane of a primitive packet, up to three unit normals (x, y, z lanes) of planes through the
/// apex: a ray from the apex can meet the primitive only on the positive side of every one.
/// Lanes whose primitive is near the apex (or absent) have zero normals and are in `keep`.
#[derive(Debug, Clone, Copy)]
struct Bounds4 {
    m: [[Vec4; 3]; 3],
    keep: u32,
    /// The lanes that hold a primitive.
    valid: u32,
}

/// A sphere packet as seen from the apex: unit directions to the centres and the sine and
/// cosine of each sphere's angular radius. Lanes in `keep` are never skipped.
#[derive(Debug, Clone, Copy)]
struct Cone4 {
    dir: [Vec4; 3],
    sin: Vec4,
    cos: Vec4,
    keep: u32,
    /// The lanes that hold a primitive.
    valid: u32,
}

#[derive(Debug, Clone, Copy)]
enum Cull {
    /// A triangle packet: the three planes through the apex and each edge.
    Tris(Bounds4),
    /// A sphere packet.
    Spheres(Cone4),
}

/// What the primitives of a [`Bvh4`]'s flat list and planes look like from one apex (a pinhole
/// camera's centre or a point light), for `Beam` tests.
#[derive(Debug, Clone)]
pub struct ApexCull {
    apex: [f32; 3],
    /// 1 + the largest |coordinate| of the apex: the scale of its rounding errors.
    scale: f32,
    /// One per plane packet: the plane's normal turned toward the apex's far side.
    planes: Vec<Bounds4>,
    /// One per entry of the flat list.
    flat: Vec<Cull>,
}

impl ApexCull {
    /// The view of `bvh`'s flat list and planes from `apex`; `None` when there is no list (a
    /// tree culls by its own boxes, and building a beam for the planes alone does not pay).
    #[must_use]
    pub fn new(bvh: &Bvh4, apex: [f32; 3]) -> Option<Self> {
        if bvh.flat.is_empty() {
            return None;
        }
        let a = DVec3::from(apex.map(f64::from));
        let scale = 1.0 + apex.iter().fold(0.0f32, |m, &x| m.max(x.abs()));
        let near = NEAR * f64::from(scale);
        let planes = bvh.planes.iter().map(|p| plane_bounds(p, a, near)).collect();
        let flat = bvh
            .flat
            .iter()
            .map(|&r| {
                if r & SPHERES != 0 {
                    Cull::Spheres(sphere_cones(&bvh.spheres[(r & !(LEAF | SPHERES)) as usize], a, near))
                } else {
                    Cull::Tris(tri_bounds(&bvh.tris[(r & !LEAF) as usize], a, near))
                }
            })
            .collect();
        Some(ApexCull {
            apex,
            scale,
            planes,
            flat,
        })
    }

    /// The lanes of plane packet `k` that some ray of `beam` may meet.
    #[inline(always)]
    pub(super) fn plane_lanes(&self, k: usize, beam: &Beam) -> u32 {
        self.planes[k].lanes(beam)
    }

    /// The lanes of the flat list's entry `k` that some ray of `beam` may meet.
    #[inline(always)]
    pub(super) fn flat_lanes(&self, k: usize, beam: &Beam) -> u32 {
        match &self.flat[k] {
            Cull::Tris(b) => b.lanes(beam),
            Cull::Spheres(c) => c.lanes(beam),
        }
    }
}

/// The cone of a packet's rays seen from an apex: a unit axis and the sine and cosine of the
/// half-angle, [`SLACK`] included.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Beam {
    axis: [Vec4; 3],
    sin: Vec4,
    /// 1 − sin², which is at most the cosine (√(1 − sin²)): a smaller cosine only makes the
    /// sphere test keep more, and it saves a second root on the packet's critical path.
    cos: Vec4,
}

impl Beam {
    /// The cone of unit directions `dirs` (negated when `flip`) of the lanes in `on`, around the
    /// first such lane's; `None` when no lane is on or the directions spread too wide.
    #[inline(always)]
    fn around_first(dirs: &[[f32; LANES]; 3], on: &Mask, flip: bool) -> Option<Self> {
        let first = on.iter().position(|&o| o)?;
        let axis = [dirs[0][first], dirs[1][first], dirs[2][first]];
        let (mut sin, mut cos) = ([0.0f32; LANES], [1.0f32; LANES]);
        for i in 0..LANES {
            let d = [dirs[0][i], dirs[1][i], dirs[2][i]];
            let x = [
                d[1] * axis[2] - d[2] * axis[1],
                d[2] * axis[0] - d[0] * axis[2],
                d[0] * axis[1] - d[1] * axis[0],
            ];
            // The root per lane, sixteen at once, rather than of the largest after the search:
            // there its latency sat on the packet's critical path.
            let si = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
            let c = d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2];
            sin[i] = if on[i] { si } else { 0.0 };
            cos[i] = if on[i] { c } else { 1.0 };
        }
        // The largest sine and smallest cosine, by halving.
        let mut w = LANES / 2;
        while w > 0 {
            for i in 0..w {
                sin[i] = if sin[i + w] > sin[i] { sin[i + w] } else { sin[i] };
                cos[i] = if cos[i + w] < cos[i] { cos[i + w] } else { cos[i] };
            }
            w /= 2;
        }
        if !above(cos[0], MIN_COS) {
            return None;
        }
        let sin = sin[0] + SLACK;
        let sign = if flip { -1.0 } else { 1.0 };
        Some(Beam {
            axis: axis.map(|x| Vec4::splat(sign * x)),
            sin: Vec4::splat(sin),
            cos: Vec4::splat(1.0 - sin * sin),
        })
    }

    /// The beam of a packet's rays in use (`t_max > t_min`) when they all leave `cull`'s apex.
    #[inline(always)]
    pub(super) fn leaving(rays: &RayPacket, t_min: f32, cull: &ApexCull) -> Option<Self> {
        let a = cull.apex;
        let mut on = [false; LANES];
        let mut elsewhere = [false; LANES];
        for i in 0..LANES {
            on[i] = rays.t_max[i] > t_min;
            let moved = (rays.o[0][i] != a[0]) | (rays.o[1][i] != a[1]) | (rays.o[2][i] != a[2]);
            elsewhere[i] = on[i] & moved;
        }
        if elsewhere.iter().fold(false, |x, &e| x | e) {
            return None;
        }
        Self::around_first(&rays.d, &on, false)
    }

    /// The beam of shadow rays in `on` that run toward `cull`'s apex (a point light) in the unit
    /// directions `rays.d`, each ending there (`t_max` is its length).
    #[inline(always)]
    pub(super) fn reaching(rays: &RayPacket, on: &Mask, cull: &ApexCull) -> Option<Self> {
        let mut reach: [f32; LANES] = std::array::from_fn(|i| if on[i] { rays.t_max[i] } else { 0.0 });
        let mut w = LANES / 2;
        while w > 0 {
            for i in 0..w {
                reach[i] = if reach[i + w] > reach[i] {
                    reach[i + w]
                } else {
                    reach[i]
                };
            }
            w /= 2;
        }
        if !above(MAX_REACH * cull.scale, reach[0]) {
            return None;
        }
        Self::around_first(&rays.d, on, true)
    }
}

impl Bounds4 {
    /// The lanes that some ray of `beam` may meet: those not wholly outside one of the planes.
    #[inline(always)]
    fn lanes(&self, beam: &Beam) -> u32 {
        let neg = -beam.sin;
        let mut out = 0;
        for m in &self.m {
            let c = m[0] * beam.axis[0] + m[1] * beam.axis[1] + m[2] * beam.axis[2];
            out |= c.cmplt(neg).bitmask();
        }
        (!out | self.keep) & self.valid
    }
}

impl Cone4 {
    /// The lanes that some ray of `beam` may meet: those whose sphere's cone of directions
    /// overlaps the beam's.
    #[inline(always)]
    fn lanes(&self, beam: &Beam) -> u32 {
        let c = self.dir[0] * beam.axis[0] + self.dir[1] * beam.axis[1] + self.dir[2] * beam.axis[2];
        // The cosine of the sum of the two half-angles.
        let limit = beam.cos * self.cos - beam.sin * self.sin;
        (!c.cmplt(limit).bitmask() | self.keep) & self.valid
    }
}

/// `a > b`, and so false when either is NaN: every test written with it fails safe.
#[inline(always)]
fn above<T: PartialOrd>(a: T, b: T) -> bool {
    a > b
}

/// A unit vector in `f32`, or zero when `v` has no usable direction.
fn unit(v: DVec3) -> [f32; 3] {
    let l = v.length();
    if l > 0.0 && l.is_finite() {
        (v / l).as_vec3().to_array()
    } else {
        [0.0; 3]
    }
}

/// Lane `k` of a 4-wide packet's per-axis vector, in `f64`.
fn lane64(v: &[Vec4; 3], k: usize) -> DVec3 {
    DVec3::new(f64::from(v[0][k]), f64::from(v[1][k]), f64::from(v[2][k]))
}

/// Writes `n` as lane `k` of the per-axis vector `m`.
fn put4(m: &mut [Vec4; 3], k: usize, n: [f32; 3]) {
    for a in 0..3 {
        m[a][k] = n[a];
    }
}

/// The lanes of a primitive packet that hold a primitive.
fn used(ids: &[u32; 4]) -> impl Iterator<Item = usize> + '_ {
    (0..4).filter(|&k| ids[k] != NO_PRIM)
}

/// [`used`] as a bit per lane.
fn used_mask(ids: &[u32; 4]) -> u32 {
    used(ids).fold(0, |v, k| v | 1 << k)
}

impl Bounds4 {
    /// No planes yet, for a packet with primitives `ids`.
    fn new(ids: &[u32; 4]) -> Self {
        Bounds4 {
            m: [[Vec4::ZERO; 3]; 3],
            keep: 0,
            valid: used_mask(ids),
        }
    }
}

fn tri_bounds(p: &TriPacket, apex: DVec3, near: f64) -> Bounds4 {
    let mut b = Bounds4::new(&p.ids);
    for k in used(&p.ids) {
        let (e1, e2) = (lane64(&p.e1, k), lane64(&p.e2, k));
        let w0 = lane64(&p.v0, k) - apex;
        let w = [w0, w0 + e1, w0 + e2];
        let n = e1.cross(e2);
        let side = w0.dot(n);
        // The apex near the triangle's plane, or a triangle with no area: kept.
        if !above(side.abs(), near * n.length()) {
            b.keep |= 1 << k;
            continue;
        }
        // Rays from the apex that meet the triangle point into the cone spanned by w0, w1, w2:
        // on the inner side of each plane through the apex and an edge.
        let s = side.signum();
        for e in 0..3 {
            let m = w[e].cross(w[(e + 1) % 3]) * s;
            // An edge seen end-on gives no reliable plane: that plane skips nothing (zero).
            let usable = m.length() > 1e-9 * w[e].length() * w[(e + 1) % 3].length();
            put4(&mut b.m[e], k, if usable { unit(m) } else { [0.0; 3] });
        }
    }
    b
}

fn sphere_cones(p: &SpherePacket, apex: DVec3, near: f64) -> Cone4 {
    let mut c = Cone4 {
        dir: [Vec4::ZERO; 3],
        sin: Vec4::ZERO,
        cos: Vec4::ONE,
        keep: 0,
        valid: used_mask(&p.ids),
    };
    for k in used(&p.ids) {
        let v = lane64(&p.c, k) - apex;
        let r = f64::from(p.r2[k]).max(0.0).sqrt();
        let dist = v.length();
        if !above(dist, r + near) {
            c.keep |= 1 << k;
            continue;
        }
        put4(&mut c.dir, k, unit(v));
        let s = r / dist;
        c.sin[k] = s as f32;
        c.cos[k] = (1.0 - s * s).sqrt() as f32;
    }
    c
}

fn plane_bounds(p: &PlanePacket, apex: DVec3, near: f64) -> Bounds4 {
    let mut b = Bounds4::new(&p.ids);
    for k in used(&p.ids) {
        let n = lane64(&p.n, k);
        let h = (lane64(&p.p, k) - apex).dot(n);
        if !above(h.abs(), near * n.length()) {
            b.keep |= 1 << k;
            continue;
        }
        // A ray from the apex meets the plane ahead only when it heads to the plane's side.
        put4(&mut b.m[0], k, unit(n * h.signum()));
    }
    b
}

#[cfg(test)]
mod tests {
    use std::fmt::Write;
    use std::path::Path;

    use glam::Vec3A;

    use super::*;
    use crate::accel::PacketHits;
    use crate::math::Ray;
    use crate::rng::Rng;
    use crate::scene::Scene;

    /// Course scene 2's room (floor, roof, eight wall triangles) with four random triangles and
    /// three spheres inside: a flat list of four packets.
    fn room(seed: u64) -> Scene {
        let mut rng = Rng::for_sample(seed, 0, 0);
        let mut r = move || rng.next_f32();
        let mut text = String::from(concat!(
            "Material \"M\" Diffuse (1, 1, 1) 1\n",
            "Plane \"F\" (0, -1, 0) (0, 1, 0) \"M\"\n",
            "Plane \"R\" (0, 1, 0) (0, -1, 0) \"M\"\n",
            "Triangle \"LA\" (-1, -1, 0) (-1, 1, 0) (-1, 1, 3) \"M\"\n",
            "Triangle \"LB\" (-1, -1, 0) (-1, 1, 3) (-1, -1, 3) \"M\"\n",
            "Triangle \"RA\" (1, 1, 0) (1, -1, 0) (1, 1, 3) \"M\"\n",
            "Triangle \"RB\" (1, 1, 3) (1, -1, 0) (1, -1, 3) \"M\"\n",
            "Triangle \"BA\" (-1, 1, 0) (-1, -1, 0) (1, 1, 0) \"M\"\n",
            "Triangle \"BB\" (1, 1, 0) (-1, -1, 0) (1, -1, 0) \"M\"\n",
            "Triangle \"FA\" (-1, -1, 3) (-1, 1, 3) (1, 1, 3) \"M\"\n",
            "Triangle \"FB\" (-1, -1, 3) (1, 1, 3) (1, -1, 3) \"M\"\n",
        ));
        let inside = |r: &mut dyn FnMut() -> f32| [r() * 1.6 - 0.8, r() * 1.6 - 0.8, r() * 2.6 + 0.2];
        for i in 0..4 {
            let c = inside(&mut r);
            let mut v = || {
                let d = inside(&mut r);
                format!("({}, {}, {})", c[0] + 0.3 * d[0], c[1] + 0.3 * d[1], c[2] + 0.2 * d[2])
            };
            let (a, b, d) = (v(), v(), v());
            writeln!(text, "Triangle \"T{i}\" {a} {b} {d} \"M\"").unwrap();
        }
        for i in 0..3 {
            let c = inside(&mut r);
            writeln!(
                text,
                "Sphere \"S{i}\" ({}, {}, {}) {} \"M\"",
                c[0],
                c[1],
                c[2],
                0.1 + 0.2 * r()
            )
            .unwrap();
        }
        Scene::from_file(&rayscope_scene::parse_str(&text, Path::new("room.txt")).unwrap())
    }

    /// Rays and shadow rays from apexes anywhere in the room (on the floor, at a wall's corner,
    /// inside), in packets from a thousandth of a degree to a few degrees wide, aimed at random
    /// points and at the walls' corners and edges (where rays graze a triangle's border): the
    /// packets that skip primitives by their beam find exactly the hits of those that test all.
    #[test]
    fn beams_skip_only_what_no_ray_hits() {
        let (mut kept, mut lanes, mut shadow_beams) = (0u64, 0u64, 0u64);
        for seed in 0..4 {
            let scene = room(seed);
            let bvh = &scene.wide;
            assert_eq!(bvh.flat.len(), 4, "the room is a flat list");
            let corners: Vec<Vec3A> = scene.triangles.iter().flat_map(|t| [t.v0(), t.v0() + t.e1()]).collect();
            let mut rng = Rng::for_sample(seed, 1, 0);
            let mut r = move || rng.next_f32();
            for round in 0..600 {
                let inside = |r: &mut dyn FnMut() -> f32| Vec3A::new(r() * 1.8 - 0.9, r() * 1.8 - 0.9, r() * 2.8 + 0.1);
                let apex = match round % 6 {
                    0 => Vec3A::new(inside(&mut r).x, -1.0, inside(&mut r).z),
                    1 => corners[round % corners.len()],
                    _ => inside(&mut r),
                };
                let target = match round % 3 {
                    0 => corners[(round / 3) % corners.len()],
                    1 => corners[round % corners.len()].lerp(corners[(round + 1) % corners.len()], r()),
                    _ => inside(&mut r),
                };
                let Some(axis) = (target - apex).try_normalize() else {
                    continue;
                };
                let spread = [1e-5, 1e-3, 1e-2, 5e-2][round % 4];
                let mut rays = RayPacket::default();
                for i in 0..LANES {
                    let jitter = Vec3A::new(r() - 0.5, r() - 0.5, r() - 0.5) * spread;
                    rays.set(i, &Ray::new(apex, (axis + jitter).normalize()), f32::INFINITY);
                }
                let cull = ApexCull::new(bvh, apex.to_array()).unwrap();
                if let Some(beam) = Beam::leaving(&rays, 0.0, &cull) {
                    for (k, &p) in bvh.flat.iter().enumerate() {
                        kept += u64::from(cull.flat_lanes(k, &beam).count_ones());
                        lanes += if p & SPHERES != 0 { 3 } else { 4 };
                    }
                }
                let plain = bvh.closest_rays(&mut rays.clone(), 0.0);
                let mut culled = PacketHits::default();
                bvh.closest_rays_from(&mut rays.clone(), 0.0, Some(&cull), &mut culled);
                for i in 0..LANES {
                    assert_eq!(culled.get(i), plain.get(i), "seed {seed} round {round} lane {i}");
                }

                // Shadow rays from those hits, pulled back a little, to a light elsewhere.
                let light = inside(&mut r);
                let cull = ApexCull::new(bvh, light.to_array()).unwrap();
                let (mut org, mut ns, mut lit) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3], [false; LANES]);
                for i in 0..LANES {
                    let Some((t, ..)) = plain.get(i) else { continue };
                    let ray = rays.ray(i);
                    let p = ray.at(t * 0.999);
                    let n = (light - p).normalize_or_zero();
                    for a in 0..3 {
                        (org[a][i], ns[a][i]) = (p[a], n[a]);
                    }
                    lit[i] = true;
                }
                let mut shadow = RayPacket::default();
                for i in 0..LANES {
                    let o = Vec3A::new(org[0][i], org[1][i], org[2][i]);
                    shadow.set(i, &Ray::new(o, (light - o).normalize_or_zero()), (light - o).length());
                }
                shadow_beams += u64::from(Beam::reaching(&shadow, &lit, &cull).is_some());
                let plain = crate::lights::point_light_rays(&scene, &org, &ns, &lit, light.to_array(), None);
                let culled = crate::lights::point_light_rays(&scene, &org, &ns, &lit, light.to_array(), Some(&cull));
                assert_eq!(culled.visible, plain.visible, "seed {seed} round {round} shadows");
                assert_eq!(culled.cos, plain.cos);
            }
        }
        // The test is worth something only if beams were built and skipped most primitives.
        assert!(
            lanes > 10_000 && kept * 2 < lanes,
            "kept {kept} of {lanes} primitive lanes"
        );
        assert!(shadow_beams > 500, "{shadow_beams} shadow packets had a beam");
    }
}
