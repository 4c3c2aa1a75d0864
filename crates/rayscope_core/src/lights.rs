//! Point lights (the course's stage 2) and area lights: every sphere and triangle (mesh
//! triangles included) whose material is Emissive.
//!
//! A point light lights a surface point through a shadow ray from the point, offset off the
//! surface, toward the light, by the course's max(0, N·L) · albedo · light colour when nothing
//! blocks the ray. The shadow ray, its shading cosine and the light's contribution are computed
//! here for one point (`toward_point_light`, `point_light_contribution`) and for sixteen
//! ([`point_light_rays`], [`add_point_light_lanes`]), the lanes' arithmetic the one point's.
//!
//! An emitter is two-sided and emits its material colour as radiance, uniformly over its surface.
//! One emitter is chosen with probability proportional to its power (luminance × area); a point
//! on it is then drawn by solid angle for spheres seen from outside (uniform in the cone the
//! sphere subtends), for triangles uniformly in the solid angle they subtend unless that is
//! tiny or nearly the whole sphere, and by area otherwise (those triangles, and spheres seen
//! from inside). Emissive
//! planes are infinite, so they cannot be sampled; they are found by BSDF sampling only.

use glam::Vec3A;

use crate::accel::ApexCull;
use crate::geometry::{PrimRef, Sphere, Triangle};
use crate::material::Material;
use crate::math::{basis, basis_lanes, not_at_most, RayPacket};
use crate::sampling::{
    spherical_sampling, spherical_triangle, spherical_triangle_point, spherical_triangle_point_in, to_world,
    to_world_unit_lanes, uniform_cone, uniform_cone_pdf, uniform_sphere, uniform_triangle,
};
use crate::scene::{Intersect, Scene};
use crate::simd::{dispatched, lane, put, sel, Mask, LANES};

/// Relative margin inside which a point counts as on or inside a sphere emitter.
const INSIDE_MARGIN: f32 = 1e-4;

/// One emitting primitive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Emitter {
    /// The primitive.
    pub prim: PrimRef,
    /// Its entity.
    pub entity: u32,
    /// Emitted radiance.
    pub(crate) radiance: Vec3A,
    /// Surface area.
    pub area: f32,
    /// A triangle's e1 × e2 (twice its area along its normal), kept because every sample and
    /// density needs it; zero for spheres.
    pub cross: Vec3A,
}

/// A point drawn on an emitter, seen from a shading point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LightSample {
    /// Unit direction from the shading point to the sampled point.
    pub dir: Vec3A,
    /// Distance to the sampled point.
    pub dist: f32,
    /// Radiance arriving from it (before visibility).
    pub(crate) radiance: Vec3A,
    /// Density of `dir` in solid angle, including the choice of emitter.
    pub pdf: f32,
    /// Index into [`Emitters::list`].
    pub emitter: u32,
}

/// The scene's emitters with a power-proportional selection table.
#[derive(Debug, Clone, Default)]
pub(crate) struct Emitters {
    /// Emitting spheres and triangles.
    pub list: Vec<Emitter>,
    /// Selection probability of each emitter.
    pub(crate) pmf: Vec<f32>,
    cdf: Vec<f32>,
    sphere_slot: Vec<u32>,
    triangle_slot: Vec<u32>,
    /// True when any entity (planes included) has an Emissive material with non-zero colour.
    pub(crate) any_emission: bool,
}

fn is_emitting(scene: &Scene, material: u32) -> Option<Vec3A> {
    scene.materials[material as usize].emission()
}

impl Emitters {
    /// Collects the emitters of `scene`.
    #[must_use]
    pub(crate) fn from_scene(scene: &Scene) -> Emitters {
        let mut e = Emitters::default();
        if !scene.materials.iter().any(Material::is_emitter) {
            return e;
        }
        e.any_emission = scene.plane_info.iter().any(|&(_, m)| is_emitting(scene, m).is_some());
        for (i, (s, &(ent, mat))) in scene.spheres.iter().zip(&scene.sphere_info).enumerate() {
            if let Some(radiance) = is_emitting(scene, mat) {
                if e.sphere_slot.is_empty() {
                    e.sphere_slot = vec![u32::MAX; scene.spheres.len()];
                }
                e.sphere_slot[i] = e.list.len() as u32;
                e.list.push(Emitter {
                    prim: PrimRef::Sphere(i as u32),
                    entity: ent,
                    radiance,
                    area: 4.0 * std::f32::consts::PI * s.radius * s.radius,
                    cross: Vec3A::ZERO,
                });
            }
        }
        for (i, (t, info)) in scene.triangles.iter().zip(&scene.triangle_info).enumerate() {
            if let Some(radiance) = is_emitting(scene, info.material) {
                if e.triangle_slot.is_empty() {
                    e.triangle_slot = vec![u32::MAX; scene.triangles.len()];
                }
                e.triangle_slot[i] = e.list.len() as u32;
                let cross = t.e1().cross(t.e2());
                e.list.push(Emitter {
                    prim: PrimRef::Triangle(i as u32),
                    entity: info.entity,
                    radiance,
                    area: 0.5 * cross.length(),
                    cross,
                });
            }
        }
        e.any_emission |= !e.list.is_empty();
        let lum = Vec3A::new(0.2126, 0.7152, 0.0722);
        let weights: Vec<f64> = e
            .list
            .iter()
            .map(|l| (l.radiance.dot(lum).max(1e-3 * l.radiance.max_element()) * l.area) as f64)
            .collect();
        let total: f64 = weights.iter().sum();
        let mut acc = 0.0f64;
        for w in &weights {
            e.pmf.push((w / total) as f32);
            acc += w / total;
            e.cdf.push(acc as f32);
        }
        if let Some(last) = e.cdf.last_mut() {
            *last = 1.0;
        }
        e
    }

