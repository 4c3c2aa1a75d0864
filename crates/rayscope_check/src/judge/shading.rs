//! Colours: each surface decision (what a ray brought back from its hit) against the course's
//! stage-2 rules, computed in f64 from the tracer's own logged children, the scene's materials and
//! its lights; and the rays a hit should have cast that the log does not have.
//!
//! A decision is judged from the children as logged, so a wrong colour gives one verdict where it
//! is made, not one at every ancestor that passed it on.

use glam::DVec3;
use rayscope_core::scene::{Lobe, PrimRef};
use rayscope_core::Stage;
use rayscope_scene::MaterialKind;
use serde_json::json;
use smallvec::{smallvec, SmallVec};

use super::{njson, vjson, Eval, Finding, Judge, Leave, Tally, Value, MIN_SHARE};
use crate::geom::angle;
use crate::log::{Answer, Kind, LoggedRay};
use crate::verdict::Code;

/// Relative tolerance on a logged colour channel: a thousand times f32's rounding.
const REL: f64 = 1e-4;
/// Absolute tolerance on a logged colour channel, for channels near zero.
const ABS: f64 = 1e-5;
/// Smallest difference between the reflected and refracted colours in a channel for that channel
/// to tell the reflected share apart.
const SPLIT: f64 = 1e-3;
/// Distance from the critical angle (in sin²θt) within which glass is not judged: whether the
/// ray is totally reflected there is rounding.
const CRITICAL: f64 = 1e-3;

/// True when `yours` is `want` to within f32 rounding plus `slack`, channel by channel.
pub(super) fn fits(yours: DVec3, want: DVec3, slack: DVec3) -> bool {
    (0..3).all(|c| (yours[c] - want[c]).abs() <= REL * yours[c].abs().max(want[c].abs()) + ABS + slack[c])
}

/// cos θt for a ray meeting a surface at cos θi from the medium of index `n1` into that of `n2`;
/// `None` under total internal reflection.
fn cos_t(ci: f64, n1: f64, n2: f64) -> Option<f64> {
    let sin2_t = (n1 / n2).powi(2) * (1.0 - ci * ci).max(0.0);
    (sin2_t < 1.0).then(|| (1.0 - sin2_t).sqrt())
}

/// The exact unpolarised Fresnel reflectance, the course's rule.
pub(super) fn fresnel(ci: f64, n1: f64, n2: f64) -> f64 {
    let Some(ct) = cos_t(ci, n1, n2) else {
        return 1.0;
    };
    let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
    let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
    0.5 * (rs * rs + rp * rp)
}

/// A way of computing glass's reflected share, right or wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Formula {
    Exact,
    /// Schlick's approximation with the larger angle's cosine (rayscope's own form).
    Schlick,
    /// Schlick's approximation with cos θi on the way out as well.
    SchlickIncident,
    /// rs² alone: cos θi and cos θt exchanged in rp.
    RsOnly,
    /// rp² alone: cos θi and cos θt exchanged in rs.
    RpOnly,
    Half,
    NoFresnel,
    /// The exact share given to the refracted colour and the rest to the reflected one.
    WeightsExchanged,
}

impl Formula {
    /// Every mistaken formula, in the order they are tried.
    const MISTAKES: [Formula; 7] = [
        Formula::Schlick,
        Formula::SchlickIncident,
        Formula::RsOnly,
        Formula::RpOnly,
        Formula::WeightsExchanged,
        Formula::Half,
        Formula::NoFresnel,
    ];

    /// The reflected share by this formula; 1 past the critical angle.
    fn kr(self, ci: f64, n1: f64, n2: f64) -> f64 {
        let Some(ct) = cos_t(ci, n1, n2) else {
            return 1.0;
        };
        let rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct);
        let rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
        let r0 = ((n1 - n2) / (n1 + n2)).powi(2);
        match self {
            Formula::Exact => 0.5 * (rs * rs + rp * rp),
            Formula::Schlick => {
                let c = if n1 <= n2 { ci } else { ct };
                r0 + (1.0 - r0) * (1.0 - c).powi(5)
            }
            Formula::SchlickIncident => r0 + (1.0 - r0) * (1.0 - ci).powi(5),
            Formula::RsOnly => rs * rs,
            Formula::RpOnly => rp * rp,
            Formula::Half => 0.5,
            Formula::NoFresnel => 0.0,
            Formula::WeightsExchanged => 1.0 - 0.5 * (rs * rs + rp * rp),
        }
    }

    fn code(self) -> Code {
        match self {
            Formula::Exact => Code::ShadingFresnel,
            Formula::Schlick | Formula::SchlickIncident => Code::ShadingFresnelSchlick,
            Formula::RsOnly | Formula::RpOnly => Code::ShadingFresnelSwappedCosines,
            Formula::Half => Code::ShadingFresnelHalf,
            Formula::NoFresnel => Code::ShadingFresnelNone,
            Formula::WeightsExchanged => Code::ShadingFresnelWeightsExchanged,
        }
    }

    fn describe(self) -> &'static str {
        match self {
            Formula::Exact => "the Fresnel equations",
            Formula::Schlick => "Schlick's approximation",
            Formula::SchlickIncident => "Schlick's approximation with cos θi on the way out as well",
            Formula::RsOnly => "rs² alone (cos θi and cos θt exchanged in rp)",
            Formula::RpOnly => "rp² alone (cos θi and cos θt exchanged in rs)",
            Formula::Half => "half and half",
            Formula::NoFresnel => "no reflection at all",
            Formula::WeightsExchanged => "the Fresnel share given to the refracted colour (1 − kr to the reflected)",
        }
    }
}

/// What a glass hit's colour says about the reflected share it was mixed with.
#[derive(Debug, Clone, Copy, PartialEq)]
enum GlassFit {
    /// The exact Fresnel weight.
    Exact,
    /// A known mistake, with the share the colour implies.
    Mistake(Formula, Option<f64>),
    /// Another share, when the colours tell it.
    Other(Option<f64>),
    /// No weighted mix of the two colours.
    NotAMix,
}

/// The reflected share `kr` for which `c = kr·r + (1 − kr)·t` fits best, from the channels where
/// `r` and `t` differ enough to tell; `None` where none does.
fn solve_kr(c: DVec3, r: DVec3, t: DVec3) -> Option<f64> {
    solve_kr_over(c, r, t, SPLIT)
}

/// [`solve_kr`] from the channels where `r` and `t` differ by more than `split`.
fn solve_kr_over(c: DVec3, r: DVec3, t: DVec3, split: f64) -> Option<f64> {
    let (mut num, mut den) = (0.0, 0.0);
    for i in 0..3 {
        let d = r[i] - t[i];
        if d.abs() > split {
            num += (c[i] - t[i]) * d;
            den += d * d;
        }
    }
    (den > 0.0).then(|| num / den)
}

/// The weights `(a, b)` with `c = a·r + b·t`, where the two colours differ in hue enough to tell
/// them apart and the colour fits.
fn solve_weights(c: DVec3, r: DVec3, t: DVec3) -> Option<(f64, f64)> {
    let (rr, tt, rt) = (r.dot(r), t.dot(t), r.dot(t));
    let det = rr * tt - rt * rt;
    // Colours of one hue (or a NaN) leave the two weights undetermined.
    if det.is_nan() || det <= 1e-6 * rr * tt {
        return None;
    }
    let (rc, tc) = (r.dot(c), t.dot(c));
    let (a, b) = ((rc * tt - tc * rt) / det, (tc * rr - rc * rt) / det);
    fits(c, r * a + t * b, DVec3::ZERO).then_some((a, b))
}

