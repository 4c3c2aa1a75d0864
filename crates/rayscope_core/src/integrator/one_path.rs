//! One path at a time: the recursive Whitted and path-tracing integrator. It is the engine every
//! other engine is checked against, bit for bit, and the only one that records rays (the
//! debugger's ray trees, `rayscope trace`).

use glam::Vec3A;

use crate::bsdf::Bsdf;
use crate::geometry::PrimRef;
use crate::lights::{point_light_contribution, point_light_contribution_brdf, toward_point_light};
use crate::math::{basis, Ray};
use crate::mistakes::{self, Mistake};
use crate::observer::{BranchFate, GlassBranch, GlassDecision, NoObserver, RayKind, RayObserver};
use crate::sampling::{power_heuristic, russian_roulette_survival, to_local, to_world};
use crate::scene::{Hit, Intersect, Lobe, Material};
use crate::settings::{Channel, DepthLimit, Stage};
use crate::sobol::{Draw, Sampler};
use crate::surface::Surface;

use super::rules::{Glass, Li, PathState, ShadowRay};
use super::{entity_color, heat, Counters, Integrator, PathCx, MAX_BOUNCES, RR_START};

/// A shading frame (tangent, bitangent, normal) and the local outgoing direction.
type Frame = (Vec3A, Vec3A, Vec3A, Vec3A);

/// How a surface reflects a point light's light.
#[derive(Clone, Copy)]
struct PointLit<'b> {
    /// The albedo, for the course's formula: albedo × light colour × max(0, N·L).
    albedo: Vec3A,
    /// When given, a BSDF and its local frame, for π · f · light colour · max(0, N·L).
    brdf: Option<(&'b Bsdf, Frame)>,
}

/// Where a lane that a packet engine hands to this engine stands ([`Integrator::hand_over`]).
#[derive(Clone, Copy)]
pub(super) enum LaneAt<'h> {
    /// Its ray is still to trace.
    Ray,
    /// Its ray's closest hit is known: this one, or none.
    Found(Option<Hit>),
    /// Its ray hit this, whose surface is the second.
    Hit(&'h Hit, &'h Surface),
}