    /// True when there is nothing to sample.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// The emitter index of a primitive, if it emits.
    #[must_use]
    #[inline]
    pub(crate) fn index_of(&self, prim: PrimRef) -> Option<u32> {
        let slot = match prim {
            PrimRef::Sphere(i) => *self.sphere_slot.get(i as usize)?,
            PrimRef::Triangle(i) => *self.triangle_slot.get(i as usize)?,
            PrimRef::Plane(_) => return None,
        };
        (slot != u32::MAX).then_some(slot)
    }

    /// Draws a point on an emitter as seen from `p`, from three uniform numbers.
    #[must_use]
    #[inline]
    pub fn sample(&self, scene: &Scene, p: Vec3A, u0: f32, u1: f32, u2: f32) -> Option<LightSample> {
        if self.list.is_empty() {
            return None;
        }
        // The same index as a binary search, counted without branches in short lists: a
        // search's branches on a fresh random number mispredict about once a sample.
        let below = if self.cdf.len() <= SHORT_CDF {
            self.cdf.iter().fold(0, |n, &c| n + usize::from(c <= u0))
        } else {
            self.cdf.partition_point(|&c| c <= u0)
        };
        let i = below.min(self.list.len() - 1);
        let e = &self.list[i];
        let (dir, dist, pdf) = match e.prim {
            PrimRef::Sphere(s) => sample_sphere(&scene.spheres[s as usize], p, u1, u2)?,
            PrimRef::Triangle(t) => {
                let t = &scene.triangles[t as usize];
                TriangleShape::of(t, e.cross, 2.0 * e.area).sample(p, u1, u2)?
            }
            PrimRef::Plane(_) => return None,
        };
        let pdf = pdf * self.pmf[i];
        (pdf > 0.0 && pdf.is_finite()).then_some(LightSample {
            dir,
            dist,
            radiance: e.radiance,
            pdf,
            emitter: i as u32,
        })
    }

    /// Density (solid angle, selection included) with which [`Emitters::sample`] from `origin`
    /// draws the direction towards `point` on `prim`, the nearest hit of that direction;
    /// 0 when `prim` does not emit.
    #[must_use]
    #[inline]
    pub fn pdf(&self, scene: &Scene, origin: Vec3A, prim: PrimRef, point: Vec3A) -> f32 {
        let Some(i) = self.index_of(prim) else {
            return 0.0;
        };
        let pdf = match prim {
            PrimRef::Sphere(s) => sphere_pdf(&scene.spheres[s as usize], origin, point),
            PrimRef::Triangle(t) => {
                let (e, t) = (&self.list[i as usize], &scene.triangles[t as usize]);
                TriangleShape::of(t, e.cross, 2.0 * e.area).pdf(origin, point)
            }
            PrimRef::Plane(_) => 0.0,
        };
        pdf * self.pmf[i as usize]
    }
}

/// [`Emitters::sample`]'s answers for sixteen lanes, in structure-of-arrays form.
#[derive(Debug, Clone)]
#[repr(align(64))]
pub(crate) struct LightLanes {
    /// The lane drew a sample ([`Emitters::sample`] returned `Some`).
    pub ok: [bool; LANES],
    /// Unit direction to the sampled point, per axis.
    pub dir: [[f32; LANES]; 3],
    /// Distance to the sampled point.
    pub dist: [f32; LANES],
    /// The emitter's radiance, per axis.
    pub(crate) radiance: [[f32; LANES]; 3],
    /// Solid-angle density, selection included.
    pub pdf: [f32; LANES],
}

