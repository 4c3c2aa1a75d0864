//! Mistakes as families with a parameter, fitted to the student's pixels: where the catalogue
//! holds a few members of a family, the picture itself says which member the student's tracer
//! is, with the fitted value against the course's. The families fitted are the Fresnel weight
//! of glass as a function of the angle of incidence (`fresnel.rs`), worked out from rayscope's
//! own rays of the render (`trees.rs`), whose glass hits split the same way whatever weight a
//! tracer gives them; and the anti-aliasing sample positions within a pixel (`aa.rs`), from
//! rayscope's colours at sub-pixel positions of the pixels on edges.
//!
//! A fit is a finding only when the course's answer (the exact weight, the `-x` grid) does not
//! explain the pixels to within rounding and the fitted family does: the course's answer is the
//! null hypothesis.

use crate::integrator::Integrator;
use crate::scene::Scene;
use crate::settings::RenderSettings;

mod aa;
mod fitted;
mod fresnel;
mod trees;

pub(crate) use aa::Reading as AaReading;
pub use fitted::Fitted;

/// Largest number of pixels traced to find the glass's (a grid over the image).
const MAX_TRACED: u32 = 40_000;

/// The families fitted to `theirs` (RGB8 of `settings`' size) from rayscope's rays of `scene`
/// under `settings`, which carry no mistake: those whose fit explains the student's pixels
/// where the course's answer does not.
pub(crate) fn fit(scene: &Scene, settings: &RenderSettings, theirs: &[u8]) -> Vec<Fitted> {
    if !settings.mistakes.is_empty()
        || !scene
            .materials
            .iter()
            .any(|m| m.kind == rayscope_scene::MaterialKind::Refractive)
    {
        return Vec::new();
    }
    let mut integ = Integrator::new(scene, settings);
    // Every glass branch traced: a weight other than the course's may make a pruned one count.
    integ.branch_cutoff = 0.0;
    let (w, h) = (settings.width, settings.height);
    let total = w * h;
    let stride = total.div_ceil(MAX_TRACED).max(1);
    let pixels: Vec<u32> = (0..total).step_by(stride as usize).collect();
    let glass = trees::glass_pixels(&integ, theirs, w, &pixels);
    fresnel::fit(&glass).into_iter().collect()
}

/// What the student's edges say about their anti-aliasing (`theirs`, RGB8 of `settings`' size,
/// against rayscope's render `ours` of `scene` under `settings`, which carry no mistake): the
/// level they show and what was fitted. Nothing where a stochastic effect makes rayscope's own
/// samples random.
pub(crate) fn read_aa(scene: &Scene, settings: &RenderSettings, ours: &[u8], theirs: &[u8]) -> AaReading {
    if !settings.mistakes.is_empty() {
        return AaReading::default();
    }
    let integ = Integrator::new(scene, settings);
    if integ.stochastic && settings.stage == crate::settings::Stage::Full {
        return AaReading::default();
    }
    let asked = settings.aa.max(1);
    let declared = if settings.stage == crate::settings::Stage::One {
        1
    } else {
        asked
    };
    aa::read(&integ, ours, theirs, declared, asked)
}
