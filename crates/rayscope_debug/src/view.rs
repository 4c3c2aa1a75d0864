//! The scene view: the scene seen from an orbit camera, drawn on the CPU with the core's
//! intersector, with the ray tracer's camera, frustum, image plane (a pixel grid carrying the
//! rendered image) and debug rays drawn in as depth-tested, anti-aliased 3D lines.
//!
//! One implementation serves the browser (frames sent as JPEG/PNG) and `rayscope view -o`.
//!
//! Coordinates: world space is the course's (left-handed, +y up, the ray tracer's camera looks
//! along +z when unrotated). Image pixels are 0-based from the top-left; pixel (x, y) spans
//! normalised image coordinates [x/W, (x+1)/W] × [y/H, (y+1)/H] on the image plane at distance 1.

use std::str::FromStr;
use std::sync::Arc;
use std::time::Instant;

use glam::{Vec2, Vec3, Vec3A, Vec4};
use rayon::prelude::*;
use rayscope_core::integrator::Integrator;
use rayscope_core::scene::{Lobe, PrimRef, Scene};
use rayscope_core::{Camera, Ray, RayKind, RayTree, RenderSettings};
use serde::{Deserialize, Serialize};

use crate::canvas::{Canvas, ScreenPoint, ID_NONE};

/// Ids of the view's own objects in the id buffer (entities use their index).
const ID_LIGHT: u32 = 0x4000_0000;
const ID_QUAD: u32 = 0x5000_0000;
const ID_CAMERA: u32 = 0x7fff_fff0;

/// Which debug rays to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum RayMode {
    /// No rays and no frustum.
    None,
    /// The four frustum edge rays only.
    Frustum,
    /// The frustum and the ray through the centre of pixel (x, y).
    Pixel(u32, u32),
    /// The frustum and the rays through every pixel of row y.
    Row(u32),
    /// The frustum and a ray through every pixel centre (decimated past the ray cap).
    All,
}

impl FromStr for RayMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        let bad = || format!("expected none, frustum, pixel:X,Y, row:Y or all, found '{s}'");
        match s {
            "none" => Ok(RayMode::None),
            "frustum" => Ok(RayMode::Frustum),
            "all" => Ok(RayMode::All),
            _ => {
                if let Some(rest) = s.strip_prefix("pixel:") {
                    let (x, y) = rest.split_once(',').ok_or_else(bad)?;
                    let x = x.trim().parse().map_err(|_| bad())?;
                    let y = y.trim().parse().map_err(|_| bad())?;
                    Ok(RayMode::Pixel(x, y))
                } else if let Some(rest) = s.strip_prefix("row:") {
                    Ok(RayMode::Row(rest.trim().parse().map_err(|_| bad())?))
                } else {
                    Err(bad())
                }
            }
        }
    }
}

/// What the image plane shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ImageMode {
    /// The rendered image (or a debug channel), one grid cell per pixel.
    Traced,
    /// A black image (the workshop's "image all black" step).
    Black,
    /// The grid only.
    None,
}

impl FromStr for ImageMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.trim() {
            "traced" => Ok(ImageMode::Traced),
            "black" => Ok(ImageMode::Black),
            "none" => Ok(ImageMode::None),
            other => Err(format!("expected traced, black or none, found '{other}'")),
        }
    }
}

/// Something selected in the hierarchy, highlighted in the view.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(tag = "type", content = "index", rename_all = "lowercase")]
pub enum Selection {
    /// An entity by index.
    Entity(u32),
    /// A point light by index.
    Light(u32),
    /// The ray tracer's camera.
    Camera,
    /// A pixel of the image plane (x, y).
    Pixel(u32, u32),
}

/// The orbit camera the view is seen from (vertical field of view).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewCamera {
    /// Eye position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view in degrees.
    pub fov_deg: f32,
}

/// An 8-bit RGB image shown on the image plane.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// RGB bytes, row-major from the top-left.
    pub rgb: Vec<u8>,
}

/// Everything that shapes a view frame besides the scene and the render settings.
#[derive(Debug, Clone)]
pub struct ViewOptions {
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Where the view is seen from.
    pub camera: ViewCamera,
    /// Debug rays.
    pub rays: RayMode,
    /// What the image plane shows.
    pub image: ImageMode,
    /// Highlighted hierarchy item.
    pub selection: Option<Selection>,
    /// Selected image pixel (outlined on the grid; its samples are shown with `samples`).
    pub pixel: Option<(u32, u32)>,
    /// A ray tree to draw, coloured by ray kind.
    pub tree: Option<RayTree>,
    /// Show the sub-pixel sample positions of `pixel` and their rays.
    pub samples: bool,
    /// Grid cells to flag (e.g. intersector mismatches), drawn in magenta.
    pub highlight: Vec<(u32, u32)>,
    /// Skip the back faces of planes and triangles, so a closed room can be seen from outside.
    pub cutaway: bool,
    /// Draw the ground grid.
    pub ground_grid: bool,
    /// Draw the image plane's red pixel grid.
    pub image_grid: bool,
    /// Opacity of the hidden parts of lines (0: hidden).
    pub hidden_alpha: f32,
    /// Most debug rays drawn for `RayMode::All`/`Row` (a stride thins them out beyond).
    pub max_rays: u32,
    /// Draw the axis gizmo in the top-right corner.
    pub gizmo: bool,
    /// Smooth the scene's silhouettes with extra samples on edge pixels.
    pub antialias: bool,
    /// Draw the selected entity's normals as arrows (a triangle's vertices numbered 0, 1, 2).
    pub normals: bool,
    /// Another tracer's rays (a student's ray log), drawn dashed beside rayscope's.
    pub foreign_rays: Vec<ForeignRay>,
    /// Per image pixel (row-major from the top-left), a colour blended over its grid cell with
    /// weight alpha / 255: the verdict map of a student's log.
    pub cell_tint: Option<Arc<Vec<[u8; 4]>>>,
}

/// A ray of another tracer (a student's log), drawn dashed in its kind's colour.
#[derive(Debug, Clone, PartialEq)]
pub struct ForeignRay {
    /// Origin.
    pub origin: Vec3,
    /// Direction (any length).
    pub direction: Vec3,
    /// Where the tracer says it ends (`None`: it fades out far away).
    pub end: Option<Vec3>,
    /// Line colour (see [`kind_color_named`]).
    pub color: Vec3,
    /// Drawn wide with an orange halo and end rings: the first ray where the trees part.
    pub highlight: bool,
}

impl ViewOptions {
    /// Defaults for a `width` × `height` frame seen from `camera`.
    #[must_use]
    pub fn new(width: u32, height: u32, camera: ViewCamera) -> Self {
        Self {
            width,
            height,
            camera,
            rays: RayMode::Frustum,
            image: ImageMode::Traced,
            selection: None,
            pixel: None,
            tree: None,
            samples: false,
            highlight: Vec::new(),
            cutaway: true,
            ground_grid: true,
            image_grid: true,
            hidden_alpha: 0.12,
            max_rays: 4096,
            gizmo: true,
            antialias: true,
            normals: false,
            foreign_rays: Vec::new(),
            cell_tint: None,
        }
    }
}

