//! The render-ready scene: primitives in f32, materials, lights and the BVH, built from a
//! parsed [`rayscope_scene::SceneFile`].

use glam::{DVec3, Vec3, Vec3A};
use rayon::prelude::*;
use rayscope_scene::{SceneFile, Shape};
use serde::Serialize;

use crate::accel::{ApexCull, PacketHits};
use crate::accel::{BuildPrim, Bvh, Bvh4, WideHit};
pub use crate::geometry::PrimRef;
use crate::geometry::{Plane, Sphere, Triangle};
pub use crate::material::{Lobe, Material};
use crate::math::{Aabb, Ray, RayPacket};
use crate::simd::{Mask, LANES};

#[cfg(any(test, feature = "test-support"))]
mod binary_reference;
#[cfg(any(test, feature = "test-support"))]
pub use binary_reference::BinaryReference;

/// A point light with the course's unattenuated model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointLight {
    /// Position in world space.
    pub position: Vec3,
    /// Colour.
    pub color: Vec3,
}

/// The closest intersection of a ray with the scene.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// Surface parameters (barycentrics for triangles).
    pub u: f32,
    /// Surface parameters (barycentrics for triangles).
    pub v: f32,
    /// The primitive hit.
    pub prim: PrimRef,
}

impl From<WideHit> for Hit {
    /// The scene-level hit of a wide-BVH query.
    #[inline(always)]
    fn from(h: WideHit) -> Self {
        Hit {
            t: h.t,
            u: h.u,
            v: h.v,
            prim: h.prim,
        }
    }
}

/// What an entity is, for names in the debugger and `trace`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EntityInfo {
    /// Name from the scene file.
    pub name: String,
    /// Scene command (`Plane`, `Sphere`, `Triangle`, `ObjModel`).
    pub kind: &'static str,
    /// Material index.
    pub material: u32,
    /// 1-based line in the scene file.
    pub line: usize,
    /// Number of primitives the entity turned into.
    pub primitives: usize,
}

/// Per-triangle data that traversal does not need.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TriangleInfo {
    /// Entity index.
    pub entity: u32,
    /// Material index.
    pub material: u32,
}

/// [`Scene::triangle_normals`] entry of a triangle without vertex normals.
pub(crate) const NO_NORMALS: [u32; 3] = [u32::MAX; 3];

/// A render-ready scene.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// Materials by index.
    pub materials: Vec<Material>,
    /// Material names by index.
    pub(crate) material_names: Vec<String>,
    /// Point lights.
    pub lights: Vec<PointLight>,
    /// Light names by index.
    pub light_names: Vec<String>,
    /// Entities by index.
    pub entities: Vec<EntityInfo>,
    /// Infinite planes (kept out of the BVH).
    pub planes: Vec<Plane>,
    /// (entity, material) of each plane.
    pub plane_info: Vec<(u32, u32)>,
    /// Spheres.
    pub spheres: Vec<Sphere>,
    /// (entity, material) of each sphere.
    pub sphere_info: Vec<(u32, u32)>,
    /// Triangles, including mesh triangles.
    pub triangles: Vec<Triangle>,
    /// Shading data of each triangle.
    pub triangle_info: Vec<TriangleInfo>,
    /// Vertex normals of the meshes, shared by the triangles that meet at a vertex.
    pub normals: Vec<Vec3>,
    /// Per triangle, its corners' indices into `normals` for smooth shading, or `NO_NORMALS`;
    /// empty when no triangle has vertex normals. Kept apart from [`TriangleInfo`] so a mesh
    /// without normals (most large scans and generated meshes) costs nothing for them.
    pub triangle_normals: Vec<[u32; 3]>,
    /// The 4-wide BVH traversed by every query.
    pub wide: Bvh4,
    /// Bounds of all finite geometry.
    pub bounds: Aabb,
}

