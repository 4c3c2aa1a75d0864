//! Glass trees: rayscope's rays of a sample, recorded as an expression that gives the sample's
//! colour for any Fresnel weight at its glass hits. The rays a glass hit sends on do not depend
//! on its weight, so the same rays with other weights are what a tracer with another weight
//! computes: each glass hit's colour is `a ∘ (F·R + (1 − F)·T)` of its reflected and refracted
//! rays' colours, a mirror's `a ∘ R`, with `a` the hit's own factor (Beer's-law absorption, 1
//! elsewhere), and everything else (a diffuse hit with its shadow rays, the background) a
//! constant.

use glam::Vec3A;
use rayon::prelude::*;

use crate::integrator::{Counters, Integrator};
use crate::math::Ray;
use crate::observer::{BranchFate, GlassDecision, RayKind, RayObserver};
use crate::scene::{Intersect, Scene};
use crate::surface::Surface;

/// Rays a sample may record before it is left out (a tree that large is no course scene's).
const MAX_RAYS: usize = 4096;

/// A glass hit at which the tree splits into a reflected and a refracted ray.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct GlassHit {
    /// The ray enters the glass.
    pub(crate) entering: bool,
    /// Cosine of the angle of incidence.
    pub(crate) cos_i: f64,
    /// Index of refraction on the incoming side.
    pub(crate) n1: f64,
    /// Index of refraction on the far side.
    pub(crate) n2: f64,
    /// The course's Fresnel weight there, as rayscope computed it.
    pub(crate) course: f64,
}

/// One step of a tree, in an order where children come before their parent; the root is last.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Op {
    /// A colour that no glass weight changes.
    Leaf([f64; 3]),
    /// `a ∘ child`: a mirror, or glass under total internal reflection.
    Gain { a: [f64; 3], child: u32 },
    /// `a ∘ (F·r + (1 − F)·t)` with F the weight at [`GlassHit`] `hit` of the pixel's list.
    Glass {
        a: [f64; 3],
        hit: u32,
        r: Option<u32>,
        t: Option<u32>,
    },
}

/// The samples of one pixel as glass trees, with the student's bytes there.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PixelTrees {
    /// Row-major index of the pixel.
    pub(crate) index: u32,
    /// The student's bytes.
    pub(crate) theirs: [u8; 3],
    /// Each sample's tree, its ops.
    trees: Vec<Vec<Op>>,
    /// The glass hits the trees split at.
    pub(crate) hits: Vec<GlassHit>,
}

/// A recorded ray: its parent, kind, glass split and colour.
struct Node {
    parent: Option<u32>,
    kind: RayKind,
    glass: Option<GlassDecision>,
    value: Vec3A,
}

/// Records the camera, reflected and refracted rays of one sample.
#[derive(Default)]
struct Recorder {
    nodes: Vec<Node>,
    overflow: bool,
}

impl RayObserver for Recorder {
    const ENABLED: bool = true;

    fn ray(&mut self, parent: Option<u32>, kind: RayKind, _depth: u32, _ray: &Ray, _t_max: f32) -> u32 {
        let kept = matches!(kind, RayKind::Camera | RayKind::Reflection | RayKind::Refraction);
        if !kept || self.nodes.len() >= MAX_RAYS {
            self.overflow |= kept;
            return u32::MAX;
        }
        self.nodes.push(Node {
            parent: parent.filter(|&p| p != u32::MAX),
            kind,
            glass: None,
            value: Vec3A::ZERO,
        });
        (self.nodes.len() - 1) as u32
    }

    fn hit(&mut self, _id: u32, _scene: &Scene, _t: f32, _s: &Surface) {}

    fn glass(&mut self, id: u32, decision: &GlassDecision) {
        if let Some(n) = self.nodes.get_mut(id as usize) {
            n.glass = Some(*decision);
        }
    }

    fn result(&mut self, id: u32, _weight: f32, value: Vec3A) {
        if let Some(n) = self.nodes.get_mut(id as usize) {
            n.value = value;
        }
    }
}