/// Facts about a drawn frame, for the UI.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ViewInfo {
    /// Debug rays drawn (pixel rays, not counting the frustum).
    pub rays_drawn: u32,
    /// Every `ray_stride`-th pixel in x and y got a ray.
    pub ray_stride: u32,
    /// Every `grid_step`-th grid line was drawn (1: all of them).
    pub grid_step: u32,
    /// Vertical grid lines drawn (image width + 1 when `grid_step` is 1).
    pub grid_lines_x: u32,
    /// Horizontal grid lines drawn (image height + 1 when `grid_step` is 1).
    pub grid_lines_y: u32,
    /// Milliseconds spent drawing, in all.
    pub millis: f64,
    /// Milliseconds of that spent on the scene pass (tracing the view's rays).
    pub scene_millis: f64,
}

/// A drawn view.
#[derive(Debug, Clone)]
pub struct ViewFrame {
    /// The picture.
    pub image: RgbImage,
    /// Facts about it.
    pub info: ViewInfo,
}

/// The view camera's projection.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    eye: Vec3A,
    right: Vec3A,
    up: Vec3A,
    fwd: Vec3A,
    focal: f32,
    cx: f32,
    cy: f32,
}

/// Nearest camera-space depth a line is drawn at.
const NEAR: f32 = 1e-3;

impl Projection {
    /// The projection of `cam` into a `width` × `height` frame.
    #[must_use]
    pub fn new(cam: &ViewCamera, width: u32, height: u32) -> Self {
        let eye = Vec3A::from(cam.eye);
        let mut fwd = (Vec3A::from(cam.target) - eye).normalize_or_zero();
        if fwd == Vec3A::ZERO {
            fwd = Vec3A::Z;
        }
        // Left-handed, +y up: right = up × forward.
        let mut right = Vec3A::Y.cross(fwd);
        if right.length_squared() < 1e-8 {
            right = Vec3A::Z.cross(fwd);
        }
        let right = right.normalize();
        let up = fwd.cross(right);
        let fov = cam.fov_deg.clamp(1.0, 170.0).to_radians();
        Self {
            eye,
            right,
            up,
            fwd,
            focal: height as f32 * 0.5 / (fov * 0.5).tan(),
            cx: width as f32 * 0.5,
            cy: height as f32 * 0.5,
        }
    }

    /// World point to camera space (x right, y up, z forward).
    #[must_use]
    #[inline]
    pub fn to_camera(&self, p: Vec3A) -> Vec3A {
        let d = p - self.eye;
        Vec3A::new(d.dot(self.right), d.dot(self.up), d.dot(self.fwd))
    }

    /// Camera-space point (z > 0) to the screen.
    #[must_use]
    #[inline]
    pub fn screen(&self, c: Vec3A) -> ScreenPoint {
        ScreenPoint {
            p: Vec2::new(self.cx + c.x / c.z * self.focal, self.cy - c.y / c.z * self.focal),
            inv_z: 1.0 / c.z,
        }
    }

    /// Projects a world point: pixel position (continuous, centres at +0.5) and depth.
    #[must_use]
    pub fn project(&self, p: Vec3) -> Option<(f32, f32, f32)> {
        let c = self.to_camera(p.into());
        (c.z > NEAR).then(|| {
            let s = self.screen(c);
            (s.p.x, s.p.y, c.z)
        })
    }

    /// The view ray through the continuous pixel position (`px`, `py`).
    #[must_use]
    #[inline]
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let d = self.fwd + self.right * ((px - self.cx) / self.focal) - self.up * ((py - self.cy) / self.focal);
        Ray::new(self.eye, d.normalize())
    }
}

/// A three-quarter view from behind and to the left of the ray tracer's camera that shows the
/// camera, its image plane and the scene's finite geometry (the workshop's framing).
#[must_use]
pub fn auto_view(scene: &Scene, settings: &RenderSettings, aspect: f32) -> ViewCamera {
    let cam = Camera::new(settings.camera, settings.width, settings.height);
    let fov_deg = 50.0f32;
    let mut pts = vec![cam.origin];
    for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        pts.push(cam.plane_point_world(u, v));
    }
    let b = scene.bounds;
    if !b.is_empty() && (b.max - b.min).length() < 1e4 {
        for i in 0..8 {
            pts.push(Vec3A::new(
                if i & 1 == 0 { b.min.x } else { b.max.x },
                if i & 2 == 0 { b.min.y } else { b.max.y },
                if i & 4 == 0 { b.min.z } else { b.max.z },
            ));
        }
    } else {
        pts.push(cam.origin + cam.rotation * Vec3A::Z * 3.0);
    }
    let (lo, hi) = pts
        .iter()
        .fold((pts[0], pts[0]), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let center = (lo + hi) * 0.5;
    let radius = pts.iter().map(|p| (*p - center).length()).fold(0.5f32, f32::max);
    // Behind, to the left and above the ray tracer's camera, in its own frame.
    let r = cam.rotation;
    let (right, up, fwd) = (r * Vec3A::X, Vec3A::Y, r * Vec3A::Z);
    let dir = (right * 0.8 + up * 0.45 - fwd * 0.8).normalize();
    let half = (fov_deg.to_radians() * 0.5).tan() * aspect.min(1.0);
    let dist = radius / half.atan().sin() * 0.85;
    ViewCamera {
        eye: (center + dir * dist).into(),
        target: center.into(),
        fov_deg,
    }
}

/// Per-frame constants the scene pass needs.
struct Ctx<'a> {
    scene: &'a Scene,
    proj: Projection,
    opts: &'a ViewOptions,
    cam: Camera,
    cam_from_world: glam::Mat3A,
    /// Image plane: corner (0,0), edge vectors along u and v, normal.
    q0: Vec3A,
    qu: Vec3A,
    qv: Vec3A,
    qn: Vec3A,
    image: Option<&'a RgbImage>,
    selected_id: u32,
    scale: f32,
    highlight: Vec<bool>,
}

#[derive(Clone, Copy)]
struct Sample {
    color: Vec3,
    z: f32,
    id: u32,
}

fn sky(dir: Vec3A) -> Vec3 {
    let top = Vec3::new(0.40, 0.47, 0.55);
    let horizon = Vec3::new(0.74, 0.70, 0.56);
    let ground = Vec3::new(0.30, 0.30, 0.32);
    if dir.y >= 0.0 {
        horizon.lerp(top, dir.y.sqrt().min(1.0))
    } else {
        horizon.lerp(ground, (-dir.y * 4.0).sqrt().min(1.0))
    }
}

/// A display colour for a material: reflective and refractive ones get a tint of their own,
/// since their colour does not show in a render.
fn material_color(lobe: Lobe, c: Vec3) -> Vec3 {
    match lobe {
        Lobe::Mirror => Vec3::new(0.80, 0.82, 0.86),
        Lobe::Dielectric => Vec3::new(0.62, 0.82, 0.92),
        Lobe::Emitter => c / c.max_element().max(1.0),
        Lobe::Lambert | Lobe::Bsdf => c.clamp(Vec3::ZERO, Vec3::ONE),
    }
}