impl Emitters {
    /// [`Emitters::sample`] from point `p` of every lane in `on`, with that lane's three
    /// numbers: the same arithmetic per lane. Triangle emitters are sampled in one pass over
    /// the lanes without branches, sphere emitters in passes of their own
    /// ([`Self::sample_spheres_lanes`]).
    // Structure-of-arrays code indexes several arrays by the same lane or axis.
    #[allow(clippy::needless_range_loop)]
    pub(crate) fn sample_lanes(
        &self,
        scene: &Scene,
        p: &[[f32; LANES]; 3],
        on: &[bool; LANES],
        u: [&[f32; LANES]; 3],
    ) -> LightLanes {
        let [u0, u1, u2] = u;
        let mut out = LightLanes {
            ok: [false; LANES],
            dir: [[0.0; LANES]; 3],
            dist: [0.0; LANES],
            radiance: [[0.0; LANES]; 3],
            pdf: [0.0; LANES],
        };
        if self.list.is_empty() {
            return out;
        }
        let mut below = [0u32; LANES];
        if self.cdf.len() <= SHORT_CDF {
            for &c in &self.cdf {
                for i in 0..LANES {
                    below[i] += u32::from(c <= u0[i]);
                }
            }
        } else {
            for i in 0..LANES {
                below[i] = self.cdf.partition_point(|&c| c <= u0[i]) as u32;
            }
        }
        let last = self.list.len() as u32 - 1;
        // Each lane's triangle (corner, edges, e1 × e2, twice its area); zeros in other lanes.
        let (mut v0, mut e1, mut e2, mut cross) = (
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
            [[0.0; LANES]; 3],
        );
        let (mut area2, mut pmf, mut tri) = ([1.0; LANES], [0.0; LANES], [false; LANES]);
        // Each lane's sphere (centre, radius); zeros in other lanes.
        let (mut centre, mut radius, mut sphere) = ([[0.0; LANES]; 3], [0.0; LANES], [false; LANES]);
        for i in 0..LANES {
            if !on[i] {
                continue;
            }
            let k = below[i].min(last) as usize;
            let e = &self.list[k];
            pmf[i] = self.pmf[k];
            for a in 0..3 {
                out.radiance[a][i] = e.radiance[a];
            }
            match e.prim {
                PrimRef::Triangle(t) => {
                    let t = &scene.triangles[t as usize];
                    let (a0, a1, a2) = (t.v0(), t.e1(), t.e2());
                    for a in 0..3 {
                        (v0[a][i], e1[a][i], e2[a][i], cross[a][i]) = (a0[a], a1[a], a2[a], e.cross[a]);
                    }
                    area2[i] = 2.0 * e.area;
                    tri[i] = true;
                }
                PrimRef::Sphere(s) => {
                    let s = &scene.spheres[s as usize];
                    for a in 0..3 {
                        centre[a][i] = s.center[a];
                    }
                    radius[i] = s.radius;
                    sphere[i] = true;
                }
                PrimRef::Plane(_) => {}
            }
        }
        if sphere.contains(&true) {
            self.sample_spheres_lanes(p, &sphere, &centre, &radius, [u1, u2], &mut out);
        }
        // TriangleShape::sample where a lane chose a triangle: the draw by solid angle in one
        // pass over the lanes without branches, then by area lane by lane where the solid
        // angle is out of that draw's range.
        if tri.contains(&true) {
            let mut by_area = [false; LANES];
            for i in 0..LANES {
                let at = |v: &[[f32; LANES]; 3]| [v[0][i], v[1][i], v[2][i]];
                let s = spherical_triangle_point(at(&v0), at(&e1), at(&e2), at(&cross), at(p), u1[i], u2[i]);
                let take = tri[i] & s.taken & s.ok;
                for a in 0..3 {
                    out.dir[a][i] = sel(take, s.dir[a], out.dir[a][i]);
                }
                out.dist[i] = sel(take, s.dist, out.dist[i]);
                out.pdf[i] = sel(take, s.pdf, out.pdf[i]);
                out.ok[i] |= take;
                by_area[i] = tri[i] & !s.taken;
            }
            for i in 0..LANES {
                if !by_area[i] {
                    continue;
                }
                let at = |v: &[[f32; LANES]; 3]| lane(v, i);
                let shape = TriangleShape {
                    v0: at(&v0),
                    e1: at(&e1),
                    e2: at(&e2),
                    cross: at(&cross),
                    area2: area2[i],
                };
                if let Some((dir, dist, pdf)) = shape.sample_by_area(at(p), u1[i], u2[i]) {
                    put(&mut out.dir, i, dir.to_array());
                    out.dist[i] = dist;
                    out.pdf[i] = pdf;
                    out.ok[i] = true;
                }
            }
        }
        for i in 0..LANES {
            let pdf = out.pdf[i] * pmf[i];
            out.pdf[i] = pdf;
            out.ok[i] = on[i] & out.ok[i] & (pdf > 0.0) & pdf.is_finite();
        }
        out
    }
}

