//! Golden tests of our own scenes, which need nothing from the course: stage-1 and stage-2
//! renders of `scenes/basic.txt` and `scenes/room.txt` against images of ours checked in under
//! `tests/goldens/` (bit for bit, as renders are deterministic), and the basic scene's pixels
//! against a small tracer written here from the course's stage-1 and stage-2 rules.
//!
//! After a deliberate change to the images, `RAYSCOPE_BLESS=1 cargo test -p rayscope --test
//! own_goldens` rewrites the goldens (and fails, so a blessing run never passes by itself);
//! look at the new images before committing them.

mod common;

use std::path::PathBuf;

use common::{render, rgb, scenes};
use rayscope_scene::{DVec3, SceneFile, Shape};

/// Renders `scene` at 160×160 with `flags`, checks it against `tests/goldens/<golden>` pixel
/// for pixel and returns it.
fn golden(scene: &str, flags: &[&str], golden: &str) -> image::RgbImage {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a.png");
    let mut args = vec!["-w", "160", "-h", "160"];
    args.extend_from_slice(flags);
    let img = render(&scenes(scene), &out, &args);
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/goldens")
        .join(golden);
    if std::env::var_os("RAYSCOPE_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::copy(&out, &path).unwrap();
        panic!(
            "wrote {}: look at it, then run again without RAYSCOPE_BLESS",
            path.display()
        );
    }
    let want = rgb(&path);
    assert_eq!(img.dimensions(), want.dimensions());
    let differ: Vec<_> = (img.enumerate_pixels())
        .filter(|(x, y, p)| want.get_pixel(*x, *y) != *p)
        .map(|(x, y, p)| ((x, y), p.0, want.get_pixel(x, y).0))
        .collect();
    assert!(
        differ.is_empty(),
        "{scene} {flags:?}: {} pixels differ from {golden}, e.g. (pixel, got, golden) {:?}",
        differ.len(),
        &differ[..differ.len().min(5)]
    );
    img
}

#[test]
fn basic_scene_stage1_golden() {
    golden("basic.txt", &["--stage", "1"], "basic_s1.png");
}

#[test]
fn basic_scene_stage2_golden() {
    golden("basic.txt", &["--stage", "2", "-x", "3"], "basic_s2_x3.png");
}

#[test]
fn room_stage2_golden() {
    // The mirror ball, the glass ball (Fresnel, total internal reflection) and two lights.
    golden("room.txt", &["--stage", "2", "-x", "2"], "room_s2_x2.png");
}

/// What one ray sees, worked out in f64 from the scene file.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Seen {
    entity: Option<usize>,
    /// Which lights reach the hit point.
    lit: [bool; 4],
    byte: [u8; 3],
    stage1: [u8; 3],
}

/// Distance along `d` from `o` to the nearest hit of `shape` beyond `t_min`.
fn hit(shape: &Shape, o: DVec3, d: DVec3, t_min: f64) -> Option<(f64, DVec3)> {
    match *shape {
        Shape::Plane { point, normal } => {
            let den = normal.dot(d);
            let t = (point - o).dot(normal) / den;
            (den != 0.0 && t > t_min).then_some((t, normal))
        }
        Shape::Sphere { center, radius } => {
            let oc = o - center;
            let (b, c) = (oc.dot(d), oc.length_squared() - radius * radius);
            let disc = b * b - c;
            if disc < 0.0 {
                return None;
            }
            let t = [-b - disc.sqrt(), -b + disc.sqrt()].into_iter().find(|&t| t > t_min)?;
            Some((t, (o + d * t - center) / radius))
        }
        Shape::Triangle { vertices: [a, b, c] } => {
            let n = (b - a).cross(c - a);
            let den = n.dot(d);
            if den == 0.0 {
                return None;
            }
            let t = (a - o).dot(n) / den;
            let p = o + d * t;
            let inside = [(a, b), (b, c), (c, a)]
                .iter()
                .all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
            (t > t_min && inside).then_some((t, n.normalize()))
        }
        Shape::Mesh { .. } => unreachable!("the basic scene has no meshes"),
    }
}