fn ray_box(o: Vec3A, d: Vec3A, lo: Vec3A, hi: Vec3A) -> Option<(f32, Vec3A)> {
    let inv = d.recip();
    let t0 = (lo - o) * inv;
    let t1 = (hi - o) * inv;
    let tmin = t0.min(t1);
    let tmax = t0.max(t1);
    let tn = tmin.max_element();
    let tf = tmax.min_element();
    if tn > tf || tf <= 0.0 || tn <= 0.0 {
        return None;
    }
    let n = if tn == tmin.x {
        Vec3A::X * -d.x.signum()
    } else if tn == tmin.y {
        Vec3A::Y * -d.y.signum()
    } else {
        Vec3A::Z * -d.z.signum()
    };
    Some((tn, n))
}

fn ray_sphere(o: Vec3A, d: Vec3A, c: Vec3A, r: f32) -> Option<f32> {
    let oc = o - c;
    let b = oc.dot(d);
    let disc = b * b - (oc.length_squared() - r * r);
    if disc < 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t > 0.0).then_some(t)
}

/// Camera glyph body in the ray tracer's camera space (behind the pinhole).
const BODY_LO: Vec3A = Vec3A::new(-0.06, -0.05, -0.25);
const BODY_HI: Vec3A = Vec3A::new(0.06, 0.05, -0.06);
const LIGHT_RADIUS: f32 = 0.045;

impl Ctx<'_> {
    fn sample(&self, px: f32, py: f32) -> Sample {
        let ray = self.proj.ray(px, py);
        let cos_f = ray.dir.dot(self.proj.fwd);
        let mut best = Sample {
            color: Vec3::ZERO,
            z: f32::INFINITY,
            id: ID_NONE,
        };
        let mut best_t = f32::INFINITY;
        // The scene, skipping back faces of planes and triangles in cutaway mode.
        let mut t_min = 0.0f32;
        for _ in 0..16 {
            let Some(hit) = self.scene.intersect(&ray, t_min, f32::INFINITY) else {
                break;
            };
            let s = self.scene.surface(&ray, &hit);
            let culled = self.opts.cutaway && !s.front_face && !matches!(hit.prim, PrimRef::Sphere(_));
            if culled {
                t_min = hit.t * (1.0 + 1e-5) + 1e-5;
                continue;
            }
            let m = &self.scene.materials[s.material as usize];
            let base = material_color(m.lobe(), m.color);
            let ndv = s.shading_normal.dot(-ray.dir).abs();
            let k = if m.lobe() == Lobe::Emitter {
                1.0
            } else {
                (0.62 + 0.3 * ndv + 0.1 * s.shading_normal.y.max(0.0)).min(1.0)
            };
            let mut c = base * k;
            if m.lobe() == Lobe::Mirror {
                // A hint of the sky in the mirror.
                let r = ray.dir - s.normal * (2.0 * ray.dir.dot(s.normal));
                c = c * 0.6 + sky(r) * 0.4;
            }
            let z = hit.t * cos_f;
            // Haze towards the horizon (negligible, so skipped, near the scene).
            if hit.t > self.scale {
                let fog = 1.0 - (-(hit.t / (self.scale * 14.0)).powi(2)).exp();
                c = c.lerp(sky(Vec3A::new(ray.dir.x, 0.0, ray.dir.z).normalize_or_zero()), fog);
            }
            if s.entity == self.selected_id {
                c = c.lerp(Vec3::new(1.0, 0.62, 0.2), 0.22);
            }
            best = Sample {
                color: c,
                z,
                id: s.entity,
            };
            best_t = hit.t;
            break;
        }
        // The image plane.
        let denom = ray.dir.dot(self.qn);
        if denom != 0.0 && self.opts.image != ImageMode::None {
            let t = (self.q0 - ray.origin).dot(self.qn) / denom;
            if t > 0.0 && t < best_t {
                let q = ray.at(t) - self.q0;
                let a = q.dot(self.qu) / self.qu.length_squared();
                let b = q.dot(self.qv) / self.qv.length_squared();
                if (0.0..1.0).contains(&a) && (0.0..1.0).contains(&b) {
                    let (w, h) = (self.cam.width, self.cam.height);
                    let ix = ((a * w as f32) as u32).min(w - 1);
                    let iy = ((b * h as f32) as u32).min(h - 1);
                    let mut c = match (self.opts.image, self.image) {
                        (ImageMode::Traced, Some(img)) if img.width == w && img.height == h => {
                            let i = (iy * w + ix) as usize * 3;
                            Vec3::new(img.rgb[i] as f32, img.rgb[i + 1] as f32, img.rgb[i + 2] as f32) / 255.0
                        }
                        _ => Vec3::splat(0.02),
                    };
                    if let Some(t) = self.opts.cell_tint.as_deref() {
                        if let Some(&[r, g, b, a]) = t.get((iy * w + ix) as usize) {
                            let tint = Vec3::new(f32::from(r), f32::from(g), f32::from(b)) / 255.0;
                            c = c.lerp(tint, f32::from(a) / 255.0);
                        }
                    }
                    if !self.highlight.is_empty() && self.highlight[(iy * w + ix) as usize] {
                        c = c.lerp(Vec3::new(1.0, 0.0, 1.0), 0.65);
                    }
                    best_t = t;
                    best = Sample {
                        color: c,
                        z: t * cos_f,
                        id: ID_QUAD + iy * w + ix,
                    };
                }
            }
        }
        // The camera glyph's body.
        let o = self.cam_from_world * (ray.origin - self.cam.origin);
        let d = self.cam_from_world * ray.dir;
        if let Some((t, n)) = ray_box(o, d, BODY_LO, BODY_HI) {
            if t < best_t {
                let k = 0.55 + 0.45 * n.dot(-d).abs();
                let mut c = Vec3::new(0.93, 0.93, 0.95) * k;
                if self.selected_id == ID_CAMERA {
                    c = c.lerp(Vec3::new(1.0, 0.62, 0.2), 0.35);
                }
                best_t = t;
                best = Sample {
                    color: c,
                    z: t * cos_f,
                    id: ID_CAMERA,
                };
            }
        }
        // Light markers.
        for (i, l) in self.scene.lights.iter().enumerate() {
            let c = Vec3A::from(l.position);
            if let Some(t) = ray_sphere(ray.origin, ray.dir, c, LIGHT_RADIUS) {
                if t < best_t {
                    let n = (ray.at(t) - c).normalize();
                    let glow = 0.75 + 0.25 * n.dot(-ray.dir).abs();
                    let lc = l.color / l.color.max_element().max(1e-6);
                    best_t = t;
                    best = Sample {
                        color: (Vec3::new(1.0, 0.9, 0.45) * 0.6 + lc * 0.4) * glow,
                        z: t * cos_f,
                        id: ID_LIGHT + i as u32,
                    };
                }
            }
        }
        if best.id == ID_NONE {
            best.color = sky(ray.dir);
        }
        best
    }

    /// Class for silhouette detection: all of the image plane counts as one object.
    fn class(id: u32) -> u32 {
        if (ID_QUAD..ID_CAMERA).contains(&id) {
            ID_QUAD
        } else {
            id
        }
    }
}