impl Emitters {
    /// [`sample_sphere`] from point `p` in every lane of `sphere`, of the sphere with centre
    /// `centre` and radius `radius`, with the lane's numbers `u`, into `out` (direction,
    /// distance, density and `ok`): the same arithmetic per lane. The cone seen from outside is
    /// computed in loops over the lanes without branches, which the compiler vectorises, except
    /// for the direction in the cone ([`uniform_cone`]), taken lane by lane where the lane has a
    /// cone; a lane inside its sphere calls [`sample_sphere`].
    #[allow(clippy::needless_range_loop)]
    #[inline(always)]
    fn sample_spheres_lanes(
        &self,
        p: &[[f32; LANES]; 3],
        sphere: &Mask,
        centre: &[[f32; LANES]; 3],
        radius: &[f32; LANES],
        [u1, u2]: [&[f32; LANES]; 2],
        out: &mut LightLanes,
    ) {
        // cone_omc, and the axis to the centre.
        let (mut d, mut axis) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3]);
        let (mut omc, mut cone) = ([0.0; LANES], [false; LANES]);
        for i in 0..LANES {
            let dv: [f32; 3] = std::array::from_fn(|a| centre[a][i] - p[a][i]);
            // glam's length_squared: (x² + y²) + z².
            let d2 = dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2];
            let r2 = radius[i] * radius[i];
            cone[i] = sphere[i] & not_at_most(d2, r2 * (1.0 + INSIDE_MARGIN));
            let sin2 = r2 / d2;
            omc[i] = sin2 / (1.0 + (1.0 - sin2).sqrt());
            let len = d2.sqrt();
            for a in 0..3 {
                d[a][i] = dv[a];
                axis[a][i] = dv[a] / len;
            }
        }
        let (t, b) = basis_lanes(&axis);
        let mut local = [[0.0; LANES]; 3];
        for i in 0..LANES {
            if cone[i] {
                put(&mut local, i, uniform_cone(u1[i], u2[i], omc[i]).to_array());
            }
        }
        let dir = to_world_unit_lanes(&local, &t, &b, &axis);
        for i in 0..LANES {
            // The nearest intersection of the direction with the sphere.
            let proj = dir[0][i] * d[0][i] + dir[1][i] * d[1][i] + dir[2][i] * d[2][i];
            let l: [f32; 3] = std::array::from_fn(|a| d[a][i] - dir[a][i] * proj);
            let disc = (radius[i] * radius[i] - (l[0] * l[0] + l[1] * l[1] + l[2] * l[2])).max(0.0);
            let dist = (proj - disc.sqrt()).max(0.0);
            let pdf = uniform_cone_pdf(omc[i]);
            for a in 0..3 {
                out.dir[a][i] = sel(cone[i], dir[a][i], out.dir[a][i]);
            }
            out.dist[i] = sel(cone[i], dist, out.dist[i]);
            out.pdf[i] = sel(cone[i], pdf, out.pdf[i]);
            out.ok[i] |= cone[i];
        }
        for i in 0..LANES {
            if !sphere[i] || cone[i] {
                continue;
            }
            let s = Sphere {
                center: lane(centre, i),
                radius: radius[i],
            };
            if let Some((dir, dist, pdf)) = sample_sphere(&s, lane(p, i), u1[i], u2[i]) {
                put(&mut out.dir, i, dir.to_array());
                out.dist[i] = dist;
                out.pdf[i] = pdf;
                out.ok[i] = true;
            }
        }
    }
}

/// Emitter lists up to this long are searched by counting (see [`Emitters::sample`]): counting
/// 32 entries takes a few vector instructions, less than one mispredicted branch.
const SHORT_CDF: usize = 32;

/// `1 − cos` of the half-angle of the cone `s` subtends from a point at squared distance `d2`
/// from its centre, or `None` when the point is inside (or on) the sphere.
fn cone_omc(s: &Sphere, d2: f32) -> Option<f32> {
    let r2 = s.radius * s.radius;
    if d2 <= r2 * (1.0 + INSIDE_MARGIN) {
        return None;
    }
    let sin2 = r2 / d2;
    Some(sin2 / (1.0 + (1.0 - sin2).sqrt()))
}

/// Direction, distance and solid-angle density of a point drawn on sphere `s` from `p`.
#[must_use]
pub fn sample_sphere(s: &Sphere, p: Vec3A, u1: f32, u2: f32) -> Option<(Vec3A, f32, f32)> {
    let d = s.center - p;
    let d2 = d.length_squared();
    if let Some(omc) = cone_omc(s, d2) {
        let axis = d / d2.sqrt();
        let (t, b) = basis(axis);
        let dir = to_world(uniform_cone(u1, u2, omc), t, b, axis).normalize();
        // Nearest intersection of the sampled direction with the sphere.
        let proj = dir.dot(d);
        let l = d - dir * proj;
        let disc = (s.radius * s.radius - l.length_squared()).max(0.0);
        let dist = proj - disc.sqrt();
        return Some((dir, dist.max(0.0), uniform_cone_pdf(omc)));
    }
    // From inside: uniform by area, converted to solid angle.
    let n = uniform_sphere(u1, u2);
    toward_area_point(p, s.center + n * s.radius, sphere_area(s), |dir| n.dot(dir).abs())
}

