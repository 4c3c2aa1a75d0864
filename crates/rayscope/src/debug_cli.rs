//! `rayscope debug` and `rayscope view`: thin wrappers over the rayscope_debug library.

use std::process::ExitCode;
use std::sync::atomic::AtomicBool;

use rayscope_check::log::IdRole;
use rayscope_check::{LogError, PixelLog};
use rayscope_core::output::Format;
use rayscope_debug::student::{self, StudentInput};
use rayscope_debug::view::{auto_view, render_view, ImageMode, RayMode, RgbImage, ViewCamera, ViewOptions};

use crate::cli::{DebugArgs, ViewArgs};
use crate::shared::{load_file, load_scene, settings, setup_threads, Failure};

/// `rayscope debug`: serve the visual debugger on a local port.
pub fn debug(a: &DebugArgs) -> Result<ExitCode, Failure> {
    setup_threads(&a.opts);
    let settings = settings(&a.opts)?;
    rayscope_debug::server::check_settings(&settings).map_err(Failure::input)?;
    // The debugger keeps the file: it draws the meshes as loaded.
    let file = load_file(&a.scene, a.opts.quiet)?;
    let scene = rayscope_core::Scene::from_file(&file);
    let student = student_input(a)?;
    let cfg = rayscope_debug::ServeConfig {
        scene_path: a.scene.clone(),
        scene_file: file,
        scene,
        settings,
        host: a.host.clone(),
        port: a.port,
        allow_hosts: a.allow_host.clone(),
        limits: rayscope_debug::ServerLimits::default(),
        student,
    };
    rayscope_debug::serve(cfg, a.open).map_err(|e| match e {
        rayscope_debug::DebugError::Settings(m) => Failure::input(m),
        other => Failure::failed(other.to_string()),
    })?;
    Ok(ExitCode::SUCCESS)
}

/// The ray log and image `rayscope debug` loads: checked here, so a missing file is an error
/// before the server starts.
fn student_input(a: &DebugArgs) -> Result<StudentInput, Failure> {
    let ray_ids = IdRole::parse_list(&a.ray_ids).map_err(|e| Failure::input(format!("--ray-ids: {e}")))?;
    if let Some(p) = &a.rays {
        // Refused now, before the server starts: only a regular file that opens is read.
        rayscope_check::log::open_file(p)
            .map_err(|e| Failure::input(e.to_string().trim_start_matches("error: ").to_string()))?;
    }
    let image = a
        .image
        .as_ref()
        .map(|p| rayscope_debug::student::load_image(p, rayscope_debug::server::MAX_IMAGE_SIDE))
        .transpose()
        .map_err(Failure::input)?;
    Ok(StudentInput {
        rays: a.rays.clone(),
        image,
        ray_ids,
        lenient: a.lenient,
    })
}

/// Judges `--rays-log` for `rayscope view`.
fn judge_log(
    a: &ViewArgs,
    scene: &rayscope_core::Scene,
    settings: &rayscope_core::RenderSettings,
) -> Result<Option<PixelLog>, Failure> {
    let Some(path) = &a.rays_log else {
        return Ok(None);
    };
    let roles = IdRole::parse_list(&a.ray_ids).map_err(|e| Failure::input(format!("--ray-ids: {e}")))?;
    let never = AtomicBool::new(false);
    let log = rayscope_debug::student::judge_file(scene, settings, path, &roles, a.lenient, &|_, _| {}, &never)
        .map_err(|e| match e {
            LogError::Io { .. } => Failure::input(e.to_string().trim_start_matches("error: ").to_string()),
            other => Failure {
                code: 2,
                message: other.to_string(),
                diagnostic: true,
            },
        })?;
    Ok(log)
}

