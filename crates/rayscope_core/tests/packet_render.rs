//! Renders traced with ray packets are the renders traced one ray at a time: the same pixels,
//! bit for bit, and the same ray counts, on the course's scenes and ours, at every stage.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use rayscope_core::geometry::Triangle;
use rayscope_core::integrator::Engine;
use rayscope_core::math::Ray;
use rayscope_core::scene::{Hit, Intersect, PrimRef};
use rayscope_core::settings::Channel;
use rayscope_core::{render, render_with, RenderOutput, RenderSettings, Scene, Stage};

/// The scene's own BVH queries, without offering packets: the one-ray-at-a-time render path,
/// which also asks a path vertex's shadow and bounce rays one after the other (the trait's
/// default) where the scene asks them together.
struct SingleRays<'a>(&'a Scene);

impl Intersect for SingleRays<'_> {
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        self.0.intersect(ray, t_min, t_max)
    }
    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        self.0.occluder(ray, t_min, t_max)
    }
}

/// The scene's single-ray queries, offering packets through the trait's default packet
/// queries, which ask one ray at a time: the packet engines on an intersector that has no packet
/// code of its own.
struct DefaultPackets<'a>(&'a Scene);

impl Intersect for DefaultPackets<'_> {
    const PACKETS: bool = true;
    fn intersect(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<Hit> {
        self.0.intersect(ray, t_min, t_max)
    }
    fn occluder(&self, ray: &Ray, t_min: f32, t_max: f32) -> Option<PrimRef> {
        self.0.occluder(ray, t_min, t_max)
    }
}

fn load(path: &Path) -> Scene {
    let file = rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e:?}", path.display()));
    Scene::from_file(&file)
}

fn both(scene: &Scene, s: &RenderSettings) -> (RenderOutput, RenderOutput) {
    let cancel = AtomicBool::new(false);
    let packets = render(scene, s, &|_, _| {}, &cancel).expect("not cancelled");
    let single = render_with(scene, &SingleRays(scene), s, &|_, _| {}, &cancel).expect("not cancelled");
    (packets, single)
}

/// How many pixels of `a` and `b` differ at all.
fn differing(a: &RenderOutput, b: &RenderOutput) -> usize {
    a.film.pixels.iter().zip(&b.film.pixels).filter(|(x, y)| x != y).count()
}

#[test]
fn packet_renders_equal_single_ray_renders() {
    let mut paths: Vec<_> = [
        "basic.txt",
        "room.txt",
        "whitted.txt",
        "camera.txt",
        "obj.txt",
        "beer.txt",
        "phong.txt",
    ]
    .map(rayscope_testkit::scene)
    .into();
    if let Some(course) = rayscope_testkit::course_part() {
        for name in [
            "sample_scene_1.txt",
            "sample_scene_2.txt",
            "sample_scene_2_2021.txt",
            "sample_scene_obj.txt",
        ] {
            paths.push(course.scene(name));
        }
    }
    for path in &paths {
        let scene = load(path);
        // 9 samples a pixel make packets that straddle pixels; 1 makes packets of 16 pixels.
        for (stage, aa) in [(Stage::One, 1), (Stage::Two, 3), (Stage::Two, 1), (Stage::Full, 2)] {
            let s = RenderSettings {
                width: 61,
                height: 47,
                aa,
                stage,
                ..RenderSettings::default()
            };
            let (p, one) = both(&scene, &s);
            let name = path.file_name().unwrap().to_string_lossy();
            assert_eq!(p.counters, one.counters, "{name} {stage:?} -x {aa}: ray counts");
            let diff = differing(&p, &one);
            assert_eq!(diff, 0, "{name} {stage:?} -x {aa}: {diff} pixels differ");
            assert!(
                p.film.pixels.iter().any(|c| c.max_element() > 0.05),
                "{name}: not black"
            );
        }
    }
}

