//! Several kinds of wrong answer that all gather on one entity, or on every entity of one kind
//! of surface, are one mistake: that entity's (or that kind's) intersection or geometry. A
//! sphere test with a wrong radius reports hits where there is nothing, misses others and puts
//! the rest at the wrong distance; a model built in the wrong place does the same; nothing else
//! in the tracer is at fault, so the report heads them with one cause naming the surfaces.

use std::collections::BTreeMap;

use rayscope_core::scene::PrimRef;

use super::{Cause, CauseCount, Judge, Tally};
use crate::verdict::Code;

/// Verdicts on what a ray met (and the normal it found there), which a wrong intersection test
/// or wrong geometry produces.
const MET: &[Code] = &[
    Code::HitMissed,
    Code::HitPhantom,
    Code::HitFarther,
    Code::HitWrongT,
    Code::HitOneSidedTriangle,
    Code::HitTriangleEdge,
    Code::HitNormalWrong,
    Code::ShadowMissedBlocker,
    Code::ShadowPhantomBlocker,
    Code::ShadowBlockedCarriedOver,
    Code::ShadowWrongBlocker,
    Code::ShadowOneSidedTriangle,
];

/// Share of those verdicts' rays that must be about the entities folded.
const GATHERED: f64 = 0.95;

impl Judge<'_> {
    /// The entities of one kind of surface that the rays of causes `met` gather on, when at least
    /// [`GATHERED`] of them do: in words ("sphere 'Ball'", "planes ('Floor', 'Roof')"), and
    /// their indices.
    fn gathered(&self, t: &Tally, met: &[Cause]) -> Option<(String, Vec<u32>)> {
        let mut entities: BTreeMap<u32, u64> = BTreeMap::new();
        let mut rays = 0;
        for c in met {
            let n = &t.causes[c];
            rays += n.rays;
            for (&e, &k) in &n.entities {
                *entities.entry(e).or_default() += k;
            }
        }
        let (&top, _) = entities.iter().max_by_key(|(_, &k)| k)?;
        let kind = self.surface_kind(top);
        let same_kind: Vec<u32> = entities
            .keys()
            .copied()
            .filter(|&e| self.surface_kind(e) == kind)
            .collect();
        let on: u64 = same_kind.iter().map(|e| entities[e]).sum();
        if (on as f64) < GATHERED * rays as f64 {
            return None;
        }
        let names: Vec<String> = same_kind.iter().map(|&e| format!("'{}'", self.name(e))).collect();
        let what = if same_kind.len() == 1 {
            format!("{kind} {}", names[0])
        } else {
            format!("{kind}s ({})", names.join(", "))
        };
        Some((what, same_kind))
    }

    /// Missed hits, and no other verdict on what rays met, that gather on one kind of surface:
    /// the headline names it, and says when the tracer never reports a hit on it at all (an
    /// intersection test that cannot succeed, as a plane test that divides by |n·d| does).
    fn missed_on_one_kind(&self, t: &mut Tally, missed: Cause) {
        let Some((what, entities)) = self.gathered(t, &[missed]) else {
            return;
        };
        let never = entities
            .iter()
            .all(|&e| t.claimed_hits.get(e as usize).copied().unwrap_or(0) == 0);
        let them = if entities.len() == 1 { "it" } else { "any of them" };
        let note = if never {
            format!("missed a hit: every ray it missed meets the {what}, and your tracer never reports a hit on {them}")
        } else {
            format!("missed a hit: every ray it missed meets the {what}")
        };
        if let Some(n) = t.causes.get_mut(&missed) {
            n.note = Some(note);
        }
    }

    /// The kind of surface entity `e` is, in words.
    fn surface_kind(&self, e: u32) -> &'static str {
        let prims = self.geo.prims(e);
        match prims.first() {
            Some(PrimRef::Sphere(_)) => "sphere",
            Some(PrimRef::Plane(_)) => "plane",
            Some(PrimRef::Triangle(_)) if prims.len() > 1 => "model",
            Some(PrimRef::Triangle(_)) => "triangle",
            None => "entity",
        }
    }

    /// Folds causes of different verdicts on what rays met into one, where they gather on one
    /// entity or one kind of surface.
    pub fn fold_surfaces(&self, t: &mut Tally) {
        let met: Vec<Cause> = t.causes.keys().copied().filter(|c| MET.contains(&c.code)).collect();
        if let [missed] = met[..] {
            if missed == Cause::of(Code::HitMissed) {
                self.missed_on_one_kind(t, missed);
            }
            return;
        }
        // Verdicts on shadow rays alone point at the shadow test (its own intersection call, a
        // direction left unnormalised there), not at the surface: only hits make it the surface.
        if met.is_empty() || met.iter().all(|c| c.code.as_str().starts_with("shadow.")) {
            return;
        }
        let Some((what, entities)) = self.gathered(t, &met) else {
            return;
        };
        let mut folded = CauseCount {
            note: Some(format!(
                "your tracer's intersection with the {what} is wrong: rays that meet {} go wrong in {} ways and no others do",
                if entities.len() == 1 { "it" } else { "them" },
                met.len()
            )),
            ..CauseCount::default()
        };
        let keep = t.keep;
        for c in met {
            if let Some(n) = t.causes.remove(&c) {
                // Each folded verdict's rays are what the mistake does: they follow from it.
                *folded.consequences.entry(c.code).or_default() += n.rays;
                let samples = n.samples;
                folded.merge(
                    CauseCount {
                        samples: 0,
                        rays: n.rays,
                        consequences: n.consequences,
                        examples: n.examples,
                        entities: n.entities,
                        note: None,
                    },
                    keep,
                );
                folded.samples = folded.samples.max(samples);
            }
        }
        let e = t.causes.entry(Cause::of(Code::HitSurfaceWrong));
        e.or_default().merge(folded, keep);
    }
}
