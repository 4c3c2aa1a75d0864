//! Scene-view tests without a browser: lines land where the geometry says, the image-plane grid
//! has width + 1 and height + 1 lines, and entities occlude rays behind them.

use glam::{Vec3, Vec3A};
use rayscope_core::{Camera, CameraSettings, FovAxis, RenderSettings, Scene};
use rayscope_debug::view::{render_view, ImageMode, Projection, RayMode, RgbImage, ViewCamera, ViewOptions};

/// Our basic scene: a floor plane (entity 0), a green sphere (entity 1), a blue triangle.
fn scene1() -> Scene {
    let file = rayscope_scene::load(&rayscope_testkit::scene("basic.txt")).expect("basic scene loads");
    Scene::from_file(&file)
}

/// The workshop's settings: a 9×9 image, vertical 60° field of view.
fn workshop(w: u32, h: u32) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        camera: CameraSettings {
            fov_axis: FovAxis::Vertical,
            ..CameraSettings::default()
        },
        ..RenderSettings::default()
    }
}

/// Plain options: no ground grid, gizmo, anti-aliasing or x-ray, so pixels are easy to read.
fn plain(cam: ViewCamera, rays: RayMode) -> ViewOptions {
    let mut o = ViewOptions::new(960, 640, cam);
    o.rays = rays;
    o.image = ImageMode::None;
    o.ground_grid = false;
    o.gizmo = false;
    o.antialias = false;
    o.hidden_alpha = 0.0;
    o
}

fn three_quarter() -> ViewCamera {
    ViewCamera {
        eye: Vec3::new(2.2, 1.3, -1.6),
        target: Vec3::new(0.0, 0.0, 1.2),
        fov_deg: 50.0,
    }
}

fn px(img: &RgbImage, x: i64, y: i64) -> [u8; 3] {
    let x = x.clamp(0, img.width as i64 - 1) as usize;
    let y = y.clamp(0, img.height as i64 - 1) as usize;
    let i = (y * img.width as usize + x) * 3;
    [img.rgb[i], img.rgb[i + 1], img.rgb[i + 2]]
}

/// Any pixel within `r` of (x, y) satisfying `pred`.
fn near(img: &RgbImage, x: f32, y: f32, r: i64, pred: impl Fn([u8; 3]) -> bool) -> bool {
    let (cx, cy) = (x.floor() as i64, y.floor() as i64);
    (-r..=r).any(|dy| (-r..=r).any(|dx| pred(px(img, cx + dx, cy + dy))))
}

fn is_blue(c: [u8; 3]) -> bool {
    c[2] > 200 && c[0] < 90 && c[1] < 130
}

fn is_white(c: [u8; 3]) -> bool {
    c.iter().all(|&v| v > 175)
}

#[test]
fn frustum_edges_project_through_the_image_plane_corners() {
    let scene = scene1();
    let s = workshop(9, 9);
    let cam = Camera::new(s.camera, 9, 9);
    let view = three_quarter();
    let proj = Projection::new(&view, 960, 640);
    let with = render_view(&scene, &s, None, &plain(view, RayMode::Frustum)).image;
    let without = render_view(&scene, &s, None, &plain(view, RayMode::None)).image;
    for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        // Halfway between the pinhole and the image-plane corner, and a bit beyond the plane.
        for k in [0.6f32, 1.5] {
            let p = cam.origin + (cam.plane_point_world(u, v) - cam.origin) * k;
            let (x, y, _) = proj.project(p.into()).expect("in front of the view");
            assert!(
                near(&with, x, y, 1, is_blue),
                "frustum edge ({u}, {v}) at {k}: no blue near ({x}, {y})"
            );
            assert!(
                !near(&without, x, y, 2, is_blue),
                "blue at ({x}, {y}) without a frustum"
            );
        }
    }
}