/// The per-channel factor `a` with `value = a ∘ sum`: 1 where the sum is too small to tell.
fn factor(value: Vec3A, sum: Vec3A) -> [f64; 3] {
    std::array::from_fn(|c| {
        let (v, s) = (f64::from(value[c]), f64::from(sum[c]));
        if s.abs() > 1e-6 {
            v / s
        } else {
            1.0
        }
    })
}

/// Builds the ops of a recorded sample into `ops` and its glass hits into `hits`; `None` where
/// its glass chose one ray at random (a path tracer's sampled glass) or it recorded too many.
fn build(rec: &Recorder, hits: &mut Vec<GlassHit>) -> Option<Vec<Op>> {
    if rec.overflow || rec.nodes.is_empty() {
        return None;
    }
    let mut children: Vec<Vec<u32>> = vec![Vec::new(); rec.nodes.len()];
    for (i, n) in rec.nodes.iter().enumerate() {
        if let Some(p) = n.parent {
            children.get_mut(p as usize)?.push(i as u32);
        }
    }
    // Parents come before children: building from the last node back, each node's children
    // are built before it. `at[i]` is node i's op, and whether its subtree holds glass.
    let mut ops = Vec::new();
    let mut at: Vec<Option<(u32, bool)>> = vec![None; rec.nodes.len()];
    for i in (0..rec.nodes.len()).rev() {
        let n = &rec.nodes[i];
        let child = |kind: RayKind| {
            children[i]
                .iter()
                .find(|&&c| rec.nodes[c as usize].kind == kind)
                .map(|&c| (c, at[c as usize]))
        };
        let leaf = Op::Leaf(n.value.to_array().map(f64::from));
        let op = match (n.glass, child(RayKind::Reflection), child(RayKind::Refraction)) {
            (Some(g), r, t) if !g.tir => {
                if [g.reflected.fate, g.refracted.fate].contains(&BranchFate::NotChosen) {
                    return None;
                }
                let kr = g.reflectance;
                let value =
                    |c: Option<(u32, Option<(u32, bool)>)>| c.map_or(Vec3A::ZERO, |(c, _)| rec.nodes[c as usize].value);
                let sum = value(r) * kr + value(t) * (1.0 - kr);
                hits.push(GlassHit {
                    entering: g.entering,
                    cos_i: f64::from(g.cos_i),
                    n1: f64::from(g.n1),
                    n2: f64::from(g.n2),
                    course: f64::from(kr),
                });
                Some(Op::Glass {
                    a: factor(n.value, sum),
                    hit: (hits.len() - 1) as u32,
                    r: r.and_then(|(_, o)| o).map(|o| o.0),
                    t: t.and_then(|(_, o)| o).map(|o| o.0),
                })
            }
            (_, Some((c, Some((op, true)))), None) => Some(Op::Gain {
                a: factor(n.value, rec.nodes[c as usize].value),
                child: op,
            }),
            _ => None,
        };
        let glass = op.is_some();
        ops.push(op.unwrap_or(leaf));
        at[i] = Some(((ops.len() - 1) as u32, glass));
    }
    // Built from the last node back, the camera ray's op is the last one.
    at[0].filter(|&(_, glass)| glass).map(|_| ops)
}

