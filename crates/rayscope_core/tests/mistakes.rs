//! Each of the course's common mistakes, rendered with `--mistake`, changes the picture where
//! and only where that mistake shows: checked against the correct render and its ray trees.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use rayscope_core::observer::{RayKind, RayNode, RayTree};
use rayscope_core::settings::Channel;
use rayscope_core::{render, trace_pixel, Mistake, Mistakes, RenderSettings, Scene, Stage};
use rayscope_scene::SceneFile;

fn load(path: &Path) -> SceneFile {
    rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn settings(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        stage: Stage::Two,
        ..RenderSettings::default()
    }
}

fn with(s: &RenderSettings, m: Mistake) -> RenderSettings {
    RenderSettings {
        mistakes: Mistakes::NONE.with(m),
        ..*s
    }
}

/// The scene as a tracer with `s`'s mistakes loads it (OBJ mistakes change the meshes).
fn scene_for(file: &SceneFile, s: &RenderSettings) -> Scene {
    let mut f = file.clone();
    s.mistakes.apply_to_file(&mut f);
    Scene::from_owned_file(f)
}

fn bytes(file: &SceneFile, s: &RenderSettings) -> Vec<u8> {
    let scene = scene_for(file, s);
    render(&scene, s, &|_, _| {}, &AtomicBool::new(false))
        .expect("not cancelled")
        .film
        .to_rgb8()
}

/// Pixel indices where the two images differ in any channel.
fn differing(a: &[u8], b: &[u8]) -> Vec<usize> {
    a.chunks_exact(3)
        .zip(b.chunks_exact(3))
        .enumerate()
        .filter(|(_, (x, y))| x != y)
        .map(|(i, _)| i)
        .collect()
}

fn px(img: &[u8], i: usize) -> [u8; 3] {
    [img[3 * i], img[3 * i + 1], img[3 * i + 2]]
}

fn trees(file: &SceneFile, s: &RenderSettings) -> Vec<RayTree> {
    let scene = scene_for(file, s);
    (0..s.height)
        .flat_map(|y| (0..s.width).map(move |x| (x, y)))
        .map(|(x, y)| trace_pixel(&scene, s, x, y, 0))
        .collect()
}

fn kind_of(file: &SceneFile, entity: u32) -> &'static str {
    file.entities[entity as usize].shape.command()
}

fn any_node(t: &RayTree, f: impl Fn(&RayNode) -> bool) -> bool {
    t.nodes.iter().any(f)
}

fn hits_material(t: &RayTree, kind: &str) -> bool {
    any_node(t, |n| n.hit.as_ref().is_some_and(|h| h.material_kind == kind))
}

fn lit(v: [f32; 3]) -> bool {
    v.iter().any(|&c| c > 0.0)
}

/// A mistake's render, the correct one and the pixels where they differ.
struct Case {
    file: SceneFile,
    base: RenderSettings,
    right: Vec<u8>,
    wrong: Vec<u8>,
    diff: Vec<usize>,
}

fn case(path: &Path, base: RenderSettings, m: Mistake) -> Case {
    let file = load(path);
    let right = bytes(&file, &base);
    let wrong = bytes(&file, &with(&base, m));
    let diff = differing(&right, &wrong);
    assert!(!diff.is_empty(), "{} changes nothing in {}", m.name(), path.display());
    Case {
        file,
        base,
        right,
        wrong,
        diff,
    }
}

impl Case {
    /// Every differing pixel's correct ray tree passes `f`.
    fn only_where(&self, what: &str, f: impl Fn(&RayTree) -> bool) {
        let t = trees(&self.file, &self.base);
        let bad: Vec<usize> = self.diff.iter().copied().filter(|&i| !f(&t[i])).collect();
        assert!(
            bad.is_empty(),
            "{} of {} differing pixels are not {what}, e.g. pixel {:?}",
            bad.len(),
            self.diff.len(),
            bad.first()
                .map(|&i| (i as u32 % self.base.width, i as u32 / self.base.width))
        );
    }

    /// Every differing pixel is darker (`sign` < 0) or brighter (> 0) in every channel.
    fn direction(&self, sign: i32) {
        self.direction_within(sign, 0);
    }

