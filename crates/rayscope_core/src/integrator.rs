//! Integrators: stage 1 (flat colour), stage 2 (Whitted: point lights, mirrors, Fresnel glass)
//! and the full renderer, all generic over a [`RayObserver`].

use glam::{Vec2, Vec3A};

use crate::camera::Camera;
use crate::math::{offset_eps, reflect, Ray};
use crate::observer::{RayKind, RayObserver};
use crate::rng::Rng;
use crate::scene::{Intersect, PrimRef, Scene, Surface};
use crate::settings::{Channel, RenderSettings, Stage};
use rayscope_scene::MaterialKind;

/// Ray counts gathered while rendering.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Camera rays.
    pub camera: u64,
    /// Reflection, refraction and bounce rays.
    pub secondary: u64,
    /// Shadow and emitter rays.
    pub shadow: u64,
}

impl Counters {
    /// All rays.
    #[must_use]
    pub fn total(&self) -> u64 {
        self.camera + self.secondary + self.shadow
    }

    /// Adds another set of counts.
    pub fn add(&mut self, o: &Counters) {
        self.camera += o.camera;
        self.secondary += o.secondary;
        self.shadow += o.shadow;
    }
}

/// The per-render state every sample needs.
#[derive(Debug, Clone, Copy)]
pub struct Integrator<'a, I: Intersect = Scene> {
    /// The scene.
    pub scene: &'a Scene,
    /// The intersector rays are traced with (the scene's BVH, or the reference).
    pub isect: &'a I,
    /// The settings.
    pub settings: &'a RenderSettings,
    /// Camera built from the settings.
    pub camera: Camera,
}