impl PixelTrees {
    /// The pixel's colour, in levels (255 × the mean of its samples), with `weight` giving the
    /// Fresnel weight at each glass hit and its derivatives by the `p` parameters of a family;
    /// `grad` receives those of the colour.
    pub(crate) fn eval(
        &self,
        weight: &dyn Fn(&GlassHit, &mut [f64]) -> f64,
        p: usize,
        grad: &mut [[f64; 3]],
    ) -> [f64; 3] {
        let weights: Vec<(f64, Vec<f64>)> = self
            .hits
            .iter()
            .map(|h| {
                let mut g = vec![0.0; p];
                let f = weight(h, &mut g);
                (f, g)
            })
            .collect();
        let mut total = [0.0; 3];
        for g in grad.iter_mut().take(p) {
            *g = [0.0; 3];
        }
        let k = 255.0 / self.trees.len() as f64;
        for ops in &self.trees {
            let mut vals: Vec<[f64; 3]> = Vec::with_capacity(ops.len());
            let mut grads: Vec<Vec<[f64; 3]>> = Vec::with_capacity(ops.len());
            for op in ops {
                let (v, g) = match *op {
                    Op::Leaf(v) => (v, vec![[0.0; 3]; p]),
                    Op::Gain { a, child } => {
                        let (v, g) = (vals[child as usize], &grads[child as usize]);
                        (mul(a, v), g.iter().map(|&d| mul(a, d)).collect())
                    }
                    Op::Glass { a, hit, r, t } => {
                        let (f, df) = &weights[hit as usize];
                        let zero = vec![[0.0; 3]; p];
                        let (rv, rg) = r.map_or(([0.0; 3], &zero), |r| (vals[r as usize], &grads[r as usize]));
                        let (tv, tg) = t.map_or(([0.0; 3], &zero), |t| (vals[t as usize], &grads[t as usize]));
                        let v: [f64; 3] = std::array::from_fn(|c| a[c] * (f * rv[c] + (1.0 - f) * tv[c]));
                        let g = (0..p)
                            .map(|j| {
                                std::array::from_fn(|c| {
                                    a[c] * (df[j] * (rv[c] - tv[c]) + f * rg[j][c] + (1.0 - f) * tg[j][c])
                                })
                            })
                            .collect();
                        (v, g)
                    }
                };
                vals.push(v);
                grads.push(g);
            }
            let (v, g) = (vals[vals.len() - 1], &grads[grads.len() - 1]);
            for c in 0..3 {
                total[c] += k * v[c];
                for j in 0..p {
                    grad[j][c] += k * g[j][c];
                }
            }
        }
        total
    }
}

/// Channel by channel product.
fn mul(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| a[c] * b[c])
}