    /// [`Self::direction`], allowing `slack` levels the other way (shading that moves by a
    /// rounding step where a ray's origin moves).
    fn direction_within(&self, sign: i32, slack: u8) {
        for &i in &self.diff {
            let (r, w) = (px(&self.right, i), px(&self.wrong, i));
            let ok = (0..3).all(|c| {
                if sign < 0 {
                    w[c] <= r[c].saturating_add(slack)
                } else {
                    w[c].saturating_add(slack) >= r[c]
                }
            });
            assert!(ok, "pixel {i}: right {r:?}, wrong {w:?}");
        }
    }
}

#[test]
fn camera_mistakes_show_only_on_non_square_images() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let file = load(&course.scene("sample_scene_2.txt"));
    for m in [Mistake::FovVertical, Mistake::AspectIgnored] {
        let square = settings(40, 40);
        assert_eq!(bytes(&file, &square), bytes(&file, &with(&square, m)), "{}", m.name());
        let wide = settings(61, 41);
        let (right, wrong) = (bytes(&file, &wide), bytes(&file, &with(&wide, m)));
        let diff = differing(&right, &wrong);
        assert!(diff.len() > 61 * 41 / 4, "{}: {} pixels", m.name(), diff.len());
        let centre = 20 * 61 + 30;
        assert_eq!(
            px(&right, centre),
            px(&wrong, centre),
            "{}: the centre ray stays",
            m.name()
        );
    }
}

#[test]
fn pixel_corners_move_the_picture_half_a_pixel() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_1.txt"),
        settings(64, 48),
        Mistake::PixelCorners,
    );
    let (w, h) = (64usize, 48usize);
    // Every camera ray goes through its pixel's top-left corner.
    let scene = Scene::from_file(&c.file);
    let cam = rayscope_core::Camera::new(c.base.camera, 64, 48);
    let wrong = with(&c.base, Mistake::PixelCorners);
    for (x, y) in (0..48).flat_map(|y| (0..64).map(move |x| (x, y))) {
        let t = trace_pixel(&scene, &wrong, x, y, 0);
        assert_eq!(
            t.nodes[0].direction,
            cam.ray(x as f32 / 64.0, y as f32 / 48.0).dir.to_array(),
            "pixel ({x}, {y})"
        );
    }
    // A corner sees what the pixels around it see: a differing pixel lies within the range of
    // the correct pixels that share the corner, but where a feature is thinner than a pixel.
    let mut outside = 0;
    for &i in &c.diff {
        let (x, y) = (i % w, i / w);
        let v = px(&c.wrong, i);
        for (ch, &value) in v.iter().enumerate() {
            let near: Vec<u8> = (y.saturating_sub(1)..=y)
                .flat_map(|yy| (x.saturating_sub(1)..=x).map(move |xx| (xx, yy)))
                .filter(|&(xx, yy)| xx < w && yy < h)
                .map(|(xx, yy)| px(&c.right, yy * w + xx)[ch])
                .collect();
            let (lo, hi) = (*near.iter().min().unwrap(), *near.iter().max().unwrap());
            if value + 1 < lo || value > hi + 1 {
                outside += 1;
                break;
            }
        }
    }
    assert!(
        outside * 50 <= c.diff.len(),
        "{outside} of {} differing pixels see what no neighbour sees",
        c.diff.len()
    );
}

#[test]
fn flipped_image_is_the_correct_one_upside_down() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let file = load(&course.scene("sample_scene_2.txt"));
    for aa in [1, 2] {
        let s = RenderSettings { aa, ..settings(50, 34) };
        let right = bytes(&file, &s);
        let wrong = bytes(&file, &with(&s, Mistake::ImageFlipped));
        let row = 50 * 3;
        for y in 0..34 {
            assert_eq!(
                wrong[y * row..(y + 1) * row],
                right[(33 - y) * row..(34 - y) * row],
                "row {y} at -x {aa}"
            );
        }
    }
}

#[test]
fn shadow_acne_darkens_only_lit_diffuse_surfaces() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_1.txt"),
        settings(64, 64),
        Mistake::NoShadowOffset,
    );
    // The light's direction from the un-offset point differs in the last bit: one level at most.
    c.direction_within(-1, 1);
    c.only_where("lit diffuse surfaces", |t| {
        t.nodes[0].hit.as_ref().is_some_and(|h| h.material_kind == "Diffuse")
            && any_node(t, |n| {
                n.kind == RayKind::Shadow && n.blocked_by.is_none() && lit(n.value)
            })
    });
    assert!(c.diff.len() > 100, "acne on {} pixels only", c.diff.len());
}