/// Draws the scene view of `scene` rendered with `settings`; `image` (the rendered image or a
/// debug channel, `settings.width` × `settings.height`) is painted on the image plane.
#[must_use]
pub fn render_view(
    scene: &Scene,
    settings: &RenderSettings,
    image: Option<&RgbImage>,
    opts: &ViewOptions,
) -> ViewFrame {
    let start = Instant::now();
    let (w, h) = (opts.width.max(1), opts.height.max(1));
    let proj = Projection::new(&opts.camera, w, h);
    let cam = Camera::new(settings.camera, settings.width.max(1), settings.height.max(1));
    let (q0, qu, qv) = image_plane_frame(&cam);
    let mut highlight = Vec::new();
    if !opts.highlight.is_empty() {
        highlight = vec![false; cam.width as usize * cam.height as usize];
        for &(x, y) in &opts.highlight {
            if x < cam.width && y < cam.height {
                highlight[(y * cam.width + x) as usize] = true;
            }
        }
    }
    let selected_id = match opts.selection {
        Some(Selection::Entity(e)) => e,
        Some(Selection::Light(l)) => ID_LIGHT + l,
        Some(Selection::Camera) => ID_CAMERA,
        _ => ID_NONE - 1,
    };
    let mut pts = vec![cam.origin, q0, q0 + qu + qv];
    let b = scene.bounds;
    if !b.is_empty() {
        pts.push(b.min);
        pts.push(b.max);
    }
    let (lo, hi) = pts
        .iter()
        .fold((pts[0], pts[0]), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let scale = (hi - lo).length().clamp(2.0, 1e4);
    let ctx = Ctx {
        scene,
        proj,
        opts,
        cam,
        cam_from_world: cam.rotation.transpose(),
        q0,
        qu,
        qv,
        qn: qu.cross(qv).normalize_or_zero(),
        image,
        selected_id,
        scale,
        highlight,
    };

    // Scene pass, in parallel over rows. Every second pixel in x and y is traced first; a pixel
    // whose four traced neighbours show the same object (and the same image-plane cell) is
    // interpolated from them (colour bilinearly, depth as 1/z, exact for planes), the others are
    // traced. Silhouettes and cell edges stay exact at a quarter of the rays elsewhere.
    let n = w as usize * h as usize;
    let (cw, ch) = ((w as usize).div_ceil(2) + 1, (h as usize).div_ceil(2) + 1);
    let blank = Sample {
        color: Vec3::ZERO,
        z: f32::INFINITY,
        id: ID_NONE,
    };
    let mut coarse = vec![blank; cw * ch];
    coarse.par_chunks_mut(cw).enumerate().for_each(|(j, row)| {
        for (i, s) in row.iter_mut().enumerate() {
            *s = ctx.sample(2.0 * i as f32 + 0.5, 2.0 * j as f32 + 0.5);
        }
    });
    let mut color = vec![Vec3::ZERO; n];
    let mut depth = vec![f32::INFINITY; n];
    let mut id = vec![ID_NONE; n];
    color
        .par_chunks_mut(w as usize)
        .zip(depth.par_chunks_mut(w as usize))
        .zip(id.par_chunks_mut(w as usize))
        .enumerate()
        .for_each(|(y, ((cr, dr), ir))| {
            let j = y / 2;
            let fy = (y % 2) as f32 * 0.5;
            for x in 0..w as usize {
                let i = x / 2;
                let fx = (x % 2) as f32 * 0.5;
                let a = coarse[j * cw + i];
                let s = if fx == 0.0 && fy == 0.0 {
                    a
                } else {
                    let (b, c, d) = (
                        coarse[j * cw + i + 1],
                        coarse[(j + 1) * cw + i],
                        coarse[(j + 1) * cw + i + 1],
                    );
                    if a.id == b.id && a.id == c.id && a.id == d.id {
                        let lerp2 = |p: f32, q: f32, r: f32, t: f32| {
                            (p * (1.0 - fx) + q * fx) * (1.0 - fy) + (r * (1.0 - fx) + t * fx) * fy
                        };
                        let color = (a.color * (1.0 - fx) + b.color * fx) * (1.0 - fy)
                            + (c.color * (1.0 - fx) + d.color * fx) * fy;
                        let z = if a.id == ID_NONE {
                            f32::INFINITY
                        } else {
                            1.0 / lerp2(1.0 / a.z, 1.0 / b.z, 1.0 / c.z, 1.0 / d.z)
                        };
                        Sample { color, z, id: a.id }
                    } else {
                        ctx.sample(x as f32 + 0.5, y as f32 + 0.5)
                    }
                };
                cr[x] = s.color;
                dr[x] = s.z;
                ir[x] = s.id;
            }
        });

    // Silhouette anti-aliasing: re-sample pixels on object edges with 4 more samples.
    if opts.antialias {
        let wu = w as usize;
        let edge: Vec<usize> = (0..n)
            .into_par_iter()
            .filter(|&i| {
                let (x, y) = (i % wu, i / wu);
                let c = Ctx::class(id[i]);
                (x + 1 < wu && Ctx::class(id[i + 1]) != c)
                    || (x > 0 && Ctx::class(id[i - 1]) != c)
                    || (y + 1 < h as usize && Ctx::class(id[i + wu]) != c)
                    || (y > 0 && Ctx::class(id[i - wu]) != c)
            })
            .collect();
        const OFF: [(f32, f32); 4] = [(0.125, 0.375), (0.375, -0.125), (-0.125, -0.375), (-0.375, 0.125)];
        let smooth: Vec<(usize, Vec3)> = edge
            .par_iter()
            .map(|&i| {
                let (x, y) = ((i % wu) as f32 + 0.5, (i / wu) as f32 + 0.5);
                let mut sum = color[i];
                for (dx, dy) in OFF {
                    sum += ctx.sample(x + dx, y + dy).color;
                }
                (i, sum / 5.0)
            })
            .collect();
        for (i, c) in smooth {
            color[i] = c;
        }
    }

    let scene_millis = start.elapsed().as_secs_f64() * 1000.0;
    let mut canvas = Canvas::new(w, h, color, depth, id);
    canvas.hidden_alpha = opts.hidden_alpha;
    outline_selection(&mut canvas, selected_id);
    let mut ov = Overlay {
        ctx: &ctx,
        canvas: &mut canvas,
    };
    let info = ov.draw(settings);
    if opts.gizmo {
        gizmo(&mut canvas, &ctx.proj);
    }
    ViewFrame {
        image: RgbImage {
            width: w,
            height: h,
            rgb: canvas.to_rgb8(),
        },
        info: ViewInfo {
            millis: start.elapsed().as_secs_f64() * 1000.0,
            scene_millis,
            ..info
        },
    }
}

/// What is under pixel (`px`, `py`) of the view (0-based from the top-left), if anything.
#[must_use]
pub fn pick(scene: &Scene, settings: &RenderSettings, opts: &ViewOptions, px: u32, py: u32) -> Option<Selection> {
    let proj = Projection::new(&opts.camera, opts.width.max(1), opts.height.max(1));
    let cam = Camera::new(settings.camera, settings.width.max(1), settings.height.max(1));
    let (q0, qu, qv) = image_plane_frame(&cam);
    let ctx = Ctx {
        scene,
        proj,
        opts,
        cam,
        cam_from_world: cam.rotation.transpose(),
        q0,
        qu,
        qv,
        qn: qu.cross(qv).normalize_or_zero(),
        image: None,
        selected_id: ID_NONE - 1,
        scale: 1.0,
        highlight: Vec::new(),
    };
    let id = ctx.sample(px as f32 + 0.5, py as f32 + 0.5).id;
    match id {
        ID_NONE => None,
        ID_CAMERA => Some(Selection::Camera),
        i if i >= ID_QUAD => {
            let p = i - ID_QUAD;
            Some(Selection::Pixel(p % cam.width, p / cam.width))
        }
        i if i >= ID_LIGHT => Some(Selection::Light(i - ID_LIGHT)),
        i => Some(Selection::Entity(i)),
    }
}

/// Paints a 2-pixel orange outline around the pixels whose id is `sel`.
fn outline_selection(c: &mut Canvas, sel: u32) {
    if sel >= ID_NONE - 1 {
        return;
    }
    let (w, h) = (c.width as usize, c.height as usize);
    let mut mark = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let inside = c.id[i] == sel;
            let differs = |j: usize| (c.id[j] == sel) != inside;
            if (x + 1 < w && differs(i + 1))
                || (x > 0 && differs(i - 1))
                || (y + 1 < h && differs(i + w))
                || (y > 0 && differs(i - w))
            {
                mark.push(i);
            }
        }
    }
    for i in mark {
        c.color[i] = c.color[i].lerp(Vec3::new(1.0, 0.55, 0.08), 0.9);
    }
}

