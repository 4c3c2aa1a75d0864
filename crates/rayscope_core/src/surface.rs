//! The surface at a hit: the point, the geometric normal flipped to face the ray, the shading
//! normal (interpolated on smooth triangles) on the same side, and where rays leaving the surface
//! on the ray's side start.
//!
//! One ray's surface is [`Scene::surface`]; [`Surface::outside`] is its shadow-ray origin. The
//! sixteen-lane form is [`surface_frames`], over the lanes' primitive data ([`HitPrims`]); the
//! packet engines get it through `PacketSurfaces`, which gathers that data from the scene and
//! hands each lane's [`Surface`] back. The tests below check that every lane's surface is the
//! single ray's, bit for bit.

// Structure-of-arrays code indexes several arrays by the same lane or axis, which reads more
// clearly as index loops than as zipped iterators.
#![allow(clippy::needless_range_loop)]

use glam::Vec3A;

use crate::accel::PacketHits;
use crate::geometry::{PrimHit, PrimRef, Primitive};
use crate::math::{offset_eps, Ray, RayPacket};
use crate::scene::{Hit, Scene};
use crate::simd::{lane, put, LANES};

mod lanes;
pub use lanes::{surface_frames, HitPrims, SmoothNormals, SurfaceFrames};
#[cfg(test)]
pub(crate) use lanes::{surface_frames_avx2, surface_frames_avx512, surface_frames_impl};

/// Local geometry at a hit, ready for shading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    /// Hit point.
    pub point: Vec3A,
    /// Unit geometric normal, flipped to face the incoming ray.
    pub normal: Vec3A,
    /// Unit shading normal (interpolated for meshes), on the same side as `normal`.
    pub shading_normal: Vec3A,
    /// True when the ray hit the side the primitive's own normal points to.
    pub front_face: bool,
    /// Entity index.
    pub entity: u32,
    /// Material index.
    pub material: u32,
}

impl Surface {
    /// How far rays leaving this surface, hit by `ray`, start off it: [`offset_eps`] of the
    /// point and the ray's origin.
    #[must_use]
    #[inline]
    pub fn offset(&self, ray: &Ray) -> f32 {
        offset_eps(self.point, ray.origin)
    }

    /// Where shadow rays leaving this surface, hit by `ray`, start: the point moved
    /// [`Self::offset`] along the facing normal, on the ray's side.
    #[must_use]
    #[inline]
    pub fn outside(&self, ray: &Ray) -> Vec3A {
        self.point + self.normal * self.offset(ray)
    }
}

impl Scene {
    /// Shading geometry at a hit of `ray`.
    #[must_use]
    #[inline]
    pub fn surface(&self, ray: &Ray, hit: &Hit) -> Surface {
        let ph = PrimHit {
            t: hit.t,
            u: hit.u,
            v: hit.v,
        };
        let (n, ns) = match hit.prim {
            PrimRef::Plane(i) => {
                let n = self.planes[i as usize].normal(ray, &ph);
                (n, n)
            }
            PrimRef::Sphere(i) => {
                let n = self.spheres[i as usize].normal(ray, &ph);
                (n, n)
            }
            PrimRef::Triangle(i) => {
                let n = self.triangles[i as usize].geometric_normal();
                let ns = match self.vertex_normals(i) {
                    Some([a, b, c]) => {
                        let w = 1.0 - hit.u - hit.v;
                        let s = Vec3A::from(a) * w + Vec3A::from(b) * hit.u + Vec3A::from(c) * hit.v;
                        let s = s.normalize_or_zero();
                        if s == Vec3A::ZERO {
                            n
                        } else {
                            s
                        }
                    }
                    None => n,
                };
                (n, ns)
            }
        };
        let (entity, material) = self.prim_info(hit.prim);
        let front_face = n.dot(ray.dir) < 0.0;
        let normal = if front_face { n } else { -n };
        // Interpolated normals are flipped with the geometric one so both face the ray.
        let shading_normal = if ns.dot(normal) < 0.0 { -ns } else { ns };
        Surface {
            point: ray.at(hit.t),
            normal,
            shading_normal,
            front_face,
            entity,
            material,
        }
    }
}

/// Copies lane 0 of `v` to every lane.
#[inline]
fn broadcast<T: Copy>(v: &mut [T; LANES]) {
    *v = [v[0]; LANES];
}