/// Direction, distance and solid-angle density from `p` of the point `y`, drawn uniformly on a
/// surface of area `area` whose |cos| with the direction `cos` gives; `None` at `y` itself or
/// where the surface is seen edge-on.
#[inline]
fn toward_area_point(p: Vec3A, y: Vec3A, area: f32, cos: impl Fn(Vec3A) -> f32) -> Option<(Vec3A, f32, f32)> {
    let w = y - p;
    let dist2 = w.length_squared();
    let dist = dist2.sqrt();
    if dist <= 0.0 {
        return None;
    }
    let dir = w / dist;
    let pdf = area_to_solid_angle(dist2, cos(dir), area)?;
    Some((dir, dist, pdf))
}

/// Solid-angle density of a point drawn uniformly by area on a surface of `area`, seen at squared
/// distance `dist2` and at `cos` to the surface normal; `None` where the surface is seen edge-on.
#[inline]
fn area_to_solid_angle(dist2: f32, cos: f32, area: f32) -> Option<f32> {
    (cos > 1e-7).then(|| dist2 / (cos * area))
}

fn sphere_area(s: &Sphere) -> f32 {
    4.0 * std::f32::consts::PI * s.radius * s.radius
}

/// Solid-angle density of [`sample_sphere`] from `p` for the point `y` on the sphere.
#[must_use]
pub fn sphere_pdf(s: &Sphere, p: Vec3A, y: Vec3A) -> f32 {
    let d2 = (s.center - p).length_squared();
    if let Some(omc) = cone_omc(s, d2) {
        return uniform_cone_pdf(omc);
    }
    let w = y - p;
    let dist2 = w.length_squared();
    let n = (y - s.center) / s.radius;
    area_to_solid_angle(dist2, n.dot(w).abs() / dist2.sqrt(), sphere_area(s)).unwrap_or(0.0)
}

/// Direction, distance and solid-angle density of a point drawn on triangle `t` from `p`:
/// uniformly by solid angle where the triangle's solid angle is in [`SPHERICAL_SAMPLING`]
/// (a triangle near `p` then brings no noise from its distance and slant), uniformly by area
/// elsewhere.
#[must_use]
pub fn sample_triangle(t: &Triangle, p: Vec3A, u1: f32, u2: f32) -> Option<(Vec3A, f32, f32)> {
    let c = t.e1().cross(t.e2());
    TriangleShape::of(t, c, c.length()).sample(p, u1, u2)
}

/// Solid-angle density of [`sample_triangle`] from `p` for the point `y` on the triangle.
#[must_use]
pub fn triangle_pdf(t: &Triangle, p: Vec3A, y: Vec3A) -> f32 {
    let c = t.e1().cross(t.e2());
    TriangleShape::of(t, c, c.length()).pdf(p, y)
}

/// A triangle as its draws and densities need it: corner `v0`, edges `e1` and `e2`, their
/// cross product and that vector's length (twice the area), the last two kept with each emitter.
#[derive(Debug, Clone, Copy)]
struct TriangleShape {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    cross: Vec3A,
    area2: f32,
}

impl TriangleShape {
    /// `t` with its e1 × e2 and that vector's length given.
    #[inline]
    fn of(t: &Triangle, cross: Vec3A, area2: f32) -> Self {
        TriangleShape {
            v0: t.v0(),
            e1: t.e1(),
            e2: t.e2(),
            cross,
            area2,
        }
    }

    /// [`sample_triangle`] of this triangle.
    #[inline]
    fn sample(&self, p: Vec3A, u1: f32, u2: f32) -> Option<(Vec3A, f32, f32)> {
        let (area, corners) = spherical_triangle(self.v0.into(), self.e1.into(), self.e2.into(), p.into());
        if spherical_sampling(area) {
            let s = spherical_triangle_point_in(area, corners, self.v0.into(), self.cross.into(), p.into(), u1, u2);
            return s.ok.then(|| (s.dir.into(), s.dist, s.pdf));
        }
        self.sample_by_area(p, u1, u2)
    }

    /// [`Self::sample`] by area: a point uniform on the triangle.
    #[inline]
    fn sample_by_area(&self, p: Vec3A, u1: f32, u2: f32) -> Option<(Vec3A, f32, f32)> {
        let (b1, b2) = uniform_triangle(u1, u2);
        let y = self.v0 + self.e1 * b1 + self.e2 * b2;
        toward_area_point(p, y, 0.5 * self.area2, |dir| self.cross.dot(dir).abs() / self.area2)
    }

    /// [`triangle_pdf`] of this triangle.
    #[inline]
    fn pdf(&self, p: Vec3A, y: Vec3A) -> f32 {
        let (area, _) = spherical_triangle(self.v0.into(), self.e1.into(), self.e2.into(), p.into());
        if spherical_sampling(area) {
            return 1.0 / area;
        }
        let w = y - p;
        let dist2 = w.length_squared();
        let (c, area2) = (self.cross, self.area2);
        area_to_solid_angle(dist2, c.dot(w).abs() / (area2 * dist2.sqrt()), 0.5 * area2).unwrap_or(0.0)
    }
}