/// The axis gizmo: world x (red), y (green), z (blue) as seen from the view.
fn gizmo(c: &mut Canvas, p: &Projection) {
    let centre = Vec2::new(c.width as f32 - 58.0, 52.0);
    if c.width < 160 || c.height < 120 {
        return;
    }
    let mut axes = [
        (Vec3A::X, Vec4::new(0.9, 0.25, 0.2, 1.0), "x"),
        (Vec3A::Y, Vec4::new(0.45, 0.85, 0.25, 1.0), "y"),
        (Vec3A::Z, Vec4::new(0.25, 0.5, 1.0, 1.0), "z"),
    ];
    // Draw the axes pointing away first.
    axes.sort_by(|a, b| b.0.dot(p.fwd).total_cmp(&a.0.dot(p.fwd)));
    for (a, col, name) in axes {
        let d = Vec2::new(a.dot(p.right), -a.dot(p.up)) * 30.0;
        let away = a.dot(p.fwd) > 0.0;
        let col = if away { col * Vec4::new(0.7, 0.7, 0.7, 0.8) } else { col };
        c.line_2d(centre, centre + d, col, 2.5);
        let tip = centre + d * 1.25 - Vec2::new(5.0, 5.0);
        c.text(tip, name, 2, Vec4::new(0.95, 0.95, 0.95, 0.95));
    }
}

/// Colour of a ray-tree edge by kind.
#[must_use]
pub fn kind_color(kind: RayKind) -> Vec3 {
    match kind {
        RayKind::Camera => Vec3::new(1.0, 1.0, 1.0),
        RayKind::Shadow => Vec3::new(1.0, 0.86, 0.2),
        RayKind::Reflection => Vec3::new(0.2, 0.9, 1.0),
        RayKind::Refraction => Vec3::new(1.0, 0.35, 0.9),
        RayKind::Emitter => Vec3::new(1.0, 0.6, 0.1),
        RayKind::Bounce => Vec3::new(0.4, 1.0, 0.4),
    }
}

/// Colour of a ray kind named as in a ray log (`camera`, `shadow`, `reflection`, `refraction`,
/// `emitter`, `bounce`; grey for any other word).
#[must_use]
pub fn kind_color_named(kind: &str) -> Vec3 {
    match kind {
        "camera" => kind_color(RayKind::Camera),
        "shadow" => kind_color(RayKind::Shadow),
        "reflection" => kind_color(RayKind::Reflection),
        "refraction" => kind_color(RayKind::Refraction),
        "emitter" => kind_color(RayKind::Emitter),
        "bounce" => kind_color(RayKind::Bounce),
        _ => Vec3::splat(0.7),
    }
}

struct Overlay<'a, 'b> {
    ctx: &'a Ctx<'a>,
    canvas: &'b mut Canvas,
}

const LINE_BIAS: f32 = 2e-3;
const BLUE: Vec3 = Vec3::new(0.12, 0.32, 1.0);
const RED: Vec3 = Vec3::new(0.95, 0.08, 0.08);

impl Overlay<'_, '_> {
    /// A world-space segment, clipped at the near plane.
    fn seg(&mut self, a: Vec3A, b: Vec3A, ca: Vec4, cb: Vec4, width: f32) {
        self.seg_ex(a, b, ca, cb, width, LINE_BIAS, 0.0);
    }

    #[allow(clippy::too_many_arguments)]
    fn seg_ex(&mut self, a: Vec3A, b: Vec3A, ca: Vec4, cb: Vec4, width: f32, bias: f32, fade_z: f32) {
        let p = &self.ctx.proj;
        let (mut pa, mut pb) = (p.to_camera(a), p.to_camera(b));
        let (mut ca, mut cb) = (ca, cb);
        if pa.z < NEAR && pb.z < NEAR {
            return;
        }
        if pa.z < NEAR {
            let s = (NEAR - pa.z) / (pb.z - pa.z);
            pa = pa.lerp(pb, s);
            ca = ca.lerp(cb, s);
        } else if pb.z < NEAR {
            let s = (NEAR - pb.z) / (pa.z - pb.z);
            pb = pb.lerp(pa, s);
            cb = cb.lerp(ca, s);
        }
        let (sa, sb) = (p.screen(pa), p.screen(pb));
        self.canvas.segment(sa, sb, ca, cb, width, bias, fade_z);
    }

    fn dot(&mut self, at: Vec3A, radius: f32, fill: Vec4, ring: Vec4) {
        let c = self.ctx.proj.to_camera(at);
        if c.z > NEAR {
            let s = self.ctx.proj.screen(c);
            self.canvas.dot(s, radius, fill, ring, 5e-3);
        }
    }

    /// Where a ray from the ray tracer's camera ends: its first hit, or `None` (a miss).
    fn first_hit(&self, ray: &Ray) -> Option<f32> {
        self.ctx.scene.intersect(ray, 0.0, f32::INFINITY).map(|h| h.t)
    }

    fn far(&self) -> f32 {
        self.ctx.scale * 2.5
    }

    /// A ray ending at its first hit (with a dot) or fading out at the far distance.
    fn ray_to_hit(&mut self, ray: &Ray, color: Vec3, alpha: f32, width: f32, dot: f32) {
        let a = ray.origin;
        match self.first_hit(ray) {
            Some(t) => {
                let c = color.extend(alpha);
                self.seg(a, ray.at(t), c, c, width);
                if dot > 0.0 {
                    self.dot(ray.at(t), dot, color.extend(1.0), Vec4::new(0.05, 0.05, 0.05, 0.9));
                }
            }
            None => {
                let far = self.far();
                self.seg(a, ray.at(far), color.extend(alpha), color.extend(0.0), width);
            }
        }
    }