/// The glass trees of `pixels` (row-major indices of an image `w` wide) under `integ`, with
/// the student's bytes from `theirs`: those pixels each of whose samples meets glass along its
/// camera ray and the mirrors that ray meets first.
pub(crate) fn glass_pixels<I: Intersect>(
    integ: &Integrator<'_, I>,
    theirs: &[u8],
    w: u32,
    pixels: &[u32],
) -> Vec<PixelTrees> {
    let spp = integ.samples_per_pixel();
    pixels
        .par_iter()
        .filter_map(|&i| {
            let (x, y) = (i % w, i / w);
            let mut hits = Vec::new();
            let mut trees = Vec::with_capacity(spp as usize);
            for s in 0..spp {
                let mut rec = Recorder::default();
                integ.sample(x, y, s, &mut rec, &mut Counters::default());
                trees.push(build(&rec, &mut hits)?);
            }
            let p = i as usize * 3;
            Some(PixelTrees {
                index: i,
                theirs: theirs.get(p..p + 3)?.try_into().ok()?,
                trees,
                hits,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;
    use crate::settings::{Edition, RenderSettings, Stage};

    /// Evaluated with the course's weights, each glass pixel's trees give rayscope's colour of
    /// it: through coloured glass that absorbs (Beer's law), and through a mirror.
    #[test]
    fn the_course_weights_give_rayscopes_colour() {
        let text = r#"
Material "Grey" Diffuse (.8, .8, .8) 1
Material "Red" Diffuse (1, .3, .3) 1
Material "Tinted" Refractive (.9, .5, .2) 1.5
Material "Mirror" Reflective (0, 0, 0) 1
PointLight "L" (0, 0.8, 1.5) (.8, .8, .8)
Sphere "Glass" (0.2, -0.2, 1.5) 0.3 "Tinted"
Sphere "Ball" (-0.35, 0.1, 2.2) 0.3 "Mirror"
Plane "Floor" (0, -1, 0) (0, 1, 0) "Grey"
Plane "Back" (0, 0, 3) (0, 0, -1) "Red"
"#;
        let file = rayscope_scene::parse_str(text, Path::new("t.txt")).unwrap();
        let scene = Scene::from_file(&file);
        let settings = RenderSettings {
            width: 40,
            height: 30,
            aa: 2,
            // Glass absorbs in the full renderer's 2022 edition; without ambient light or
            // emitters its glass still splits into both rays.
            stage: Stage::Full,
            edition: Edition::Y2022,
            ..RenderSettings::default()
        };
        let mut integ = Integrator::new(&scene, &settings);
        integ.branch_cutoff = 0.0;
        let pixels: Vec<u32> = (0..40 * 30).collect();
        let found = glass_pixels(&integ, &vec![0; 40 * 30 * 3], 40, &pixels);
        assert!(found.len() > 60, "{} glass pixels", found.len());
        let mut mirrored = 0;
        for px in &found {
            let (x, y) = (px.index % 40, px.index / 40);
            let spp = integ.samples_per_pixel();
            let mean = (0..spp)
                .map(|s| integ.sample(x, y, s, &mut crate::observer::NoObserver, &mut Counters::default()))
                .fold(Vec3A::ZERO, |a, v| a + v)
                / spp as f32;
            let v = px.eval(&|h, _| h.course, 0, &mut []);
            for c in 0..3 {
                let ours = 255.0 * f64::from(mean[c]);
                assert!(
                    (v[c] - ours).abs() <= 1e-3 * ours.max(1.0),
                    "({x}, {y}) {v:?} against {mean:?}"
                );
            }
            mirrored += usize::from(px.trees.iter().any(|t| matches!(t.last(), Some(Op::Gain { .. }))));
        }
        assert!(mirrored > 0, "no glass pixel seen in the mirror");
        let absorbs = found
            .iter()
            .flat_map(|px| px.trees.iter().flatten())
            .any(|op| match op {
                Op::Glass { a, .. } | Op::Gain { a, .. } => a.iter().any(|k| (k - 1.0).abs() > 1e-3),
                Op::Leaf(_) => false,
            });
        assert!(absorbs, "no hit absorbs");
    }

    /// The derivatives `eval` gives are those of its colour: a weight that is a·cos θi + b,
    /// against differences of the colour.
    #[test]
    fn eval_differentiates_its_colour() {
        let text = r#"
Material "Grey" Diffuse (.8, .7, .6) 1
Material "Glass" Refractive (0, 0, 0) 1.5
PointLight "L" (0, 0.8, 1.5) (.8, .8, .8)
Sphere "Glass" (0, -0.2, 1.5) 0.4 "Glass"
Plane "Floor" (0, -1, 0) (0, 1, 0) "Grey"
Plane "Back" (0, 0, 3) (0, 0, -1) "Grey"
"#;
        let file = rayscope_scene::parse_str(text, Path::new("t.txt")).unwrap();
        let scene = Scene::from_file(&file);
        let settings = RenderSettings {
            width: 20,
            height: 15,
            stage: Stage::Two,
            ..RenderSettings::default()
        };
        let integ = Integrator::new(&scene, &settings);
        let pixels: Vec<u32> = (0..20 * 15).collect();
        let found = glass_pixels(&integ, &vec![0; 20 * 15 * 3], 20, &pixels);
        assert!(!found.is_empty());
        let weight = |p: [f64; 2]| {
            move |h: &GlassHit, g: &mut [f64]| {
                if g.len() == 2 {
                    g[0] = h.cos_i;
                    g[1] = 1.0;
                }
                p[0] * h.cos_i + p[1]
            }
        };
        let p = [0.1, 0.05];
        let e = 1e-6;
        for px in &found {
            let mut grad = [[0.0; 3]; 2];
            px.eval(&weight(p), 2, &mut grad);
            for j in 0..2 {
                let (mut up, mut down) = (p, p);
                up[j] += e;
                down[j] -= e;
                let (a, b) = (px.eval(&weight(up), 0, &mut []), px.eval(&weight(down), 0, &mut []));
                for c in 0..3 {
                    let numeric = (a[c] - b[c]) / (2.0 * e);
                    assert!(
                        (numeric - grad[j][c]).abs() <= 1e-4 * numeric.abs().max(1.0),
                        "{numeric} against {:?}",
                        grad[j]
                    );
                }
            }
        }
    }
}