/// A closest-hit and any-hit query over a [`Scene`]: rayscope's BVH or the parry3d reference.
pub trait Intersect: Sync {
    /// True for an intersector whose renders make the course's mistakes
    /// (`crate::render::Mistaken`); false everywhere else, so the integrator's checks for
    /// them compile away.
    const MISTAKEN: bool = false;
    /// The mistakes this intersector's renders make.
    #[inline]
    fn mistakes(&self) -> crate::mistakes::Mistakes {
        crate::mistakes::Mistakes::NONE
    }
    /// The closest hit with `t_min < t < t_max`.
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit>;
    /// Some primitive on the ray with `t_min < t < t_max`, not necessarily the closest.
    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef>;
    /// True when anything lies on the ray with `t_min < t < t_max`.
    #[inline]
    fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.occluder(ray, t_min, t_max).is_some()
    }
    /// The closest hit on `ray` with `0 < t`, and whether anything lies on `shadow` with
    /// `0 < t < shadow_t_max`: what [`Self::intersect`] and [`Self::occluded`] answer, asked
    /// together because the path tracer needs both at each vertex and neither depends on the
    /// other.
    #[inline]
    fn intersect_and_occluded(&self, ray: &Ray, shadow: &Ray, shadow_t_max: f32) -> (Option<Hit>, bool) {
        let blocked = self.occluded(shadow, 0.0, shadow_t_max);
        (self.intersect(ray, 0.0, f32::INFINITY), blocked)
    }
    /// True when this intersector answers the packet queries below faster than it answers
    /// their rays one at a time, so the engines that trace sixteen rays together
    /// ([`crate::integrator::Engine`]) pay for it. The queries' defaults ask one ray at a time.
    const PACKETS: bool = false;

    /// The closest hit of each ray of `rays` with `t_min < t < t_max` (the lane's own `t_max`,
    /// −∞ in lanes not in use), into `hits`; each hit lane's `t_max` is left at its hit.
    /// `cull`, when given, is the view from a point every ray starts at
    /// ([`Self::apex_cull`]), which an implementation may use to skip what no ray can meet.
    #[inline]
    fn closest_packet(&self, rays: &mut RayPacket, t_min: f32, cull: Option<&ApexCull>, hits: &mut PacketHits) {
        let _ = cull;
        *hits = PacketHits::default();
        for i in 0..LANES {
            let hit = self.intersect(&rays.ray(i), t_min, rays.t_max[i]);
            if let Some(h) = hit {
                rays.t_max[i] = h.t;
            }
            hits.set(i, hit.map(|h| (h.t, h.u, h.v, h.prim)));
        }
    }

    /// [`Self::closest_packet`] for rays that all start inside the sphere at `slot`
    /// ([`Self::sphere_slot`]), which nothing else comes near: returns false, with `rays` as
    /// they were, when it cannot answer that way (the caller then asks [`Self::closest_packet`]).
    #[inline]
    fn closest_packet_inside(&self, rays: &mut RayPacket, t_min: f32, slot: (u32, u32), hits: &mut PacketHits) -> bool {
        let _ = (rays, t_min, slot, hits);
        false
    }

    /// [`Self::closest_packet`] for rays that share little of their way through the scene (a
    /// wave of paths' bounce rays).
    #[inline]
    fn scattered_closest_packet(&self, rays: &mut RayPacket, t_min: f32) -> PacketHits {
        let mut hits = PacketHits::default();
        self.closest_packet(rays, t_min, None, &mut hits);
        hits
    }

    /// For each ray of `rays` that share little of their way, whether anything lies on it with
    /// `t_min < t < t_max`.
    #[inline]
    fn scattered_occluded_packet(&self, rays: &mut RayPacket, t_min: f32) -> Mask {
        std::array::from_fn(|i| self.occluded(&rays.ray(i), t_min, rays.t_max[i]))
    }

    /// For each lane of `shadow` in `traced` (the others are not in use), whether anything lies
    /// on its ray with `0 < t < t_max`: shadow rays that all end at one point, whose view
    /// ([`Self::apex_cull`]) `cull` is when given.
    #[inline]
    fn occluded_packet_toward(&self, shadow: &mut RayPacket, traced: &Mask, cull: Option<&ApexCull>) -> Mask {
        let _ = cull;
        std::array::from_fn(|i| traced[i] && self.occluded(&shadow.ray(i), 0.0, shadow.t_max[i]))
    }

    /// The view from `apex` that packet queries of rays sharing that end point may use; `None`
    /// when there is nothing to gain.
    #[inline]
    fn apex_cull(&self, apex: [f32; 3]) -> Option<ApexCull> {
        let _ = apex;
        None
    }

    /// Where sphere `k` sits for [`Self::closest_packet_inside`], when that query can use it.
    #[inline]
    fn sphere_slot(&self, k: u32) -> Option<(u32, u32)> {
        let _ = k;
        None
    }

    /// True when a packet's rays meet every primitive whatever their origins (the queries test
    /// one list, not a tree), so a wave loses nothing by mixing camera rays with bounce rays.
    #[inline]
    fn packets_test_everything(&self) -> bool {
        false
    }
}