/// Exact unpolarised Fresnel reflectance for a ray meeting an interface with `cos_i` = cos of
/// the incidence angle (≥ 0), going from index `n1` to `n2`; 1 under total internal reflection.
#[must_use]
#[inline]
pub fn fresnel(cos_i: f32, n1: f32, n2: f32) -> f32 {
    let eta = n1 / n2;
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    let rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Refracted direction of unit `d` through unit normal `n` (facing `d`'s origin side) with
/// `eta = n1 / n2`; `None` under total internal reflection.
#[must_use]
#[inline]
pub fn refract(d: Vec3A, n: Vec3A, eta: f32) -> Option<Vec3A> {
    let cos_i = -d.dot(n);
    let sin2_t = eta * eta * (1.0 - cos_i * cos_i).max(0.0);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some((d * eta + n * (eta * cos_i - cos_t)).normalize())
}

impl<'a> Integrator<'a, Scene> {
    /// An integrator for `scene` with `settings`, tracing with the scene's BVH.
    #[must_use]
    pub fn new(scene: &'a Scene, settings: &'a RenderSettings) -> Self {
        Self {
            scene,
            isect: scene,
            settings,
            camera: Camera::new(settings.camera, settings.width, settings.height),
        }
    }
}

impl<'a, I: Intersect> Integrator<'a, I> {
    /// An integrator for `scene` with `settings`, tracing with `isect`.
    #[must_use]
    pub fn with_intersector(scene: &'a Scene, isect: &'a I, settings: &'a RenderSettings) -> Self {
        Self {
            scene,
            isect,
            settings,
            camera: Camera::new(settings.camera, settings.width, settings.height),
        }
    }

    /// Samples per pixel the settings ask for.
    #[must_use]
    pub fn samples_per_pixel(&self) -> u32 {
        match self.settings.stage {
            Stage::One => 1,
            _ if self.settings.channel != Channel::Color => 1,
            _ => self.settings.aa * self.settings.aa,
        }
    }

    /// Normalised image position of sample `s` of pixel (`x`, `y`): the N×N regular grid for
    /// `-x N`, the pixel centre for stage 1 and debug channels.
    #[must_use]
    #[inline]
    pub fn sample_position(&self, x: u32, y: u32, s: u32) -> (f32, f32) {
        let n = if self.samples_per_pixel() == 1 {
            1
        } else {
            self.settings.aa
        };
        let (i, j) = (s % n, s / n);
        let w = self.settings.width as f32;
        let h = self.settings.height as f32;
        (
            (x as f32 + (i as f32 + 0.5) / n as f32) / w,
            (y as f32 + (j as f32 + 0.5) / n as f32) / h,
        )
    }

    /// The camera ray of sample `s` of pixel (`x`, `y`).
    #[must_use]
    #[inline]
    pub fn camera_ray(&self, x: u32, y: u32, s: u32, rng: &mut Rng) -> Ray {
        let (u, v) = self.sample_position(x, y, s);
        if self.settings.stage == Stage::Full && self.settings.camera.aperture_radius > 0.0 {
            self.camera
                .lens_ray(u, v, concentric_disk(rng.next_f32(), rng.next_f32()))
        } else {
            self.camera.ray(u, v)
        }
    }

    /// Colour of one sample of pixel (`x`, `y`).
    #[inline]
    pub fn sample<O: RayObserver>(&self, x: u32, y: u32, s: u32, obs: &mut O, c: &mut Counters) -> Vec3A {
        let pixel = y as u64 * self.settings.width as u64 + x as u64;
        let mut rng = Rng::for_sample(self.settings.seed, pixel, s as u64);
        let ray = self.camera_ray(x, y, s, &mut rng);
        c.camera += 1;
        if self.settings.channel != Channel::Color {
            return self.channel(&ray, obs);
        }
        let id = obs.ray(None, RayKind::Camera, 0, &ray, f32::INFINITY);
        let v = self.trace(&ray, 0, id, &mut rng, obs, c);
        obs.result(id, 1.0, v);
        v
    }

    fn channel<O: RayObserver>(&self, ray: &Ray, obs: &mut O) -> Vec3A {
        let id = obs.ray(None, RayKind::Camera, 0, ray, f32::INFINITY);
        let Some(hit) = self.isect.intersect(ray, 0.0, f32::INFINITY) else {
            return Vec3A::ZERO;
        };
        let s = self.scene.surface(ray, &hit);
        obs.hit(id, self.scene, hit.t, &s);
        match self.settings.channel {
            Channel::Normal => s.shading_normal * 0.5 + Vec3A::splat(0.5),
            Channel::Depth => {
                let far = (self.scene.bounds.max - self.scene.bounds.min).length().max(1.0)
                    + (self.camera.origin - self.scene.bounds.center()).length();
                Vec3A::splat(1.0 - (hit.t / far).clamp(0.0, 1.0))
            }
            Channel::Entity => entity_color(s.entity),
            Channel::Albedo | Channel::Color => self.scene.materials[s.material as usize].color.into(),
            Channel::Cost => {
                let cost = self.scene.traversal_cost(ray);
                heat((cost as f32 / 64.0).min(1.0))
            }
        }
    }

    /// Radiance along `ray`, which has already been reported to `obs` as `id`.
    fn trace<O: RayObserver>(
        &self,
        ray: &Ray,
        depth: u32,
        id: u32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        let Some(hit) = self.isect.intersect(ray, 0.0, f32::INFINITY) else {
            return Vec3A::ZERO;
        };
        let s = self.scene.surface(ray, &hit);
        if O::ENABLED {
            obs.hit(id, self.scene, hit.t, &s);
        }
        let m = self.scene.materials[s.material as usize];
        let stage = self.settings.stage;
        if stage == Stage::One {
            return m.color.into();
        }
        let color = match m.kind {
            MaterialKind::Diffuse | MaterialKind::Glossy => {
                self.direct_point_lights(&s, ray, Vec3A::from(m.color), id, obs, c)
            }
            MaterialKind::Emissive => {
                if stage == Stage::Two {
                    self.direct_point_lights(&s, ray, Vec3A::from(m.color), id, obs, c)
                } else {
                    m.color.into()
                }
            }
            MaterialKind::Reflective => {
                if depth >= self.settings.max_depth {
                    return Vec3A::ZERO;
                }
                let eps = offset_eps(s.point, ray.origin);
                let r = Ray::new(s.point + s.normal * eps, reflect(ray.dir, s.normal).normalize());
                self.secondary(&r, depth + 1, id, RayKind::Reflection, 1.0, rng, obs, c)
            }
            MaterialKind::Refractive => {
                if depth >= self.settings.max_depth {
                    return Vec3A::ZERO;
                }
                let (n1, n2) = if s.front_face { (1.0, m.value) } else { (m.value, 1.0) };
                let cos_i = (-ray.dir.dot(s.normal)).clamp(0.0, 1.0);
                let kr = fresnel(cos_i, n1, n2);
                let eps = offset_eps(s.point, ray.origin);
                let mut out = Vec3A::ZERO;
                if kr > 0.0 {
                    let r = Ray::new(s.point + s.normal * eps, reflect(ray.dir, s.normal).normalize());
                    out += self.secondary(&r, depth + 1, id, RayKind::Reflection, kr, rng, obs, c) * kr;
                }
                if kr < 1.0 {
                    if let Some(t) = refract(ray.dir, s.normal, n1 / n2) {
                        let r = Ray::new(s.point - s.normal * eps, t);
                        out +=
                            self.secondary(&r, depth + 1, id, RayKind::Refraction, 1.0 - kr, rng, obs, c) * (1.0 - kr);
                    }
                }
                out
            }
        };
        // Beer's law: a ray that hit the inside of a Refractive surface travelled `t` through it.
        if stage == Stage::Full && !s.front_face {
            if let Some(absorb) = self.medium_absorbance(hit.prim) {
                return color * (-absorb * hit.t).exp();
            }
        }
        color
    }

    #[allow(clippy::too_many_arguments)]
    fn secondary<O: RayObserver>(
        &self,
        r: &Ray,
        depth: u32,
        parent: u32,
        kind: RayKind,
        weight: f32,
        rng: &mut Rng,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        c.secondary += 1;
        let id = obs.ray(Some(parent), kind, depth, r, f32::INFINITY);
        let v = self.trace(r, depth, id, rng, obs, c);
        obs.result(id, weight, v);
        v
    }

    fn medium_absorbance(&self, prim: PrimRef) -> Option<Vec3A> {
        let (_, mat) = self.scene.prim_info(prim);
        let m = &self.scene.materials[mat as usize];
        (m.kind == MaterialKind::Refractive && m.color != glam::Vec3::ZERO).then(|| m.color.into())
    }

    /// The course's diffuse term: Σ max(0, N·L) · albedo · light colour over visible point lights.
    fn direct_point_lights<O: RayObserver>(
        &self,
        s: &Surface,
        ray: &Ray,
        albedo: Vec3A,
        parent: u32,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        let mut sum = Vec3A::ZERO;
        let origin = s.point + s.normal * offset_eps(s.point, ray.origin);
        for (li, light) in self.scene.lights.iter().enumerate() {
            let to = Vec3A::from(light.position) - origin;
            let dist = to.length();
            if dist == 0.0 {
                continue;
            }
            let l = to / dist;
            let cos = s.shading_normal.dot(l);
            let shadow = Ray::new(origin, l);
            c.shadow += 1;
            let id = obs.ray(Some(parent), RayKind::Shadow, 0, &shadow, dist);
            let blocker = if O::ENABLED {
                self.isect
                    .occluder(&shadow, 0.0, dist)
                    .map(|p| self.scene.prim_info(p).0)
            } else if cos <= 0.0 || self.isect.occluded(&shadow, 0.0, dist) {
                // Shadow rays behind the surface cannot contribute; only the recorder needs them traced.
                Some(u32::MAX)
            } else {
                None
            };
            if O::ENABLED {
                obs.shadow(id, self.scene, &self.scene.light_names[li], blocker);
            }
            let contrib = if blocker.is_none() && cos > 0.0 {
                albedo * Vec3A::from(light.color) * cos
            } else {
                Vec3A::ZERO
            };
            obs.result(id, cos.max(0.0), contrib);
            sum += contrib;
        }
        sum
    }
}

/// Uniform point on the unit disk from two uniform numbers (Shirley–Chiu concentric mapping).
#[must_use]
#[inline]
pub fn concentric_disk(u1: f32, u2: f32) -> Vec2 {
    let a = 2.0 * u1 - 1.0;
    let b = 2.0 * u2 - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (b, std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b))
    };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

/// A distinct, stable colour for entity `i`.
#[must_use]
pub fn entity_color(i: u32) -> Vec3A {
    // Golden-ratio hue steps keep neighbouring ids far apart.
    let h = (i as f32 * 0.618_034 + 0.1).fract();
    let f = |n: f32| {
        let k = (n + h * 6.0) % 6.0;
        1.0 - 0.8 * (k.min(4.0 - k).clamp(0.0, 1.0))
    };
    Vec3A::new(f(5.0), f(3.0), f(1.0)) * 0.85 + Vec3A::splat(0.1)
}

/// A blue→cyan→green→yellow→red ramp for `t` ∈ [0, 1].
#[must_use]
pub fn heat(t: f32) -> Vec3A {
    let t = t.clamp(0.0, 1.0) * 4.0;
    let stops = [
        Vec3A::new(0.0, 0.0, 0.6),
        Vec3A::new(0.0, 0.8, 1.0),
        Vec3A::new(0.1, 0.9, 0.1),
        Vec3A::new(1.0, 0.9, 0.0),
        Vec3A::new(1.0, 0.1, 0.0),
    ];
    let i = (t as usize).min(3);
    stops[i].lerp(stops[i + 1], t - i as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_limits() {
        // Normal incidence air→glass 1.5: ((1−1.5)/(1+1.5))² = 0.04.
        assert!((fresnel(1.0, 1.0, 1.5) - 0.04).abs() < 1e-6);
        // Grazing: total reflection.
        assert!((fresnel(0.0, 1.0, 1.5) - 1.0).abs() < 1e-6);
        // Inside glass past the critical angle (41.8° for 1.5): TIR.
        assert_eq!(fresnel(50f32.to_radians().cos(), 1.5, 1.0), 1.0);
        assert!(fresnel(30f32.to_radians().cos(), 1.5, 1.0) < 1.0);
    }

    #[test]
    fn refraction_obeys_snell() {
        let d = Vec3A::new(1.0, -1.0, 0.0).normalize();
        let n = Vec3A::Y;
        let t = refract(d, n, 1.0 / 1.4).unwrap();
        let sin_i = d.x;
        let sin_t = t.x;
        assert!((sin_i - 1.4 * sin_t).abs() < 1e-6);
        assert!(
            refract(Vec3A::new(0.9, -0.1, 0.0).normalize(), n, 1.4).is_none(),
            "TIR from inside"
        );
    }

    #[test]
    fn disk_samples_inside() {
        for i in 0..32 {
            for j in 0..32 {
                let p = concentric_disk(i as f32 / 31.0, j as f32 / 31.0);
                assert!(p.length() <= 1.0 + 1e-6);
            }
        }
    }
}
