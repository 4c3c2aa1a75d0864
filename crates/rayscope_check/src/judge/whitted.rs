//! The colour a ray brings back by the course's stage-2 rules, traced by the oracle in double
//! precision: needed where a tracer's mirror or glass hit logs a colour but casts no ray, so that
//! nothing in the log says what it should have brought back.

use glam::DVec3;
use rayscope_core::scene::Lobe;

use super::shading::fresnel;
use super::{Eval, Judge, Leave};
use crate::geom::{reflect, refract};
use crate::tie::scale;

/// Branches carrying less of the colour than this are left out: even a light of colour 1 seen
/// through them would change a byte by less than half a level.
const SMALLEST_SHARE: f64 = 1.0 / 1024.0;

/// How far past its start a ray leaving a surface begins to meet things, relative to the
/// coordinates' scale: past the rounding of the point it leaves, short of anything visible.
const LEAVE: f64 = 1e-9;

impl Judge<'_> {
    /// The colour `o + t d` (unit `d`, `t > t_min`) brings back at `depth` bounces from the
    /// camera, times `share`; `None` where the course's stage-2 rules do not say.
    fn whitted(&self, o: DVec3, d: DVec3, t_min: f64, depth: u32, share: f64) -> Option<DVec3> {
        if share < SMALLEST_SHARE {
            return Some(DVec3::ZERO);
        }
        let hit = Eval {
            rs: self.trace(o, d, t_min, f64::INFINITY, o),
            sound: true,
            origin: o,
            dir: d,
            dir_len: 1.0,
        };
        let Some(lv) = hit.leave() else {
            return Some(DVec3::ZERO);
        };
        self.whitted_at(&lv, depth, share)
    }

    /// The colour a ray brings back from its hit `lv` at `depth` bounces from the camera, times
    /// `share`, by the course's stage-2 rules: the diffuse sum over the lights the oracle sees
    /// unblocked, a mirror's reflection, glass's Fresnel mix, black at the depth limit. `None`
    /// for what those rules do not cover (an emitter, a glossy material, stage 3's emitters,
    /// ambient light and coloured glass).
    pub(super) fn whitted_at(&self, lv: &Leave, depth: u32, share: f64) -> Option<DVec3> {
        if self.beyond_stage_two(lv.material) {
            return None;
        }
        let m = &self.scene.materials[lv.material as usize];
        let eps = LEAVE * scale(&[lv.point]);
        let d = lv.parent_dir.normalize();
        match m.lobe() {
            Lobe::Lambert => {
                let mut sum = DVec3::ZERO;
                for light in &self.scene.lights {
                    let to = light.position.as_dvec3() - lv.point;
                    let dist = to.length();
                    let l = to / dist;
                    let cos = lv.shade.dot(l);
                    if cos <= 0.0 || self.oracle.closest(lv.point, l, eps, dist - eps).is_some() {
                        continue;
                    }
                    sum += m.color.as_dvec3() * light.color.as_dvec3() * cos;
                }
                Some(sum * share)
            }
            Lobe::Mirror | Lobe::Dielectric if depth >= self.settings.max_depth => Some(DVec3::ZERO),
            Lobe::Mirror => self.whitted(lv.point, reflect(d, lv.facing), eps, depth + 1, share),
            Lobe::Dielectric => {
                let ior = f64::from(m.value);
                let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
                let kr = fresnel((-d.dot(lv.facing)).clamp(0.0, 1.0), n1, n2);
                let r = self.whitted(lv.point, reflect(d, lv.facing), eps, depth + 1, share * kr)?;
                let t = match refract(d, lv.facing, n1 / n2) {
                    Some(t) if kr < 1.0 => self.whitted(lv.point, t, eps, depth + 1, share * (1.0 - kr))?,
                    _ => DVec3::ZERO,
                };
                Some(r + t)
            }
            Lobe::Emitter | Lobe::Bsdf => None,
        }
    }
}
