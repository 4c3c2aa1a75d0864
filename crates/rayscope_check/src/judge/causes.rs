//! One mistake, one headline: within a pixel sample's ray tree, the first ray that went wrong is
//! the cause, and the verdicts on the rays below it are its consequences.
//!
//! A ray inherits what its parent hit (point, normal, material) and the direction its parent's
//! mistake gave it, so a verdict below a wrong ray says more about the ray above than about the
//! code that cast it. Verdicts on how a surface's colour was put together, and on rays that were
//! never cast, are not handed down: a child's own rays are judged from its own start.

use rustc_hash::FxHashSet;
use serde::Serialize;

use super::Finding;
use crate::verdict::Code;

/// A root cause: the first wrong verdict on a ray with no wrong ray above it, and the code it
/// cannot be told apart from on that ray, when there is one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub struct Cause {
    /// The verdict.
    pub code: Code,
    /// A second verdict the same rays fit as well (both fixes are named).
    pub or: Option<Code>,
}

impl Cause {
    /// The cause of verdict `code` alone.
    #[must_use]
    pub const fn of(code: Code) -> Cause {
        Cause { code, or: None }
    }

    /// The codes of the cause, first the one reports lead with.
    #[must_use]
    pub fn codes(self) -> Vec<Code> {
        std::iter::once(self.code).chain(self.or).collect()
    }

    /// The cause's name as reports print it: `a` or `a | b`.
    #[must_use]
    pub fn name(self) -> String {
        match self.or {
            Some(b) => format!("{} | {}", self.code.as_str(), b.as_str()),
            None => self.code.as_str().to_string(),
        }
    }
}

/// Pairs of verdicts the rays of one mistake fit equally well: the second is named beside the
/// first as one cause.
const SAME_RAYS: &[(Code, Code)] = &[
    // Leaving glass with the outward normal and the entering indices bends the ray exactly as
    // either mistake alone would in some other place: the ray cannot say which of the two it was.
    (Code::RefractionNormalNotFlipped, Code::RefractionIndicesNotSwapped),
    // Entering glass, a reflection where the ray refracts fits a critical-angle test with the
    // leaving side's ratio and a ratio upside down alike (the log as a whole decides).
    (Code::RefractionTirInvented, Code::RefractionIndicesNotSwapped),
    // A camera ray a fraction of a pixel from its sample's place fits another sub-pixel layout
    // and a slightly scaled image plane alike (the log as a whole decides).
    (Code::CameraSubpixelGrid, Code::CameraPlaneDistance),
];

/// Verdicts that are one mistake wherever they show: merged into the first as one cause.
const SAME_MISTAKE: &[(Code, Code)] = &[
    // A one-sided triangle test lets camera, secondary and shadow rays alike through back faces.
    (Code::ShadowOneSidedTriangle, Code::HitOneSidedTriangle),
];

/// Causes on sibling rays (cast from the same hit) that one mistake at that hit explains: the
/// first is counted as a consequence of the second. Leaving glass with the outward normal both
/// offsets the reflected ray behind the surface and bends the refracted ray back in.
const SAME_HIT: &[(Code, Code)] = &[(Code::SecondaryOffsetWrongSide, Code::RefractionNormalNotFlipped)];

/// True when a wrong verdict on a ray can explain verdicts on the rays cast from its hit.
fn handed_down(code: Code) -> bool {
    !code.is_excused()
        && !matches!(code, Code::RefractionTirInvented)
        && !code.as_str().starts_with("shading.")
        && !code.as_str().starts_with("missing.")
}

/// The cause a ray's wrong verdicts stand for, with how many of its other verdicts follow from it.
fn cause_of(own: &[&Finding]) -> Cause {
    let code = own[0].code;
    let or = own[1..]
        .iter()
        .map(|f| f.code)
        .find(|&c| SAME_RAYS.contains(&(code, c)) || SAME_RAYS.contains(&(c, code)));
    merged(Cause { code, or })
}

/// The cause under which a verdict that is one mistake with another is counted.
fn merged(c: Cause) -> Cause {
    match SAME_MISTAKE
        .iter()
        .find(|(a, b)| c.or.is_none() && (c.code == *a || c.code == *b))
    {
        Some(&(a, b)) => Cause { code: a, or: Some(b) },
        None => c,
    }
}

/// What one pixel sample's verdicts come to.
#[derive(Debug, Default)]
pub struct SampleCauses {
    /// Rays that are a cause: (ray, cause).
    pub roots: Vec<(usize, Cause)>,
    /// Wrong verdicts that follow from a cause: (cause, code).
    pub consequences: Vec<(Cause, Code)>,
}

impl SampleCauses {
    /// The distinct causes of the sample.
    #[must_use]
    pub fn distinct(&self) -> Vec<Cause> {
        let mut seen = FxHashSet::default();
        self.roots.iter().map(|r| r.1).filter(|c| seen.insert(*c)).collect()
    }
}

