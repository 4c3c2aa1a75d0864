//! The recorded ray tree states every decision, and states it truly: offsets, shadow blockers,
//! glass decisions, pruned branches and shadow-ray depths, checked against the geometry.

use rayscope_core::math::offset_eps;
use rayscope_core::optics::fresnel;
use rayscope_core::{trace_pixel, BranchFate, RayKind, RayNode, RayTree, RenderSettings, Scene, Stage};

fn load(path: &std::path::Path) -> Scene {
    Scene::from_file(&rayscope_scene::load(path).expect("scene loads"))
}

fn settings(size: u32) -> RenderSettings {
    RenderSettings {
        width: size,
        height: size,
        stage: Stage::Two,
        ..RenderSettings::default()
    }
}

/// The trees of every `step`-th pixel of a `size`² image.
fn trees(scene: &Scene, s: &RenderSettings, step: usize) -> Vec<RayTree> {
    let mut out = Vec::new();
    for y in (0..s.height).step_by(step) {
        for x in (0..s.width).step_by(step) {
            out.push(trace_pixel(scene, s, x, y, 0));
        }
    }
    out
}

fn parent<'a>(t: &'a RayTree, n: &RayNode) -> &'a RayNode {
    &t.nodes[n.parent.expect("a secondary ray has a parent") as usize]
}

#[test]
fn offsets_are_the_origin_minus_the_parents_hit_point() {
    let scene = load(&rayscope_testkit::scene("whitted.txt"));
    let s = settings(60);
    let (mut along, mut through) = (0, 0);
    for t in trees(&scene, &s, 3) {
        for n in &t.nodes {
            if n.kind == RayKind::Camera {
                assert!(n.offset.is_none() && n.offset_along_normal.is_none());
                continue;
            }
            let p = parent(&t, n);
            let h = p.hit.as_ref().expect("the parent hit something");
            let o = n.offset.expect("secondary rays record their offset");
            for ((p, o), origin) in h.point.iter().zip(o).zip(n.origin) {
                // Exact: the point plus the offset is the origin, to the last bit.
                assert_eq!((f64::from(*p) + o) as f32, origin);
            }
            let k = n.offset_along_normal.expect("rayscope offsets along the normal");
            let eps = f64::from(offset_eps(h.point.into(), p.origin.into()));
            // The f32 sum rounds each coordinate by up to half an ulp of the point's.
            assert!((k.abs() - eps).abs() <= 0.02 * eps, "k {k} vs eps {eps}");
            if n.kind == RayKind::Refraction {
                assert!(k < 0.0, "refracted rays start on the far side");
                through += 1;
            } else {
                assert!(k > 0.0);
                along += 1;
            }
        }
    }
    assert!(along > 100 && through > 10, "{along} {through}");
}

#[test]
fn shadow_rays_have_their_parents_depth_and_blockers_are_on_the_ray() {
    let scene = load(&rayscope_testkit::scene("whitted.txt"));
    let s = settings(60);
    let mut blocked = 0;
    for t in trees(&scene, &s, 2) {
        for n in t.nodes.iter().filter(|n| n.kind == RayKind::Shadow) {
            assert_eq!(n.depth, parent(&t, n).depth, "pixel ({}, {}) #{}", t.x, t.y, n.id);
            match (&n.blocked_by, &n.blocker) {
                (None, None) => {}
                (Some(name), Some(b)) => {
                    blocked += 1;
                    assert_eq!(&b.entity_name, name);
                    let t_max = n.t_max.expect("shadow rays stop at the light");
                    assert!(b.t > 0.0 && b.t < t_max, "blocker at {} of {t_max}", b.t);
                    for i in 0..3 {
                        let on_ray = n.origin[i] + b.t * n.direction[i];
                        assert!((on_ray - b.point[i]).abs() < 1e-4, "{on_ray} vs {}", b.point[i]);
                    }
                    // The recorded normal faces the shadow ray.
                    let d: f32 = (0..3).map(|i| b.normal[i] * n.direction[i]).sum();
                    assert!(d <= 0.0);
                }
                other => panic!("blocked_by and blocker disagree: {other:?}"),
            }
        }
    }
    assert!(blocked > 5, "{blocked} blocked shadow rays");
}