#[test]
fn the_ray_through_a_pixel_goes_through_its_centre_and_ends_at_its_hit() {
    let scene = scene1();
    let s = workshop(9, 9);
    let cam = Camera::new(s.camera, 9, 9);
    let view = three_quarter();
    let proj = Projection::new(&view, 960, 640);
    // Pixel (7, 7): right of centre, below the horizon: its ray hits the floor plane, in plain
    // sight from this view.
    let (x, y) = (7, 7);
    let img = render_view(&scene, &s, None, &plain(view, RayMode::Pixel(x, y))).image;
    let (u, v) = cam.pixel_center(x, y);
    let ray = cam.ray(u, v);
    let hit = scene
        .intersect(&ray, 0.0, f32::INFINITY)
        .expect("pixel (7, 7) sees the floor");
    assert_eq!(scene.entities[scene.prim_info(hit.prim).0 as usize].name, "Plane");
    // The pixel centre on the image plane, and points along the ray.
    let on_plane = cam.plane_point_world(u, v);
    assert!(
        (ray.at(on_plane.length()) - on_plane).length() < 1e-4,
        "the ray passes through the pixel centre"
    );
    for p in [on_plane * 0.5, on_plane, ray.at(hit.t * 0.5), ray.at(hit.t * 0.9)] {
        let (sx, sy, _) = proj.project(p.into()).unwrap();
        assert!(near(&img, sx, sy, 1, is_white), "no white ray pixel near ({sx}, {sy})");
    }
    // The hit is marked with a dot: white fill ringed in black.
    let (hx, hy, _) = proj.project(ray.at(hit.t).into()).unwrap();
    assert!(near(&img, hx, hy, 1, is_white));
    assert!(
        near(&img, hx, hy, 3, |c| c.iter().all(|&v| v < 60)),
        "dark ring around the hit dot"
    );
    // The ray stops at the hit: nothing white beyond it.
    let (bx, by, _) = proj.project(ray.at(hit.t * 1.3).into()).unwrap();
    assert!(!near(&img, bx, by, 1, is_white), "the ray must end at its first hit");
    // Another pixel's ray is not drawn.
    let other = cam.ray(cam.pixel_center(1, 2).0, cam.pixel_center(1, 2).1);
    let (ox, oy, _) = proj.project(other.at(0.6).into()).unwrap();
    assert!(!near(&img, ox, oy, 1, is_white));
}

/// Counts runs of pixels along row `y` that the grid made redder than they are without it.
fn red_runs(img: &RgbImage, base: &RgbImage, y: u32) -> usize {
    let mut runs = 0;
    let mut inside = false;
    for x in 0..img.width {
        let (a, b) = (px(img, x as i64, y as i64), px(base, x as i64, y as i64));
        let r = b[1] as i32 - a[1] as i32 > 30 && b[2] as i32 - a[2] as i32 > 30;
        if r && !inside {
            runs += 1;
        }
        inside = r;
    }
    runs
}

#[test]
fn the_grid_has_width_plus_one_and_height_plus_one_lines() {
    let scene = scene1();
    // Straight on: from behind the ray tracer's camera, looking along +z.
    let view = ViewCamera {
        eye: Vec3::new(0.0, 0.0, -1.0),
        target: Vec3::new(0.0, 0.0, 1.0),
        fov_deg: 50.0,
    };
    let proj = Projection::new(&view, 960, 640);
    for (w, h) in [(9, 9), (12, 9), (5, 7)] {
        let s = workshop(w, h);
        let cam = Camera::new(s.camera, w, h);
        let frame = render_view(&scene, &s, None, &plain(view, RayMode::None));
        assert_eq!((frame.info.grid_lines_x, frame.info.grid_lines_y), (w + 1, h + 1));
        let mut no_grid = plain(view, RayMode::None);
        no_grid.image_grid = false;
        let base = render_view(&scene, &s, None, &no_grid);
        // A scanline through the middle of cell row 1 crosses every vertical line once.
        let (_, y, _) = proj.project(cam.plane_point_world(0.5, 1.5 / h as f32).into()).unwrap();
        assert_eq!(
            red_runs(&frame.image, &base.image, y as u32),
            (w + 1) as usize,
            "{w}×{h}: vertical lines"
        );
        // A column through the middle of cell column 1 crosses every horizontal line once.
        let (x, _, _) = proj.project(cam.plane_point_world(1.5 / w as f32, 0.5).into()).unwrap();
        let transpose = |img: &RgbImage| RgbImage {
            width: img.height,
            height: img.width,
            rgb: (0..img.width)
                .flat_map(|cx| (0..img.height).map(move |cy| (cx, cy)))
                .flat_map(|(cx, cy)| px(img, cx as i64, cy as i64))
                .collect(),
        };
        let runs = red_runs(&transpose(&frame.image), &transpose(&base.image), x as u32);
        assert_eq!(runs, (h + 1) as usize, "{w}×{h}: horizontal lines");
    }
}