/// Finds the causes among a sample's verdicts: `order` lists the rays parents first, `parent`
/// links them, `findings` holds each ray's verdicts in the order they were found (how the ray
/// was made before what it met).
#[must_use]
pub fn causes(order: &[usize], parent: &[Option<usize>], findings: &[Vec<Finding>]) -> SampleCauses {
    let mut out = SampleCauses::default();
    // The cause each ray hands down to the rays cast from its hit.
    let mut blame: Vec<Option<Cause>> = vec![None; findings.len()];
    for &i in order {
        let inherited = parent[i].and_then(|p| blame[p]);
        let wrong: Vec<&Finding> = findings[i].iter().filter(|f| !f.code.is_excused()).collect();
        if wrong.is_empty() {
            blame[i] = inherited;
            continue;
        }
        if let Some(c) = inherited {
            out.consequences.extend(wrong.iter().map(|f| (c, f.code)));
            blame[i] = Some(c);
            continue;
        }
        let c = cause_of(&wrong);
        out.roots.push((i, c));
        out.consequences.extend(
            wrong[1..]
                .iter()
                .filter(|f| Some(f.code) != c.or && f.code != c.code)
                .map(|f| (c, f.code)),
        );
        blame[i] = handed_down(c.code).then_some(c);
    }
    fold_siblings(&mut out, parent);
    fold_into_child(&mut out, parent);
    out
}

/// Folds a root into a sibling's cause where one mistake at their parent's hit explains both.
fn fold_siblings(out: &mut SampleCauses, parent: &[Option<usize>]) {
    let mut k = 0;
    while k < out.roots.len() {
        let (i, c) = out.roots[k];
        let by = out.roots.iter().find(|&&(j, d)| {
            j != i && parent[j].is_some() && parent[j] == parent[i] && SAME_HIT.contains(&(c.code, d.code))
        });
        match by {
            Some(&(_, d)) => {
                out.consequences.push((d, c.code));
                for x in &mut out.consequences {
                    if x.0 == c {
                        x.0 = d;
                    }
                }
                out.roots.remove(k);
            }
            None => k += 1,
        }
    }
}

/// Causes on a ray (a code, or a family ending in '.') that a cause on one of the rays cast from
/// its hit explains (the start of its code). A missing reflected ray at glass whose refracted ray
/// bends wrong: the tracer's Fresnel weight comes from the same wrong indices or normal. A
/// diffuse colour that takes N·L along shadow rays that miss their lights: the shadow rays'
/// direction is the mistake. Any colour judged from children that logged their colours already
/// weighted: judged from those, it cannot come out right.
const FROM_CHILD: &[(&str, &str)] = &[
    ("missing.reflection", "refraction."),
    ("shading.shadow-direction", "shadow.not-at-light"),
    ("shading.shadow-direction", "shadow.other-light"),
    ("shading.", "shading.logged-weighted"),
];