    fn draw(&mut self, settings: &RenderSettings) -> ViewInfo {
        let opts = self.ctx.opts;
        let cam = self.ctx.cam;
        let mut info = ViewInfo {
            rays_drawn: 0,
            ray_stride: 1,
            grid_step: 1,
            grid_lines_x: 0,
            grid_lines_y: 0,
            millis: 0.0,
            scene_millis: 0.0,
        };
        if opts.ground_grid {
            self.ground_grid();
        }
        // The ray tracer's camera glyph.
        self.camera_glyph();
        // Frustum edges through the image-plane corners.
        if opts.rays != RayMode::None {
            for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
                let ray = cam.ray(u, v);
                self.ray_to_hit(&ray, BLUE, 1.0, 1.5, 0.0);
            }
        }
        // Image-plane grid: width + 1 vertical and height + 1 horizontal lines.
        if opts.image_grid {
            (info.grid_step, info.grid_lines_x, info.grid_lines_y) = self.image_grid();
        }
        // Debug rays through pixel centres.
        let (w, h) = (cam.width, cam.height);
        let mut pixels: Vec<(u32, u32)> = Vec::new();
        match opts.rays {
            RayMode::None | RayMode::Frustum => {}
            RayMode::Pixel(x, y) => {
                if x < w && y < h {
                    pixels.push((x, y));
                }
            }
            RayMode::Row(y) => {
                if y < h {
                    let stride = w.div_ceil(opts.max_rays.max(1)).max(1);
                    info.ray_stride = stride;
                    pixels.extend((0..w).step_by(stride as usize).map(|x| (x, y)));
                }
            }
            RayMode::All => {
                let total = w as u64 * h as u64;
                let stride = ((total as f64 / opts.max_rays.max(1) as f64).sqrt().ceil() as u32).max(1);
                info.ray_stride = stride;
                for y in (0..h).step_by(stride as usize) {
                    for x in (0..w).step_by(stride as usize) {
                        pixels.push((x, y));
                    }
                }
            }
        }
        info.rays_drawn = pixels.len() as u32;
        let many = pixels.len() > 400;
        let (alpha, width, dot) = if many { (0.55, 1.0, 1.4) } else { (0.92, 1.2, 2.4) };
        for &(x, y) in &pixels {
            let (u, v) = cam.pixel_center(x, y);
            let ray = cam.ray(u, v);
            self.ray_to_hit(&ray, Vec3::ONE, alpha, width, dot);
        }
        // The selected pixel: outline its cell, its samples, its ray tree.
        if let Some((x, y)) = opts.pixel.filter(|&(x, y)| x < w && y < h) {
            if opts.samples {
                self.samples(settings, x, y);
            }
            self.cell_outline(x, y, Vec3::new(1.0, 0.85, 0.1), 2.2);
        }
        if let Some(tree) = &opts.tree {
            self.tree(tree);
        }
        if let (true, Some(Selection::Entity(e))) = (opts.normals, opts.selection) {
            self.normals(e);
        }
        self.foreign_rays(&opts.foreign_rays);
        for (x, y) in opts.highlight.iter().take(4096) {
            if *x < w && *y < h {
                self.cell_outline(*x, *y, Vec3::new(1.0, 0.1, 1.0), 1.6);
            }
        }
        self.light_glyphs();
        info
    }

    fn ground_grid(&mut self) {
        let scene = self.ctx.scene;
        // On the lowest upward-facing horizontal plane, else under everything.
        let floor = scene
            .planes
            .iter()
            .filter(|p| p.normal.y > 0.98)
            .map(|p| p.point.y)
            .fold(f32::INFINITY, f32::min);
        let y = if floor.is_finite() {
            floor
        } else if !scene.bounds.is_empty() {
            scene.bounds.min.y.min(self.ctx.cam.origin.y - 1.0)
        } else {
            self.ctx.cam.origin.y - 1.0
        };
        let step = if self.ctx.scale > 60.0 { 10.0 } else { 1.0 };
        let n = ((self.ctx.scale * 3.0 / step).ceil() as i32).clamp(10, 80);
        let cx = (self.ctx.opts.camera.target.x / step).round() * step;
        let cz = (self.ctx.opts.camera.target.z / step).round() * step;
        let fade = self.ctx.scale * 9.0;
        let col = Vec4::new(0.32, 0.32, 0.34, 0.5);
        let saved = std::mem::replace(&mut self.canvas.hidden_alpha, 0.0);
        for i in -n..=n {
            let o = i as f32 * step;
            let e = n as f32 * step;
            for (a, b) in [
                (Vec3A::new(cx + o, y, cz - e), Vec3A::new(cx + o, y, cz + e)),
                (Vec3A::new(cx - e, y, cz + o), Vec3A::new(cx + e, y, cz + o)),
            ] {
                self.seg_ex(a, b, col, col, 1.0, 4e-3, fade);
            }
        }
        self.canvas.hidden_alpha = saved;
    }

    /// Grid lines of the image plane; thins them out when cells get smaller than 4 pixels.
    fn image_grid(&mut self) -> (u32, u32, u32) {
        let cam = self.ctx.cam;
        let (w, h) = (cam.width, cam.height);
        let p = &self.ctx.proj;
        // Smallest projected cell size over the plane's corners.
        let mut cell = f32::INFINITY;
        for (u, v) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)] {
            let a = p.to_camera(cam.plane_point_world(u, v));
            let bu = p.to_camera(cam.plane_point_world(u + 1.0 / w as f32, v));
            let bv = p.to_camera(cam.plane_point_world(u, v + 1.0 / h as f32));
            if a.z > NEAR && bu.z > NEAR && bv.z > NEAR {
                let (sa, su, sv) = (p.screen(a).p, p.screen(bu).p, p.screen(bv).p);
                cell = cell.min((su - sa).length().max((sv - sa).length()));
            }
        }
        let mut step = 1u32;
        if cell.is_finite() {
            for s in [1u32, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000, 5000] {
                step = s;
                if cell * s as f32 >= 4.0 {
                    break;
                }
            }
        }
        let red = RED.extend(0.95);
        let (mut nx, mut ny) = (0, 0);
        for i in (0..=w).filter(|i| i % step == 0 || *i == w) {
            nx += 1;
            let u = i as f32 / w as f32;
            let width = if i == 0 || i == w { 1.6 } else { 1.15 };
            self.seg(
                cam.plane_point_world(u, 0.0),
                cam.plane_point_world(u, 1.0),
                red,
                red,
                width,
            );
        }
        for j in (0..=h).filter(|j| j % step == 0 || *j == h) {
            ny += 1;
            let v = j as f32 / h as f32;
            let width = if j == 0 || j == h { 1.6 } else { 1.15 };
            self.seg(
                cam.plane_point_world(0.0, v),
                cam.plane_point_world(1.0, v),
                red,
                red,
                width,
            );
        }
        (step, nx, ny)
    }

    fn cell_outline(&mut self, x: u32, y: u32, color: Vec3, width: f32) {
        let cam = self.ctx.cam;
        let (w, h) = (cam.width as f32, cam.height as f32);
        let (u0, v0, u1, v1) = (x as f32 / w, y as f32 / h, (x + 1) as f32 / w, (y + 1) as f32 / h);
        let c = color.extend(1.0);
        let p = |u, v| cam.plane_point_world(u, v);
        self.seg(p(u0, v0), p(u1, v0), c, c, width);
        self.seg(p(u1, v0), p(u1, v1), c, c, width);
        self.seg(p(u1, v1), p(u0, v1), c, c, width);
        self.seg(p(u0, v1), p(u0, v0), c, c, width);
    }

    fn samples(&mut self, settings: &RenderSettings, x: u32, y: u32) {
        let integ = Integrator::new(self.ctx.scene, settings);
        let spp = integ.samples_per_pixel().min(1024);
        let cyan = Vec3::new(0.2, 0.95, 1.0);
        let aperture = settings.camera.aperture_radius;
        let lens = settings.stage == rayscope_core::Stage::Full && aperture > 0.0;
        if lens {
            // The aperture disk in the camera's lens plane, where the lens samples start.
            let cam = &self.ctx.cam;
            let ring = |k: u32| {
                let a = k as f32 / 48.0 * std::f32::consts::TAU;
                cam.origin + cam.rotation * Vec3A::new(a.cos() * aperture, a.sin() * aperture, 0.0)
            };
            let orange = Vec3::new(1.0, 0.6, 0.1).extend(1.0);
            for k in 0..48 {
                self.seg(ring(k), ring(k + 1), orange, orange, 1.4);
            }
        }
        for s in 0..spp {
            let ray = integ.camera_ray(x, y, s, &mut integ.sample_rng(x, y, s));
            let (u, v) = integ.sample_position(x, y, s);
            if spp <= 64 {
                self.ray_to_hit(&ray, cyan, 0.5, 0.9, 0.0);
            }
            if lens {
                // Where this sample's ray leaves the lens.
                self.dot(
                    ray.origin,
                    2.0,
                    Vec3::new(1.0, 0.6, 0.1).extend(1.0),
                    Vec4::new(0.1, 0.05, 0.0, 1.0),
                );
            }
            self.dot(
                self.ctx.cam.plane_point_world(u, v),
                2.2,
                cyan.extend(1.0),
                Vec4::new(0.0, 0.1, 0.2, 1.0),
            );
        }
    }

    fn tree(&mut self, tree: &RayTree) {
        for n in tree.nodes.iter().take(20_000) {
            let o = Vec3A::from(n.origin);
            let d = Vec3A::from(n.direction);
            let color = kind_color(n.kind);
            let c = color.extend(1.0);
            let ray = Ray::new(o, d);
            match (&n.hit, n.kind) {
                (Some(hit), _) => {
                    self.seg(o, ray.at(hit.t), c, c, 2.2);
                    self.dot(ray.at(hit.t), 3.0, c, Vec4::new(0.05, 0.05, 0.05, 0.95));
                }
                (None, RayKind::Shadow | RayKind::Emitter) => {
                    let end = n.t_max.unwrap_or(self.far());
                    if n.blocked_by.is_some() {
                        // Up to the blocker in full colour, then faint to the light.
                        let t = self.ctx.scene.intersect(&ray, 0.0, end).map(|h| h.t).unwrap_or(end);
                        let blocked = Vec3::new(1.0, 0.25, 0.15);
                        self.seg(o, ray.at(t), c, c, 2.0);
                        self.dot(ray.at(t), 3.0, blocked.extend(1.0), Vec4::new(0.05, 0.05, 0.05, 0.95));
                        self.seg(ray.at(t), ray.at(end), blocked.extend(0.45), blocked.extend(0.45), 1.2);
                    } else {
                        self.seg(o, ray.at(end), c, c, 2.0);
                    }
                }
                (None, _) => {
                    let end = n.t_max.unwrap_or(self.far());
                    self.seg(o, ray.at(end), c, color.extend(0.0), 2.0);
                }
            }
        }
    }

    /// An arrow from `from` along the unit vector `d`, `len` long.
    fn arrow(&mut self, from: Vec3A, d: Vec3A, len: f32, color: Vec3) {
        let tip = from + d * len;
        let c = color.extend(1.0);
        self.seg(from, tip, c, c, 2.4);
        let (t, b) = rayscope_core::math::basis(d);
        let head = len * 0.25;
        for side in [t, -t, b, -b] {
            self.seg(tip, tip - d * head + side * (head * 0.45), c, c, 1.6);
        }
        self.dot(from, 2.2, c, Vec4::new(0.05, 0.05, 0.05, 0.9));
    }

    /// Arrows along entity `e`'s outward (geometric) normals: at a plane's point, at a
    /// triangle's centroid (its vertices numbered, so the winding shows), over a sphere, and at
    /// up to 400 of a mesh's triangles.
    fn normals(&mut self, e: u32) {
        // Arrows behind a surface (a triangle seen from its back) still show, faintly.
        let saved = std::mem::replace(&mut self.canvas.hidden_alpha, 0.5);
        self.normal_arrows(e);
        self.canvas.hidden_alpha = saved;
    }

    /// [`Self::normals`]' arrows.
    fn normal_arrows(&mut self, e: u32) {
        let scene = self.ctx.scene;
        // Yellow: apart from the selection's orange outline and from most materials.
        let color = Vec3::new(1.0, 0.92, 0.1);
        let base = self.ctx.scale * 0.08;
        for (p, _) in scene.planes.iter().zip(&scene.plane_info).filter(|(_, i)| i.0 == e) {
            self.arrow(p.point, p.normal, base, color);
        }
        for (sp, _) in scene.spheres.iter().zip(&scene.sphere_info).filter(|(_, i)| i.0 == e) {
            let mut dirs = vec![Vec3A::X, -Vec3A::X, Vec3A::Y, -Vec3A::Y, Vec3A::Z, -Vec3A::Z];
            for sx in [-1.0, 1.0] {
                for sy in [-1.0, 1.0] {
                    for sz in [-1.0, 1.0] {
                        dirs.push(Vec3A::new(sx, sy, sz).normalize());
                    }
                }
            }
            for d in dirs {
                self.arrow(sp.center + d * sp.radius, d, sp.radius * 0.6, color);
            }
        }
        let tris: Vec<usize> = (0..scene.triangles.len())
            .filter(|&i| scene.triangle_info[i].entity == e)
            .collect();
        let stride = tris.len().div_ceil(400).max(1);
        let single = tris.len() == 1;
        for &i in tris.iter().step_by(stride) {
            let t = &scene.triangles[i];
            let n = t.geometric_normal();
            if n == Vec3A::ZERO {
                continue;
            }
            let [a, b, c] = t.vertices();
            let centroid = (a + b + c) / 3.0;
            let edge = (b - a).length().max((c - b).length()).max((a - c).length());
            let len = (edge * 0.4).clamp(self.ctx.scale * 0.004, base);
            self.arrow(centroid, n, len, color);
            if single {
                for (k, v) in [a, b, c].into_iter().enumerate() {
                    self.dot(v, 3.0, color.extend(1.0), Vec4::new(0.05, 0.05, 0.05, 0.9));
                    let cam = self.ctx.proj.to_camera(v);
                    if cam.z > NEAR {
                        let sp = self.ctx.proj.screen(cam);
                        let at = sp.p + Vec2::new(5.0, -16.0);
                        self.canvas.text(at, &k.to_string(), 3, Vec4::new(1.0, 1.0, 1.0, 1.0));
                    }
                }
            }
        }
    }

    /// Another tracer's rays, dashed (about 9 pixels on, 6 off); the highlighted one over an
    /// orange halo, with rings at both ends.
    fn foreign_rays(&mut self, rays: &[ForeignRay]) {
        let halo = Vec4::new(1.0, 0.42, 0.05, 0.6);
        let ring = Vec4::new(1.0, 0.42, 0.05, 1.0);
        let far = self.far();
        // Through surfaces more than other lines: a student's mistake is often inside glass.
        let saved = self.canvas.hidden_alpha;
        for r in rays.iter().take(20_000) {
            self.canvas.hidden_alpha = if r.highlight {
                saved.max(0.7)
            } else if saved > 0.0 {
                saved.max(0.3)
            } else {
                0.0
            };
            let o = Vec3A::from(r.origin);
            let d = Vec3A::from(r.direction).normalize_or_zero();
            let (end, fades) = match r.end {
                Some(e) => (Vec3A::from(e), false),
                None => (o + d * far, true),
            };
            if r.highlight {
                self.seg(o, end, halo, if fades { halo.with_w(0.0) } else { halo }, 7.0);
            }
            // Dash count from the projected length (clipped at the near plane).
            let p = &self.ctx.proj;
            let (ca, cb) = (p.to_camera(o), p.to_camera(end));
            let len = if ca.z > NEAR && cb.z > NEAR {
                (p.screen(ca).p - p.screen(cb).p).length()
            } else {
                400.0
            };
            let n = ((len / 15.0).ceil() as u32).clamp(1, 400);
            let width = if r.highlight { 2.8 } else { 2.0 };
            for k in 0..n {
                let (s0, s1) = (k as f32 / n as f32, (k as f32 + 0.6) / n as f32);
                let fade = |s: f32| if fades { 1.0 - s } else { 1.0 };
                let c0 = r.color.extend(fade(s0));
                let c1 = r.color.extend(fade(s1));
                self.seg(o.lerp(end, s0), o.lerp(end, s1), c0, c1, width);
            }
            if let Some(e) = r.end {
                let e = Vec3A::from(e);
                if r.highlight {
                    self.dot(e, 5.0, r.color.extend(1.0), ring);
                } else {
                    self.dot(e, 2.6, Vec4::new(0.05, 0.05, 0.05, 0.95), r.color.extend(1.0));
                }
            }
            if r.highlight {
                self.dot(o, 4.0, Vec4::new(0.05, 0.05, 0.05, 0.9), ring);
            }
        }
        self.canvas.hidden_alpha = saved;
    }

    fn light_glyphs(&mut self) {
        let lights: Vec<_> = self.ctx.scene.lights.iter().map(|l| (l.position, l.color)).collect();
        for (p, col) in lights {
            let p = Vec3A::from(p);
            let lc = (col / col.max_element().max(1e-6)).lerp(Vec3::new(1.0, 0.9, 0.4), 0.5);
            let r0 = LIGHT_RADIUS * 1.5;
            let r1 = LIGHT_RADIUS * 3.2;
            for d in [Vec3A::X, -Vec3A::X, Vec3A::Y, -Vec3A::Y, Vec3A::Z, -Vec3A::Z] {
                self.seg(p + d * r0, p + d * r1, lc.extend(0.95), lc.extend(0.2), 1.5);
            }
        }
    }

    fn camera_glyph(&mut self) {
        let cam = self.ctx.cam;
        let to_world = |p: Vec3A| cam.origin + cam.rotation * p;
        let dark = Vec4::new(0.12, 0.12, 0.14, 0.9);
        let (lo, hi) = (BODY_LO, BODY_HI);
        let corner = |i: u32| {
            Vec3A::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        for (a, b) in [
            (0, 1),
            (2, 3),
            (4, 5),
            (6, 7),
            (0, 2),
            (1, 3),
            (4, 6),
            (5, 7),
            (0, 4),
            (1, 5),
            (2, 6),
            (3, 7),
        ] {
            self.seg(to_world(corner(a)), to_world(corner(b)), dark, dark, 1.0);
        }
        // Lens: a short pyramid from the body to the pinhole.
        let white = Vec4::new(0.95, 0.95, 0.97, 1.0);
        let front = [(-0.035, -0.03), (0.035, -0.03), (0.035, 0.03), (-0.035, 0.03)];
        for i in 0..4 {
            let (x0, y0) = front[i];
            let (x1, y1) = front[(i + 1) % 4];
            let a = to_world(Vec3A::new(x0, y0, hi.z));
            let b = to_world(Vec3A::new(x1, y1, hi.z));
            let tip = to_world(Vec3A::new(x0 * 1.6, y0 * 1.6, 0.0));
            let tip2 = to_world(Vec3A::new(x1 * 1.6, y1 * 1.6, 0.0));
            self.seg(a, b, white, white, 1.4);
            self.seg(a, tip, white, white, 1.4);
            self.seg(tip, tip2, white, white, 1.4);
        }
        // Two film reels on top.
        for zc in [-0.105f32, -0.205] {
            let c = Vec3A::new(0.0, hi.y + 0.05, zc);
            let r = 0.045;
            let mut prev = None;
            for k in 0..=24 {
                let a = k as f32 / 24.0 * std::f32::consts::TAU;
                let p = to_world(c + Vec3A::new(0.0, a.sin() * r, a.cos() * r));
                if let Some(q) = prev {
                    self.seg(q, p, white, white, 1.6);
                }
                prev = Some(p);
            }
        }
    }
}