#[test]
fn huge_offsets_move_only_shadows() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for path in [
        course.scene("sample_scene_1.txt"),
        rayscope_testkit::scene("whitted.txt"),
    ] {
        let c = case(&path, settings(64, 48), Mistake::HugeShadowOffset);
        // The shadow test moves; the light's direction is taken from the hit point (rayscope
        // takes it from the offset point, 1e-5 away: a level at most). So a pixel changes by
        // more than a level only where one of the two renders finds its light blocked.
        let wrong = trees(&c.file, &with(&c.base, Mistake::HugeShadowOffset));
        let right = trees(&c.file, &c.base);
        let shadowed = |t: &RayTree| any_node(t, |n| n.blocked_by.is_some());
        for &i in &c.diff {
            let step = (0..3).map(|k| px(&c.right, i)[k].abs_diff(px(&c.wrong, i)[k])).max();
            if step > Some(1) {
                assert!(
                    shadowed(&right[i]) || shadowed(&wrong[i]),
                    "{}: pixel {i}",
                    path.display()
                );
            }
        }
        let lighter = c.diff.iter().filter(|&&i| px(&c.wrong, i) > px(&c.right, i)).count();
        assert!(lighter > 0, "some shadow shrinks");
    }
}

#[test]
fn one_sided_triangles_change_only_the_shadows_they_cast_from_behind() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_1.txt"),
        settings(64, 64),
        Mistake::OneSidedTriangles,
    );
    c.direction(1);
    let file = &c.file;
    c.only_where("shadowed by a triangle", |t| {
        any_node(t, |n| {
            n.blocked_by.as_ref().is_some_and(|b| {
                file.entities
                    .iter()
                    .any(|e| &e.name == b && e.shape.command() == "Triangle")
            })
        })
    });
}

#[test]
fn reversed_normals_blacken_the_triangles_seen_from_the_front() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_1.txt"),
        settings(64, 64),
        Mistake::ReversedNormals,
    );
    let file = &c.file;
    c.only_where("on a triangle", |t| {
        t.nodes[0]
            .hit
            .as_ref()
            .is_some_and(|h| kind_of(file, h.entity) == "Triangle" && h.front_face)
    });
    for &i in &c.diff {
        assert_eq!(px(&c.wrong, i), [0, 0, 0], "pixel {i}");
    }
}

#[test]
fn glass_mistakes_change_only_what_is_seen_in_glass() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let base = settings(64, 64);
    for m in [
        Mistake::RefractionNoNormalFlip,
        Mistake::RefractionNoIndexSwap,
        Mistake::NoTir,
        Mistake::NoFresnel,
        Mistake::FresnelHalf,
        Mistake::Schlick,
        Mistake::EtaEnteringInverted,
        Mistake::FresnelSwapped,
    ] {
        // No ray inside a sphere meets its surface past the critical angle (it leaves at the
        // angle it entered at), so total internal reflection needs the glass slab of ours.
        let path = if m == Mistake::NoTir {
            rayscope_testkit::scene("beer.txt")
        } else {
            course.scene("sample_scene_2.txt")
        };
        let c = case(&path, base, m);
        c.only_where("seen through glass", |t| hits_material(t, "Refractive"));
        if m == Mistake::NoTir {
            // Only where a glass hit reflected everything: one reflection of weight 1, no
            // refraction.
            c.only_where("totally internally reflected", |t| {
                t.nodes.iter().any(|n| {
                    n.hit.as_ref().is_some_and(|h| h.material_kind == "Refractive")
                        && !t
                            .nodes
                            .iter()
                            .any(|k| k.parent == Some(n.id) && k.kind == RayKind::Refraction)
                        && t.nodes
                            .iter()
                            .any(|k| k.parent == Some(n.id) && k.kind == RayKind::Reflection && k.weight == 1.0)
                })
            });
            c.direction(-1);
        }
    }
}

#[test]
fn recursion_limit_3_darkens_only_deep_paths() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_2.txt"),
        settings(64, 64),
        Mistake::RecursionLimit3,
    );
    c.direction(-1);
    c.only_where("a path more than 3 bounces deep", |t| {
        any_node(t, |n| {
            n.depth >= 3
                && n.hit
                    .as_ref()
                    .is_some_and(|h| h.material_kind == "Reflective" || h.material_kind == "Refractive")
        })
    });
}