impl Intersect for Scene {
    #[inline]
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        Scene::intersect(self, ray, t_min, t_max)
    }
    #[inline]
    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        Scene::occluder(self, ray, t_min, t_max)
    }
    #[inline]
    fn intersect_and_occluded(&self, ray: &Ray, shadow: &Ray, shadow_t_max: f32) -> (Option<Hit>, bool) {
        let (hit, blocked) = self.wide.closest_and_occluded(ray, shadow, shadow_t_max);
        (hit.map(Hit::from), blocked)
    }
    const PACKETS: bool = true;
    #[inline(always)]
    fn closest_packet(&self, rays: &mut RayPacket, t_min: f32, cull: Option<&ApexCull>, hits: &mut PacketHits) {
        self.wide.closest_rays_from(rays, t_min, cull, hits);
    }
    #[inline(always)]
    fn closest_packet_inside(&self, rays: &mut RayPacket, t_min: f32, slot: (u32, u32), hits: &mut PacketHits) -> bool {
        self.wide.closest_rays_inside(rays, t_min, slot, hits)
    }
    #[inline]
    fn scattered_closest_packet(&self, rays: &mut RayPacket, t_min: f32) -> PacketHits {
        self.wide.scattered_closest_rays(rays, t_min)
    }
    #[inline]
    fn scattered_occluded_packet(&self, rays: &mut RayPacket, t_min: f32) -> Mask {
        self.wide.scattered_occluded_rays(rays, t_min)
    }
    #[inline(always)]
    fn occluded_packet_toward(&self, shadow: &mut RayPacket, traced: &Mask, cull: Option<&ApexCull>) -> Mask {
        self.wide.occluded_toward_apex(shadow, traced, cull)
    }
    #[inline]
    fn apex_cull(&self, apex: [f32; 3]) -> Option<ApexCull> {
        ApexCull::new(&self.wide, apex)
    }
    #[inline]
    fn sphere_slot(&self, k: u32) -> Option<(u32, u32)> {
        self.wide.sphere_slot(k)
    }
    #[inline]
    fn packets_test_everything(&self) -> bool {
        !self.wide.single.is_empty()
    }
}

/// Spheres are tagged in BVH references with this bit.
const SPHERE_BIT: u32 = 1 << 31;

fn v3(d: DVec3) -> Vec3A {
    Vec3A::new(d.x as f32, d.y as f32, d.z as f32)
}

/// Most triangles [`Scene::sphere_alone`] checks a sphere against (more would slow loading).
pub(crate) const MAX_ALONE_TRIANGLES: usize = 4096;

impl Scene {
    /// Converts a parsed scene file and builds its BVH. Degenerate triangles are dropped.
    #[must_use]
    pub fn from_file(file: &SceneFile) -> Scene {
        let mut s = Scene::convert(file);
        s.build_bvh();
        s
    }

    /// [`Self::from_file`] for a file the caller no longer needs: its meshes are freed before
    /// the BVH build, which lowers the peak memory of loading a large mesh by their size.
    #[must_use]
    pub fn from_owned_file(file: SceneFile) -> Scene {
        let mut s = Scene::convert(&file);
        drop(file);
        s.build_bvh();
        s
    }

