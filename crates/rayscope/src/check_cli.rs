//! `rayscope check`: reads a tracer's ray log and prints rayscope_check's verdicts.

use std::io::IsTerminal;
use std::process::ExitCode;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use rayscope_check::image::{ImageCheck, LogNext};
use rayscope_check::log::IdRole;
use rayscope_check::{CheckOptions, Finding, Judge, LogContext, LogError};

use crate::cli::CheckArgs;
use crate::shared::{load_scene, settings, setup_threads, Failure};

fn log_failure(e: LogError) -> Failure {
    match e {
        LogError::Io { .. } => Failure::input(e.to_string().trim_start_matches("error: ").to_string()),
        other => Failure {
            code: 2,
            message: other.to_string(),
            diagnostic: true,
        },
    }
}

/// The refusal of a log without a ray to judge: a check that judged nothing has no verdict.
fn nothing_judged(path: &std::path::Path, report: &rayscope_check::Report) -> Failure {
    let mut message = format!("{} has no ray to judge, so nothing was checked", path.display());
    match &report.first_skipped {
        Some(first) if report.skipped_lines > 0 => message.push_str(&format!(
            ": its {} non-blank line{} {} malformed (skipped under --lenient); the first:\n{first}",
            report.skipped_lines,
            if report.skipped_lines == 1 { "" } else { "s" },
            if report.skipped_lines == 1 { "is" } else { "are all" },
        )),
        _ => message.push_str(" (the log is empty or has only blank lines): make your tracer write a record per ray, as docs/check.md describes"),
    }
    Failure::input(message)
}

/// Largest picture `check --image` compares: its colour sums take 47 bytes a pixel (188 MiB at
/// this size; rayscope's own render, made after they are dropped, 15), far past any course image
/// (400×400) and a 2560×1600 screen.
const MAX_PICTURE_PIXELS: u64 = 1 << 22;

/// `--image`: the picture's bytes against the colours the log's camera rays brought back, read
/// in a second pass over the log, and, for a render without random sampling, against rayscope's
/// render where the log lacks pixels.
fn picture(
    a: &CheckArgs,
    png: &std::path::Path,
    judge: &Judge<'_>,
    roles: &[IdRole],
) -> Result<(ImageCheck, Option<LogNext>), Failure> {
    let s = judge.settings();
    let pixels = u64::from(s.width) * u64::from(s.height);
    if pixels > MAX_PICTURE_PIXELS {
        return Err(Failure::input(format!(
            "--image: a {}×{} picture is over check's {} megapixels (its colour sums take 47 bytes a pixel); check a region of it rendered on its own",
            s.width,
            s.height,
            MAX_PICTURE_PIXELS >> 20
        )));
    }
    let img = crate::shared::read_rgb8(png, a.opts.allow_large)?;
    if (img.width(), img.height()) != (s.width, s.height) {
        return Err(Failure::input(format!(
            "'{}' is {}×{} but the flags ask for {}×{}: give check the -w and -h the picture was rendered with",
            png.display(),
            img.width(),
            img.height(),
            s.width,
            s.height
        )));
    }
    let ctx = LogContext::new(judge.scene(), s.width, s.height, judge.samples_per_pixel(), s.aa);
    let mut source = rayscope_check::log::open(&a.rays, ctx, a.lenient, roles).map_err(log_failure)?;
    let mut sums = rayscope_check::image::PixelSums::new(s.width, s.height, judge.samples_per_pixel());
    let camera = |r: &rayscope_check::LoggedRay| judge.kind_of(r) == rayscope_check::log::Kind::Camera;
    sums.read(source.as_mut(), &camera).map_err(log_failure)?;
    let check = rayscope_check::image::judge(&sums, img.as_raw(), a.examples as usize);
    let logged = sums.into_logged();
    // With random sampling, two correct pictures differ in every pixel's noise.
    if rayscope_core::integrator::Integrator::new(judge.scene(), s).stochastic {
        return Ok((check, None));
    }
    let ours = rayscope_core::render(judge.scene(), s, &|_, _| {}, &AtomicBool::new(false))
        .map_err(|e| Failure::failed(e.to_string()))?
        .film
        .to_rgb8();
    let next = LogNext::picture(
        judge.scene(),
        s,
        (&ours, img.as_raw()),
        &logged,
        &s.flags(),
        (&a.file.display().to_string(), &png.display().to_string()),
    );
    Ok((check, Some(next)))
}

/// Runs `rayscope check`: exit 0 when every ray agrees, 1 when any disagrees, 2 for bad input
/// or a log without a ray.
pub fn check(a: &CheckArgs) -> Result<ExitCode, Failure> {
    let settings = settings(&a.opts)?;
    let roles = IdRole::parse_list(&a.ray_ids).map_err(|e| Failure::input(format!("--ray-ids: {e}")))?;
    setup_threads(&a.opts);
    let scene = load_scene(&a.file, a.opts.quiet)?;
    let judge = Judge::new(&scene, &settings);
    let ctx = LogContext::new(
        &scene,
        settings.width,
        settings.height,
        judge.samples_per_pixel(),
        settings.aa,
    );
    let mut source = rayscope_check::log::open(&a.rays, ctx, a.lenient, &roles).map_err(log_failure)?;

    let show = !a.opts.quiet && std::io::stderr().is_terminal();
    let bar = ProgressBar::with_draw_target(None, ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{spinner} checking [{bar:40}] {bytes}/{total_bytes} ({eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    if show {
        bar.set_draw_target(ProgressDrawTarget::stderr());
    }
    let progress = |done: u64, total: u64| {
        bar.set_length(total.max(done));
        bar.set_position(done);
    };
    let start = Instant::now();
    let opts = CheckOptions {
        examples: a.examples as usize,
    };
    let report = rayscope_check::check(&judge, source.as_mut(), opts, &progress);
    bar.finish_and_clear();
    let mut report = report.map_err(log_failure)?;
    if report.rays == 0 {
        return Err(nothing_judged(&a.rays, &report));
    }
    if let Some(png) = &a.image {
        let (image, next) = picture(a, png, &judge, &roles)?;
        report.image = Some(image);
        report.next = next;
    } else {
        report.next = LogNext::sparse(
            report.camera_rays,
            (settings.width, settings.height, judge.samples_per_pixel()),
            &settings.flags(),
            &a.file.display().to_string(),
        );
    }
    let secs = start.elapsed().as_secs_f64();

    let flags = settings.flags();
    let file = a.file.display().to_string();
    let trace = |f: &Finding| {
        f.pixel.map(|[x, y]| {
            format!(
                "rayscope trace -f {file} --pixel {x},{y} --sample {} {flags}",
                f.sample.unwrap_or(0)
            )
        })
    };
    crate::set_verdict(u8::from(!report.passed()));
    if a.json {
        let v = report.to_json(&trace);
        println!(
            "{}",
            serde_json::to_string_pretty(&v).map_err(|e| Failure::failed(e.to_string()))?
        );
    } else {
        print!("{}", report.to_text(&trace));
    }
    if !a.opts.quiet {
        let t = report.timing;
        eprintln!(
            "{} rays in {secs:.3} s ({:.2} M rays/s; reading {:.3} s and judging {:.3} s, side by side, on {} threads)",
            report.rays,
            report.rays as f64 / 1e6 / secs.max(1e-9),
            t.reading.as_secs_f64(),
            t.judging.as_secs_f64(),
            rayon::current_num_threads()
        );
    }
    Ok(if report.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