/// Folds a root into the cause of a ray cast from its hit where [`FROM_CHILD`] says that cause
/// explains it.
fn fold_into_child(out: &mut SampleCauses, parent: &[Option<usize>]) {
    // Rays whose cause was folded into another, with that cause: a ray above them folds into it
    // in turn (glass above glass above the ray the mistake is on).
    let mut joined: Vec<(usize, Cause)> = Vec::new();
    loop {
        let before = out.roots.len();
        let mut k = 0;
        while k < out.roots.len() {
            let (i, c) = out.roots[k];
            let name = c.code.as_str();
            let of = |p: &str| {
                if p.ends_with('.') {
                    name.starts_with(p)
                } else {
                    name == p
                }
            };
            let by = FROM_CHILD.iter().filter(|(p, _)| of(p)).find_map(|&(_, child)| {
                out.roots
                    .iter()
                    .chain(&joined)
                    .find(|&&(j, d)| parent[j] == Some(i) && d.code.as_str().starts_with(child))
                    .map(|&(_, d)| d)
            });
            match by {
                Some(d) => {
                    out.consequences.push((d, c.code));
                    joined.push((i, d));
                    out.roots.remove(k);
                }
                None => k += 1,
            }
        }
        if out.roots.len() == before {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::log::LoggedRay;

    fn finding(code: Code) -> Finding {
        let r = LoggedRay::for_tests([0, 0], 0, 1);
        Finding {
            code,
            line: r.line,
            pixel: r.pixel,
            sample: r.sample,
            id: None,
            kind: "ray".into(),
            detail: String::new(),
            values: vec![],
            entity: None,
        }
    }

    #[test]
    fn verdicts_below_a_wrong_ray_are_its_consequences() {
        // camera ray 0 with a wrong normal; its shadow ray 1 and reflection 2 go wrong with it;
        // reflection 2's own child 3 too.
        let parent = [None, Some(0), Some(0), Some(2)];
        let findings = vec![
            vec![finding(Code::HitNormalNotUnit)],
            vec![finding(Code::ShadowPhantomBlocker)],
            vec![finding(Code::ReflectionNotMirror), finding(Code::HitPhantom)],
            vec![finding(Code::HitMissed)],
        ];
        let c = causes(&[0, 1, 2, 3], &parent, &findings);
        let root = Cause::of(Code::HitNormalNotUnit);
        assert_eq!(c.roots, vec![(0, root)]);
        assert_eq!(c.consequences.len(), 4);
        assert!(c.consequences.iter().all(|(k, _)| *k == root));
    }

    #[test]
    fn separate_branches_are_separate_causes_and_ties_blame_nothing() {
        let parent = [None, Some(0), Some(0), Some(1)];
        let findings = vec![
            vec![finding(Code::TieGrazing)],
            vec![finding(Code::SecondaryAcne), finding(Code::HitFarther)],
            vec![finding(Code::ShadowAcne)],
            vec![finding(Code::HitMissed)],
        ];
        let c = causes(&[0, 1, 2, 3], &parent, &findings);
        let codes: Vec<Code> = c.roots.iter().map(|r| r.1.code).collect();
        assert_eq!(codes, vec![Code::SecondaryAcne, Code::ShadowAcne]);
        assert_eq!(c.consequences.len(), 2, "{:?}", c.consequences);
    }

    #[test]
    fn verdicts_the_rays_cannot_tell_apart_are_one_cause_with_both_names() {
        let parent = [None, Some(0)];
        let findings = vec![
            vec![],
            vec![
                finding(Code::RefractionNormalNotFlipped),
                finding(Code::RefractionIndicesNotSwapped),
                finding(Code::SecondaryOffsetWrongSide),
                finding(Code::SecondaryAcne),
            ],
        ];
        let c = causes(&[0, 1], &parent, &findings);
        assert_eq!(
            c.roots,
            vec![(
                1,
                Cause {
                    code: Code::RefractionNormalNotFlipped,
                    or: Some(Code::RefractionIndicesNotSwapped)
                }
            )]
        );
        let follow: Vec<Code> = c.consequences.iter().map(|x| x.1).collect();
        assert_eq!(follow, vec![Code::SecondaryOffsetWrongSide, Code::SecondaryAcne]);
    }

    #[test]
    fn a_one_sided_triangle_test_is_one_cause_for_every_kind_of_ray() {
        let parent = [None, None];
        let findings = vec![
            vec![finding(Code::HitOneSidedTriangle)],
            vec![finding(Code::ShadowOneSidedTriangle)],
        ];
        let c = causes(&[0, 1], &parent, &findings);
        assert_eq!(c.distinct().len(), 1, "{:?}", c.roots);
    }

    #[test]
    fn one_mistake_at_a_hit_that_shows_on_both_children_is_one_cause() {
        // Leaving glass with the outward normal: the reflection starts behind the surface, the
        // refraction bends back in.
        let parent = [None, Some(0), Some(0)];
        let findings = vec![
            vec![],
            vec![finding(Code::SecondaryOffsetWrongSide)],
            vec![finding(Code::RefractionNormalNotFlipped)],
        ];
        let c = causes(&[0, 1, 2], &parent, &findings);
        let codes: Vec<Code> = c.roots.iter().map(|r| r.1.code).collect();
        assert_eq!(codes, vec![Code::RefractionNormalNotFlipped]);
        assert_eq!(c.consequences.len(), 1);
    }

    #[test]
    fn a_colour_verdict_does_not_blame_the_rays_below() {
        // A verdict on how the colour was mixed leaves the children to be judged on their own.
        let parent = [None, Some(0)];
        let findings = vec![
            vec![finding(Code::RefractionTirInvented)],
            vec![finding(Code::HitMissed)],
        ];
        let c = causes(&[0, 1], &parent, &findings);
        assert_eq!(c.roots.len(), 2);
    }

    #[test]
    fn a_colour_made_with_a_wrong_shadow_ray_follows_from_that_ray_alone() {
        // Camera ray 0's diffuse colour takes N·L along its shadow ray 1, which misses its light;
        // shadow ray 2, aimed right, has nothing to add. A diffuse colour wrong on its own terms
        // stays a cause.
        let parent = [None, Some(0), Some(0)];
        let findings = vec![
            vec![finding(Code::ShadingShadowDirection)],
            vec![finding(Code::ShadowNotAtLight)],
            vec![],
        ];
        let c = causes(&[0, 1, 2], &parent, &findings);
        assert_eq!(c.roots, vec![(1, Cause::of(Code::ShadowNotAtLight))]);
        assert_eq!(
            c.consequences,
            vec![(Cause::of(Code::ShadowNotAtLight), Code::ShadingShadowDirection)]
        );
        let findings = vec![
            vec![finding(Code::ShadingDiffuse)],
            vec![finding(Code::ShadowNotAtLight)],
            vec![],
        ];
        assert_eq!(causes(&[0, 1, 2], &parent, &findings).roots.len(), 2);
    }
}