#[test]
fn an_entity_in_front_hides_the_ray_behind_it() {
    let scene = scene1();
    let s = workshop(9, 9);
    let cam = Camera::new(s.camera, 9, 9);
    // From behind the sphere, looking back at the camera: the sphere hides the camera and the
    // centre pixel's ray, which ends on the sphere's far side (as seen from here).
    let c = scene.spheres[0].center;
    let view = ViewCamera {
        eye: Vec3::new(c.x, c.y, c.z + 2.5),
        target: Vec3::new(c.x + 0.15, c.y, 0.0),
        fov_deg: 50.0,
    };
    let proj = Projection::new(&view, 960, 640);
    let ray = cam.ray(0.5, 0.5);
    let hit = scene.intersect(&ray, 0.0, f32::INFINITY).unwrap();
    assert_eq!(scene.prim_info(hit.prim).0, 1, "the centre ray hits the sphere");
    let mut opts = plain(view, RayMode::Pixel(4, 4));
    let with = render_view(&scene, &s, None, &opts).image;
    let without = render_view(&scene, &s, None, &plain(view, RayMode::None)).image;
    let mid = ray.at(hit.t * 0.5);
    let (x, y, _) = proj.project(mid.into()).unwrap();
    let green = |c: [u8; 3]| c[1] > 150 && c[0] < 150 && c[2] < 150;
    assert!(
        green(px(&with, x as i64, y as i64)),
        "the sphere covers the ray: {:?}",
        px(&with, x as i64, y as i64)
    );
    for dy in -2..=2 {
        for dx in -2..=2 {
            assert_eq!(
                px(&with, x as i64 + dx, y as i64 + dy),
                px(&without, x as i64 + dx, y as i64 + dy),
                "a hidden ray must not change the picture"
            );
        }
    }
    // With x-ray on, the hidden ray shows faintly: it really is there.
    opts.hidden_alpha = 0.5;
    let xray = render_view(&scene, &s, None, &opts).image;
    assert!(near(&xray, x, y, 1, |c| c != px(&without, x as i64, y as i64)));
    // Sanity: the point is behind the sphere as seen from the eye.
    let to_mid = (mid - Vec3A::from(view.eye)).normalize();
    let occ = rayscope_core::Ray::new(view.eye.into(), to_mid);
    assert!(scene
        .intersect(&occ, 0.0, (mid - Vec3A::from(view.eye)).length())
        .is_some());
}

#[test]
fn the_image_plane_carries_the_rendered_pixels() {
    let scene = scene1();
    let s = workshop(3, 3);
    let cam = Camera::new(s.camera, 3, 3);
    let view = ViewCamera {
        eye: Vec3::new(0.0, 0.0, -1.0),
        target: Vec3::new(0.0, 0.0, 1.0),
        fov_deg: 50.0,
    };
    let proj = Projection::new(&view, 960, 640);
    // A 3×3 image with a distinct colour per pixel.
    let rgb: Vec<u8> = (0..9u8).flat_map(|i| [i * 25, 200 - i * 20, 40 + i * 10]).collect();
    let image = RgbImage {
        width: 3,
        height: 3,
        rgb,
    };
    let mut opts = plain(view, RayMode::None);
    opts.image = ImageMode::Traced;
    let frame = render_view(&scene, &s, Some(&image), &opts).image;
    // Look at cell centres off the camera glyph (which sits in the middle of this view).
    for (x, y) in [(0u32, 0u32), (2, 0), (0, 2), (2, 2), (1, 0)] {
        let (u, v) = cam.pixel_center(x, y);
        let (sx, sy, _) = proj.project(cam.plane_point_world(u, v).into()).unwrap();
        let i = (y * 3 + x) as usize * 3;
        let want = [image.rgb[i], image.rgb[i + 1], image.rgb[i + 2]];
        assert_eq!(px(&frame, sx as i64, sy as i64), want, "cell ({x}, {y})");
    }
}

#[test]
fn odd_and_tiny_frame_sizes_draw() {
    let scene = scene1();
    let s = workshop(9, 9);
    for (w, h) in [(961, 641), (17, 16), (16, 17), (1, 1), (3, 2)] {
        let mut o = ViewOptions::new(w, h, three_quarter());
        o.rays = RayMode::All;
        let f = render_view(&scene, &s, None, &o);
        assert_eq!(f.image.rgb.len(), (w * h * 3) as usize);
    }
}