/// The unit direction `l` from `from` toward a point light at `light`, the light's distance,
/// and N·L with the shading normal `ns`; `None` at the light's position, where no shadow ray is
/// sent. Only a positive cosine lets the light contribute.
#[inline(always)]
#[must_use]
pub(crate) fn toward_point_light(from: Vec3A, ns: Vec3A, light: Vec3A) -> Option<(Vec3A, f32, f32)> {
    let to = light - from;
    let dist = to.length();
    if dist == 0.0 {
        return None;
    }
    let l = to / dist;
    Some((l, dist, ns.dot(l)))
}

/// What a visible point light of colour `color` adds at a surface of albedo `albedo` whose
/// shading normal makes cosine `cos` with the shadow ray: the course's albedo · colour · N·L.
#[inline(always)]
#[must_use]
pub(crate) fn point_light_contribution(albedo: Vec3A, color: Vec3A, cos: f32) -> Vec3A {
    albedo * color * cos
}

/// What a visible point light of colour `color` adds at a surface whose BRDF value toward it is
/// `f`: π · f · colour · N·L (π · f is the albedo of a Lambertian surface).
#[inline(always)]
#[must_use]
pub(crate) fn point_light_contribution_brdf(f: Vec3A, color: Vec3A, cos: f32) -> Vec3A {
    f * color * (std::f32::consts::PI * cos)
}

/// What [`point_light_rays`] finds for each lane.
#[derive(Debug, Clone)]
#[repr(align(64))]
pub struct LightRays {
    /// N·L with the shading normal (0 for lanes without a ray).
    pub cos: [f32; LANES],
    /// The light is in front of the surface and nothing blocks it.
    pub visible: [bool; LANES],
    /// Shadow rays counted (lanes with a surface not at the light's position).
    pub rays: u32,
}

/// The shadow rays of [`toward_point_light`] from `org` (one per lane in `lit`) toward a point
/// light at `light`, and their cosines with the shading normals `ns`, written to `shadow` (lanes
/// not traced get `t_max` −∞), `cos` (0 without a ray), `valid` (the lanes with a ray) and
/// `traced` (those whose ray is traced: in front of the surface).
// Written through references to the caller's locals: returned as a tuple, the packet was copied.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn shadow_ray_lanes(
    org: &[[f32; LANES]; 3],
    ns: &[[f32; LANES]; 3],
    lit: &Mask,
    light: [f32; 3],
    shadow: &mut RayPacket,
    cos: &mut [f32; LANES],
    valid: &mut Mask,
    traced: &mut Mask,
) {
    // Only the caller's locals are written here: a running count in `LightRays` kept the loop
    // scalar.
    for i in 0..LANES {
        let to = [light[0] - org[0][i], light[1] - org[1][i], light[2] - org[2][i]];
        // glam's length and division by a scalar, per component.
        let dist = (to[0] * to[0] + to[1] * to[1] + to[2] * to[2]).sqrt();
        let dir = [to[0] / dist, to[1] / dist, to[2] / dist];
        valid[i] = lit[i] & (dist != 0.0);
        let c = ns[0][i] * dir[0] + ns[1][i] * dir[1] + ns[2][i] * dir[2];
        cos[i] = sel(valid[i], c, 0.0);
        // Rays behind the surface cannot contribute and are not traced.
        traced[i] = valid[i] & (c > 0.0);
        for a in 0..3 {
            shadow.o[a][i] = org[a][i];
            shadow.d[a][i] = dir[a];
        }
        shadow.t_max[i] = sel(traced[i], dist, f32::NEG_INFINITY);
    }
}

/// [`point_light_rays`]: the rays made here, traced by `isect`'s packet query.
#[inline(always)]
fn point_light_rays_impl<I: Intersect>(
    isect: &I,
    org: &[[f32; LANES]; 3],
    ns: &[[f32; LANES]; 3],
    lit: &Mask,
    light: [f32; 3],
    cull: Option<&ApexCull>,
) -> LightRays {
    let mut shadow = RayPacket::default();
    let mut cos = [0.0; LANES];
    let (mut valid, mut traced) = ([false; LANES], [false; LANES]);
    shadow_ray_lanes(org, ns, lit, light, &mut shadow, &mut cos, &mut valid, &mut traced);
    let mut out = LightRays {
        cos,
        visible: [false; LANES],
        rays: valid.iter().map(|&v| u32::from(v)).sum(),
    };
    if traced.iter().fold(false, |a, &b| a | b) {
        let blocked = isect.occluded_packet_toward(&mut shadow, &traced, cull);
        for i in 0..LANES {
            out.visible[i] = traced[i] & !blocked[i];
        }
    }
    out
}

dispatched!(
    /// [`point_light_rays`] with the best instruction set the CPU has.
    best_point_light_rays, point_light_rays_avx512, point_light_rays_avx2, <I: Intersect>
    (
        isect: &I,
        org: &[[f32; LANES]; 3],
        ns: &[[f32; LANES]; 3],
        lit: &Mask,
        light: [f32; 3],
        cull: Option<&ApexCull>
    ) -> LightRays,
    point_light_rays_impl(isect, org, ns, lit, light, cull)
);

