//! The scene's closest hits by the binary BVH's walk: a cross-check of the wide traversal for
//! tests (this crate's, and others' through the `test-support` feature), not built into the
//! product.

use super::{Hit, PrimRef, Scene, SPHERE_BIT};
use crate::accel::Bvh;
use crate::geometry::Primitive;
use crate::math::Ray;

/// The scene's closest hits by a binary BVH and the scalar primitive routines: slower than
/// [`Scene::intersect`], kept as a cross-check of the wide traversal in tests.
#[derive(Debug)]
pub struct BinaryReference<'a> {
    scene: &'a Scene,
    bvh: Bvh,
}

impl<'a> BinaryReference<'a> {
    /// Builds the binary BVH over `scene`'s triangles and spheres.
    #[must_use]
    pub fn new(scene: &'a Scene) -> Self {
        BinaryReference {
            scene,
            bvh: Bvh::build(scene.build_prims()),
        }
    }

    /// Closest hit with `t_min < t < t_max`.
    #[must_use]
    pub fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let scene = self.scene;
        let mut best = scene.nearest_plane(ray, t_min, t_max);
        let t_max = best.map_or(t_max, |h| h.t);
        self.bvh.traverse(ray, t_min, t_max, |prims, mut t_max| {
            for &id in prims {
                if id & SPHERE_BIT != 0 {
                    let i = id & !SPHERE_BIT;
                    if let Some(h) = scene.spheres[i as usize].intersect(ray, t_min, t_max) {
                        t_max = h.t;
                        best = Some(Hit {
                            t: h.t,
                            u: 0.0,
                            v: 0.0,
                            prim: PrimRef::Sphere(i),
                        });
                    }
                } else if let Some(h) = scene.triangles[id as usize].intersect(ray, t_min, t_max) {
                    t_max = h.t;
                    best = Some(Hit {
                        t: h.t,
                        u: h.u,
                        v: h.v,
                        prim: PrimRef::Triangle(id),
                    });
                }
            }
            t_max
        });
        best
    }
}

impl Scene {
    /// The nearest infinite plane with `t_min < t < t_max` (planes are kept out of the BVH).
    #[inline]
    fn nearest_plane(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut t_max = t_max;
        for (i, p) in self.planes.iter().enumerate() {
            if let Some(h) = p.intersect(ray, t_min, t_max) {
                t_max = h.t;
                best = Some(Hit {
                    t: h.t,
                    u: 0.0,
                    v: 0.0,
                    prim: PrimRef::Plane(i as u32),
                });
            }
        }
        best
    }
}