/// The course's rules: stage 1 is the nearest hit's material colour; stage 2 adds over the
/// lights max(0, N·L)·Cm·Cl where nothing lies between the hit and the light; then each channel
/// is clamped to 1 and truncated to a byte.
fn trace(scene: &SceneFile, o: DVec3, d: DVec3) -> Seen {
    let nearest = (scene.entities.iter().enumerate())
        .filter_map(|(i, e)| hit(&e.shape, o, d, 0.0).map(|(t, n)| (t, n, i)))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    let Some((t, n, i)) = nearest else {
        return Seen {
            entity: None,
            lit: [false; 4],
            byte: [0; 3],
            stage1: [0; 3],
        };
    };
    let m = scene.materials[scene.entities[i].material].color;
    let p = o + d * t;
    let n = if n.dot(d) > 0.0 { -n } else { n };
    let mut lit = [false; 4];
    let mut c = DVec3::ZERO;
    for (k, light) in scene.lights.iter().enumerate() {
        let to = light.position - p;
        let (dist, l) = (to.length(), to.normalize());
        let start = p + n * 1e-6;
        let blocked = (scene.entities.iter()).any(|e| hit(&e.shape, start, l, 0.0).is_some_and(|(s, _)| s < dist));
        lit[k] = !blocked;
        if !blocked {
            c += m * light.color * n.dot(l).max(0.0);
        }
    }
    let byte = |v: DVec3| v.to_array().map(|x| (x.min(1.0) * 255.0) as u8);
    Seen {
        entity: Some(i),
        lit,
        byte: byte(c),
        stage1: byte(m),
    }
}

/// The pinhole camera at the origin looking along +z with a 60° horizontal field of view,
/// through (x, y) in pixels of a `w`×`h` image.
fn camera_ray(x: f64, y: f64, w: u32, h: u32) -> DVec3 {
    let k = 30f64.to_radians().tan();
    let aspect = f64::from(h) / f64::from(w);
    DVec3::new(
        (2.0 * x / f64::from(w) - 1.0) * k,
        (1.0 - 2.0 * y / f64::from(h)) * k * aspect,
        1.0,
    )
    .normalize()
}

#[test]
fn basic_scene_follows_the_course_s_stage1_and_stage2_rules() {
    let (w, h) = (120, 90);
    let path = scenes("basic.txt");
    let file = rayscope_scene::load(&path).unwrap();
    assert!(file.lights.len() <= 4);
    let dir = tempfile::tempdir().unwrap();
    let at = |stage: &str| {
        let out = dir.path().join(format!("s{stage}.png"));
        render(&path, &out, &["-w", "120", "-h", "90", "--stage", stage])
    };
    let (s1, s2) = (at("1"), at("2"));
    let (mut checked, mut kinds) = (0, [0; 5]);
    for y in 0..h {
        for x in 0..w {
            let centre = trace(
                &file,
                DVec3::ZERO,
                camera_ray(f64::from(x) + 0.5, f64::from(y) + 0.5, w, h),
            );
            // Pixels on an edge, a silhouette or a shadow's border could go either way.
            let clear = [(-0.05, 0.0), (0.05, 0.0), (0.0, -0.05), (0.0, 0.05)]
                .iter()
                .all(|(dx, dy)| {
                    let near = trace(
                        &file,
                        DVec3::ZERO,
                        camera_ray(f64::from(x) + 0.5 + dx, f64::from(y) + 0.5 + dy, w, h),
                    );
                    (near.entity, near.lit) == (centre.entity, centre.lit)
                });
            if !clear {
                continue;
            }
            checked += 1;
            kinds[centre.entity.map_or(3, |e| e)] += 1;
            kinds[4] += usize::from(centre.entity.is_some() && !centre.lit[0]);
            assert_eq!(
                s1.get_pixel(x, y).0,
                centre.stage1,
                "stage 1 pixel ({x}, {y}): {centre:?}"
            );
            let got = s2.get_pixel(x, y).0;
            // rayscope shades in f32: a channel may land one level either side of a truncation.
            assert!(
                got.iter().zip(centre.byte).all(|(&g, want)| g.abs_diff(want) <= 1),
                "stage 2 pixel ({x}, {y}): {got:?}, the rules give {centre:?}"
            );
        }
    }
    assert!(checked > w * h * 9 / 10, "only {checked} pixels away from edges");
    // Plane, sphere, triangle, background and shadow all take part.
    assert!(kinds.iter().all(|&k| k > 100), "{kinds:?}");
}