#[test]
fn lighting_mistakes_change_what_they_should() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let s1 = course.scene("sample_scene_1.txt");
    let s2 = course.scene("sample_scene_2.txt");
    let base = settings(48, 48);

    let c = case(&s1, base, Mistake::LightFalloff);
    c.only_where("lit", |t| lit(t.color));
    let lit_pixels = c.right.chunks_exact(3).filter(|p| p.iter().any(|&v| v > 1)).count();
    assert!(
        c.diff.len() * 10 > lit_pixels * 9,
        "falloff changes nearly every lit pixel"
    );

    let c = case(&s1, base, Mistake::AmbientTerm);
    c.direction(1);
    c.only_where("on a diffuse surface", |t| hits_material(t, "Diffuse"));
    let t = trees(&c.file, &base);
    for (i, tree) in t.iter().enumerate() {
        if tree.nodes[0].hit.is_some() && px(&c.right, i) == [0, 0, 0] {
            assert_ne!(px(&c.wrong, i), [0, 0, 0], "a shadow stays black at pixel {i}");
        }
    }

    let c = case(&s2, base, Mistake::ShadowPastLight);
    c.direction(-1);
    c.only_where("shaded by a light", |t| any_node(t, |n| n.kind == RayKind::Shadow));

    let c = case(&s2, base, Mistake::FirstLightOnly);
    c.direction(-1);
    c.only_where("lit by the second light", |t| {
        any_node(t, |n| {
            n.light.as_deref() == Some("Light2") && n.blocked_by.is_none() && lit(n.value)
        })
    });
}

#[test]
fn output_mistakes_change_levels_not_shapes() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let base = settings(48, 48);
    let c = case(&course.scene("sample_scene_2.txt"), base, Mistake::RoundedColours);
    for (r, w) in c.right.iter().zip(&c.wrong) {
        assert!(*w == *r || *w == r + 1, "{r} → {w}");
    }
    assert!(c.diff.len() > 48 * 48 / 4, "rounding raises about half the pixels");

    let c = case(&course.scene("sample_scene_2.txt"), base, Mistake::Gamma);
    c.direction(1);
    for (r, w) in c.right.iter().zip(&c.wrong) {
        if *r == 0 || *r == 255 {
            assert_eq!(r, w, "black and white stay");
        }
    }
}

#[test]
fn obj_mistakes_change_only_the_model_and_its_shadow() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for path in [course.scene("sample_scene_obj.txt"), rayscope_testkit::scene("obj.txt")] {
        let base = settings(48, 48);
        let file = load(&path);
        let mesh = |t: &RayTree| {
            any_node(t, |n| {
                n.hit.as_ref().is_some_and(|h| kind_of(&file, h.entity) == "ObjModel")
                    || n.blocked_by.as_ref().is_some_and(|b| {
                        file.entities
                            .iter()
                            .any(|e| &e.name == b && e.shape.command() == "ObjModel")
                    })
            })
        };

        let c = case(&path, base, Mistake::ObjNoZFlip);
        let flipped = trees(&file, &with(&base, Mistake::ObjNoZFlip));
        let right = trees(&file, &base);
        for &i in &c.diff {
            assert!(mesh(&right[i]) || mesh(&flipped[i]), "{}: pixel {i}", path.display());
        }

        let c = case(&path, base, Mistake::ObjFlatNormals);
        let entity = |s: &RenderSettings| {
            bytes(
                &file,
                &RenderSettings {
                    channel: Channel::Entity,
                    ..*s
                },
            )
        };
        assert_eq!(
            entity(&base),
            entity(&with(&base, Mistake::ObjFlatNormals)),
            "same silhouette"
        );
        c.only_where("on the model (directly or in a mirror)", |t| {
            any_node(t, |n| {
                n.hit.as_ref().is_some_and(|h| kind_of(&file, h.entity) == "ObjModel")
            })
        });
    }
}