/// `w·name` with the share of the Fresnel reflectance `kr` that `w` is, where it is one.
fn weight_words(w: f64, name: &str, kr: f64) -> String {
    let known = [
        (kr, "kr"),
        (1.0 - kr, "1 − kr"),
        (kr * kr, "kr²"),
        ((1.0 - kr).powi(2), "(1 − kr)²"),
        (1.0, "1"),
    ];
    match known.iter().find(|(v, _)| (w - v).abs() <= 1e-4 * v.abs().max(1.0)) {
        Some((_, "1")) => name.to_string(),
        Some((v, words)) => format!("{w:.4}·{name} ({words} = {v:.4})"),
        None => format!("{w:.4}·{name}"),
    }
}

/// Which formula's share mixes `r` and `t` into `c` at cos θi `ci` from index `n1` into `n2`,
/// with `unc` the uncertainty of the exact share (from the normal's).
fn classify_glass(c: DVec3, r: DVec3, t: DVec3, ci: f64, n1: f64, n2: f64, unc: f64) -> GlassFit {
    let spread = (r - t).abs();
    let mix = |kr: f64| r * kr + t * (1.0 - kr);
    if fits(c, mix(Formula::Exact.kr(ci, n1, n2)), spread * unc) {
        return GlassFit::Exact;
    }
    let solved = solve_kr(c, r, t);
    let best = Formula::MISTAKES
        .iter()
        .map(|&f| (f, f.kr(ci, n1, n2)))
        .filter(|&(_, k)| fits(c, mix(k), spread * unc))
        .min_by(|a, b| {
            let off = |k: f64| solved.map_or(0.0, |s| (s - k).abs());
            off(a.1).total_cmp(&off(b.1))
        });
    if let Some((f, _)) = best {
        return GlassFit::Mistake(f, solved);
    }
    // Colours too alike for the share to be read safely still give it where it fits exactly.
    match solved.or_else(|| solve_kr_over(c, r, t, 0.0)) {
        Some(k) if fits(c, mix(k), DVec3::ZERO) => GlassFit::Other(Some(k)),
        _ => GlassFit::NotAMix,
    }
}

/// The verdict on one surface decision, for the counts.
enum Decision {
    /// Its colour was judged.
    Judged,
    /// Its colour could not be judged.
    Unjudged,
}

/// One ray's children by kind.
#[derive(Default)]
struct Children<'a> {
    shadow: &'a [usize],
    reflection: &'a [usize],
    refraction: &'a [usize],
    other: usize,
    /// A refracted child breaks Snell's law or the total-internal-reflection test: the
    /// tracer's Fresnel weight then follows from the same mistaken angles or indices, which that
    /// child's verdict already names.
    refraction_wrong: bool,
}

/// One pixel sample's rays as its surface decisions are judged: the rays, each one's parent,
/// rayscope's answer and kind, and what the tracer logs.
#[derive(Clone, Copy)]
struct Sample<'a> {
    rays: &'a [LoggedRay],
    parent: &'a [Option<usize>],
    evals: &'a [Option<Eval>],
    kinds: &'a [Kind],
    logs: &'a Logs,
}

/// What the group's rays say about what the tracer logs.
struct Logs {
    shadow: bool,
    secondary: bool,
}

thread_local! {
    /// The children lists of [`Judge::shading`]: where each ray's children start, a cursor per
    /// ray, and the children.
    #[allow(clippy::type_complexity)]
    static KIDS: std::cell::RefCell<(Vec<usize>, Vec<usize>, Vec<usize>)> = std::cell::RefCell::default();
}