/// The surfaces a packet's rays hit, in structure-of-arrays form: per lane, what
/// [`Scene::surface`] returns ([`surface_frames`] computes the geometry).
#[repr(align(64))]
pub(crate) struct PacketSurfaces {
    /// Every lane hit the same primitive.
    pub(crate) one_prim: bool,
    /// Lanes whose ray hit something.
    pub(crate) hit: [bool; LANES],
    /// Hit distance.
    pub(crate) t: [f32; LANES],
    /// Hit points, normals and offset origins.
    pub(crate) frames: SurfaceFrames,
    /// Entity index.
    entity: [u32; LANES],
    /// Material index.
    pub(crate) material: [u32; LANES],
}

impl PacketSurfaces {
    /// The surfaces of `hits`, found by tracing `rays`.
    pub(crate) fn new(scene: &Scene, rays: &RayPacket, hits: &PacketHits) -> Self {
        let mut g = HitPrims::default();
        (g.hit, g.t) = hits.distances();
        let (mut entity, mut material) = ([0; LANES], [0; LANES]);
        // One pixel's samples mostly meet one primitive: its data is then looked up for the
        // first lane and copied to the others (the same values a lookup per lane finds).
        let one_prim = hits.one_prim();
        let lanes = if one_prim { 1 } else { LANES };
        for i in 0..lanes {
            let Some((_, _, _, prim)) = hits.get(i) else {
                continue;
            };
            (entity[i], material[i]) = scene.prim_info(prim);
            match prim {
                PrimRef::Plane(k) => put(&mut g.a, i, scene.planes[k as usize].normal.to_array()),
                PrimRef::Sphere(k) => {
                    let sp = &scene.spheres[k as usize];
                    g.sphere[i] = true;
                    put(&mut g.a, i, sp.center.to_array());
                    g.radius[i] = sp.radius;
                }
                PrimRef::Triangle(k) => {
                    let tri = &scene.triangles[k as usize];
                    g.triangle[i] = true;
                    put(&mut g.a, i, tri.e1().to_array());
                    put(&mut g.b, i, tri.e2().to_array());
                    if let Some(ns) = scene.vertex_normals(k) {
                        let sm = g.smooth.get_or_insert_with(SmoothNormals::default);
                        sm.on[i] = true;
                        for (c, n) in ns.iter().enumerate() {
                            put(&mut sm.vn[c], i, n.to_array());
                        }
                    }
                }
            }
        }
        if let Some(sm) = &mut g.smooth {
            // Every lane's: those without vertex normals ignore theirs.
            (sm.bu, sm.bv) = hits.barycentrics();
        }
        if one_prim {
            broadcast(&mut g.sphere);
            broadcast(&mut g.triangle);
            g.a.iter_mut().chain(g.b.iter_mut()).for_each(broadcast);
            broadcast(&mut g.radius);
            broadcast(&mut entity);
            broadcast(&mut material);
            if let Some(sm) = &mut g.smooth {
                broadcast(&mut sm.on);
                sm.vn.iter_mut().flatten().for_each(broadcast);
            }
        }
        Self {
            frames: surface_frames(rays, &g),
            one_prim,
            hit: g.hit,
            t: g.t,
            entity,
            material,
        }
    }