#[test]
fn path_traced_renders_are_the_same_with_camera_packets_and_paired_queries() {
    // Our emitter-lit scenes (and the depth-of-field one, whose camera rays start across the
    // lens; the point-lit room; mirrors and glass), path traced with indirect light and without.
    // The scene traces its paths in waves of sixteen (see `integrator::wave`) where that pays,
    // or else a pixel's camera rays as packets and, at each diffuse or glossy vertex, the emitter
    // sample's shadow ray together with the bounce ray; traced one ray at a time and asked one
    // after the other, the image must be the same bit for bit.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for name in [
        "emissive.txt",
        "glossy.txt",
        "showcase.txt",
        "dof.txt",
        "ambient.txt",
        "whitted.txt",
    ] {
        let scene = load(&root.join(name));
        // The depth-of-field scene through its lens too, whose camera rays start across it.
        let apertures: &[f32] = if name == "dof.txt" { &[0.0, 0.1] } else { &[0.0] };
        for (ambient, &aperture) in [true, false]
            .into_iter()
            .flat_map(|a| apertures.iter().map(move |r| (a, r)))
        {
            let mut s = RenderSettings {
                width: 48,
                height: 36,
                aa: 2,
                quality: 2,
                ambient,
                stage: Stage::Full,
                ..RenderSettings::default()
            };
            if aperture > 0.0 {
                s.camera.aperture_radius = aperture;
                s.camera.focal_length = 3.6;
            }
            let label = format!("{name} -r {aperture} -l {ambient}");
            let (paired, one) = both(&scene, &s);
            assert_eq!(paired.counters, one.counters, "{label}: ray counts");
            // The point-lit room has nothing that sends rays on without -l.
            if ambient || name != "ambient.txt" {
                assert!(paired.counters.secondary > 1000, "{label}: paths go on");
            }
            let diff = differing(&paired, &one);
            assert_eq!(diff, 0, "{label}: {diff} pixels differ");
        }
    }
}

#[test]
fn hits_at_exactly_the_same_distance_go_to_the_first_declared_primitive() {
    // Two coincident walls with different materials: every ray that meets one meets the other at
    // exactly the same distance. Scattered spheres and triangles make the scene a tree, whose
    // single-ray and packet walks visit leaves in different orders. Whatever the order, the tie
    // goes to the primitive declared first, so a render shows that wall, and packet and
    // single-ray renders agree; both declaration orders are checked.
    let mut extra = String::new();
    for i in 0..12 {
        let (x, y) = ((i % 4) as f32 * 0.6 - 0.9, (i / 4) as f32 * 0.6 - 0.6);
        extra += &format!("Sphere \"S{i}\" ({x}, {y}, 1.6) 0.08 \"Blue\"\n");
        extra += &format!(
            "Triangle \"T{i}\" ({x}, {y}, 2.2) ({}, {y}, 2.2) ({x}, {}, 2.2) \"Blue\"\n",
            x + 0.1,
            y + 0.1
        );
    }
    let wall = |name: &str, mat: &str| {
        format!(
            "Triangle \"{name}A\" (-1, -1, 3) (-1, 1, 3) (1, 1, 3) \"{mat}\"\n\
             Triangle \"{name}B\" (-1, -1, 3) (1, 1, 3) (1, -1, 3) \"{mat}\"\n\
             Sphere \"{name}Ball\" (0.3, 0.2, 2.6) 0.2 \"{mat}\"\n"
        )
    };
    let materials = "Material \"Red\" Diffuse (1, 0, 0) 1\nMaterial \"Green\" Diffuse (0, 1, 0) 1\n\
        Material \"Blue\" Diffuse (0, 0, 1) 1\nPointLight \"L\" (0, 0, 0) (1, 1, 1)\n";
    for (first, second, want) in [("Red", "Green", 0), ("Green", "Red", 1)] {
        let text = format!("{materials}{}{}{extra}", wall("W1", first), wall("W2", second));
        let file = rayscope_scene::parse_str(&text, Path::new("coincident.txt")).unwrap();
        let scene = Scene::from_file(&file);
        assert!(
            scene.wide.root != u32::MAX && !scene.wide.nodes.is_empty(),
            "the scene is a tree"
        );
        let s = RenderSettings {
            width: 40,
            height: 40,
            stage: Stage::One,
            camera: rayscope_core::CameraSettings {
                fov_deg: 50.0,
                ..Default::default()
            },
            ..RenderSettings::default()
        };
        let (p, one) = both(&scene, &s);
        assert_eq!(p.film.pixels, one.film.pixels, "{first} first");
        // Pixels showing the wall or its ball (not blue, not background) are the first one's.
        let shown: Vec<_> = p
            .film
            .pixels
            .iter()
            .filter(|c| c.z == 0.0 && c.max_element() > 0.0)
            .collect();
        assert!(shown.len() > 500, "{first} first: {} wall pixels", shown.len());
        let right = shown.iter().filter(|c| c.to_array()[want] == 1.0).count();
        assert_eq!(
            right,
            shown.len(),
            "{first} first: the tie went to {second} in some pixels"
        );
    }
}