/// For each lane in `lit`, the shadow ray from `org` toward a point light at `light`, traced by
/// `isect`: its cosine with the shading normal `ns`, and whether the light is visible (in front
/// of the surface and unblocked). `cull`, when given, is the view from the light's position
/// ([`Intersect::apex_cull`]).
// Calls the dispatcher rather than being it (see `crate::simd::dispatched`).
#[must_use]
pub fn point_light_rays<I: Intersect>(
    isect: &I,
    org: &[[f32; LANES]; 3],
    ns: &[[f32; LANES]; 3],
    lit: &[bool; LANES],
    light: [f32; 3],
    cull: Option<&ApexCull>,
) -> LightRays {
    best_point_light_rays(isect, org, ns, lit, light, cull)
}

/// Adds to `sums` (per axis) what a point light of colour `color` found by `vis` adds at
/// surfaces of albedo `alb`: `point_light_contribution` in the lanes where it is visible.
#[inline(always)]
pub fn add_point_light_lanes(sums: &mut [[f32; LANES]; 3], alb: &[[f32; LANES]; 3], color: [f32; 3], vis: &LightRays) {
    for a in 0..3 {
        for i in 0..LANES {
            // albedo × colour × cosine, or zero when the light is hidden (glam's order).
            // Computed for every lane, then selected: with the products inside the
            // condition the loop compiled to a branch per lane.
            let lit_by = alb[a][i] * color[a] * vis.cos[i];
            sums[a][i] += if vis.visible[i] { lit_by } else { 0.0 };
        }
    }
}

#[cfg(test)]
mod tests {
    use std::fmt::Write;
    use std::path::Path;

    use super::*;

    /// `n` emissive triangles of different sizes and colours on the plane z = 5, facing the origin.
    fn panels(n: usize) -> Scene {
        let mut text = String::new();
        for i in 0..n {
            let (x, s) = (i as f32 * 0.7 - 10.0, 0.1 + (i % 7) as f32 * 0.13);
            let c = 1.0 + (i % 3) as f32;
            writeln!(text, "Material \"E{i}\" Emissive ({c}, 1, 0.5) 1").unwrap();
            writeln!(
                text,
                "Triangle \"T{i}\" ({x}, 0, 5) ({x}, {s}, 5) ({}, 0, 5) \"E{i}\"",
                x + s
            )
            .unwrap();
        }
        Scene::from_file(&rayscope_scene::parse_str(&text, Path::new("panels.txt")).unwrap())
    }

    #[test]
    fn sixteen_lanes_draw_what_one_sample_draws() {
        // Short and long lists (counted and searched), and a scene with sphere emitters too;
        // points near and far, lanes switched off, numbers at the ends of [0, 1).
        let mut with_spheres =
            String::from("Material \"E\" Emissive (4, 3, 2) 1\nMaterial \"F\" Emissive (1, 1, 1) 1\n");
        with_spheres += "Sphere \"S\" (0, 1, 4) 0.5 \"E\"\nSphere \"Tiny\" (2, 0, 3) 0.01 \"F\"\n";
        with_spheres += "Triangle \"T\" (-1, 0, 5) (1, 0, 5) (0, 2, 5) \"F\"\n";
        let spheres = Scene::from_file(&rayscope_scene::parse_str(&with_spheres, Path::new("s.txt")).unwrap());
        let mut rng = crate::rng::Rng::for_sample(3, 1, 4);
        for scene in [panels(3), panels(SHORT_CDF + 9), spheres] {
            let e = Emitters::from_scene(&scene);
            for round in 0..64 {
                let mut p = [[0.0; LANES]; 3];
                let mut u = [[0.0; LANES]; 3];
                let on: [bool; LANES] = std::array::from_fn(|i| (i + round) % 5 != 0);
                for i in 0..LANES {
                    for a in 0..3 {
                        p[a][i] = (rng.next_f32() - 0.5) * 8.0;
                        u[a][i] = rng.next_f32();
                    }
                }
                // The sphere's inside, a point 0.01 from the first panel (a large solid angle,
                // drawn by solid angle), one far from everything (drawn by area), and the ends
                // of the unit interval.
                (p[0][1], p[1][1], p[2][1]) = (0.1, 1.1, 4.0);
                (p[0][4], p[1][4], p[2][4]) = (-9.98, 0.02, 4.99);
                (p[0][5], p[1][5], p[2][5]) = (0.0, 0.0, -300.0);
                (u[0][2], u[1][2], u[2][2]) = (0.0, 0.0, 0.0);
                u[1][3] = 1.0f32.next_down();
                let got = e.sample_lanes(&scene, &p, &on, [&u[0], &u[1], &u[2]]);
                for i in 0..LANES {
                    let want = if on[i] {
                        e.sample(&scene, lane(&p, i), u[0][i], u[1][i], u[2][i])
                    } else {
                        None
                    };
                    assert_eq!(got.ok[i], want.is_some(), "round {round}, lane {i}");
                    let Some(w) = want else { continue };
                    let bits = |v: [f32; 3]| v.map(f32::to_bits);
                    assert_eq!(
                        bits(lane(&got.dir, i).to_array()),
                        bits(w.dir.to_array()),
                        "round {round}, lane {i}"
                    );
                    assert_eq!(got.dist[i].to_bits(), w.dist.to_bits(), "round {round}, lane {i}");
                    assert_eq!(got.pdf[i].to_bits(), w.pdf.to_bits(), "round {round}, lane {i}");
                    assert_eq!(lane(&got.radiance, i), w.radiance, "round {round}, lane {i}");
                }
            }
        }
    }