/// The image plane in world space: its top-left corner and the edges along +u and +v.
fn image_plane_frame(cam: &Camera) -> (Vec3A, Vec3A, Vec3A) {
    let q0 = cam.plane_point_world(0.0, 0.0);
    (
        q0,
        cam.plane_point_world(1.0, 0.0) - q0,
        cam.plane_point_world(0.0, 1.0) - q0,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_modes_parse() {
        assert_eq!("none".parse::<RayMode>().unwrap(), RayMode::None);
        assert_eq!("pixel:3, 4".parse::<RayMode>().unwrap(), RayMode::Pixel(3, 4));
        assert_eq!("row:7".parse::<RayMode>().unwrap(), RayMode::Row(7));
        assert!("pixel:3".parse::<RayMode>().is_err());
        assert!("rows".parse::<RayMode>().is_err());
        assert!("black".parse::<ImageMode>().is_ok());
        assert!("white".parse::<ImageMode>().is_err());
    }

    #[test]
    fn projection_round_trips() {
        let cam = ViewCamera {
            eye: Vec3::new(-3.0, 2.0, -4.0),
            target: Vec3::new(0.0, 0.0, 2.0),
            fov_deg: 50.0,
        };
        let p = Projection::new(&cam, 320, 200);
        let r = p.ray(100.5, 50.5);
        let (x, y, z) = p.project(r.at(7.0).into()).unwrap();
        assert!((x - 100.5).abs() < 1e-2 && (y - 50.5).abs() < 1e-2 && z > 0.0);
        let (cx, cy, _) = p.project(cam.target).unwrap();
        assert!((cx - 160.0).abs() < 1e-3 && (cy - 100.0).abs() < 1e-3);
    }
}