impl Judge<'_> {
    /// Judges the colour of every surface decision of one pixel sample and names the rays its
    /// hits should have cast and did not, adding findings to the ray whose hit it is.
    pub(super) fn shading(
        &self,
        rays: &[LoggedRay],
        parent: &[Option<usize>],
        evals: &[Option<Eval>],
        kinds: &[Kind],
        findings: &mut [Vec<Finding>],
        tally: &mut Tally,
    ) {
        if self.settings.stage == Stage::One {
            return;
        }
        KIDS.with(|k| {
            let (start, next, kids) = &mut *k.borrow_mut();
            self.shading_with(rays, parent, evals, kinds, findings, tally, (start, next, kids));
        });
    }

    /// [`Self::shading`] with the buffers for the children lists.
    #[allow(clippy::too_many_arguments)]
    fn shading_with(
        &self,
        rays: &[LoggedRay],
        parent: &[Option<usize>],
        evals: &[Option<Eval>],
        kinds: &[Kind],
        findings: &mut [Vec<Finding>],
        tally: &mut Tally,
        (start, next, kids): (&mut Vec<usize>, &mut Vec<usize>, &mut Vec<usize>),
    ) {
        let n = rays.len();
        // Each ray's children, together in `kids` from `start[i]` and sorted by kind, in buffers
        // kept per thread from sample to sample.
        let rank = |k: usize| match kinds[k] {
            Kind::Shadow => 0,
            Kind::Reflection => 1,
            Kind::Refraction => 2,
            _ => 3,
        };
        start.clear();
        start.resize(n + 1, 0);
        for p in parent.iter().flatten() {
            start[p + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        next.clear();
        next.extend_from_slice(start);
        kids.clear();
        kids.resize(start[n], 0);
        for (i, p) in parent.iter().enumerate() {
            if let Some(p) = *p {
                kids[next[p]] = i;
                next[p] += 1;
            }
        }
        for i in 0..n {
            kids[start[i]..start[i + 1]].sort_by_key(|&k| rank(k));
        }
        let children = |i: usize, findings: &[Vec<Finding>]| {
            let all = &kids[start[i]..start[i + 1]];
            let upto = |r: u8| all.partition_point(|&k| rank(k) < r);
            let (a, b, c) = (upto(1), upto(2), upto(3));
            Children {
                shadow: &all[..a],
                reflection: &all[a..b],
                refraction: &all[b..c],
                other: all.len() - c,
                refraction_wrong: all[b..c]
                    .iter()
                    .any(|&k| findings[k].iter().any(|f| !f.code.is_excused())),
            }
        };
        let logs = Logs {
            shadow: kinds.contains(&Kind::Shadow),
            secondary: kinds.iter().any(|k| matches!(k, Kind::Reflection | Kind::Refraction)),
        };
        let sample = Sample {
            rays,
            parent,
            evals,
            kinds,
            logs: &logs,
        };
        // The sample's rays with some colours divided by their glass shares, filled at the first
        // decision that needs it ([`Self::logged_weighted`]).
        let mut unweighted = Vec::new();
        for i in 0..n {
            if kinds[i] == Kind::Shadow {
                continue;
            }
            let Some(ev) = evals[i].as_ref().filter(|e| e.sound) else {
                continue;
            };
            let ch = children(i, findings);
            let before = findings[i].len();
            let d = self.decision(i, &sample, ev, &ch, &mut findings[i]);
            if findings[i][before..].iter().any(|f| f.code.is_shading()) {
                self.logged_weighted(i, &sample, ev, &ch, &mut findings[i], before, &mut unweighted);
                let black = |&k: &usize| rays[k].color.is_some_and(|c| fits(c, DVec3::ZERO, DVec3::ZERO));
                let has = |code: Code| findings[i].iter().any(|f| f.code == code);
                if ch.reflection.iter().all(black) && has(Code::ShadingFresnelNone) {
                    tally.glass_black_reflection += 1;
                }
                if ch.reflection.iter().chain(ch.refraction).any(black) && has(Code::ShadingFresnel) {
                    tally.glass_black_other += 1;
                }
            }
            if matches!(d, Decision::Judged) {
                tally.shaded_judged += 1;
            } else {
                tally.shaded_unjudged += 1;
            }
        }
    }

    /// True where the full renderer's rules for a hit on `material` go past stage 2's: a diffuse
    /// surface lit by emitters or ambient light as well, and Beer's law inside coloured glass.
    pub(super) fn beyond_stage_two(&self, material: u32) -> bool {
        if self.settings.stage != Stage::Full {
            return false;
        }
        let m = &self.scene.materials[material as usize];
        match m.lobe() {
            Lobe::Lambert => {
                self.settings.ambient
                    || self
                        .scene
                        .materials
                        .iter()
                        .any(|m| m.kind == MaterialKind::Emissive && m.color.max_element() > 0.0)
            }
            Lobe::Dielectric => m.color != glam::Vec3::ZERO,
            Lobe::Mirror | Lobe::Emitter | Lobe::Bsdf => false,
        }
    }

    /// Judges ray `i`'s surface decision.
    fn decision(&self, i: usize, s: &Sample, ev: &Eval, kids: &Children, f: &mut Vec<Finding>) -> Decision {
        let Sample {
            rays,
            parent,
            evals,
            kinds,
            logs,
        } = *s;
        let r = &rays[i];
        let Some(lv) = ev.leave() else {
            // rayscope's trace misses too: a miss brings back black.
            let Some(c) = r.color else {
                return Decision::Unjudged;
            };
            if !fits(c, DVec3::ZERO, DVec3::ZERO) {
                f.push(self.finding(
                    r,
                    &kinds[i],
                    Code::ShadingMissNotBlack,
                    "this ray hits nothing, so it brings back black; yours brought back a colour".into(),
                    vec![colour_value(c, DVec3::ZERO)],
                ));
            }
            return Decision::Judged;
        };
        let m = &self.scene.materials[lv.material as usize];
        // The share of the sample this hit carries, needed only where a ray is missing.
        let weight = || self.path_weight(i, parent, evals, kinds);
        match m.lobe() {
            Lobe::Lambert => {
                if self.beyond_stage_two(lv.material) {
                    return Decision::Unjudged;
                }
                self.diffuse(r, &kinds[i], &lv, rays, kids, logs, &weight, f)
            }
            Lobe::Mirror | Lobe::Dielectric => {
                let depth = depth_of(i, parent);
                if kids.reflection.is_empty() && kids.refraction.is_empty() && kids.other == 0 {
                    return self.no_children(r, &kinds[i], &lv, depth, logs, &weight, f);
                }
                if m.lobe() == Lobe::Mirror {
                    self.mirror(r, &kinds[i], &lv, rays, kids, f)
                } else if self.beyond_stage_two(lv.material) {
                    Decision::Unjudged
                } else {
                    self.glass(r, &kinds[i], &lv, rays, kids, logs, &weight, f)
                }
            }
            Lobe::Emitter | Lobe::Bsdf => Decision::Unjudged,
        }
    }

    /// Replaces the colour verdicts from `before` on in `f`, ray `i`'s, with one
    /// [`Code::ShadingLoggedWeighted`] where its decision holds once its logged colour, and its
    /// reflected and refracted children's, are divided by the share of its parent glass each
    /// carries (its own share, or the product down from the camera ray that a tracer carrying a
    /// path weight logs): then the log, not the shading, is what differs. Decisions at glass are
    /// left as they are. `unweighted` holds a copy of the sample's rays between calls.
    #[allow(clippy::too_many_arguments)]
    fn logged_weighted(
        &self,
        i: usize,
        s: &Sample,
        ev: &Eval,
        kids: &Children,
        f: &mut Vec<Finding>,
        before: usize,
        unweighted: &mut Vec<LoggedRay>,
    ) {
        let Sample {
            rays,
            parent,
            evals,
            kinds,
            ..
        } = *s;
        let (Some(c), Some(p)) = (rays[i].color, parent[i]) else {
            return;
        };
        // The share of ray `k` (a reflected or refracted ray) that its parent glass gives it.
        let own = |k: usize| -> Option<f64> {
            let lv = evals[parent[k]?]?.leave()?;
            let m = &self.scene.materials[lv.material as usize];
            let kr = super::secondary::glass_fresnel(&lv, f64::from(m.value));
            match kinds[k] {
                Kind::Reflection if m.is_glass() => Some(kr),
                Kind::Refraction if m.is_glass() => Some(1.0 - kr),
                _ => None,
            }
        };
        let Some(share) = own(i) else {
            return;
        };
        let path = |k: usize| self.path_weight(k, parent, evals, kinds);
        let mut scratch = Vec::new();
        let weights: [&dyn Fn(usize) -> Option<f64>; 2] = [&own, &|k| Some(path(k))];
        // At glass, colours logged with a weight read as mistakes in the mix itself (the weights
        // left out, or exchanged where a sphere's inner bounces keep one angle): only a decision
        // at another surface tells the readings apart, and the glass above it follows from it.
        if ev
            .leave()
            .is_some_and(|lv| self.scene.materials[lv.material as usize].is_glass())
        {
            return;
        }
        let fit = weights.iter().find_map(|weight| {
            let w = weight(i)?;
            if !(1e-6..1.0 - 1e-9).contains(&w) {
                return None;
            }
            // The sample's rays are copied once a sample; each try changes the colours of this
            // ray and its children and puts them back.
            if unweighted.len() != rays.len() {
                unweighted.clear();
                unweighted.extend_from_slice(rays);
            }
            let changed = || std::iter::once(i).chain(kids.reflection.iter().chain(kids.refraction).copied());
            unweighted[i].color = Some(c / w);
            for k in changed().skip(1) {
                if let (Some(ck), Some(wk)) = (rays[k].color, weight(k).filter(|&wk| wk > 1e-6)) {
                    unweighted[k].color = Some(ck / wk);
                }
            }
            scratch.clear();
            let alt = Sample { rays: unweighted, ..*s };
            let d = self.decision(i, &alt, ev, kids, &mut scratch);
            for k in changed() {
                unweighted[k].color = rays[k].color;
            }
            (matches!(d, Decision::Judged) && scratch.iter().all(|s| !s.code.is_shading())).then_some(w)
        });
        let Some(w) = fit else {
            return;
        };
        let lv = evals[p].and_then(|e| e.leave()).expect("a glass parent");
        let why = if w == share {
            format!(
                "the share its parent glass '{}' gives the {} ray ({} = {share:.4})",
                self.name(lv.entity),
                kinds[i].name(),
                if kinds[i] == Kind::Reflection { "kr" } else { "1 − kr" }
            )
        } else {
            format!("the product of the glass shares down to it from the camera ray ({w:.4})")
        };
        let mut kept: Vec<Finding> = f.drain(before..).filter(|x| !x.code.is_shading()).collect();
        kept.insert(
            0,
            self.finding(
                &rays[i],
                &kinds[i],
                Code::ShadingLoggedWeighted,
                format!("your logged colour is what this ray brings back times {w:.4}, {why}"),
                vec![colour_value(c, c / w)],
            ),
        );
        f.extend(kept);
    }

    /// A mirror or glass hit that cast no ray: black at the depth limit, a missing ray above it.
    #[allow(clippy::too_many_arguments)]
    fn no_children(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        lv: &Leave,
        depth: u32,
        logs: &Logs,
        weight: &dyn Fn() -> f64,
        f: &mut Vec<Finding>,
    ) -> Decision {
        let limit = self.settings.max_depth;
        if depth >= limit {
            let Some(c) = r.color else {
                return Decision::Unjudged;
            };
            if !fits(c, DVec3::ZERO, DVec3::ZERO) {
                f.push(self.finding(
                    r,
                    kind,
                    Code::ShadingDepthLimit,
                    format!(
                        "'{}' is hit after {depth} bounces, at the depth limit of {limit}: it casts no ray and brings back black; yours cast none but brought back a colour",
                        self.name(lv.entity)
                    ),
                    vec![colour_value(c, DVec3::ZERO)],
                ));
            }
            return Decision::Judged;
        }
        let share = if logs.secondary { weight() } else { 0.0 };
        if share >= MIN_SHARE {
            f.push(self.finding(
                r,
                kind,
                Code::MissingSecondary,
                format!(
                    "'{}' is hit after {depth} bounces, below the depth limit of {limit}, and carries {:.1} % of the sample, but no ray leaves it",
                    self.name(lv.entity),
                    share * 100.0
                ),
                vec![Value {
                    what: "rays cast from this hit".into(),
                    yours: json!("none"),
                    rayscope: json!(if self.scene.materials[lv.material as usize].is_glass() {
                        "reflection and refraction"
                    } else {
                        "reflection"
                    }),
                }],
            ));
            return Decision::Unjudged;
        }
        // Nothing in this sample says whether the tracer logs its reflected and refracted rays;
        // the colour it logged says what its hit brought back, against what the course's rules
        // trace from there.
        let Some(c) = r.color else {
            return Decision::Unjudged;
        };
        let Some(want) = self.whitted_at(lv, depth, 1.0) else {
            return Decision::Unjudged;
        };
        if fits(c, want, want.abs() * 1e-3) {
            return Decision::Judged;
        }
        let visible = (want * weight()).max_element() >= 2.0 / 255.0;
        if !fits(c, DVec3::ZERO, DVec3::ZERO) || !visible {
            return Decision::Unjudged;
        }
        let glass = self.scene.materials[lv.material as usize].is_glass();
        f.push(self.finding(
            r,
            kind,
            Code::MissingSecondary,
            format!(
                "'{}' is hit after {depth} bounces, below the depth limit of {limit}: no ray leaves it and it brings back black, where what it {} is ({:.3}, {:.3}, {:.3})",
                self.name(lv.entity),
                if glass { "reflects and refracts" } else { "reflects" },
                want.x,
                want.y,
                want.z
            ),
            vec![
                Value {
                    what: "rays cast from this hit".into(),
                    yours: json!("none"),
                    rayscope: json!(if glass { "reflection and refraction" } else { "reflection" }),
                },
                colour_value(c, want),
            ],
        ));
        Decision::Judged
    }

    /// The verdict on a diffuse hit whose shadow rays leave out lights `untested`, which face it
    /// (`facing`: N·L of a light), all after light `stopped` where the last shadow ray cast, toward
    /// it, is blocked.
    fn missing_shadow_rays(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        lv: &Leave,
        (untested, stopped): (&[usize], Option<usize>),
        facing: &dyn Fn(usize) -> f64,
        f: &mut Vec<Finding>,
    ) {
        let names: Vec<String> = untested
            .iter()
            .map(|&li| format!("'{}' (N·L = {:.4})", self.light_name(li as u32), facing(li)))
            .collect();
        let why = stopped.map_or(String::new(), |li| {
            format!(
                "; the last shadow ray cast from it, toward light '{}', is blocked, and no light after that one is tested: the loop over the lights stops at a blocked light (a break where the next light should be tried)",
                self.light_name(li as u32)
            )
        });
        f.push(self.finding(
            r,
            kind,
            Code::MissingShadowRay,
            format!(
                "light {} faces this point of '{}' but no shadow ray was cast toward it{why}",
                names.join(", light "),
                self.name(lv.entity)
            ),
            vec![Value {
                what: "shadow rays toward".into(),
                yours: json!("none"),
                rayscope: json!(untested.iter().map(|&li| self.light_name(li as u32)).collect::<Vec<_>>()),
            }],
        ));
    }

    /// A diffuse hit: the shadow rays it needs, and its colour from those it cast.
    #[allow(clippy::too_many_arguments)]
    fn diffuse(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        lv: &Leave,
        rays: &[LoggedRay],
        kids: &Children,
        logs: &Logs,
        weight: &dyn Fn() -> f64,
        f: &mut Vec<Finding>,
    ) -> Decision {
        let lights = &self.scene.lights;
        let light_pos = |li: usize| lights[li].position.as_dvec3();
        // Which light each shadow ray tests: the one it names, else the one it points at.
        let aimed = |k: usize| -> Option<usize> {
            let s = &rays[k];
            s.light.map(|l| l as usize).or_else(|| {
                (0..lights.len()).min_by(|&a, &b| {
                    angle(s.direction, light_pos(a) - s.origin).total_cmp(&angle(s.direction, light_pos(b) - s.origin))
                })
            })
        };
        let facing = |li: usize| lv.shade.dot((light_pos(li) - lv.point).normalize_or_zero());
        // Held in place for the few lights of a course scene: this runs for every diffuse hit.
        let mut tested: SmallVec<[bool; 8]> = smallvec![false; lights.len()];
        // Per light, the first shadow ray that reaches it.
        let mut reached: SmallVec<[Option<usize>; 8]> = smallvec![None; lights.len()];
        let mut unknown = false;
        for &k in kids.shadow {
            let Some(li) = aimed(k).filter(|&li| li < lights.len()) else {
                continue;
            };
            tested[li] = true;
            match rays[k].blocked_by {
                Answer::Nothing => {
                    reached[li].get_or_insert(k);
                }
                Answer::Found(_) => {}
                // Only a light in front of the surface can add to its colour.
                Answer::NotLogged => unknown |= facing(li) > 0.0,
            }
        }
        // A light this close to the surface's plane adds under 0.1 % of its colour: a tracer
        // that skips it by its own rounding of N·L loses nothing visible.
        let untested: SmallVec<[usize; 8]> = (0..lights.len())
            .filter(|&li| !tested[li] && facing(li) > 1e-3)
            .collect();
        if logs.shadow && !untested.is_empty() && weight() >= MIN_SHARE {
            // The last shadow ray cast is blocked and every light left out comes after its light:
            // the loop over the lights stopped there.
            let stopped = kids.shadow.last().and_then(|&k| {
                let li = aimed(k)?;
                (matches!(rays[k].blocked_by, Answer::Found(_)) && untested.iter().all(|&u| u > li)).then_some(li)
            });
            self.missing_shadow_rays(r, kind, lv, (&untested, stopped), &facing, f);
        }
        let Some(c) = r.color else {
            return Decision::Unjudged;
        };
        // A reflected or refracted ray off a diffuse surface is named on that ray; the colour
        // then mixes in what it brought back.
        let secondary = !kids.reflection.is_empty() || !kids.refraction.is_empty() || kids.other > 0;
        if kids.shadow.is_empty() && !logs.shadow && !secondary {
            // No shadow ray in the sample: the tracer may not log them. A colour that is the
            // oracle's own sum over the lights it sees is judged right; any other is left, as
            // nothing says which light the tracer saw.
            return match self.whitted_at(lv, 0, 1.0) {
                Some(want) if fits(c, want, want.abs() * 1e-3) => Decision::Judged,
                _ => Decision::Unjudged,
            };
        }
        if unknown || secondary || !untested.is_empty() {
            return Decision::Unjudged;
        }
        let m = &self.scene.materials[lv.material as usize];
        let albedo = m.color.as_dvec3();
        // Each reached light's term by the course's rule, and the slack rounding allows.
        let mut t = DiffuseTerms::default();
        let lit_by = || (0..lights.len()).filter(|&li| reached[li].is_some());
        for li in lit_by() {
            let to = light_pos(li) - lv.point;
            let cos = lv.shade.dot(to.normalize_or_zero());
            let term = albedo * lights[li].color.as_dvec3();
            t.exact += term * cos.max(0.0);
            // The light's direction may be taken from the offset origin of the shadow ray, and
            // the normal is known to its rounding.
            let from_origin = kids
                .shadow
                .iter()
                .filter(|&&k| rays[k].light.is_none_or(|l| l as usize == li))
                .map(|&k| (cos - lv.shade.dot((light_pos(li) - rays[k].origin).normalize_or_zero())).abs())
                .fold(0.0, f64::max);
            t.slack += term.abs() * (from_origin + 2.0 * lv.un + 1e-6);
        }
        if fits(c, t.exact, t.slack) {
            return Decision::Judged;
        }
        let name = self.name(lv.entity);
        let lit: Vec<&str> = lit_by().map(|li| self.light_name(li as u32)).collect();
        let from = if lit.is_empty() {
            "no light (every shadow ray is blocked), so it is black".to_string()
        } else {
            format!("light{} {}", if lit.len() == 1 { "" } else { "s" }, lit.join(", "))
        };
        // A tracer that takes L in N·L from its own shadow rays, where those miss their lights,
        // makes the colour that follows from them: the sum along each reaching shadow ray.
        let mut along = DVec3::ZERO;
        let mut apart = 0.0f64;
        for (li, &k) in reached.iter().enumerate() {
            if let Some(k) = k {
                let s = &rays[k];
                along += albedo * lights[li].color.as_dvec3() * lv.shade.dot(s.direction.normalize_or_zero()).max(0.0);
                apart = apart.max(angle(s.direction, light_pos(li) - s.origin));
            }
        }
        if apart > self.tol.direction && fits(c, along, t.slack) {
            f.push(self.finding(
                r,
                kind,
                Code::ShadingShadowDirection,
                format!(
                    "diffuse '{name}' lit by {from}: your colour is the course's sum with L along your shadow rays, which point up to {:.3}° away from their lights",
                    apart.to_degrees()
                ),
                vec![colour_value(c, t.exact)],
            ));
            return Decision::Judged;
        }
        // The same terms by the usual mistakes, needed only for a colour that does not fit.
        for li in lit_by() {
            let to = light_pos(li) - lv.point;
            let cos = lv.shade.dot(to.normalize_or_zero());
            let cl = lights[li].color.as_dvec3();
            let term = albedo * cl;
            t.unclamped += term * cos;
            t.falloff += term * cos.max(0.0) / to.length_squared().max(1e-300);
            t.no_albedo += cl * cos.max(0.0);
            t.no_light += albedo * cos.max(0.0);
            t.flat += term * lv.facing.dot(to.normalize_or_zero()).max(0.0);
            t.unnormalised += term * lv.shade.dot(to).max(0.0);
            t.from_origin += term * lv.shade.dot(light_pos(li).normalize_or_zero()).max(0.0);
            t.light_twice += term * cl * cos.max(0.0);
            t.toward_eye += term * lv.shade.dot(-lv.parent_dir.normalize_or_zero()).max(0.0);
            t.first.get_or_insert(term * cos.max(0.0));
            t.last = Some(term * cos.max(0.0));
            t.reach = t.reach.max(to.length());
        }
        if lit.len() < 2 {
            (t.first, t.last) = (None, None);
        }
        let radius = match self.geo.prims(lv.entity) {
            [PrimRef::Sphere(i)] => Some(f64::from(self.scene.spheres[*i as usize].radius)),
            _ => None,
        };
        let guess = diffuse_guess(
            c,
            &t,
            albedo,
            (lv.shade - lv.facing).length() > 1e-9,
            lit.is_empty(),
            (lights.len(), radius),
        );
        let detail = match guess {
            Some(g) => format!("diffuse '{name}' lit by {from}: {g}"),
            None => format!(
                "diffuse '{name}' lit by {from}: your colour is not albedo × Σ light colour × max(0, N·L), nor any of the usual mistakes"
            ),
        };
        f.push(self.finding(r, kind, Code::ShadingDiffuse, detail, vec![colour_value(c, t.exact)]));
        Decision::Judged
    }

    /// A mirror hit: its colour is its reflected ray's.
    fn mirror(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        lv: &Leave,
        rays: &[LoggedRay],
        kids: &Children,
        f: &mut Vec<Finding>,
    ) -> Decision {
        let ([k], [], 0) = (kids.reflection, kids.refraction, kids.other) else {
            return Decision::Unjudged;
        };
        let (Some(c), Some(rc)) = (r.color, rays[*k].color) else {
            return Decision::Unjudged;
        };
        if fits(c, rc, DVec3::ZERO) {
            return Decision::Judged;
        }
        let tint = self.scene.materials[lv.material as usize].color.as_dvec3();
        // One factor for all three channels, where the reflected colour is not black.
        let factor = (rc.length_squared() > 1e-12)
            .then(|| c.dot(rc) / rc.length_squared())
            .filter(|&s| fits(c, rc * s, DVec3::ZERO));
        let detail = if fits(c, rc * tint, DVec3::ZERO) {
            format!(
                "mirror '{}': your colour is the reflected colour multiplied by the material colour {:?}; the course's mirror has no colour of its own",
                self.name(lv.entity),
                tint.to_array()
            )
        } else if let Some(s) = factor {
            format!(
                "mirror '{}': your colour is {s:.4} × what your reflected ray (line {}) brought back; the course's mirror reflects everything, a factor of 1",
                self.name(lv.entity),
                rays[*k].line
            )
        } else {
            format!(
                "mirror '{}': your colour is not what your reflected ray (line {}) brought back",
                self.name(lv.entity),
                rays[*k].line
            )
        };
        f.push(self.finding(r, kind, Code::ShadingMirror, detail, vec![colour_value(c, rc)]));
        Decision::Judged
    }

    /// A glass hit: the missing reflected ray, and the reflected share its colour was mixed with.
    #[allow(clippy::too_many_arguments)]
    fn glass(
        &self,
        r: &LoggedRay,
        kind: &Kind,
        lv: &Leave,
        rays: &[LoggedRay],
        kids: &Children,
        logs: &Logs,
        weight: &dyn Fn() -> f64,
        f: &mut Vec<Finding>,
    ) -> Decision {
        let ior = f64::from(self.scene.materials[lv.material as usize].value);
        let (n1, n2) = if lv.front { (1.0, ior) } else { (ior, 1.0) };
        let ci = (-lv.parent_dir.dot(lv.facing)).clamp(0.0, 1.0);
        let exact = fresnel(ci, n1, n2);
        let sin2_t = (n1 / n2).powi(2) * (1.0 - ci * ci);
        let name = self.name(lv.entity);
        let share = if kids.reflection.is_empty() && logs.secondary {
            weight() * exact
        } else {
            0.0
        };
        if share >= MIN_SHARE {
            f.push(self.finding(
                r,
                kind,
                Code::MissingReflection,
                format!(
                    "at '{name}' the Fresnel reflectance is {exact:.4} ({:.1} % of the sample), but no reflected ray was cast",
                    share * 100.0
                ),
                vec![Value {
                    what: "reflected share kr".into(),
                    yours: json!("no reflected ray"),
                    rayscope: njson(exact),
                }],
            ));
        }
        let Some(c) = r.color else {
            return Decision::Unjudged;
        };
        if (sin2_t - 1.0).abs() <= CRITICAL || kids.other > 0 || kids.refraction_wrong {
            return Decision::Unjudged;
        }
        let colour = |k: &[usize]| match k {
            [k] => rays[*k].color,
            _ => None,
        };
        // The course's mix multiplied by the glass's material colour, which plays no part here.
        let tint = self.scene.materials[lv.material as usize].color.as_dvec3();
        let tinted = |want: DVec3| {
            (tint != DVec3::ONE && !fits(c, want, DVec3::ZERO) && fits(c, want * tint, DVec3::ZERO)).then(|| {
                self.finding(
                    r,
                    kind,
                    Code::ShadingGlass,
                    format!(
                        "at '{name}' your colour is the course's mix of your reflected and refracted colours multiplied by the material colour {:?}; here the glass has no colour of its own",
                        tint.to_array()
                    ),
                    vec![colour_value(c, want)],
                )
            })
        };
        if sin2_t >= 1.0 {
            // Total internal reflection: everything is reflected.
            let (Some(rc), true) = (colour(kids.reflection), kids.refraction.is_empty()) else {
                return Decision::Unjudged;
            };
            if let Some(t) = tinted(rc) {
                f.push(t);
            } else if !fits(c, rc, DVec3::ZERO) {
                f.push(self.finding(
                    r,
                    kind,
                    Code::ShadingFresnel,
                    format!(
                        "at '{name}' the ray is past the critical angle (sin²θt = {sin2_t:.4} > 1), so all light is reflected (kr = 1); your colour is not your reflected ray's"
                    ),
                    vec![colour_value(c, rc)],
                ));
            }
            return Decision::Judged;
        }
        let (Some(rc), Some(tc)) = (colour(kids.reflection), colour(kids.refraction)) else {
            return Decision::Unjudged;
        };
        let unc = fresnel_uncertainty(ci, n1, n2, 2.0 * lv.un + 1e-6);
        let want = rc * exact + tc * (1.0 - exact);
        let kr_value = |k: Option<f64>| kr_value(k, exact);
        let fit = classify_glass(c, rc, tc, ci, n1, n2, unc);
        // The tint is said where no formula gives the colour; where one does too (with a black
        // tint, a black colour fits both), the hit cannot tell them apart and is left unjudged.
        if let Some(t) = tinted(want) {
            if !matches!(fit, GlassFit::Other(_) | GlassFit::NotAMix) {
                return Decision::Unjudged;
            }
            f.push(t);
            return Decision::Judged;
        }
        // The refracted colour added whole beside a weighted reflection: told from the plain
        // sum and from no reflection only where the reflected colour is not black.
        let unweighted_t = !matches!(fit, GlassFit::Exact)
            && !fits(rc, DVec3::ZERO, DVec3::ZERO)
            && fits(c, rc * exact + tc, DVec3::ZERO)
            && !fits(c, rc + tc, DVec3::ZERO);
        let (code, mut detail, values) = match fit {
            GlassFit::Exact => return Decision::Judged,
            _ if unweighted_t => (
                Code::ShadingTransmissionUnweighted,
                format!(
                    "at '{name}' your colour is kr·R + T with kr = {exact:.4}: your reflected colour weighted by the Fresnel reflectance and your refracted colour added whole, weights that add up to {:.4}, not 1",
                    1.0 + exact
                ),
                vec![colour_value(c, want)],
            ),
            GlassFit::Mistake(formula, k) => (
                formula.code(),
                format!(
                    "at '{name}' ({}, cos θi = {ci:.4}) your colour fits the reflected and refracted colours mixed by {}: kr = {:.4}; the Fresnel equations give {exact:.4}",
                    if lv.front { "entering" } else { "leaving" },
                    formula.describe(),
                    formula.kr(ci, n1, n2)
                ),
                vec![kr_value(k), colour_value(c, want)],
            ),
            // Colours of one hue are a "mix" for some share outside [0, 1] as well: the plain sum
            // is the simpler reading, and no share in [0, 1] gives it.
            GlassFit::Other(k)
                if fits(c, rc + tc, DVec3::ZERO) && k.is_some_and(|k| !(0.0..=1.0).contains(&k)) =>
            {
                (
                    Code::ShadingGlassSum,
                    format!(
                        "at '{name}' your colour is your reflected and refracted rays' colours added, R + T, with no weights; kr = {exact:.4} by the Fresnel equations"
                    ),
                    vec![colour_value(c, want)],
                )
            }
            GlassFit::NotAMix if fits(c, rc + tc, DVec3::ZERO) => (
                Code::ShadingGlassSum,
                format!(
                    "at '{name}' your colour is your reflected and refracted rays' colours added, R + T, with no weights; kr = {exact:.4} by the Fresnel equations"
                ),
                vec![colour_value(c, want)],
            ),
            GlassFit::Other(k) => (
                Code::ShadingFresnel,
                format!(
                    "at '{name}' ({}, cos θi = {ci:.4}) your colour fits the reflected and refracted colours mixed with kr = {:.4}; the Fresnel equations give {exact:.4}",
                    if lv.front { "entering" } else { "leaving" },
                    k.unwrap_or(f64::NAN)
                ),
                vec![kr_value(k), colour_value(c, want)],
            ),
            GlassFit::NotAMix => (
                Code::ShadingGlass,
                match solve_weights(c, rc, tc) {
                    Some((a, b)) => format!(
                        "at '{name}' your colour is {} + {}, weights that add up to {:.4}, not kr·R + (1 − kr)·T with kr = {exact:.4}",
                        weight_words(a, "R", exact),
                        weight_words(b, "T", exact),
                        a + b
                    ),
                    None => format!(
                        "at '{name}' your colour is no mix kr·R + (1 − kr)·T of your reflected and refracted rays' colours"
                    ),
                },
                vec![
                    colour_value(c, want),
                    Value {
                        what: "reflected colour R, refracted colour T".into(),
                        yours: json!([vjson(rc), vjson(tc)]),
                        rayscope: json!([vjson(rc), vjson(tc)]),
                    },
                ],
            ),
        };
        if matches!(code, Code::ShadingFresnelNone | Code::ShadingFresnel) && fits(c, rc + tc, DVec3::ZERO) {
            // One colour is black: the share read is also the two colours added, R + T.
            detail.push_str("; one of the two colours is black, so your colour is R + T as well");
        }
        f.push(self.finding(r, kind, code, detail, values));
        Decision::Judged
    }
}

/// The logged colour beside the one the course's rule gives.
fn colour_value(yours: DVec3, want: DVec3) -> Value {
    Value {
        what: "colour".into(),
        yours: vjson(yours),
        rayscope: vjson(want),
    }
}

/// Mirror and glass bounces before ray `i`: the number of its ancestors.
fn depth_of(i: usize, parent: &[Option<usize>]) -> u32 {
    let (mut d, mut k) = (0, i);
    while let Some(p) = parent[k] {
        d += 1;
        if d > 64 {
            break;
        }
        k = p;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    const R: DVec3 = DVec3::new(0.8, 0.2, 0.5);
    const T: DVec3 = DVec3::new(0.1, 0.6, 0.3);

    /// The colour a tracer mixing by `kr` brings back, rounded to f32 as such a tracer logs it.
    fn mixed(kr: f64) -> DVec3 {
        (R * kr + T * (1.0 - kr)).as_vec3().as_dvec3()
    }

    #[test]
    fn the_exact_share_is_accepted_entering_and_leaving() {
        for (ci, n1, n2) in [
            (1.0, 1.0, 1.4),
            (0.6, 1.0, 1.4),
            (0.1, 1.0, 1.4),
            (0.9, 1.4, 1.0),
            (0.75, 1.5, 1.0),
        ] {
            let k = fresnel(ci, n1, n2);
            assert_eq!(
                classify_glass(mixed(k), R, T, ci, n1, n2, 1e-6),
                GlassFit::Exact,
                "{ci} {n1} {n2}"
            );
        }
    }

    #[test]
    fn each_mistaken_share_is_recognised() {
        // Entering at 69.5° from the normal; leaving at 41.4°, short of the critical angle.
        for (ci, n1, n2) in [(0.35, 1.0, 1.4), (0.75, 1.4, 1.0)] {
            for (f, code) in [
                (Formula::Schlick, Code::ShadingFresnelSchlick),
                (Formula::RsOnly, Code::ShadingFresnelSwappedCosines),
                (Formula::RpOnly, Code::ShadingFresnelSwappedCosines),
                (Formula::Half, Code::ShadingFresnelHalf),
                (Formula::NoFresnel, Code::ShadingFresnelNone),
                (Formula::WeightsExchanged, Code::ShadingFresnelWeightsExchanged),
            ] {
                let k = f.kr(ci, n1, n2);
                match classify_glass(mixed(k), R, T, ci, n1, n2, 1e-6) {
                    GlassFit::Mistake(g, Some(solved)) => {
                        assert_eq!(g.code(), code, "{f:?} from {n1} into {n2}");
                        assert!((solved - k).abs() < 1e-5, "{f:?}: solved {solved}, used {k}");
                    }
                    other => panic!("{f:?} from {n1} into {n2}: {other:?}"),
                }
            }
        }
    }

    #[test]
    fn exchanging_both_cosines_is_the_exact_share() {
        // rs and rp with cos θi and cos θt exchanged are −rp and −rs: their mean square is the same.
        let (ci, n1, n2) = (0.4_f64, 1.0, 1.4);
        let ct = cos_t(ci, n1, n2).unwrap();
        let rs = (n1 * ct - n2 * ci) / (n1 * ct + n2 * ci);
        let rp = (n2 * ct - n1 * ci) / (n2 * ct + n1 * ci);
        assert!((0.5 * (rs * rs + rp * rp) - fresnel(ci, n1, n2)).abs() < 1e-15);
    }

    #[test]
    fn another_share_is_given_with_its_value_and_a_non_mix_is_named() {
        let (ci, n1, n2) = (0.5, 1.0, 1.4);
        match classify_glass(mixed(0.3), R, T, ci, n1, n2, 1e-6) {
            GlassFit::Other(Some(k)) => assert!((k - 0.3).abs() < 1e-5),
            other => panic!("{other:?}"),
        }
        // The glass colour multiplied in: no weights summing to 1 give it.
        let tinted = mixed(fresnel(ci, n1, n2)) * DVec3::new(1.0, 0.5, 0.5);
        assert_eq!(classify_glass(tinted, R, T, ci, n1, n2, 1e-6), GlassFit::NotAMix);
    }

    #[test]
    fn total_internal_reflection_reflects_everything() {
        // Leaving glass of index 1.4 at cos θi = 0.5 (60°) is past the critical angle (45.6°).
        assert_eq!(cos_t(0.5, 1.4, 1.0), None);
        assert_eq!(fresnel(0.5, 1.4, 1.0), 1.0);
        assert_eq!(classify_glass(R, R, T, 0.5, 1.4, 1.0, 1e-6), GlassFit::Exact);
        assert!(matches!(
            classify_glass(T, R, T, 0.5, 1.4, 1.0, 1e-6),
            GlassFit::Mistake(Formula::NoFresnel, _) | GlassFit::Other(_)
        ));
    }

    #[test]
    fn colours_within_f32_rounding_fit_and_a_visible_difference_does_not() {
        let c = DVec3::new(0.25, 0.0, 3.0);
        assert!(fits(
            c.as_vec3().as_dvec3() + DVec3::new(0.0, 5e-6, 0.0),
            c,
            DVec3::ZERO
        ));
        assert!(!fits(c + DVec3::new(0.0, 0.0, 1e-3), c, DVec3::ZERO));
        assert!(!fits(DVec3::splat(f64::NAN), c, DVec3::ZERO));
    }
}

/// Each reached light's diffuse term summed by the course's rule and by the usual mistakes, and
/// the slack a colour may differ from them by rounding.
#[derive(Default)]
struct DiffuseTerms {
    exact: DVec3,
    unclamped: DVec3,
    falloff: DVec3,
    no_albedo: DVec3,
    no_light: DVec3,
    flat: DVec3,
    /// N·L with L = light − point not normalised: each term times the light's distance.
    unnormalised: DVec3,
    /// N·L with L the light's position normalised, the hit point left out of light − point.
    from_origin: DVec3,
    /// Each light's colour multiplied in twice.
    light_twice: DVec3,
    /// The first and the last lit light's terms alone, where two or more lights are lit.
    first: Option<DVec3>,
    last: Option<DVec3>,
    /// N·V, the cosine toward where the ray came from, in place of each light's N·L.
    toward_eye: DVec3,
    /// The distance to the farthest light that is reached, which scales `unnormalised`'s slack.
    reach: f64,
    slack: DVec3,
}

/// Which usual mistake a diffuse colour `c` fits, in words (`smooth`: the hit has an
/// interpolated normal; `unlit`: every shadow ray is blocked; `lights`: the scene's lights, and
/// the radius of the sphere hit where it is one).
fn diffuse_guess(
    c: DVec3,
    t: &DiffuseTerms,
    albedo: DVec3,
    smooth: bool,
    unlit: bool,
    (lights, radius): (usize, Option<f64>),
) -> Option<String> {
    let diff = c - t.exact;
    let ambient_k = (albedo.length_squared() > 0.0)
        .then(|| diff.dot(albedo) / albedo.length_squared())
        .filter(|&k| k > 1e-4 && fits(c, t.exact + albedo * k, t.slack));
    let scale = (t.exact.length_squared() > 0.0)
        .then(|| c.dot(t.exact) / t.exact.length_squared())
        .filter(|&s| (s - 1.0).abs() > 1e-4 && fits(c, t.exact * s, t.slack * s.abs().max(1.0)))
        // On a hit one light reaches, any mistake in N·L is some factor: only a plain fraction,
        // or a sphere's radius, is worth a name.
        .filter(|&s| plain_fraction(s) || radius_factor(s, radius).is_some());
    let constant = (diff.x + diff.y + diff.z) / 3.0;
    // A wrong rule's colour that `c` fits and the course's does not.
    let only = |wrong: DVec3| fits(c, wrong, t.slack) && !fits(wrong, t.exact, t.slack);
    let twice = only(t.light_twice);
    if smooth && fits(c, t.flat, t.slack) {
        Some("it fits the triangle's face normal instead of the mesh's normal interpolated from its vertices' vn normals (flat shading)".to_string())
    } else if fits(c, t.unclamped, t.slack) {
        Some("it fits N·L without the clamp at 0: a light behind the surface subtracts".to_string())
    } else if fits(c, t.falloff, t.slack) {
        Some("it fits each light divided by its squared distance: the course's point lights do not fall off".into())
    } else if only(t.from_origin) {
        Some(
            "it fits N·L with L = the light's position normalised: the hit point is left out of L = light − point"
                .into(),
        )
    } else if fits(c, t.unnormalised, t.slack * t.reach.max(1.0)) {
        Some("it fits N·L with L = light − point not normalised (each light's term times its distance): normalise L before the dot product".into())
    } else if fits(c, t.no_light, t.slack) {
        Some(if fits(c, t.no_albedo, t.slack) {
            "it fits the albedo without the lights' colour or, the same on this hit (the albedo is the lights' colour), the lights' colour without the albedo".into()
        } else {
            "it fits the albedo without the lights' colour".into()
        })
    } else if fits(c, t.no_albedo, t.slack) {
        Some("it fits the lights' colour without the surface's albedo".into())
    } else if t.first.is_some_and(only) {
        Some("it fits the first lit light's term alone: the sum over the lights stops after the first light that reaches the surface".into())
    } else if t.last.is_some_and(only) {
        Some("it fits the last lit light's term alone: each light's term replaces the sum (sum = …) instead of adding to it (sum += …)".into())
    } else if only(t.toward_eye) {
        Some("it fits N·V, the cosine toward where the ray came from, in place of N·L toward each light: L is the direction from the hit point to the light".into())
    } else if twice && scale.is_none() {
        Some("it fits each light's colour multiplied in twice, albedo × light colour² × N·L: the course multiplies by it once".into())
    } else if let Some(s) = scale {
        let mut factor = scale_words(s, lights, radius);
        if twice {
            // Under lights of one grey, each light's colour taken twice is the sum times it.
            factor.push_str(" or, the same under these lights, each light's colour multiplied in twice (albedo × light colour² × N·L)");
        }
        Some(match ambient_k {
            // Under white lights the course's sum is a multiple of the albedo, so one hit
            // cannot tell a factor from an added term: the number that stays the same over
            // every hit can.
            Some(k) => format!(
                "it fits the course's sum × {s:.4}{factor} or, the same on this hit, an ambient term of {k:.4} × the albedo added: whichever number is the same on every hit is yours (the course has neither at stage 2)"
            ),
            None => format!(
                "it fits the course's sum × {s:.4} in every channel{factor}: a factor the course does not have"
            ),
        })
    } else if let Some(k) = ambient_k {
        Some(if unlit {
            format!("it fits an ambient term of {k:.4} × the albedo added: the course has no ambient term at stage 2")
        } else {
            format!(
                "it fits an ambient term of {k:.4} × the albedo added, if that is the same on every hit (the course has none at stage 2); one that varies from hit to hit is a wrong N·L instead"
            )
        })
    } else if constant > 1e-4 && fits(c, t.exact + DVec3::splat(constant), t.slack) {
        Some(format!(
            "it fits a constant {constant:.4} added to every channel: the course has no ambient term at stage 2"
        ))
    } else {
        None
    }
}

/// True when `s` is p/q with q at most 8, to the precision a logged colour carries.
fn plain_fraction(s: f64) -> bool {
    (1..=8).any(|q| {
        let p = (s * f64::from(q)).round();
        p >= 1.0 && (s * f64::from(q) - p).abs() <= 1e-4 * f64::from(q)
    })
}

/// What a factor `s` on the course's diffuse sum may come from, as words to follow it (empty
/// when no usual cause gives exactly that factor); `lights`: the scene's lights.
/// A diffuse factor `s` that is the hit sphere's radius (other than 1), or its reciprocal: the
/// length of a sphere normal divided by the radius not at all, or twice.
fn radius_factor(s: f64, radius: Option<f64>) -> Option<String> {
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-4 * b.abs().max(1e-30);
    match radius {
        Some(r) if !near(r, 1.0) && near(s, r) => Some(format!(
            " (the sphere's radius, {r}: a normal P − C not divided by the radius is that long, not 1)"
        )),
        Some(r) if !near(r, 1.0) && near(s, 1.0 / r) => Some(format!(
            " (1 / the sphere's radius, {r}: a normal divided by the radius twice is that long, not 1)"
        )),
        _ => None,
    }
}

fn scale_words(s: f64, lights: usize, radius: Option<f64>) -> String {
    if let Some(words) = radius_factor(s, radius) {
        return words;
    }
    if lights > 1 && (s * lights as f64 - 1.0).abs() < 1e-4 {
        format!(" (the sum over the {lights} lights divided by their number: the course adds them)")
    } else {
        String::new()
    }
}

/// How far the Fresnel reflectance at cos θi = `ci` may be off when the normal is known to
/// `delta` radians (the reflectance is steep near the critical angle).
fn fresnel_uncertainty(ci: f64, n1: f64, n2: f64, delta: f64) -> f64 {
    let exact = fresnel(ci, n1, n2);
    let sin_i = (1.0 - ci * ci).max(0.0).sqrt();
    let lo = fresnel((ci - delta * sin_i).clamp(0.0, 1.0), n1, n2);
    let hi = fresnel((ci + delta * sin_i).clamp(0.0, 1.0), n1, n2);
    (lo - exact).abs().max((hi - exact).abs()) + 1e-6
}

/// The reflected share kr the tracer used (when its colours tell) beside the exact one.
fn kr_value(k: Option<f64>, exact: f64) -> Value {
    Value {
        what: "reflected share kr".into(),
        yours: k.map_or(
            json!("not determined (the reflected and refracted colours are alike)"),
            njson,
        ),
        rayscope: njson(exact),
    }
}