    /// The scene's geometry and materials, without the BVH.
    fn convert(file: &SceneFile) -> Scene {
        let mut s = Scene {
            materials: file.materials.iter().map(Material::from_def).collect(),
            material_names: file.materials.iter().map(|m| m.name.clone()).collect(),
            lights: file
                .lights
                .iter()
                .map(|l| PointLight {
                    position: v3(l.position).into(),
                    color: v3(l.color).into(),
                })
                .collect(),
            light_names: file.lights.iter().map(|l| l.name.clone()).collect(),
            ..Scene::default()
        };
        for (ei, e) in file.entities.iter().enumerate() {
            let (ent, mat) = (ei as u32, e.material as u32);
            let before = s.planes.len() + s.spheres.len() + s.triangles.len();
            match &e.shape {
                Shape::Plane { point, normal } => {
                    s.planes.push(Plane {
                        point: v3(*point),
                        normal: v3(*normal).normalize(),
                    });
                    s.plane_info.push((ent, mat));
                }
                Shape::Sphere { center, radius } => {
                    s.spheres.push(Sphere {
                        center: v3(*center),
                        radius: *radius as f32,
                    });
                    s.sphere_info.push((ent, mat));
                }
                Shape::Triangle { vertices } => {
                    let t = Triangle::new(v3(vertices[0]), v3(vertices[1]), v3(vertices[2]));
                    if !t.is_degenerate() {
                        s.push_triangle(t, ent, mat, None);
                    }
                }
                Shape::Mesh { mesh, .. } => {
                    s.triangles.reserve(mesh.triangles.len());
                    s.triangle_info.reserve(mesh.triangles.len());
                    let base = s.normals.len() as u32;
                    if mesh.triangles.iter().any(|t| t.normals.is_some()) {
                        s.normals.extend_from_slice(&mesh.normals);
                    }
                    // Made on every thread, in place (a large mesh's triangles are fresh memory,
                    // whose first writes are most of the cost), then the degenerate ones dropped
                    // in order on this one.
                    let first = s.triangles.len();
                    s.triangles
                        .par_extend(mesh.triangles.par_iter().with_min_len(1 << 12).map(|tri| {
                            let p = tri.positions.map(|i| Vec3A::from(mesh.positions[i as usize]));
                            Triangle::new(p[0], p[1], p[2])
                        }));
                    let mut kept = first;
                    for (k, tri) in mesh.triangles.iter().enumerate() {
                        let t = s.triangles[first + k];
                        if !t.is_degenerate() {
                            s.triangles[kept] = t;
                            s.push_info(kept, ent, mat, tri.normals.map(|n| n.map(|i| base + i)));
                            kept += 1;
                        }
                    }
                    s.triangles.truncate(kept);
                }
            }
            let after = s.planes.len() + s.spheres.len() + s.triangles.len();
            s.entities.push(EntityInfo {
                name: e.name.clone(),
                kind: e.shape.command(),
                material: mat,
                line: e.line,
                primitives: after - before,
            });
        }
        s
    }

    /// Appends a triangle with its entity, material and (indices into [`Self::normals`] of)
    /// vertex normals.
    fn push_triangle(&mut self, t: Triangle, entity: u32, material: u32, normals: Option<[u32; 3]>) {
        self.triangles.push(t);
        self.push_info(self.triangles.len() - 1, entity, material, normals);
    }

    /// Records the entity, material and vertex normals of triangle `index`, the next one
    /// without them.
    fn push_info(&mut self, index: usize, entity: u32, material: u32, normals: Option<[u32; 3]>) {
        self.triangle_info.push(TriangleInfo { entity, material });
        match normals {
            Some(n) => {
                if self.triangle_normals.is_empty() {
                    // The first smooth triangle: the flat ones before it get their entries now.
                    self.triangle_normals.resize(index, NO_NORMALS);
                }
                self.triangle_normals.push(n);
            }
            None if !self.triangle_normals.is_empty() => self.triangle_normals.push(NO_NORMALS),
            None => {}
        }
    }

    /// The vertex normals of triangle `i` for smooth shading, in vertex order.
    #[must_use]
    #[inline]
    pub fn vertex_normals(&self, i: u32) -> Option<[Vec3; 3]> {
        let ids = self.triangle_normals.get(i as usize)?;
        (*ids != NO_NORMALS).then(|| ids.map(|k| self.normals[k as usize]))
    }

    /// The build's input: every triangle and sphere with its bounds.
    fn build_prims(&self) -> Vec<BuildPrim> {
        let mut prims: Vec<BuildPrim> = Vec::with_capacity(self.triangles.len() + self.spheres.len());
        self.triangles
            .par_iter()
            .with_min_len(1 << 12)
            .enumerate()
            .map(|(i, t)| BuildPrim::new(i as u32, t.bounds()))
            .collect_into_vec(&mut prims);
        prims.extend(
            self.spheres
                .iter()
                .enumerate()
                .map(|(i, s)| BuildPrim::new(i as u32 | SPHERE_BIT, s.bounds())),
        );
        prims
    }

    fn build_bvh(&mut self) {
        let prims = self.build_prims();
        self.bounds = prims.iter().fold(Aabb::EMPTY, |b, p| b.union(p.bounds()));
        // The binary tree is only the collapse's input: dropped here, it does not add to a large
        // mesh's resident memory for the whole render.
        let bvh = Bvh::build(prims);
        self.wide = Bvh4::from_binary(&bvh, &self.triangles, &self.spheres, SPHERE_BIT, &self.planes);
    }