#[test]
fn settings_with_mistakes_round_trip_through_json_and_old_json_still_reads() {
    let s = RenderSettings {
        mistakes: Mistakes::parse("no-tir,gamma").unwrap(),
        ..RenderSettings::default()
    };
    let json = serde_json::to_string(&s).unwrap();
    assert!(json.contains(r#""mistakes":["no-tir","gamma"]"#), "{json}");
    assert_eq!(serde_json::from_str::<RenderSettings>(&json).unwrap(), s);
    let plain = serde_json::to_string(&RenderSettings::default()).unwrap();
    assert!(
        !plain.contains("mistakes"),
        "correct settings serialise as before: {plain}"
    );
    assert_eq!(
        serde_json::from_str::<RenderSettings>(&plain).unwrap(),
        RenderSettings::default()
    );
}

#[test]
fn a_camera_angle_read_as_radians_turns_the_camera_by_that_many_radians() {
    let path = rayscope_testkit::scene("whitted.txt");
    let file = load(&path);
    // Without --cam-angle the mistake cannot show.
    let base = settings(48, 36);
    assert_eq!(
        bytes(&file, &base),
        bytes(&file, &with(&base, Mistake::CamAngleRadians))
    );
    let mut turned = base;
    turned.camera.axis = glam::Vec3::Y;
    turned.camera.angle_deg = 0.5;
    let c = case(&path, turned, Mistake::CamAngleRadians);
    // The mistaken render is the correct one turned by 0.5 rad (28.6°) instead of 0.5°: the
    // same picture up to the rounding of converting the angle there and back.
    let mut as_radians = turned;
    as_radians.camera.angle_deg = 0.5f32.to_degrees();
    let expected = bytes(&c.file, &as_radians);
    let off = differing(&expected, &c.wrong);
    assert!(
        off.len() * 100 <= c.diff.len(),
        "{} of {} pixels differ from the render turned by 0.5 rad",
        off.len(),
        c.diff.len()
    );
    assert!(c.diff.len() * 2 > c.wrong.len() / 3, "{} pixels changed", c.diff.len());
}

#[test]
fn a_minimum_hit_distance_changes_only_rays_that_meet_something_that_near() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // Our spheres rest on the ground, the bunny's triangles lie close, and a pane of glass
    // 0.03 thick loses its back face.
    for path in [
        rayscope_testkit::scene("whitted.txt"),
        course.scene("sample_scene_obj.txt"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/thin_pane.txt"),
    ] {
        let c = case(&path, settings(64, 64), Mistake::MinHitDistance);
        c.only_where("a ray meeting a surface or blocker nearer than 0.05", |t| {
            any_node(t, |n| {
                n.hit.as_ref().is_some_and(|h| h.t < 0.05) || n.blocker.as_ref().is_some_and(|h| h.t < 0.05)
            })
        });
    }
}

#[test]
fn choosing_the_nearest_hit_by_another_distance_changes_only_what_it_should() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    // From a camera at the origin, distance from the origin is distance along the camera ray:
    // only what mirrors and glass show changes, and shadows, whose test keeps the closest hit's
    // answer on the whole ray.
    let c = case(
        &course.scene("sample_scene_2.txt"),
        settings(64, 64),
        Mistake::NearestByOriginDistance,
    );
    c.only_where("seen in a mirror or through glass, or in a shadow", |t| {
        hits_material(t, "Reflective")
            || hits_material(t, "Refractive")
            || any_node(t, |n| n.kind == RayKind::Shadow && n.blocker.is_some())
    });
    // Scene 1 lists its floor first: kept whenever a camera ray meets it at all, the floor
    // covers the sphere's and the triangle's lower halves, only where their rays go on down to
    // it (and not where the floor behind them is as dark as they are).
    let c = case(
        &course.scene("sample_scene_1.txt"),
        settings(64, 64),
        Mistake::FirstHitInSceneOrder,
    );
    let t = trees(&c.file, &c.base);
    let covered: Vec<usize> = (0..t.len())
        .filter(|&i| {
            let cam = &t[i].nodes[0];
            cam.hit.as_ref().is_some_and(|h| h.entity != 0) && cam.direction[1] < 0.0
        })
        .collect();
    let outside: Vec<&usize> = c.diff.iter().filter(|i| !covered.contains(i)).collect();
    assert!(outside.is_empty(), "{outside:?}");
    assert!(
        c.diff.len() * 5 >= covered.len() * 4,
        "{} of {} covered pixels changed",
        c.diff.len(),
        covered.len()
    );
}

#[test]
fn glass_rays_started_on_the_wrong_side_change_only_what_is_seen_in_glass() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for m in [
        Mistake::GlassReflectionAlongRay,
        Mistake::GlassReflectionOutward,
        Mistake::RefractionOffsetOutside,
    ] {
        for path in [course.scene("sample_scene_2.txt"), rayscope_testkit::scene("beer.txt")] {
            let c = case(&path, settings(64, 64), m);
            c.only_where("seen through glass", |t| hits_material(t, "Refractive"));
        }
    }
}