#[test]
fn lanes_that_continue_one_ray_at_a_time_match_too() {
    // A switched-off emitter (zero radiance) keeps the render deterministic, so it is traced as
    // packets, but its hits are shaded by the full renderer's general path, one lane at a time;
    // seen directly, through a mirror and through coloured (absorbing) glass.
    let text = "Material \"W\" Diffuse (0.8, 0.8, 0.8) 1\nMaterial \"Off\" Emissive (0, 0, 0) 1\n\
        Material \"M\" Reflective (1, 1, 1) 1\nMaterial \"G\" Refractive (0.4, 0.1, 0.1) 1.5\n\
        PointLight \"L\" (0, 2, 1) (1, 1, 1)\nPlane \"Floor\" (0, -1, 0) (0, 1, 0) \"W\"\n\
        Sphere \"Lamp\" (-0.7, 0, 3) 0.5 \"Off\"\nSphere \"Mirror\" (0.7, 0, 3.5) 0.5 \"M\"\n\
        Sphere \"Glass\" (0, -0.5, 2.2) 0.4 \"G\"\nTriangle \"T\" (-2, -1, 5) (0, 2, 5) (2, -1, 5) \"Off\"\n";
    let file = rayscope_scene::parse_str(text, Path::new("off.txt")).unwrap();
    let scene = Scene::from_file(&file);
    let s = RenderSettings {
        width: 48,
        height: 36,
        aa: 2,
        ..RenderSettings::default()
    };
    assert_eq!(
        rayscope_core::integrator::Integrator::new(&scene, &s).engine(),
        Engine::Packets
    );
    let (p, one) = both(&scene, &s);
    assert_eq!(p.counters, one.counters);
    assert_eq!(p.film.pixels, one.film.pixels);
}

#[test]
fn the_engines_run_on_any_intersector_through_the_default_packet_queries() {
    // Stage 2 (ray packets) and path tracing (waves, with camera packets after the pilot) on
    // an intersector whose packet queries are the trait's defaults: the scene's own images, bit
    // for bit, with the same ray counts.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    for (name, stage, ambient) in [
        ("whitted.txt", Stage::Two, false),
        ("room.txt", Stage::Two, false),
        ("beer.txt", Stage::Full, false),
        ("emissive.txt", Stage::Full, true),
    ] {
        let scene = load(&root.join(name));
        let s = RenderSettings {
            width: 40,
            height: 30,
            aa: 2,
            ambient,
            stage,
            ..RenderSettings::default()
        };
        let default_packets = DefaultPackets(&scene);
        let integ = rayscope_core::integrator::Integrator::with_intersector(&scene, &default_packets, &s);
        assert_ne!(integ.engine(), Engine::OnePath, "{name}");
        let cancel = AtomicBool::new(false);
        let own = render(&scene, &s, &|_, _| {}, &cancel).expect("not cancelled");
        let default = render_with(&scene, &default_packets, &s, &|_, _| {}, &cancel).expect("not cancelled");
        assert_eq!(default.counters, own.counters, "{name}: ray counts");
        let diff = differing(&default, &own);
        assert_eq!(diff, 0, "{name}: {diff} pixels differ");
    }
}