    #[test]
    fn emitters_are_chosen_by_the_cumulative_table_in_short_and_long_lists() {
        // Short lists count the table's entries at or below the random number instead of
        // searching it; both must pick the emitter the search picks, at every boundary.
        for n in [1, 3, SHORT_CDF, SHORT_CDF + 9] {
            let scene = panels(n);
            let e = Emitters::from_scene(&scene);
            assert_eq!(e.list.len(), n);
            let mut us: Vec<f32> = e.cdf.iter().flat_map(|&c| [c.next_down(), c, c.next_up()]).collect();
            us.extend((0..500).map(|k| k as f32 / 500.0));
            us.extend([0.0, 1.0f32.next_down()]);
            let mut seen = vec![false; n];
            for u0 in us.into_iter().filter(|u| (0.0..1.0).contains(u)) {
                let want = e.cdf.partition_point(|&c| c <= u0).min(n - 1);
                let got = e.sample(&scene, Vec3A::ZERO, u0, 0.3, 0.4).map(|s| s.emitter as usize);
                assert_eq!(got, Some(want), "{n} emitters, u0 = {u0}");
                seen[want] = true;
            }
            assert!(seen.iter().all(|&s| s), "{n} emitters: every one is reachable");
        }
    }

    /// A little deterministic stream for the lane tests.
    fn lcg(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((*state >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    #[test]
    fn point_light_lanes_return_one_points_bits() {
        let mut st = 7u64;
        for round in 0..200 {
            let light = [lcg(&mut st) * 5.0, lcg(&mut st) * 5.0, lcg(&mut st) * 5.0];
            let (mut org, mut ns, mut alb) = ([[0.0; LANES]; 3], [[0.0; LANES]; 3], [[0.0; LANES]; 3]);
            let mut lit = [false; LANES];
            for i in 0..LANES {
                // Lane 3 sits at the light; lane 5 is not lit.
                let p = if i == 3 {
                    Vec3A::from(light)
                } else {
                    Vec3A::new(lcg(&mut st), lcg(&mut st), lcg(&mut st)) * 3.0
                };
                let n = Vec3A::new(lcg(&mut st), lcg(&mut st), lcg(&mut st)).normalize_or_zero();
                for a in 0..3 {
                    (org[a][i], ns[a][i], alb[a][i]) = (p[a], n[a], lcg(&mut st).abs());
                }
                lit[i] = i != 5;
            }
            let mut shadow = RayPacket::default();
            let mut cos = [0.0; LANES];
            let (mut valid, mut traced) = ([false; LANES], [false; LANES]);
            shadow_ray_lanes(&org, &ns, &lit, light, &mut shadow, &mut cos, &mut valid, &mut traced);
            let color = [0.9, 0.5, lcg(&mut st).abs()];
            let vis = LightRays {
                cos,
                visible: traced,
                rays: 0,
            };
            let mut sums = [[0.25; LANES]; 3];
            add_point_light_lanes(&mut sums, &alb, color, &vis);
            for i in 0..LANES {
                let one = toward_point_light(lane(&org, i), lane(&ns, i), Vec3A::from(light));
                let want_valid = lit[i] && one.is_some();
                assert_eq!(valid[i], want_valid, "round {round} lane {i}");
                let mut want_sum = Vec3A::splat(0.25);
                if let (true, Some((l, dist, c))) = (want_valid, one) {
                    assert_eq!(cos[i].to_bits(), c.to_bits(), "round {round} lane {i}");
                    assert_eq!(traced[i], c > 0.0);
                    let d = shadow.ray(i).dir;
                    assert_eq!(d.to_array().map(f32::to_bits), l.to_array().map(f32::to_bits));
                    if traced[i] {
                        assert_eq!(shadow.t_max[i].to_bits(), dist.to_bits());
                        want_sum += point_light_contribution(lane(&alb, i), Vec3A::from(color), c);
                    }
                } else {
                    assert_eq!(cos[i].to_bits(), 0.0f32.to_bits());
                    assert!(!traced[i]);
                }
                assert_eq!(
                    lane(&sums, i).to_array().map(f32::to_bits),
                    want_sum.to_array().map(f32::to_bits)
                );
            }
        }
    }
}
