//! `rayscope diff`: PSNR and differing pixels of two images, a per-channel heat map with its
//! scale, and with `--scene` which entities the differing pixels show.

use std::process::ExitCode;

use clap::parser::ValueSource;
use clap::{Args, CommandFactory};
use glam::{Vec2, Vec3, Vec4};
use rayscope_core::compare::{compare_rgb8, heatmap, Heatmap};
use rayscope_core::diagnose::{attribution, attribution_text, differing_pixels};
use rayscope_core::output::{check_writable, write_film};
use rayscope_core::Film;
use rayscope_debug::canvas::{Canvas, ID_NONE};

use crate::cli::{Cli, DiffArgs, RenderOpts};
use crate::shared::{given, load_scene_for, read_rgb8, setup_threads, Failure};

/// Height of the scale bar's strip for an image `width` pixels wide, and its font scale.
fn legend_size(width: u32) -> (u32, u32) {
    let scale = if width >= 256 { 2 } else { 1 };
    (4 + 8 * scale + 3 + 5 * scale + 4, scale)
}

/// The heat map with a scale bar under it: a ramp from black (equal) to white (`range` levels
/// or more in every channel), labelled 0 and `range`.
fn with_legend(h: &Heatmap, width: u32, height: u32) -> (Vec<u8>, u32) {
    let (strip, scale) = legend_size(width);
    let n = (width * strip) as usize;
    let mut c = Canvas::new(
        width,
        strip,
        vec![Vec3::splat(0.12); n],
        vec![f32::INFINITY; n],
        vec![ID_NONE; n],
    );
    let margin = 4u32;
    let bar_h = 8 * scale;
    let x0 = margin;
    let x1 = width.saturating_sub(margin).max(x0 + 1);
    for y in margin..margin + bar_h {
        for x in x0..x1 {
            let f = (x - x0) as f32 / (x1 - 1 - x0).max(1) as f32;
            c.color[(y * width + x) as usize] = Vec3::splat(f);
        }
    }
    let label_y = (margin + bar_h + 3) as f32;
    let white = Vec4::new(0.9, 0.9, 0.9, 1.0);
    c.text(Vec2::new(x0 as f32, label_y), "0", scale, white);
    let r = h.range.to_string();
    let r_w = (4 * r.len() as u32 - 1) * scale;
    c.text(Vec2::new(x1.saturating_sub(r_w) as f32, label_y), &r, scale, white);
    let mut rgb = h.rgb.clone();
    rgb.extend(c.to_rgb8());
    (rgb, height + strip)
}

/// True when any render flag was given on `diff`'s command line.
fn render_flags_given() -> bool {
    let Ok(m) = Cli::command().try_get_matches() else {
        return false;
    };
    let Some(d) = m.subcommand_matches("diff") else {
        return false;
    };
    let opts = RenderOpts::augment_args(clap::Command::new("diff"));
    let given = opts
        .get_arguments()
        .any(|a| d.value_source(a.get_id().as_str()) == Some(ValueSource::CommandLine));
    given
}

/// `rayscope diff`: exit 0 when the images match (or PSNR ≥ `--tol`), 1 when not, 2 for bad
/// input.
pub fn diff(a: &DiffArgs) -> Result<ExitCode, Failure> {
    if a.scene.is_none() && render_flags_given() {
        return Err(Failure::input(
            "render flags only apply with --scene SCENE (to trace the pixels that differ)",
        ));
    }
    let ia = read_rgb8(&a.a, false)?;
    let ib = read_rgb8(&a.b, false)?;
    if ia.dimensions() != ib.dimensions() {
        return Err(Failure::input(format!(
            "the images differ in size: '{}' is {}×{}, '{}' is {}×{}",
            a.a.display(),
            ia.width(),
            ia.height(),
            a.b.display(),
            ib.width(),
            ib.height()
        )));
    }
    let (w, h) = ia.dimensions();
    // Everything that can fail on input is checked before anything is written.
    let traced = match &a.scene {
        Some(scene) => {
            let mut opts = a.opts.clone();
            if !given("diff", "width") && !given("diff", "height") {
                opts.width = w;
                opts.height = h;
            }
            let settings = opts.settings().map_err(Failure::input)?;
            if (settings.width, settings.height) != (w, h) {
                return Err(Failure::input(format!(
                    "the images are {w}×{h} but the flags ask for {}×{}; pass -w {w} -h {h} (or leave both out)",
                    settings.width, settings.height
                )));
            }
            setup_threads(&opts);
            Some((load_scene_for(scene, opts.quiet, &settings)?, settings))
        }
        None => None,
    };
    if let Some(out) = &a.output {
        check_writable(out).map_err(|e| Failure::input(e.to_string()))?;
    }

    let c = compare_rgb8(ia.as_raw(), ib.as_raw());
    let ok = match a.tol {
        Some(db) => c.psnr >= db,
        None => c.differing == 0,
    };
    crate::set_verdict(u8::from(!ok));
    let psnr = if c.psnr.is_infinite() {
        "inf".to_string()
    } else {
        format!("{:.2}", c.psnr)
    };
    println!(
        "psnr_db={psnr} differing_pixels={} of {} ({:.3}%) max_channel_diff={}",
        c.differing,
        c.total,
        100.0 * c.differing as f64 / c.total.max(1) as f64,
        c.max_diff
    );
    if let Some(out) = &a.output {
        let heat = heatmap(ia.as_raw(), ib.as_raw(), a.range);
        let legend = !a.no_legend && w >= 32;
        let (rgb, out_h) = if legend {
            with_legend(&heat, w, h)
        } else {
            (heat.rgb.clone(), h)
        };
        let mut film = Film::new(w, out_h);
        for (p, c) in film.pixels.iter_mut().zip(rgb.chunks_exact(3)) {
            // +0.5 keeps the 8-bit round trip through the course's truncating conversion exact.
            *p = glam::Vec3::new(c[0] as f32 + 0.5, c[1] as f32 + 0.5, c[2] as f32 + 0.5) / 255.0;
        }
        write_film(&film, out).map_err(|e| Failure::failed(e.to_string()))?;
        let how = if heat.auto { "chosen from the images" } else { "--range" };
        let bar = if legend {
            format!("; a scale bar from 0 to {} is under the image", heat.range)
        } else {
            String::new()
        };
        println!(
            "heat map {}: each channel is that channel's |a − b|, black where equal, full brightness at {} levels or more ({how}; {} pixels beyond){bar}",
            out.display(),
            heat.range,
            heat.clipped
        );
    }
    if let Some((scene, settings)) = &traced {
        let (differing, threshold) = differing_pixels(ia.as_raw(), ib.as_raw());
        if !differing.is_empty() {
            let shares = attribution(scene, settings, &differing);
            println!(
                "Where the {} pixels that differ by {threshold} or more levels are (rayscope's ray tree of each):",
                differing.len()
            );
            print!("{}", attribution_text(&shares));
        }
    }
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::from(1) })
}