/// Checks a tree's glass decisions against Snell's law, Fresnel and the children it has;
/// returns (pruned branches, total internal reflections) seen.
fn check_glass(t: &RayTree) -> (usize, usize) {
    let (mut pruned, mut tir) = (0, 0);
    for n in &t.nodes {
        let Some(g) = &n.glass else {
            continue;
        };
        let h = n.hit.as_ref().expect("glass decisions are made at hits");
        assert_eq!(h.material_kind, "Refractive");
        assert_eq!(g.entering, h.front_face);
        let (n1, n2) = (g.n1, g.n2);
        assert!(if g.entering {
            n1 == 1.0 && n2 > 1.0
        } else {
            n1 > 1.0 && n2 == 1.0
        });
        let cos_i: f32 = -(0..3).map(|i| n.direction[i] * h.normal[i]).sum::<f32>();
        assert!((g.cos_i - cos_i.clamp(0.0, 1.0)).abs() < 1e-6);
        assert!((g.reflectance - fresnel(g.cos_i, n1, n2)).abs() < 1e-6);
        let sin_i = (1.0 - g.cos_i * g.cos_i).max(0.0).sqrt();
        match g.cos_t {
            Some(ct) => {
                assert!(!g.tir);
                let sin_t = (1.0 - ct * ct).max(0.0).sqrt();
                assert!(
                    (n1 * sin_i - n2 * sin_t).abs() < 1e-3,
                    "Snell: {n1}·{sin_i} vs {n2}·{sin_t}"
                );
            }
            None => assert_eq!(g.refracted.fate, BranchFate::Absent),
        }
        if g.tir {
            assert!(n1 / n2 * sin_i >= 1.0 - 1e-5, "TIR past the critical angle only");
            assert!(g.cos_t.is_none() && g.reflectance == 1.0);
            tir += 1;
        }
        for (b, kind) in [(&g.reflected, RayKind::Reflection), (&g.refracted, RayKind::Refraction)] {
            let child = t.nodes.iter().find(|c| c.parent == Some(n.id) && c.kind == kind);
            assert_eq!(
                child.is_some(),
                b.fate == BranchFate::Traced,
                "#{} {kind:?} {:?}",
                n.id,
                b.fate
            );
            if let Some(c) = child {
                assert_eq!(Some(c.origin), b.origin);
                assert_eq!(Some(c.direction), b.direction);
                assert_eq!(c.weight, b.weight);
                assert!(b.path_weight >= g.prune_below);
            }
            if b.fate == BranchFate::Pruned {
                assert!(b.path_weight < g.prune_below && b.weight > 0.0);
                pruned += 1;
            }
        }
    }
    (pruned, tir)
}

#[test]
fn glass_decisions_obey_snell_and_fresnel_and_name_pruned_branches() {
    let scene = load(&rayscope_testkit::scene("whitted.txt"));
    let s = settings(80);
    let mut pruned = 0;
    let mut glass = 0;
    for t in trees(&scene, &s, 1) {
        glass += t.nodes.iter().filter(|n| n.glass.is_some()).count();
        pruned += check_glass(&t).0;
    }
    assert!(glass > 100, "{glass} glass hits");
    assert!(pruned > 0, "whitted.txt's glass ball has branches too weak to trace");
}

#[test]
fn total_internal_reflection_is_recorded_with_no_refracted_ray() {
    let cube = rayscope_testkit::workspace().join("crates/rayscope_check/tests/scenes/glass_cube.txt");
    let scene = load(&cube);
    let s = settings(48);
    let tir: usize = trees(&scene, &s, 1).iter().map(|t| check_glass(t).1).sum();
    assert!(
        tir > 0,
        "rays meeting the cube's sides from inside are totally reflected"
    );
}

#[test]
fn a_mistaken_tracers_offset_is_shown_as_it_is() {
    // Without the shadow offset, shadow rays start exactly at the hit point.
    let scene = load(&rayscope_testkit::scene("whitted.txt"));
    let s = RenderSettings {
        mistakes: rayscope_core::Mistakes::parse("no-shadow-offset").expect("catalogued"),
        ..settings(40)
    };
    let mut shadows = 0;
    for t in trees(&scene, &s, 4) {
        for n in t.nodes.iter().filter(|n| n.kind == RayKind::Shadow) {
            assert_eq!(n.offset, Some([0.0; 3]));
            shadows += 1;
        }
    }
    assert!(shadows > 0);
}
