//! rayscope's renderer and the checker's oracle check each other: on every course scene and our
//! own, both must find the same entity for every pixel centre and for random rays from the hit
//! points, except where the oracle says the ray passes within rounding of an edge or a rim; and
//! the oracle's camera must give rayscope's camera rays to within f32 rounding.

use std::collections::BTreeMap;
use std::path::Path;

use glam::{DVec3, Vec3, Vec3A};
use rayscope_check::geom::{angle, d3};
use rayscope_check::oracle::{Oracle, OracleCamera};
use rayscope_core::integrator::Integrator;
use rayscope_core::{FovAxis, Ray, RenderSettings, Scene};

/// Distance (relative to the ray's scale) within which a disagreement is rounding: a hundred
/// times the f32 renderer's rounding at unit scale, a tenth of the checker's tie tolerance.
const ROUNDING: f64 = 1e-5;

fn load(path: &Path) -> Scene {
    let file = rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    Scene::from_file(&file)
}

/// The scenes compared: the course's four and every scene of ours.
fn scenes() -> Vec<(String, Scene)> {
    let mut out = Vec::new();
    if let Some(course) = rayscope_testkit::course_part() {
        for name in [
            "sample_scene_1.txt",
            "sample_scene_2.txt",
            "sample_scene_2_2021.txt",
            "sample_scene_obj.txt",
        ] {
            out.push((name.to_string(), load(&course.scene(name))));
        }
    }
    let dir = rayscope_testkit::workspace().join("scenes");
    let mut ours: Vec<_> = std::fs::read_dir(&dir)
        .expect("scenes/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "txt"))
        .collect();
    ours.sort();
    assert!(ours.len() >= 10, "our scenes are missing from {}", dir.display());
    for p in ours {
        out.push((p.file_name().unwrap().to_string_lossy().into_owned(), load(&p)));
    }
    out
}

/// A small deterministic generator (SplitMix64).
struct Rand(u64);

impl Rand {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as f64 / u64::MAX as f64
    }

    fn unit(&mut self) -> DVec3 {
        loop {
            let v = DVec3::new(self.next(), self.next(), self.next()) * 2.0 - DVec3::ONE;
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// What the two sides said about a set of rays.
#[derive(Default, Debug)]
struct Tally {
    rays: u64,
    /// Different answers where the oracle says the ray is within rounding of another answer,
    /// by what is that close.
    near: BTreeMap<String, u64>,
    /// Different answers with nothing close: a bug in one of them.
    wrong: Vec<String>,
}

impl Tally {
    /// Traces `o + t d` for `0 < t < t_max` with both and compares the entities they hit;
    /// returns the oracle's hit point and normal facing the ray.
    fn compare(&mut self, scene: &Scene, oracle: &Oracle, o: Vec3A, d: Vec3A, t_max: f64) -> Option<(DVec3, DVec3)> {
        self.rays += 1;
        let d = d.normalize();
        let rs = scene.intersect(&Ray::new(o, d), 0.0, t_max as f32);
        let rs_entity = rs.map(|h| scene.prim_info(h.prim).0);
        // The same ray, the renderer's f32 numbers read exactly.
        let (od, dd) = (d3(o), d3(d).normalize());
        let h = oracle.closest(od, dd, 0.0, t_max);
        if h.map(|h| h.entity) != rs_entity {
            let far = h.map_or(od, |h| h.point).abs().max_element();
            let eps = ROUNDING * od.abs().max_element().max(far).max(1.0);
            match oracle.near_boundary(od, dd, 0.0, t_max, eps) {
                Some(n) => {
                    // ORACLE_DEBUG=1 lists these rays, to see what kind of tie each is.
                    if std::env::var("ORACLE_DEBUG").is_ok() {
                        eprintln!(
                            "near {n:?} eps {eps:e}: {od} → {dd} t<{t_max}: rs {rs_entity:?} {:?} oracle {:?} {:?}",
                            rs.map(|h| h.t),
                            h.map(|h| h.entity),
                            h.map(|h| h.t)
                        );
                    }
                    *self.near.entry(format!("{:?}", n.kind)).or_default() += 1
                }
                None => self.wrong.push(format!(
                    "ray {od} → {dd} (t < {t_max}): renderer {:?} at {:?}, oracle {:?} at {:?}",
                    rs_entity,
                    rs.map(|h| h.t),
                    h.map(|h| h.entity),
                    h.map(|h| h.t)
                )),
            }
        }
        h.map(|h| (h.point, if h.front { h.normal } else { -h.normal }))
    }
}

#[test]
fn renderer_and_oracle_agree_on_what_every_ray_hits() {
    let mut total = Tally::default();
    for (name, scene) in scenes() {
        let oracle = Oracle::new(&scene);
        let settings = RenderSettings {
            width: 64,
            height: 48,
            ..RenderSettings::default()
        };
        let camera = Integrator::new(&scene, &settings).camera;
        let mut rng = Rand(0x5EED ^ name.len() as u64);
        let mut t = Tally::default();
        for y in 0..settings.height {
            for x in 0..settings.width {
                let (u, v) = camera.pixel_center(x, y);
                let ray = camera.ray(u, v);
                let Some((p, n)) = t.compare(&scene, &oracle, ray.origin, ray.dir, f64::INFINITY) else {
                    continue;
                };
                let scale = p.abs().max_element().max(1.0);
                // Random rays leaving the hit on either side, as reflected and refracted rays do.
                for _ in 0..6 {
                    let d = rng.unit();
                    let side = if d.dot(n) >= 0.0 { n } else { -n };
                    let o = p + side * (1e-5 * scale);
                    t.compare(
                        &scene,
                        &oracle,
                        Vec3A::from(o.as_vec3()),
                        Vec3A::from(d.as_vec3()),
                        f64::INFINITY,
                    );
                }
                // Shadow rays: does anything lie between the hit and each light?
                for light in &scene.lights {
                    let lp = light.position.as_dvec3();
                    let o = p + n * (1e-5 * scale);
                    let to = lp - o;
                    if to.length() > 1e-3 {
                        t.compare(
                            &scene,
                            &oracle,
                            Vec3A::from(o.as_vec3()),
                            Vec3A::from(to.as_vec3()),
                            to.length() * (1.0 - 1e-6),
                        );
                    }
                }
            }
        }
        eprintln!(
            "{name}: {} rays; differ within rounding {:?}; otherwise {}",
            t.rays,
            t.near,
            t.wrong.len()
        );
        assert!(t.rays > 3072, "{name}: {} rays", t.rays);
        assert!(
            t.wrong.is_empty(),
            "{name}: the renderer and the oracle disagree away from any edge:\n{}",
            t.wrong[..t.wrong.len().min(10)].join("\n")
        );
        // Rays within rounding of an edge or a rim are rare. Surfaces that coincide (ambient.txt's
        // boxes stand on the floor with floors of their own) tie wherever a ray meets them.
        let edges: u64 = t.near.iter().filter(|(k, _)| *k != "Depth").map(|(_, n)| n).sum();
        assert!(
            edges * 500 <= t.rays,
            "{name}: {edges} of {} rays near an edge or rim",
            t.rays
        );
        total.rays += t.rays;
        for (k, n) in t.near {
            *total.near.entry(k).or_default() += n;
        }
    }
    eprintln!("all scenes: {} rays; within rounding {:?}", total.rays, total.near);
}

/// A scene with nothing stochastic, so the renderer's camera rays sit at the cell centres.
fn plain_scene() -> Scene {
    let src = "Material \"M\" Diffuse (1, 1, 1) 1\nSphere \"S\" (0, 0, 3) 1 \"M\"\n";
    Scene::from_file(&rayscope_scene::parse_str(src, Path::new("s.txt")).expect("scene"))
}

#[test]
fn oracle_camera_gives_rayscopes_camera_rays() {
    let scene = plain_scene();
    let moved = rayscope_core::CameraSettings {
        position: Vec3::new(0.5, 1.0, -2.0),
        axis: Vec3::new(0.3, -1.0, 0.2),
        angle_deg: 37.0,
        ..Default::default()
    };
    let down = rayscope_core::CameraSettings {
        axis: Vec3::X,
        angle_deg: 45.0,
        fov_axis: FovAxis::Vertical,
        ..Default::default()
    };
    let mut cases = Vec::new();
    for (w, h) in [(400, 300), (40, 40)] {
        for aa in [1, 3] {
            for camera in [Default::default(), moved, down] {
                cases.push(RenderSettings {
                    width: w,
                    height: h,
                    aa,
                    camera,
                    ..RenderSettings::default()
                });
            }
        }
    }
    for s in &cases {
        let integ = Integrator::new(&scene, s);
        let cam = OracleCamera::new(s);
        let spp = integ.samples_per_pixel();
        assert_eq!(spp, cam.grid * cam.grid, "{s:?}");
        let mut worst: f64 = 0.0;
        for y in 0..s.height {
            for x in 0..s.width {
                for k in 0..spp {
                    let rs = integ.camera_ray(x, y, k, &mut integ.sample_rng(x, y, k));
                    let (o, d) = cam.ray(x, y, k);
                    assert!(
                        (o - d3(rs.origin)).length() < 1e-6,
                        "{s:?}: origin {o} vs {}",
                        rs.origin
                    );
                    worst = worst.max(angle(d, d3(rs.dir)));
                }
            }
        }
        // f32 rounding of the image position, the rotation and the normalisation: a few ulps of
        // a unit vector, far below the checker's camera tolerance (2e-5 rad) and the spacing
        // of neighbouring samples (1.2e-4 rad at 400 × 3).
        eprintln!(
            "{}×{} -x {} axis {}: worst angle {worst:.2e} rad",
            s.width, s.height, s.aa, s.camera.axis
        );
        assert!(
            worst < 1e-6,
            "{}×{} -x {} {:?}: worst angle {worst:e}",
            s.width,
            s.height,
            s.aa,
            s.camera
        );
    }
}

#[test]
fn rays_through_the_bunnys_shared_edges_never_slip_through() {
    let Some(course) = rayscope_testkit::course() else {
        return;
    };
    let scene = load(&course.scene("sample_scene_obj.txt"));
    let oracle = Oracle::new(&scene);
    let bunny = scene
        .entities
        .iter()
        .position(|e| e.kind == "ObjModel")
        .expect("the bunny") as u32;
    // Edges by their corners' bits: an edge two triangles share has the same corners in both.
    let key = |a: DVec3, b: DVec3| {
        let (a, b) = (a.to_array().map(f64::to_bits), b.to_array().map(f64::to_bits));
        if a < b {
            (a, b)
        } else {
            (b, a)
        }
    };
    let mut edges: BTreeMap<_, (DVec3, DVec3, Vec<DVec3>)> = BTreeMap::new();
    for i in 0..scene.triangles.len() as u32 {
        if scene.triangle_info[i as usize].entity != bunny {
            continue;
        }
        let v = oracle.triangle(i);
        let n = (v[1] - v[0]).cross(v[2] - v[0]);
        for k in 0..3 {
            let (a, b) = (v[k], v[(k + 1) % 3]);
            edges.entry(key(a, b)).or_insert((a, b, Vec::new())).2.push(n);
        }
    }
    let shared: Vec<_> = edges.values().filter(|e| e.2.len() == 2).collect();
    // The bunny has 4968 triangles and 7715 edges, all but the 526 on the rims of its holes
    // shared by two; with corners left off the f32 grid (v0 + the scene's f32 edge), 88 of
    // them would differ in the last bits from one triangle to the other.
    assert_eq!((shared.len(), edges.len()), (7189, 7715));
    let mut rays = 0;
    for &(a, b, n) in &shared {
        for w in [0.5, 1.0 / 3.0, 0.9] {
            let p = a + (b - a) * w;
            // From the camera, and from beside the bunny through the edge.
            for o in [DVec3::ZERO, p + DVec3::new(0.37, 0.21, -0.5)] {
                let d = (p - o).normalize();
                let dist = (p - o).length();
                if n[0].dot(d).signum() != n[1].dot(d).signum() {
                    // A silhouette: both triangles lie on one side of the edge as the ray sees
                    // them, so a ray along it may genuinely pass between.
                    continue;
                }
                let h = oracle
                    .closest(o, d, 0.0, f64::INFINITY)
                    .expect("the ray meets the bunny");
                rays += 1;
                assert!(
                    h.t <= dist * (1.0 + 1e-12),
                    "ray {o} → {p} through a shared edge meets '{}' at t = {} beyond the edge at {dist}",
                    scene.entities[h.entity as usize].name,
                    h.t
                );
            }
        }
    }
    eprintln!(
        "{} shared edges of {}; {rays} rays through them",
        shared.len(),
        edges.len()
    );
}