#[test]
fn packets_are_used_only_where_they_apply() {
    use rayscope_core::integrator::Integrator;
    let scene = load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/whitted.txt"));
    let base = RenderSettings::default();
    assert_eq!(Integrator::new(&scene, &base).engine(), Engine::Packets);
    let normals = RenderSettings {
        channel: Channel::Normal,
        ..base
    };
    assert_eq!(
        Integrator::new(&scene, &normals).engine(),
        Engine::OnePath,
        "debug channels"
    );
    let mut dof = base;
    dof.camera.aperture_radius = 0.1;
    assert_eq!(Integrator::new(&scene, &dof).engine(), Engine::Waves, "lens rays");
    let ambient = RenderSettings { ambient: true, ..base };
    assert_eq!(
        Integrator::new(&scene, &ambient).engine(),
        Engine::Waves,
        "path tracing"
    );
    let stage_two_dof = RenderSettings {
        stage: Stage::Two,
        ..dof
    };
    assert_eq!(
        Integrator::new(&scene, &stage_two_dof).engine(),
        Engine::Packets,
        "stage 2 has no depth of field"
    );
    let single_rays = SingleRays(&scene);
    let single = Integrator::with_intersector(&scene, &single_rays, &base);
    assert_eq!(
        single.engine(),
        Engine::OnePath,
        "an intersector without fast packet queries"
    );
}

#[test]
fn a_triangle_edge_between_packet_lanes_is_not_a_crack() {
    // Two triangles sharing an edge that runs between neighbouring pixels: every pixel of the
    // quad must be covered in both paths.
    let text = "Material \"W\" Diffuse (1, 1, 1) 1\nPointLight \"L\" (0, 0, 0) (1, 1, 1)\n\
        Triangle \"A\" (-1, -1, 2) (1, 1, 2) (1, -1, 2) \"W\"\nTriangle \"B\" (-1, -1, 2) (-1, 1, 2) (1, 1, 2) \"W\"\n";
    let file = rayscope_scene::parse_str(text, Path::new("edge.txt")).unwrap();
    let scene = Scene::from_file(&file);
    let _ = Triangle::new; // the scene holds exactly these two triangles
    assert_eq!(scene.triangles.len(), 2);
    let s = RenderSettings {
        width: 32,
        height: 32,
        stage: Stage::Two,
        camera: rayscope_core::CameraSettings {
            fov_deg: 40.0,
            ..Default::default()
        },
        ..RenderSettings::default()
    };
    let (p, one) = both(&scene, &s);
    assert_eq!(p.film.pixels, one.film.pixels);
    assert!(p.film.pixels.iter().all(|c| c.x > 0.0), "a pixel of the quad is black");
}

#[test]
fn deep_mirror_recursion_matches_past_the_packet_depth() {
    // Two facing mirrors: every ray bounces until max_depth, beyond the depth where packets hand
    // over to one ray at a time.
    let text = "Material \"W\" Diffuse (0.8, 0.6, 0.4) 1\nMaterial \"M\" Reflective (1, 1, 1) 1\n\
        Material \"G\" Refractive (0, 0, 0) 1.5\nPointLight \"L\" (0, 1.5, 3) (1, 1, 1)\n\
        Plane \"Left\" (-2, 0, 0) (1, 0, 0) \"M\"\nPlane \"Right\" (2, 0, 0) (-1, 0, 0) \"M\"\n\
        Plane \"Floor\" (0, -1, 0) (0, 1, 0) \"W\"\nSphere \"Ball\" (0.5, -0.4, 3) 0.6 \"W\"\n\
        Sphere \"Glass\" (-0.6, -0.5, 2.5) 0.4 \"G\"\n";
    let file = rayscope_scene::parse_str(text, Path::new("mirrors.txt")).unwrap();
    let scene = Scene::from_file(&file);
    for max_depth in [3, 20] {
        let s = RenderSettings {
            width: 40,
            height: 30,
            aa: 2,
            stage: Stage::Two,
            max_depth,
            ..RenderSettings::default()
        };
        let (p, one) = both(&scene, &s);
        assert_eq!(p.counters, one.counters, "max_depth {max_depth}");
        assert_eq!(p.film.pixels, one.film.pixels, "max_depth {max_depth}");
        if max_depth > 12 {
            assert!(
                p.counters.secondary > 5 * p.counters.camera,
                "rays bounce deep: {:?}",
                p.counters
            );
        }
    }
}