/// `rayscope view`: write the debugger's scene view to a PNG, headless.
pub fn view(a: &ViewArgs) -> Result<ExitCode, Failure> {
    setup_threads(&a.opts);
    let settings = settings(&a.opts)?;
    let rays: RayMode = a.rays.parse().map_err(|e| Failure::input(format!("--rays: {e}")))?;
    let image_mode: ImageMode = a.image.parse().map_err(|e| Failure::input(format!("--image: {e}")))?;
    match rays {
        RayMode::Pixel(x, y) if x >= settings.width || y >= settings.height => {
            return Err(Failure::input(format!(
                "--rays pixel:{x},{y} is outside the {}×{} image (pixels are 0-based from the top-left)",
                settings.width, settings.height
            )))
        }
        RayMode::Row(y) if y >= settings.height => {
            return Err(Failure::input(format!(
                "--rays row:{y} is outside the {}×{} image (rows are 0-based from the top)",
                settings.width, settings.height
            )))
        }
        _ => {}
    }
    match rayscope_core::output::check_writable(&a.output) {
        Ok(Format::Png) => {}
        Ok(_) | Err(rayscope_core::output::OutputError::UnsupportedFormat { .. }) => {
            return Err(Failure::input("the scene view is written as PNG: use a .png output"))
        }
        Err(e) => return Err(Failure::input(e.to_string())),
    }
    let scene = load_scene(&a.file, a.opts.quiet)?;
    let normals_of = match &a.normals {
        Some(name) => match scene.entities.iter().position(|e| &e.name == name) {
            Some(e) => Some(e as u32),
            None => {
                let names: Vec<&str> = scene.entities.iter().take(12).map(|e| e.name.as_str()).collect();
                return Err(Failure::input(format!(
                    "--normals: the scene has no entity '{name}' (entities: {}{})",
                    names.join(", "),
                    if scene.entities.len() > 12 { ", …" } else { "" }
                )));
            }
        },
        None => None,
    };
    let aspect = a.view_width as f32 / a.view_height as f32;
    let auto = auto_view(&scene, &settings, aspect);
    let camera = ViewCamera {
        eye: a.eye.unwrap_or(auto.eye),
        target: a.target.unwrap_or(auto.target),
        fov_deg: auto.fov_deg,
    };
    if (camera.eye - camera.target).length() < 1e-4 {
        return Err(Failure::input("--eye and --target must differ"));
    }
    let image = if image_mode == ImageMode::Traced {
        let never = AtomicBool::new(false);
        let out = rayscope_core::render(&scene, &settings, &|_, _| {}, &never)
            .map_err(|_| Failure::failed("render cancelled"))?;
        Some(RgbImage {
            width: out.film.width,
            height: out.film.height,
            rgb: out.film.to_rgb8(),
        })
    } else {
        None
    };
    let mut opts = ViewOptions::new(a.view_width, a.view_height, camera);
    opts.rays = rays;
    opts.image = image_mode;
    if let RayMode::Pixel(x, y) = rays {
        opts.pixel = Some((x, y));
        opts.samples = a.samples;
        if a.tree {
            opts.tree = Some(rayscope_core::trace_pixel(&scene, &settings, x, y, 0));
        }
    } else if a.samples || a.tree {
        return Err(Failure::input("--samples and --tree need --rays pixel:X,Y"));
    }
    if let Some(e) = normals_of {
        opts.selection = Some(rayscope_debug::Selection::Entity(e));
        opts.normals = true;
    }
    if let Some(log) = judge_log(a, &scene, &settings)? {
        opts.cell_tint = Some(std::sync::Arc::new(student::verdict_tint(&log)));
        if let RayMode::Pixel(x, y) = rays {
            // Every logged sample of the pixel, each with its first divergent ray highlighted.
            for s in student::samples_at(&log, x, y) {
                let cmp = student::compare_pixel(&scene, &settings, &log, x, y, s);
                let hl = cmp.alignment.divergence.and_then(|r| cmp.alignment.rows[r].yours);
                opts.foreign_rays.extend(student::foreign_rays(&cmp.yours, hl));
            }
        } else {
            opts.foreign_rays = student::overview_rays(&log, 1500);
        }
        if !a.opts.quiet {
            let [none, agree, tie, bad] = log.counts();
            eprintln!(
                "{}: {} rays; pixels: {bad} disagree, {tie} only ties, {agree} agree, {none} not logged",
                a.rays_log.as_ref().map_or(String::new(), |p| p.display().to_string()),
                log.report.rays
            );
        }
    }
    let frame = render_view(&scene, &settings, image.as_ref(), &opts);
    let png = rayscope_debug::encode::png_small(&frame.image);
    rayscope_core::output::write_atomic(&a.output, |w| std::io::Write::write_all(w, &png))
        .map_err(|e| Failure::failed(format!("cannot write {}: {e}", a.output.display())))?;
    if !a.opts.quiet {
        eprintln!(
            "wrote {} ({}×{}, {:.1} ms, {} rays)",
            a.output.display(),
            frame.image.width,
            frame.image.height,
            frame.info.millis,
            frame.info.rays_drawn
        );
    }
    Ok(ExitCode::SUCCESS)
}
