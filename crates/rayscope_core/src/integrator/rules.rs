//! The shading rules every engine shares: the state a path carries, the rays a mirror and glass
//! send on (from [`crate::optics`], with the course's mistakes where a render makes them), which
//! of glass's rays a path follows, Beer's law inside absorbing glass, and the radiance a ray
//! brings back. The engines (one path at a time, ray packets, waves) call these; none re-derives
//! them.

use glam::Vec3A;

use crate::math::Ray;
use crate::mistakes::Mistake;
use crate::optics::{fresnel, fresnel_swapped, glass_rays, mirror_ray, schlick};
use crate::scene::{Intersect, Material};
use crate::surface::Surface;

use super::Integrator;

/// State carried down a path.
#[derive(Debug, Clone, Copy)]
pub(super) struct PathState {
    /// Mirror, glass and specular-lobe bounces so far (limited by `max_depth`).
    pub(super) depth: u32,
    /// Non-specular (sampled) bounces so far.
    pub(super) bounces: u32,
    /// The path throughput so far (what the camera's sample is multiplied by): Russian roulette
    /// keeps a path with its largest channel's probability, and glass branches are pruned by it.
    // A `Vec3`, not a `Vec3A`: its 16-byte alignment would pad the state from 32 to 48 bytes,
    // which packets and waves copy per lane.
    pub(super) beta: glam::Vec3,
    /// Material whose absorbance applies to the ray (Beer's law), if it travels inside one.
    pub(super) medium: Option<u32>,
    /// Split glass into both rays (Whitted) rather than choosing one by its Fresnel weight.
    pub(super) branch: bool,
}

/// The rays leaving a glass hit (see [`Integrator::glass`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Glass {
    /// Fresnel reflectance.
    pub(super) kr: f32,
    /// The reflected ray.
    pub(super) reflected: Ray,
    /// The refracted ray; none under total internal reflection.
    pub(super) refracted: Option<Ray>,
    /// Medium the reflected ray travels in.
    pub(super) refl_medium: Option<u32>,
    /// Medium the refracted ray travels in.
    pub(super) refr_medium: Option<u32>,
}

impl PathState {
    /// The state of the ray a mirror reflects this path into.
    #[inline]
    pub(super) fn mirrored(self) -> PathState {
        self.specular(self.medium, self.beta)
    }

    /// The state of a ray a mirror or glass sends on: one level deeper, travelling in `medium`,
    /// with path weight `beta`.
    #[inline]
    pub(super) fn specular(self, medium: Option<u32>, beta: glam::Vec3) -> PathState {
        PathState {
            depth: self.depth + 1,
            medium,
            beta,
            ..self
        }
    }

    /// The path vertex this ray's hit is, for the dimensions its draws take
    /// ([`crate::sobol::Draw::dim`]): every ray a path sends on adds one level or one bounce (or
    /// both), so the number grows along a path and no two of its vertices share one.
    #[inline(always)]
    pub(super) fn vertex(&self) -> u32 {
        self.depth + self.bounces
    }

    /// The state of a camera ray.
    pub(super) const CAMERA: PathState = PathState {
        depth: 0,
        bounces: 0,
        beta: glam::Vec3::ONE,
        medium: None,
        branch: true,
    };
}

/// An emitter sample's shadow ray and the light it brings when nothing blocks it.
#[derive(Debug, Clone, Copy)]
pub(super) struct ShadowRay {
    pub(super) ray: Ray,
    /// Just short of the sampled point, so the emitter does not block itself.
    pub(super) t_max: f32,
    /// The weighted light the sample adds when the ray is not blocked.
    pub(super) unblocked: Vec3A,
    /// Beer's-law transmittance to the emitter, inside an absorbing medium.
    pub(super) attenuation: Option<Vec3A>,
}

impl ShadowRay {
    /// What the sample adds, given whether the ray is blocked.
    #[inline(always)]
    pub(super) fn contrib(&self, blocked: bool) -> Vec3A {
        let c = if blocked { Vec3A::ZERO } else { self.unblocked };
        self.attenuation.map_or(c, |a| c * a)
    }
}