#[test]
fn a_sum_never_reset_makes_each_pixel_the_sum_of_those_before_it() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let file = load(&course.scene("sample_scene_1.txt"));
    let base = settings(40, 30);
    let film = render(&Scene::from_file(&file), &base, &|_, _| {}, &AtomicBool::new(false))
        .expect("not cancelled")
        .film;
    let mut sum = glam::Vec3::ZERO;
    let expected: Vec<u8> = film
        .pixels
        .iter()
        .flat_map(|p| {
            sum += *p;
            sum.to_array().map(|v| (v.clamp(0.0, 1.0) * 255.0) as u8)
        })
        .collect();
    let wrong = bytes(&file, &with(&base, Mistake::AccumulatorNotReset));
    assert_eq!(wrong, expected);
    // Past the first lit pixels every channel a surface has lit is saturated.
    let lit = wrong.iter().filter(|&&v| v == 255).count();
    assert!(lit * 2 > wrong.len(), "{lit} of {} channels saturated", wrong.len());
}

#[test]
fn a_reflection_without_its_factor_2_changes_only_what_mirrors_and_glass_show() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let c = case(
        &course.scene("sample_scene_2.txt"),
        settings(64, 64),
        Mistake::ReflectNo2,
    );
    c.only_where("seen in a mirror or glass", |t| {
        hits_material(t, "Reflective") || hits_material(t, "Refractive")
    });
}

#[test]
fn a_too_strict_triangle_test_changes_only_what_triangles_show_or_shade() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    for path in [course.scene("sample_scene_1.txt"), course.scene("sample_scene_2.txt")] {
        let c = case(&path, settings(64, 64), Mistake::StrictEdges);
        let file = c.file.clone();
        let triangle = |h: &Option<rayscope_core::observer::RayHitInfo>| {
            h.as_ref().is_some_and(|h| kind_of(&file, h.entity) == "Triangle")
        };
        c.only_where("meeting a triangle", |t| {
            any_node(t, |n| triangle(&n.hit) || triangle(&n.blocker))
        });
    }
}

/// The scene file with its spheres' radii set to `r`.
fn spheres_of_radius(file: &SceneFile, r: f64) -> SceneFile {
    let mut f = file.clone();
    for e in &mut f.entities {
        if let rayscope_scene::Shape::Sphere { radius, .. } = &mut e.shape {
            *radius = r;
        }
    }
    f
}

#[test]
fn unnormalised_sphere_normals_change_only_what_spheres_show_and_nothing_at_radius_1() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let base = settings(64, 64);
    let m = Mistake::SphereNormalUnnormalised;
    for path in [course.scene("sample_scene_1.txt"), course.scene("sample_scene_2.txt")] {
        let c = case(&path, base, m);
        let file = c.file.clone();
        c.only_where("meeting a sphere", |t| {
            any_node(t, |n| {
                n.hit.as_ref().is_some_and(|h| kind_of(&file, h.entity) == "Sphere")
            })
        });
        // The normals the mistaken render shades with are the unit ones times the radius.
        let wrong = trees(&file, &with(&base, m));
        let right = trees(&file, &base);
        for (w, r) in wrong.iter().zip(&right) {
            let (Some(wh), Some(rh)) = (&w.nodes[0].hit, &r.nodes[0].hit) else {
                continue;
            };
            if let rayscope_scene::Shape::Sphere { radius, .. } = file.entities[rh.entity as usize].shape {
                assert_eq!(wh.entity, rh.entity);
                for k in 0..3 {
                    let want = rh.normal[k] * radius as f32;
                    assert!((wh.normal[k] - want).abs() < 1e-6, "{:?} vs {want}", wh.normal);
                }
            }
        }
        // With radius 1, p − c is the unit normal: nothing changes.
        let unit = spheres_of_radius(&file, 1.0);
        assert_eq!(bytes(&unit, &base), bytes(&unit, &with(&base, m)), "{}", path.display());
    }
    // Scene 1's only sphere is diffuse, of radius 0.5: N·L halves, and the sphere darkens.
    let c = case(&course.scene("sample_scene_1.txt"), base, m);
    c.direction(-1);
}