impl<I: Intersect> Integrator<'_, I> {
    /// Colour of one sample of pixel (`x`, `y`).
    #[inline]
    pub fn sample<O: RayObserver>(&self, x: u32, y: u32, s: u32, obs: &mut O, c: &mut Counters) -> Vec3A {
        self.sample_nudged(x, y, s, [0.0; 2], obs, c)
    }

    /// [`Self::sample`] with the camera ray through the sample's image position moved by
    /// `nudge` (normalised image coordinates): what a sample that close to this one gives.
    #[inline]
    pub(crate) fn sample_nudged<O: RayObserver>(
        &self,
        x: u32,
        y: u32,
        s: u32,
        nudge: [f32; 2],
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        let y = if self.mistake(Mistake::ImageFlipped) {
            self.settings.height - 1 - y
        } else {
            y
        };
        let mut rng = self.sample_rng(x, y, s);
        let ray = self.camera_ray_nudged(x, y, s, &mut rng, nudge);
        c.camera += 1;
        if self.settings.channel != Channel::Color {
            return self.channel(&ray, obs);
        }
        let id = obs.ray(None, RayKind::Camera, 0, &ray, f32::INFINITY);
        let v = self.radiance(&ray, id, &mut rng, obs, c);
        obs.result(id, 1.0, v);
        v
    }

    /// Radiance along `ray` (a camera ray, reported to `obs` as `id`) with a fresh path state.
    #[inline]
    pub(crate) fn radiance<O: RayObserver>(
        &self,
        ray: &Ray,
        id: u32,
        rng: &mut Sampler,
        obs: &mut O,
        c: &mut Counters,
    ) -> Vec3A {
        self.trace(ray, PathState::CAMERA, true, id, &mut PathCx { rng, obs, c })
            .total()
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
                // Scenes of planes alone have no bounds; fall back to a fixed range then.
                let b = &self.scene.bounds;
                let far = if b.is_empty() {
                    100.0
                } else {
                    (b.max - b.min).length().max(1.0) + (self.camera.origin - b.center()).length()
                };
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

    /// Radiance along `ray`, which has already been reported to `obs` as `id`. With
    /// `want_reflected` false only the hit surface's own emission is computed.
    pub(super) fn trace<O: RayObserver>(
        &self,
        ray: &Ray,
        path: PathState,
        want_reflected: bool,
        id: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Li {
        if self.cancelled() {
            return Li::default();
        }
        let hit = self.isect.intersect(ray, 0.0, f32::INFINITY);
        self.trace_found(ray, hit, path, want_reflected, id, cx)
    }

    /// [`Self::trace`] once the ray's closest hit has been found: `hit`, or none.
    #[inline]
    pub(super) fn trace_found<O: RayObserver>(
        &self,
        ray: &Ray,
        hit: Option<Hit>,
        path: PathState,
        want_reflected: bool,
        id: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Li {
        let Some(hit) = hit else {
            return Li::default();
        };
        let s = self.scene.surface(ray, &hit);
        self.trace_hit(ray, (&hit, &s), path, want_reflected, id, cx)
    }

    /// [`Self::trace`] from the ray's closest hit `hit`, whose surface is `s`.
    pub(super) fn trace_hit<O: RayObserver>(
        &self,
        ray: &Ray,
        (hit, s): (&Hit, &Surface),
        path: PathState,
        want_reflected: bool,
        id: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Li {
        let reversed;
        let s = if self.mistake(Mistake::ReversedNormals) {
            reversed = self.reversed_normal(hit, s);
            &reversed
        } else {
            s
        };
        let unscaled;
        let s = if self.mistake(Mistake::SphereNormalUnnormalised) {
            unscaled = self.unnormalised_sphere_normal(hit, s);
            &unscaled
        } else {
            s
        };
        if O::ENABLED {
            cx.obs.hit(id, self.scene, hit.t, s);
        }
        let m = &self.scene.materials[s.material as usize];
        let stage = self.settings.stage;
        if stage == Stage::One {
            return Li::reflected(m.color.into());
        }
        let every_material = self.settings.depth_limit == DepthLimit::All;
        if every_material && path.depth > self.settings.max_depth {
            return Li::default();
        }
        let full = stage == Stage::Full;
        let out = match m.lobe() {
            Lobe::Emitter if full => Li {
                emitted: m.color.into(),
                reflected: Vec3A::ZERO,
                light_pdf: if self.emitters.is_empty() {
                    0.0
                } else {
                    self.emitters.pdf(self.scene, ray.origin, hit.prim, s.point)
                },
            },
            _ if !want_reflected => return Li::default(),
            Lobe::Lambert | Lobe::Bsdf if full => self.shade(ray, s, m, path, id, cx),
            Lobe::Lambert | Lobe::Bsdf | Lobe::Emitter => Li::reflected(self.direct_point_lights(
                s,
                ray,
                PointLit {
                    albedo: m.color.into(),
                    brdf: None,
                },
                id,
                path.depth,
                cx,
            )),
            Lobe::Mirror => {
                if !every_material && path.depth >= self.settings.max_depth {
                    return Li::default();
                }
                let (r, child) = self.mirror(ray, s, path);
                let r = self.mistaken_mirror(r, ray, s.normal);
                Li::reflected(self.secondary(&r, child, id, RayKind::Reflection, 1.0, cx))
            }
            Lobe::Dielectric => {
                if !every_material && path.depth >= self.settings.max_depth {
                    return Li::default();
                }
                Li::reflected(self.refractive(ray, s, m, path, id, cx))
            }
        };
        self.absorb(path, hit.t, out)
    }

    /// The rest of the path of a lane that a packet engine hands to this engine where it stands
    /// (`at`), with path state `path`, one ray at a time, with `rng` its numbers, unrecorded.
    #[inline]
    pub(super) fn hand_over(
        &self,
        ray: &Ray,
        at: LaneAt<'_>,
        path: PathState,
        rng: &mut Sampler,
        c: &mut Counters,
    ) -> Li {
        let cx = &mut PathCx {
            rng,
            obs: &mut NoObserver,
            c,
        };
        match at {
            LaneAt::Ray => self.trace(ray, path, true, 0, cx),
            LaneAt::Found(hit) => self.trace_found(ray, hit, path, true, 0, cx),
            LaneAt::Hit(hit, s) => self.trace_hit(ray, (hit, s), path, true, 0, cx),
        }
    }

    /// The surface as a tracer with [`Mistake::ReversedNormals`] sees it: a triangle's normal
    /// (v2 − v0) × (v1 − v0), not turned towards the ray.
    #[cold]
    fn reversed_normal(&self, hit: &Hit, s: &Surface) -> Surface {
        let triangle =
            matches!(hit.prim, PrimRef::Triangle(_)) && self.scene.entities[s.entity as usize].kind == "Triangle";
        if !triangle {
            return *s;
        }
        if !s.front_face {
            // Seen from behind, the reversed normal is the one that faces the ray.
            return Surface { front_face: true, ..*s };
        }
        Surface {
            normal: -s.normal,
            shading_normal: -s.shading_normal,
            front_face: false,
            ..*s
        }
    }

    /// The surface as a tracer with [`Mistake::SphereNormalUnnormalised`] sees it: a sphere's
    /// normals p − c, the unit normals times the radius. (The glass rules clamp cos θi at 1, so
    /// glass spheres of radius over 1 bend as with cos θi = 1 where p − c makes it larger.)
    #[cold]
    fn unnormalised_sphere_normal(&self, hit: &Hit, s: &Surface) -> Surface {
        let PrimRef::Sphere(i) = hit.prim else {
            return *s;
        };
        let r = self.scene.spheres[i as usize].radius;
        Surface {
            normal: s.normal * r,
            shading_normal: s.shading_normal * r,
            ..*s
        }
    }

    /// Fresnel glass: both rays while the path is still deterministic, one chosen by its
    /// Fresnel weight after a sampled bounce.
    fn refractive<O: RayObserver>(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        path: PathState,
        id: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Vec3A {
        let g = self.glass(ray, s, m, path);
        if path.branch || self.settings.stage != Stage::Full {
            let mut out = Vec3A::ZERO;
            // Only renders with mistakes lose the reflection, and they all take this engine.
            let reflected = self
                .glass_reflected(&g, path)
                .filter(|_| !self.isect.mistakes().reflection_lost());
            let refracted = self.glass_refracted(&g, path);
            if O::ENABLED {
                let fate = |kept: bool, exists: bool| match (kept, exists) {
                    (true, _) => BranchFate::Traced,
                    (false, true) => BranchFate::Pruned,
                    (false, false) => BranchFate::Absent,
                };
                let fates = (
                    fate(reflected.is_some(), g.kr > 0.0),
                    fate(refracted.is_some(), g.refracted.is_some()),
                );
                cx.obs.glass(id, &self.glass_decision(ray, s, m, &g, path, fates));
            }
            if let Some((r, p)) = reflected {
                out += self.secondary(&r, p, id, RayKind::Reflection, g.kr, cx) * g.kr;
            }
            if let Some((r, p)) = refracted {
                out += self.secondary(&r, p, id, RayKind::Refraction, 1.0 - g.kr, cx) * (1.0 - g.kr);
            }
            out
        } else {
            let child = |medium| path.specular(medium, path.beta);
            match g.refracted {
                Some(r) if cx.rng.get1d(Draw::GlassChoice.dim(path.vertex())) >= g.kr => {
                    if O::ENABLED {
                        let fates = (BranchFate::NotChosen, BranchFate::Traced);
                        cx.obs.glass(id, &self.glass_decision(ray, s, m, &g, path, fates));
                    }
                    self.secondary(&r, child(g.refr_medium), id, RayKind::Refraction, 1.0, cx)
                }
                _ => {
                    if O::ENABLED {
                        let refr = if g.refracted.is_some() {
                            BranchFate::NotChosen
                        } else {
                            BranchFate::Absent
                        };
                        cx.obs.glass(
                            id,
                            &self.glass_decision(ray, s, m, &g, path, (BranchFate::Traced, refr)),
                        );
                    }
                    self.secondary(&g.reflected, child(g.refl_medium), id, RayKind::Reflection, 1.0, cx)
                }
            }
        }
    }

    /// What the recorder shows of a glass hit: the indices and angles Snell's law and Fresnel
    /// used (as this render's mistakes, if any, chose them) and the fates of both rays.
    #[cold]
    fn glass_decision(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        g: &Glass,
        path: PathState,
        (refl_fate, refr_fate): (BranchFate, BranchFate),
    ) -> GlassDecision {
        let swap = !s.front_face && !self.mistake(Mistake::RefractionNoIndexSwap);
        let (n1, n2) = if swap { (m.value, 1.0) } else { (1.0, m.value) };
        let cos_i = (-ray.dir.dot(s.normal)).clamp(0.0, 1.0);
        let beta = path.beta.max_element();
        // Measured from the ray actually sent, so a wrong refraction formula shows.
        let cos_t = g.refracted.map(|r| -r.dir.dot(s.normal));
        let split = path.branch || self.settings.stage != Stage::Full;
        let (wr, wt) = if split { (g.kr, 1.0 - g.kr) } else { (1.0, 1.0) };
        GlassDecision {
            entering: s.front_face,
            n1,
            n2,
            cos_i,
            cos_t,
            tir: (n1 / n2).powi(2) * (1.0 - cos_i * cos_i).max(0.0) >= 1.0,
            reflectance: g.kr,
            prune_below: if split { self.branch_cutoff } else { 0.0 },
            reflected: GlassBranch {
                fate: refl_fate,
                weight: wr,
                path_weight: beta * wr,
                origin: Some(g.reflected.origin.to_array()),
                direction: Some(g.reflected.dir.to_array()),
            },
            refracted: GlassBranch {
                fate: refr_fate,
                weight: if g.refracted.is_some() { wt } else { 0.0 },
                path_weight: if g.refracted.is_some() { beta * wt } else { 0.0 },
                origin: g.refracted.map(|r| r.origin.to_array()),
                direction: g.refracted.map(|r| r.dir.to_array()),
            },
        }
    }

    /// A hit on a [`Lobe::Lambert`] or [`Lobe::Bsdf`] material in the full renderer: point lights, one emitter sample and one
    /// BRDF sample (MIS), and the bounce's indirect light where the rules carry it.
    fn shade<O: RayObserver>(
        &self,
        ray: &Ray,
        s: &Surface,
        m: &Material,
        path: PathState,
        id: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Li {
        let ambient = self.settings.ambient;
        let specular_only = !ambient && !self.emitters.any_emission;
        let Some(bsdf) = Bsdf::of(m, specular_only) else {
            return Li::default();
        };
        let n = s.shading_normal;
        let (t, b) = basis(n);
        let mut wo = to_local(-ray.dir, t, b, n);
        if wo.z < 1e-4 {
            // Interpolated normals can face away from the viewer near silhouettes.
            wo = Vec3A::new(wo.x, wo.y, 1e-4).normalize();
        }
        let frame = (t, b, n, wo);
        let specular = bsdf.has_specular();
        let origin = s.point + s.normal * self.offset(s, ray);
        let lit = PointLit {
            albedo: m.color.into(),
            brdf: specular.then_some((&bsdf, frame)),
        };
        let mut l = self.direct_point_lights(s, ray, lit, id, path.depth, cx);

        // Emitter sampling, weighted against BRDF sampling. With no observer recording the
        // rays, the shadow ray waits and is traced together with the bounce ray below, whose
        // query does not depend on it (`Intersect::intersect_and_occluded`); its light is still
        // added before the bounce's, so the sum is the same.
        let mut pending: Option<ShadowRay> = None;
        if !self.emitters.is_empty() {
            let u0 = cx.rng.get1d(Draw::LightChoice.dim(path.vertex()));
            let [u1, u2] = cx.rng.get2d(Draw::LightPoint.dim(path.vertex()));
            if let Some(ls) = self.emitters.sample(self.scene, origin, u0, u1, u2) {
                let wi = to_local(ls.dir, t, b, n);
                let (f, _) = bsdf.eval(wo, wi);
                if wi.z > 0.0 && ls.dir.dot(s.normal) > 0.0 && f != Vec3A::ZERO {
                    let shadow = Ray::new(origin, ls.dir);
                    let t_max = ls.dist * (1.0 - 1e-4);
                    cx.c.shadow += 1;
                    let sid = cx.obs.ray(Some(id), RayKind::Emitter, path.depth, &shadow, t_max);
                    let w = power_heuristic(ls.pdf, bsdf.pdf(wo, wi));
                    let sr = ShadowRay {
                        ray: shadow,
                        t_max,
                        unblocked: f * ls.radiance * (wi.z * w / ls.pdf),
                        // Beer's law for rays that stay inside the medium the hit lies in.
                        attenuation: self.transmittance(path, ls.dist),
                    };
                    if O::ENABLED {
                        let blocker = self
                            .isect
                            .occluder(&shadow, 0.0, t_max)
                            .map(|p| self.scene.prim_info(p).0);
                        let e = &self.emitters.list[ls.emitter as usize];
                        let nearest = self.nearest_blocker(&shadow, t_max, blocker);
                        let name = &self.scene.entities[e.entity as usize].name;
                        cx.obs
                            .shadow(sid, self.scene, name, blocker, nearest.as_ref().map(|(t, s)| (*t, s)));
                        let contrib = sr.contrib(blocker.is_some());
                        cx.obs.result(sid, w, contrib);
                        l += contrib;
                    } else {
                        pending = Some(sr);
                    }
                }
            }
        }
        // Where no bounce ray follows, the waiting shadow ray is traced alone.
        let alone = |l: Vec3A, pending: Option<ShadowRay>| match pending {
            Some(sr) => l + sr.contrib(self.isect.occluded(&sr.ray, 0.0, sr.t_max)),
            None => l,
        };

        // BRDF sampling: emitters it finds (MIS) and, where carried, indirect light.
        if !(self.emitters.any_emission || ambient || specular) {
            return Li::reflected(alone(l, pending));
        }
        // A Lambert BRDF has one lobe, so no lobe is drawn (its sample ignores `u0`).
        let u0 = if bsdf.has_lobes() {
            cx.rng.get1d(Draw::Lobe.dim(path.vertex()))
        } else {
            0.0
        };
        let [u1, u2] = cx.rng.get2d(Draw::BsdfDirection.dim(path.vertex()));
        let Some(bs) = bsdf.sample(wo, u0, u1, u2) else {
            return Li::reflected(alone(l, pending));
        };
        let wi_w = to_world(bs.wi, t, b, n).normalize();
        if wi_w.dot(s.normal) <= 0.0 {
            return Li::reflected(alone(l, pending));
        }
        let w_total = bs.f * (bs.wi.z / bs.pdf);
        let mut carry = if ambient {
            w_total
        } else {
            bs.f_specular * (bs.wi.z / bs.pdf)
        };
        let mut child = PathState {
            depth: path.depth,
            bounces: path.bounces + 1,
            beta: path.beta * glam::Vec3::from(carry),
            medium: path.medium,
            branch: false,
        };
        let mut want = carry.max_element() > 0.0;
        if ambient {
            // Under `--depth-limit all` a bounce is one level deeper like any other ray.
            child.depth += u32::from(self.settings.depth_limit == DepthLimit::All);
            want &= path.bounces < MAX_BOUNCES;
            if want && path.bounces >= RR_START {
                let p = russian_roulette_survival(child.beta);
                if cx.rng.get1d(Draw::Roulette.dim(path.vertex())) < p {
                    carry /= p;
                    child.beta /= p;
                } else {
                    want = false;
                }
            }
        } else {
            // Without -l only the specular part's reflection recurses, like a blurred mirror.
            want &= path.depth < self.settings.max_depth;
            child.depth += 1;
        }
        if !want && self.emitters.is_empty() && !self.emitters.any_emission {
            return Li::reflected(alone(l, pending));
        }
        let r = Ray::new(origin, wi_w);
        cx.c.secondary += 1;
        let cid = cx.obs.ray(Some(id), RayKind::Bounce, child.depth, &r, f32::INFINITY);
        let hit = match pending {
            Some(sr) => {
                let (hit, blocked) = self.isect.intersect_and_occluded(&r, &sr.ray, sr.t_max);
                l += sr.contrib(blocked);
                hit
            }
            None => self.isect.intersect(&r, 0.0, f32::INFINITY),
        };
        let li = self.trace_found(&r, hit, child, want, cid, cx);
        let mis = if li.light_pdf > 0.0 {
            power_heuristic(bs.pdf, li.light_pdf)
        } else {
            1.0
        };
        let contrib = w_total * li.emitted * mis + carry * li.reflected;
        cx.obs.result(cid, mis, contrib);
        l += contrib;
        Li::reflected(l)
    }

    fn secondary<O: RayObserver>(
        &self,
        r: &Ray,
        path: PathState,
        parent: u32,
        kind: RayKind,
        weight: f32,
        cx: &mut PathCx<'_, O>,
    ) -> Vec3A {
        cx.c.secondary += 1;
        let id = cx.obs.ray(Some(parent), kind, path.depth, r, f32::INFINITY);
        let v = self.trace(r, path, true, id, cx).total();
        cx.obs.result(id, weight, v);
        v
    }

    /// The closest surface on a shadow ray the occluder query found `blocker` on, for the
    /// recorder: its distance and surface.
    #[cold]
    fn nearest_blocker(&self, shadow: &Ray, t_max: f32, blocker: Option<u32>) -> Option<(f32, Surface)> {
        blocker?;
        let hit = self.isect.intersect(shadow, 0.0, t_max)?;
        Some((hit.t, self.scene.surface(shadow, &hit)))
    }

    /// Point lights: the course's Σ max(0, N·L) · albedo · light colour over visible lights, or
    /// with a BRDF, Σ π · f · light colour · max(0, N·L). The shadow rays are recorded at
    /// `depth`, that of the ray whose hit they light.
    fn direct_point_lights<O: RayObserver>(
        &self,
        s: &Surface,
        ray: &Ray,
        lit: PointLit<'_>,
        parent: u32,
        depth: u32,
        cx: &mut PathCx<'_, O>,
    ) -> Vec3A {
        let mut sum = Vec3A::ZERO;
        // `Surface::outside` when the scale is 1, bit for bit.
        let eps = self.offset(s, ray);
        let origin = if I::MISTAKEN {
            mistakes::shadow_origin(self.isect.mistakes(), s.point, s.normal, eps)
        } else {
            s.point + s.normal * eps
        };
        // A student's N·L without its clamp at 0 adds the negative terms of lights behind the
        // shading normal that its shadow rays reach.
        let unclamped = self.mistake(Mistake::NdotLUnclamped);
        for (li, light) in self.scene.lights.iter().enumerate() {
            if li > 0 && self.mistake(Mistake::FirstLightOnly) {
                break;
            }
            // A student's huge offset moves the shadow ray only: the light's direction is
            // still taken from the hit point.
            let from = if self.mistake(Mistake::HugeShadowOffset) || self.isect.mistakes().shadow_offset().is_some() {
                s.point
            } else {
                origin
            };
            let Some((l, dist, cos)) = toward_point_light(from, s.shading_normal, Vec3A::from(light.position)) else {
                continue;
            };
            let shadow = Ray::new(origin, l);
            cx.c.shadow += 1;
            let reach = if self.mistake(Mistake::ShadowPastLight) {
                f32::INFINITY
            } else {
                dist
            };
            let id = cx.obs.ray(Some(parent), RayKind::Shadow, depth, &shadow, reach);
            let blocker = if O::ENABLED {
                self.isect
                    .occluder(&shadow, 0.0, reach)
                    .map(|p| self.scene.prim_info(p).0)
            } else if (cos <= 0.0 && !unclamped) || self.isect.occluded(&shadow, 0.0, reach) {
                // Shadow rays behind the surface cannot contribute; only the recorder needs them traced.
                Some(u32::MAX)
            } else {
                None
            };
            if O::ENABLED {
                let nearest = self.nearest_blocker(&shadow, reach, blocker);
                let name = &self.scene.light_names[li];
                cx.obs
                    .shadow(id, self.scene, name, blocker, nearest.as_ref().map(|(t, s)| (*t, s)));
            }
            let contrib = if blocker.is_none() && (cos > 0.0 || unclamped) {
                match lit.brdf {
                    None => point_light_contribution(lit.albedo, Vec3A::from(light.color), cos),
                    Some((bsdf, (t, b, n, wo))) => {
                        let (f, _) = bsdf.eval(wo, to_local(l, t, b, n));
                        point_light_contribution_brdf(f, Vec3A::from(light.color), cos)
                    }
                }
            } else {
                Vec3A::ZERO
            };
            let contrib = if self.mistake(Mistake::LightFalloff) {
                contrib / (dist * dist)
            } else {
                contrib
            };
            cx.obs.result(id, cos.max(0.0), contrib);
            sum += contrib;
        }
        if self.mistake(Mistake::AmbientTerm) {
            sum += lit.albedo * mistakes::AMBIENT;
        }
        sum
    }
}