    /// The closest hit with `t_min < t < t_max`, using the BVH and the planes.
    #[must_use]
    #[inline]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        self.intersect_counting::<false>(ray, t_min, t_max, &mut 0)
    }

    /// Calls `each(i, hit)` once for every ray `rays[i]` with what [`Self::intersect`] returns
    /// for it, in no particular order; faster than one call per ray for scattered rays in very
    /// large scenes (see [`Bvh4::closest_many`]). Only `rayscope bench rays` uses it (feature
    /// `bench-kernels`).
    #[cfg(feature = "bench-kernels")]
    #[inline]
    pub fn intersect_many(&self, rays: &[Ray], t_min: f32, t_max: f32, mut each: impl FnMut(usize, Option<Hit>)) {
        self.wide
            .closest_many(rays, t_min, t_max, |i, h| each(i, h.map(Hit::from)));
    }

    #[inline]
    fn intersect_counting<const COUNT: bool>(
        &self,
        ray: &Ray,
        t_min: f32,
        t_max: f32,
        visits: &mut u32,
    ) -> Option<Hit> {
        self.wide.closest::<COUNT>(ray, t_min, t_max, visits).map(Hit::from)
    }

    /// True when anything lies on the ray with `t_min < t < t_max` (shadow rays).
    #[must_use]
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_min: f32, t_max: f32) -> bool {
        self.occluder(ray, t_min, t_max).is_some()
    }

    /// Some primitive on the ray with `t_min < t < t_max`, not necessarily the closest.
    #[must_use]
    #[inline]
    pub fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        self.wide.any(ray, t_min, t_max)
    }

    /// Node and packet tests (planes count one each) the closest-hit query of `ray` makes: the
    /// "cost" debug channel.
    #[must_use]
    pub(crate) fn traversal_cost(&self, ray: &Ray) -> u32 {
        self.intersect_with_cost(ray).1
    }

    /// [`Self::intersect`] of `ray` over `t > 0`, with the `Self::traversal_cost` of that walk.
    #[must_use]
    pub fn intersect_with_cost(&self, ray: &Ray) -> (Option<Hit>, u32) {
        let mut visits = 0;
        let hit = self.intersect_counting::<true>(ray, 0.0, f32::INFINITY, &mut visits);
        (hit, visits)
    }

    /// (entity, material) of a primitive.
    #[must_use]
    #[inline]
    pub fn prim_info(&self, prim: PrimRef) -> (u32, u32) {
        match prim {
            PrimRef::Plane(i) => self.plane_info[i as usize],
            PrimRef::Sphere(i) => self.sphere_info[i as usize],
            PrimRef::Triangle(i) => {
                let t = &self.triangle_info[i as usize];
                (t.entity, t.material)
            }
        }
    }

    /// True when no other primitive comes within a margin of sphere `k`, so a ray that starts
    /// inside it meets nothing before it leaves. Scenes of more than `MAX_ALONE_TRIANGLES`
    /// triangles are not searched (false).
    #[must_use]
    pub fn sphere_alone(&self, k: usize) -> bool {
        let Some(s) = self.spheres.get(k) else {
            return false;
        };
        let (c, r) = (s.center, s.radius);
        if !(r > 0.0 && c.is_finite() && r.is_finite()) || self.triangles.len() > MAX_ALONE_TRIANGLES {
            return false;
        }
        // Far wider than the few ulps by which a ray's origin, offset off the surface, can lie
        // outside the sphere, or a computed distance be off.
        let reach = r * (1.0 + 1e-3) + 1e-4 * (1.0 + c.abs().max_element());
        let spheres =
            (self.spheres.iter().enumerate()).all(|(j, o)| j == k || (o.center - c).length() > o.radius + reach);
        let planes = self.planes.iter().all(|p| (c - p.point).dot(p.normal).abs() > reach);
        let triangles = self.triangles.iter().all(|t| (t.closest_point(c) - c).length() > reach);
        spheres && planes && triangles
    }

    /// Number of primitives (planes, spheres, triangles).
    #[must_use]
    pub fn primitive_count(&self) -> usize {
        self.planes.len() + self.spheres.len() + self.triangles.len()
    }
}