#[test]
fn a_sphere_hit_behind_the_origin_changes_only_what_glass_shows() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let base = settings(64, 64);
    let m = Mistake::SphereNearRootBehind;
    let c = case(&course.scene("sample_scene_2.txt"), base, m);
    c.only_where("seen through glass", |t| hits_material(t, "Refractive"));
    // Every ray that travels inside the glass meets it behind its origin, where it entered.
    let wrong = trees(&c.file, &with(&base, m));
    let mut inside = 0;
    for t in &wrong {
        for n in &t.nodes {
            let parent = n.parent.map(|p| &t.nodes[p as usize]);
            let entered = n.kind == RayKind::Refraction
                && parent.is_some_and(|p| {
                    p.hit
                        .as_ref()
                        .is_some_and(|h| h.front_face && h.material_kind == "Refractive")
                });
            if entered {
                let h = n.hit.as_ref().expect("a ray inside glass hits it");
                assert!(h.t < 0.0 && h.material_kind == "Refractive" && h.front_face, "{h:?}");
                inside += 1;
            }
        }
    }
    assert!(inside > 0, "no ray entered the glass");
    // Camera and shadow rays start outside every sphere: without glass nothing changes.
    let file = load(&course.scene("sample_scene_1.txt"));
    assert_eq!(bytes(&file, &base), bytes(&file, &with(&base, m)));
}

#[test]
fn plane_hits_behind_the_origin_blacken_every_scene_with_a_plane_and_no_other() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let base = settings(48, 48);
    let m = Mistake::PlaneHitsBehind;
    for path in [course.scene("sample_scene_1.txt"), course.scene("sample_scene_2.txt")] {
        let c = case(&path, base, m);
        assert!(c.wrong.iter().all(|&v| v == 0), "{}: not all black", path.display());
        // A camera ray that meets a plane behind the camera stops on the farthest such plane
        // behind it, and every diffuse hit's shadow rays are blocked.
        let wrong = trees(&c.file, &with(&base, m));
        for t in &wrong {
            let d = glam::Vec3::from(t.nodes[0].direction);
            let behind = c.file.entities.iter().enumerate().filter_map(|(k, e)| match e.shape {
                rayscope_scene::Shape::Plane { point, normal } => {
                    let (p, n) = (point.as_vec3(), normal.as_vec3().normalize());
                    let t = p.dot(n) / d.dot(n);
                    (t < 0.0).then_some((k, t))
                }
                _ => None,
            });
            let farthest = behind.min_by(|a, b| a.1.total_cmp(&b.1));
            let hit = t.nodes[0].hit.as_ref();
            match farthest {
                Some((k, _)) => {
                    let h = hit.expect("a hit behind the camera");
                    assert!(h.entity as usize == k && h.t < 0.0, "{h:?}");
                }
                None => assert!(hit.is_none_or(|h| h.t > 0.0)),
            }
            for n in &t.nodes {
                assert!(n.kind != RayKind::Shadow || n.blocked_by.is_some(), "a light reached");
            }
        }
    }
    // Without its planes scene 2 renders as it should.
    let mut file = load(&course.scene("sample_scene_2.txt"));
    file.entities
        .retain(|e| !matches!(e.shape, rayscope_scene::Shape::Plane { .. }));
    assert_eq!(bytes(&file, &base), bytes(&file, &with(&base, m)));
}

#[test]
fn n_dot_l_unclamped_darkens_only_where_an_unblocked_light_lies_behind_the_shading_normal() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let m = Mistake::NdotLUnclamped;
    for path in [
        course.scene("sample_scene_obj.txt"),
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/scenes/smooth_ball.txt"),
    ] {
        let c = case(&path, settings(64, 64), m);
        c.direction(-1);
        c.only_where("lit past a reached light that adds nothing", |t| {
            any_node(t, |n| {
                n.kind == RayKind::Shadow && n.blocked_by.is_none() && !lit(n.value)
            })
        });
    }
    // Without interpolated normals every light behind a surface is blocked by that surface.
    for name in ["sample_scene_1.txt", "sample_scene_2.txt"] {
        let file = load(&course.scene(name));
        let base = settings(48, 48);
        assert_eq!(bytes(&file, &base), bytes(&file, &with(&base, m)), "{name}");
    }
}