    /// Lane `i`'s surface as [`Scene::surface`] returns it.
    #[inline]
    pub(crate) fn get(&self, i: usize) -> Surface {
        let f = &self.frames;
        Surface {
            point: lane(&f.point, i),
            normal: lane(&f.normal, i),
            shading_normal: lane(&f.shading_normal, i),
            front_face: f.front_face[i],
            entity: self.entity[i],
            material: self.material[i],
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::rng::Rng;

    /// Random packets from points inside and outside `scene`'s objects: with `narrow`, every
    /// lane on and aimed within a hair of one direction (so many packets hit one primitive);
    /// otherwise in random directions with some lanes off. `check` sees every lane with a hit.
    fn packets(scene: &Scene, seed: u64, narrow: bool, mut check: impl FnMut(&RayPacket, &PacketSurfaces, usize)) {
        let bvh = &scene.wide;
        let mut rng = Rng::for_sample(seed, 0, 0);
        let mut r = move || rng.next_f32() * 2.0 - 1.0;
        let mut hits = 0;
        for _ in 0..300 {
            let mut rays = RayPacket::default();
            let o = Vec3A::new(r() * 0.9, r() * 0.9, 1.5 + r() * 1.4);
            let aim = Vec3A::new(r(), r(), r());
            for i in 0..LANES {
                if narrow {
                    let d = (aim + Vec3A::new(r(), r(), r()) * 1e-3).normalize();
                    rays.set(i, &Ray::new(o, d), f32::INFINITY);
                } else if i % 7 != 3 {
                    // Some lanes off, so unused lanes are covered too.
                    let d = Vec3A::new(r(), r(), r()).normalize();
                    rays.set(i, &Ray::new(o, d), f32::INFINITY);
                }
            }
            let mut traced = rays.clone();
            let h = bvh.closest_rays(&mut traced, 0.0);
            let surf = PacketSurfaces::new(scene, &rays, &h);
            for i in 0..LANES {
                assert_eq!(surf.hit[i], h.get(i).is_some(), "lane {i}");
                if surf.hit[i] {
                    hits += 1;
                    check(&rays, &surf, i);
                }
            }
        }
        assert!(hits > 1000, "only {hits} hits");
    }

    fn load(path: &Path) -> Scene {
        Scene::from_file(&rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e:?}", path.display())))
    }

    /// Each lane's surface is what `Scene::surface` returns for its ray and hit, bit for bit,
    /// and its offset origin is `Surface::outside`: on planes, spheres (from inside and out),
    /// flat triangles and the smooth ones of meshes (our torus, the course's bunny), in packets
    /// of mixed primitives and in packets whose lanes all hit one.
    #[test]
    fn packet_surfaces_are_scene_surfaces() {
        let mut scenes = vec![
            (rayscope_testkit::scene("room.txt"), 1),
            (rayscope_testkit::scene("obj.txt"), 2),
        ];
        if let Some(course) = rayscope_testkit::course_part() {
            scenes.push((course.scene("sample_scene_2.txt"), 1));
            scenes.push((course.scene("sample_scene_obj.txt"), 2));
        }
        // Lanes on planes, spheres, flat triangles and smooth triangles over every scene, in
        // packets of mixed primitives and in packets of one.
        let (mut kinds, mut one_prim_kinds) = ([0; 4], [0; 4]);
        for (path, seed) in scenes {
            let name = path.display();
            let scene = load(&path);
            let mut scene_kinds = [0; 4];
            for narrow in [false, true] {
                packets(&scene, seed, narrow, |rays, surf, i| {
                    let ray = Ray::new(lane(&rays.o, i), lane(&rays.d, i));
                    let mut traced = rays.clone();
                    let (t, u, v, prim) = scene.wide.closest_rays(&mut traced, 0.0).get(i).unwrap();
                    let kind = match prim {
                        PrimRef::Plane(_) => 0,
                        PrimRef::Sphere(_) => 1,
                        PrimRef::Triangle(k) if scene.vertex_normals(k).is_none() => 2,
                        PrimRef::Triangle(_) => 3,
                    };
                    scene_kinds[kind] += 1;
                    one_prim_kinds[kind] += usize::from(surf.one_prim);
                    let want = scene.surface(&ray, &Hit { t, u, v, prim });
                    let got = surf.get(i);
                    let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
                    assert_eq!(bits(got.point), bits(want.point), "{name} lane {i} point");
                    assert_eq!(bits(got.normal), bits(want.normal), "{name} lane {i} normal");
                    assert_eq!(bits(got.shading_normal), bits(want.shading_normal), "{name} lane {i}");
                    assert_eq!(
                        (got.front_face, got.entity, got.material),
                        (want.front_face, want.entity, want.material)
                    );
                    let f = &surf.frames.outside;
                    assert_eq!([f[0][i], f[1][i], f[2][i]].map(f32::to_bits), bits(want.outside(&ray)));
                });
            }
            assert!(
                scene_kinds.iter().filter(|&&k| k > 0).count() >= 2,
                "{name}: {scene_kinds:?}"
            );
            kinds.iter_mut().zip(scene_kinds).for_each(|(k, s)| *k += s);
        }
        assert!(kinds.iter().all(|&k| k > 0), "lanes per kind: {kinds:?}");
        assert!(
            one_prim_kinds.iter().all(|&k| k > 0),
            "lanes per kind in packets of one: {one_prim_kinds:?}"
        );
    }
}