/// Radiance arriving along a ray, split so the caller can weight emission by MIS.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Li {
    /// Radiance emitted by the surface the ray hit.
    pub(super) emitted: Vec3A,
    /// Everything else (light reflected or transmitted by that surface).
    pub(super) reflected: Vec3A,
    /// Density with which emitter sampling from the ray's origin would pick the hit point.
    pub(super) light_pdf: f32,
}

impl Li {
    pub(super) fn total(&self) -> Vec3A {
        self.emitted + self.reflected
    }

    pub(super) fn reflected(v: Vec3A) -> Li {
        Li {
            reflected: v,
            ..Li::default()
        }
    }

    /// This radiance after a segment with transmittance `att` (Beer's law), if any.
    #[inline]
    pub(super) fn absorbed(mut self, att: Option<Vec3A>) -> Li {
        if let Some(a) = att {
            self.emitted *= a;
            self.reflected *= a;
        }
        self
    }
}

impl<I: Intersect> Integrator<'_, I> {
    /// The two rays leaving a glass hit, before any is chosen or pruned.
    #[inline]
    pub(super) fn glass(&self, ray: &Ray, s: &Surface, m: &Material, path: PathState) -> Glass {
        if I::MISTAKEN {
            return self.mistaken_glass(ray, s, m, path);
        }
        let eps = self.offset(s, ray);
        let (kr, reflected, refracted) = glass_rays(ray.dir, s.normal, s.point, eps, s.front_face, m.value);
        let (refl_medium, refr_medium) = self.glass_media(s, m, path);
        Glass {
            kr,
            reflected,
            refracted,
            refl_medium,
            refr_medium,
        }
    }

    /// The glass's reflected ray about `n` as a tracer with this render's mistakes starts it:
    /// along the incident ray, off the outward side, or (correctly) off the side the ray came from.
    #[cold]
    fn mistaken_reflection(&self, ray: &Ray, s: &Surface, n: Vec3A, eps: f32) -> Ray {
        let r = self.mistaken_mirror(mirror_ray(ray.dir, n, s.point, eps), ray, n);
        if self.mistake(Mistake::GlassReflectionAlongRay) {
            Ray::new(s.point + ray.dir * eps, r.dir)
        } else if self.mistake(Mistake::GlassReflectionOutward) {
            let outward = if s.front_face { s.normal } else { -s.normal };
            Ray::new(s.point + outward * eps, r.dir)
        } else {
            r
        }
    }

    /// `r`, the mirror image of `ray` about `n`, as a tracer with this render's mistakes reflects
    /// it: without the formula's factor 2, d − (d · n) n.
    #[inline]
    pub(super) fn mistaken_mirror(&self, r: Ray, ray: &Ray, n: Vec3A) -> Ray {
        if I::MISTAKEN && self.mistake(Mistake::ReflectNo2) {
            let d = ray.dir - n * ray.dir.dot(n);
            Ray::new(r.origin, d.normalize_or(r.dir))
        } else {
            r
        }
    }

    /// [`Self::glass`] as a tracer with this render's glass mistakes computes it.
    #[cold]
    pub(super) fn mistaken_glass(&self, ray: &Ray, s: &Surface, m: &Material, path: PathState) -> Glass {
        let swap = !s.front_face && !self.mistake(Mistake::RefractionNoIndexSwap);
        // Entering with η inverted is the indices of the way out.
        let inverted = s.front_face && self.mistake(Mistake::EtaEnteringInverted);
        let (n1, n2) = if swap || inverted {
            (m.value, 1.0)
        } else {
            (1.0, m.value)
        };
        let cos_i = (-ray.dir.dot(s.normal)).clamp(0.0, 1.0);
        let tir = {
            let eta = n1 / n2;
            eta * eta * (1.0 - cos_i * cos_i).max(0.0) >= 1.0
        };
        let kr = if tir {
            1.0
        } else if self.mistake(Mistake::NoFresnel) {
            0.0
        } else if self.mistake(Mistake::FresnelHalf) {
            0.5
        } else if self.mistake(Mistake::Schlick) {
            schlick(cos_i, n1, n2)
        } else if self.mistake(Mistake::FresnelSwapped) {
            fresnel_swapped(cos_i, n1, n2)
        } else {
            fresnel(cos_i, n1, n2)
        };
        // Leaving the glass without the flip, the normal is the outward one, facing away from
        // the ray: Snell's formula then gets cos θᵢ < 0 and the offsets go to the wrong sides.
        let n = if !s.front_face && self.mistake(Mistake::RefractionNoNormalFlip) {
            -s.normal
        } else {
            s.normal
        };
        let eps = self.offset(s, ray);
        let refracted = if tir {
            None
        } else {
            let eta = n1 / n2;
            let c = -ray.dir.dot(n);
            let cos_t = (1.0 - eta * eta * (1.0 - c * c)).max(0.0).sqrt();
            Some((ray.dir * eta + n * (eta * c - cos_t)).normalize())
        };
        let (refl_medium, refr_medium) = self.glass_media(s, m, path);
        let no_tir = tir && self.mistake(Mistake::NoTir);
        Glass {
            // Without total internal reflection the ray that should reflect brings nothing.
            kr: if no_tir { 0.0 } else { kr },
            reflected: self.mistaken_reflection(ray, s, n, eps),
            refracted: refracted.filter(|_| !self.isect.mistakes().refraction_lost()).map(|t| {
                let side = if self.mistake(Mistake::RefractionOffsetOutside) {
                    eps
                } else {
                    -eps
                };
                Ray::new(s.point + n * side, t)
            }),
            refl_medium,
            refr_medium,
        }
    }

    /// The media a glass hit's reflected and refracted rays travel in.
    #[inline]
    pub(super) fn glass_media(&self, s: &Surface, m: &Material, path: PathState) -> (Option<u32>, Option<u32>) {
        let absorbing = m.absorbs(self.settings.stage, self.settings.edition);
        let this = absorbing.then_some(s.material);
        // Reflected rays stay on the incoming side; refracted rays cross into the other medium
        // (the outside of every object is air).
        if s.front_face {
            (path.medium, this)
        } else {
            (this, None)
        }
    }

    /// Whitted glass's reflected ray (weight `kr`) and its path, unless it is pruned.
    #[inline]
    pub(super) fn glass_reflected(&self, g: &Glass, path: PathState) -> Option<(Ray, PathState)> {
        (g.kr > 0.0 && path.beta.max_element() * g.kr >= self.branch_cutoff)
            .then(|| (g.reflected, path.specular(g.refl_medium, path.beta * g.kr)))
    }

    /// Whitted glass's refracted ray (weight 1 − `kr`) and its path, unless there is none (total
    /// internal reflection) or it is pruned.
    #[inline]
    pub(super) fn glass_refracted(&self, g: &Glass, path: PathState) -> Option<(Ray, PathState)> {
        let r = g
            .refracted
            .filter(|_| path.beta.max_element() * (1.0 - g.kr) >= self.branch_cutoff)?;
        Some((r, path.specular(g.refr_medium, path.beta * (1.0 - g.kr))))
    }

    /// A mirror's reflected ray and its path.
    #[inline]
    pub(super) fn mirror(&self, ray: &Ray, s: &Surface, path: PathState) -> (Ray, PathState) {
        let eps = self.offset(s, ray);
        (mirror_ray(ray.dir, s.normal, s.point, eps), path.mirrored())
    }

    /// Beer's law over the segment of length `t` a ray travelled inside an absorbing medium.
    #[inline]
    pub(super) fn absorb(&self, path: PathState, t: f32, out: Li) -> Li {
        out.absorbed(self.transmittance(path, t))
    }

    /// Beer's-law transmittance over distance `t` for a ray with state `path`, when it travels
    /// inside an absorbing medium.
    #[inline]
    pub(super) fn transmittance(&self, path: PathState, t: f32) -> Option<Vec3A> {
        path.medium.map(|mi| {
            let sigma = Vec3A::from(self.scene.materials[mi as usize].color);
            (-sigma * t).exp()
        })
    }
}
