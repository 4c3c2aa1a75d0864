//! What each command does: glue between validated flags and library calls.

use std::io::IsTerminal;
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayscope_core::animation::frame_path;
use rayscope_core::farm;
use rayscope_core::output::{check_writable, write_film, Format};
use rayscope_core::{render, render_tiles_of, trace_pixel, RenderOutput, RenderSettings, Scene};

use crate::cli::{BenchCommand, BenchRaysArgs, BenchRenderArgs, Cli, Command, MergeArgs, RenderArgs, TraceArgs};
use crate::shared::{load_file, load_scene, load_scene_for, settings, setup_threads, Failure};

/// Runs the parsed command line.
pub fn run(cli: Cli) -> Result<ExitCode, Failure> {
    match cli.command {
        None => render_command(&cli.render),
        Some(Command::Trace(a)) => trace_command(&a),
        Some(Command::Diff(a)) => crate::diff_cli::diff(&a),
        Some(Command::Bench(BenchCommand::Render(a))) => bench_render(&a),
        Some(Command::Bench(BenchCommand::Rays(a))) => bench_rays(&a),
        Some(Command::Debug(a)) => crate::debug_cli::debug(&a),
        Some(Command::View(a)) => crate::debug_cli::view(&a),
        Some(Command::Probe(a)) => crate::probe::run(&a),
        Some(Command::Check(a)) => crate::check_cli::check(&a),
        Some(Command::Mistakes) => crate::diagnose_cli::list(),
        Some(Command::Diagnose(a)) => crate::diagnose_cli::diagnose(&a),
        Some(Command::Merge(a)) => merge_command(&a),
    }
}

fn render_command(args: &RenderArgs) -> Result<ExitCode, Failure> {
    let (Some(file), Some(output)) = (&args.file, &args.output) else {
        return Err(Failure::input("both -f/--file and -o/--output are required"));
    };
    let opts = &args.opts;
    let farm = &args.farm;
    let base = settings(opts)?;
    let path = farm.camera_path().map_err(Failure::input)?;
    if let Some(spec) = farm.part {
        if Format::from_path(output).ok() != Some(Format::Exr) {
            return Err(Failure::input(format!(
                "--part {}/{} writes a part in linear float: give -o an .exr name (e.g. part_{}.exr), and `rayscope merge` the parts into the image you want",
                spec.index, spec.count, spec.index
            )));
        }
        let (tx, ty) = rayscope_core::render::tile_grid(base.width, base.height);
        if spec.count > tx * ty {
            return Err(Failure::input(format!(
                "--part {}/{}: a {}×{} image has only {} tiles of {t}×{t} pixels, so at most {} parts",
                spec.index,
                spec.count,
                base.width,
                base.height,
                tx * ty,
                tx * ty,
                t = rayscope_core::render::TILE
            )));
        }
    }
    // Frames one after another, none of them held (`--frames` bounds their number).
    let frames: Box<dyn Iterator<Item = Option<u32>>> = match farm.frames {
        Some((a, b)) => Box::new((a..=b).map(Some)),
        None => Box::new(std::iter::once(None)),
    };
    let out_path = |frame: Option<u32>| match frame {
        Some(f) => frame_path(output, f),
        None => output.clone(),
    };
    // Fail before the (possibly long) render if the output cannot be written.
    check_writable(&out_path(farm.frames.map(|(a, _)| a))).map_err(|e| Failure::input(e.to_string()))?;
    // Before loading: the BVH build already uses the pool.
    setup_threads(opts);
    // The note on what a glass colour means comes first, before the scene's warnings.
    let mut scene_file = load_file(file, true)?;
    if !opts.quiet {
        if let Some(note) = rayscope_core::edition::glass_colour_note(&scene_file, &base) {
            eprintln!("{note}");
        }
        for w in &scene_file.warnings {
            eprintln!("{w}");
        }
    }
    let hash = match farm.part {
        Some(_) => Some(farm::scene_hash(&scene_file).map_err(Failure::input)?),
        None => None,
    };
    base.mistakes.apply_to_file(&mut scene_file);
    let scene = Scene::from_owned_file(scene_file);

    let cancel = Arc::new(AtomicBool::new(false));
    {
        let cancel = cancel.clone();
        // Ctrl-C (or SIGTERM) sets the flag: the render stops within a batch of samples and
        // nothing is written. A second one ends the process at once.
        let _ = ctrlc::set_handler(move || {
            if cancel.swap(true, Ordering::SeqCst) {
                std::process::exit(130);
            }
        });
    }
    let show = !opts.quiet && std::io::stderr().is_terminal();
    for frame in frames {
        let mut settings = base;
        if let Some(f) = frame {
            settings.camera = path.camera_at(base.camera, f);
        }
        let output = out_path(frame);
        let tiles = farm.part.map(|spec| {
            let (tx, ty) = rayscope_core::render::tile_grid(settings.width, settings.height);
            farm::deal(tx, ty, spec)
        });
        let out = render_progress(&scene, &settings, show, &cancel, tiles.as_deref())?;
        if out.nonfinite > 0 {
            let (x, y, s) = out.first_nonfinite.unwrap_or_default();
            eprintln!(
                "warning: {} samples were NaN or infinite and were written as black; replay the first with:\n  rayscope trace -f {} --pixel {x},{y} --sample {s} {}",
                out.nonfinite,
                file.display(),
                settings.flags()
            );
        }
        match (farm.part, &tiles, &hash) {
            (Some(spec), Some(tiles), Some(hash)) => {
                let mut header =
                    farm::PartHeader::new(file, hash.clone(), &settings, settings.flags(), frame, spec, tiles);
                header.nonfinite = out.nonfinite;
                header.render_seconds = out.elapsed.as_secs_f64();
                farm::write_part(&output, &header, &out.film).map_err(|e| Failure::failed(e.to_string()))?;
            }
            _ => write_film(&out.film, &output).map_err(|e| Failure::failed(e.to_string()))?,
        }
        if !opts.quiet {
            let what = match farm.part {
                Some(p) => format!(
                    "part {}/{} ({} tiles), ",
                    p.index,
                    p.count,
                    tiles.as_ref().map_or(0, Vec::len)
                ),
                None => String::new(),
            };
            let frame = frame.map_or(String::new(), |f| format!("frame {f}, "));
            eprintln!("{frame}{what}{}", summary(&settings, &out, &output));
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn merge_command(a: &MergeArgs) -> Result<ExitCode, Failure> {
    check_writable(&a.output).map_err(|e| Failure::input(e.to_string()))?;
    let start = Instant::now();
    let mut limits = rayscope_core::settings::Limits::command_line(a.allow_large);
    if !a.allow_large {
        limits.pixel_hint = " (8192×8192); pass --allow-large to merge it anyway";
    }
    // Merging traces no ray: the parts' samples are already taken.
    limits.max_grid_samples = None;
    let m = farm::merge_within(&a.parts, a.allow_missing, &limits).map_err(|e| Failure::input(e.0))?;
    let (w, h) = (m.film.width, m.film.height);
    if !m.missing_parts.is_empty() {
        let rects: Vec<String> = m
            .missing_tiles
            .iter()
            .take(8)
            .map(|&t| {
                let (x0, y0, x1, y1) = rayscope_core::render::tile_rect(w, h, t);
                format!("x {x0}..{x1} y {y0}..{y1}")
            })
            .collect();
        let more = m.missing_tiles.len().saturating_sub(rects.len());
        let (which, again) = match m.missing_parts.as_slice() {
            [k] => (
                format!("part {k} of {} is", m.header.parts),
                format!("--part {k}/{}", m.header.parts),
            ),
            ks => (
                format!("parts {} of {} are", farm::list(ks), m.header.parts),
                format!("--part K/{}", m.header.parts),
            ),
        };
        eprintln!(
            "warning: {which} missing; {} tiles are black: {}{}. Render them with `{again}` and merge again",
            m.missing_tiles.len(),
            rects.join("; "),
            if more > 0 {
                format!("; and {more} more")
            } else {
                String::new()
            },
        );
    }
    if m.nonfinite > 0 {
        eprintln!(
            "warning: {} samples were NaN or infinite and were written as black (the parts' own messages say where)",
            m.nonfinite
        );
    }
    write_film(&m.film, &a.output).map_err(|e| Failure::failed(e.to_string()))?;
    if !a.quiet {
        let frame = m.header.frame.map_or(String::new(), |f| format!(", frame {f}"));
        eprintln!(
            "merged {} of {} parts of {}{frame} ({w}×{h}, {}) in {:.3} s → {}",
            a.parts.len(),
            m.header.parts,
            m.header.scene,
            m.header.flags,
            start.elapsed().as_secs_f64(),
            a.output.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Renders every tile, or only `tiles`, with an indicatif bar that appears only for renders
/// longer than about half a second.
fn render_progress(
    scene: &Scene,
    settings: &RenderSettings,
    show: bool,
    cancel: &AtomicBool,
    tiles: Option<&[u32]>,
) -> Result<RenderOutput, Failure> {
    let total = settings.width as u64 * settings.height as u64;
    let bar = ProgressBar::with_draw_target(Some(total), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{spinner} rendering [{bar:40}] {percent:>3}% {elapsed_precise} (eta {eta})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    let start = Instant::now();
    let shown = Mutex::new(false);
    let progress = |done: u64, total: u64| {
        bar.set_length(total);
        if show && start.elapsed() > Duration::from_millis(500) {
            let mut s = shown.lock().unwrap_or_else(|e| e.into_inner());
            if !*s {
                bar.set_draw_target(ProgressDrawTarget::stderr());
                *s = true;
            }
        }
        bar.set_position(done);
    };
    let result = match tiles {
        Some(t) => render_tiles_of(scene, settings, t, &progress, cancel),
        None => render(scene, settings, &progress, cancel),
    };
    bar.finish_and_clear();
    result.map_err(|_| Failure {
        code: 130,
        message: "interrupted; no image was written".into(),
        diagnostic: false,
    })
}

fn summary(s: &RenderSettings, out: &RenderOutput, path: &Path) -> String {
    let secs = out.elapsed.as_secs_f64();
    let rays = out.counters.total();
    let m = |n: u64| n as f64 / 1e6;
    let c = &out.counters;
    format!(
        "{}×{}, {} spp, {:.3} s, {:.2} M rays ({:.1} Mrays/s; camera {:.2} M, secondary {:.2} M, shadow {:.2} M) → {}",
        s.width,
        s.height,
        out.samples_per_pixel,
        secs,
        m(rays),
        m(rays) / secs.max(1e-9),
        m(c.camera),
        m(c.secondary),
        m(c.shadow),
        path.display()
    )
}

fn trace_command(a: &TraceArgs) -> Result<ExitCode, Failure> {
    let settings = settings(&a.opts)?;
    let (x, y) = a.pixel;
    if x >= settings.width || y >= settings.height {
        return Err(Failure::input(format!(
            "pixel ({x}, {y}) is outside the {}×{} image (pixels are 0-based from the top-left)",
            settings.width, settings.height
        )));
    }
    let scene = load_scene_for(&a.file, a.opts.quiet, &settings)?;
    let spp = rayscope_core::integrator::Integrator::new(&scene, &settings).samples_per_pixel();
    if a.sample >= spp {
        return Err(Failure::input(format!(
            "sample {} does not exist: pixels have {spp} samples (0 to {})",
            a.sample,
            spp - 1
        )));
    }
    let tree = trace_pixel(&scene, &settings, x, y, a.sample);
    if a.json {
        let s = serde_json::to_string_pretty(&tree).map_err(|e| Failure::failed(e.to_string()))?;
        println!("{s}");
    } else {
        print!("{}", crate::trace_text::format_tree(&tree, a.precision.into()));
    }
    Ok(ExitCode::SUCCESS)
}

fn bench_render(a: &BenchRenderArgs) -> Result<ExitCode, Failure> {
    let settings = settings(&a.opts)?;
    setup_threads(&a.opts);
    let t0 = Instant::now();
    let scene = load_scene(&a.file, true)?;
    let load = t0.elapsed();
    let cancel = AtomicBool::new(false);
    let noop = |_: u64, _: u64| {};
    let warm = render(&scene, &settings, &noop, &cancel).map_err(|e| Failure::failed(e.to_string()))?;
    let mut times: Vec<f64> = Vec::new();
    for _ in 0..a.repeat {
        let out = render(&scene, &settings, &noop, &cancel).map_err(|e| Failure::failed(e.to_string()))?;
        times.push(out.elapsed.as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let rays = warm.counters.total();
    println!(
        "scene={} size={}x{} spp={} threads={} load_s={:.4} runs={} median_s={:.4} min_s={:.4} max_s={:.4} mrays_per_s={:.1}",
        a.file.display(),
        settings.width,
        settings.height,
        warm.samples_per_pixel,
        rayon::current_num_threads(),
        load.as_secs_f64(),
        a.repeat,
        median,
        times[0],
        times[times.len() - 1],
        rays as f64 / 1e6 / median
    );
    Ok(ExitCode::SUCCESS)
}

/// Bytes of one ray in a `bench rays --rays-file` file: six little-endian f32.
const RAY_RECORD: u64 = 24;

/// Most rays `bench rays --rays-file` reads: 384 MiB of records, traced from 512 MiB of rays.
pub const MAX_BENCH_RAYS: u64 = 1 << 24;

fn bench_rays(a: &BenchRaysArgs) -> Result<ExitCode, Failure> {
    use rayon::prelude::*;
    use rayscope_core::{math::RayPacket, simd::LANES};
    use rayscope_core::{Camera, CameraSettings, Ray};

    if let Some(n) = a.threads {
        let _ = rayon::ThreadPoolBuilder::new().num_threads(n as usize).build_global();
    }
    let file = load_file(&a.file, false)?;
    let t0 = Instant::now();
    let scene = Scene::from_owned_file(file);
    let build = t0.elapsed().as_secs_f64();
    let rays: Vec<Ray> = match (&a.rays_file, a.primary) {
        (Some(path), _) => {
            let bytes = rayscope_scene::input::read_bounded(path, MAX_BENCH_RAYS * RAY_RECORD).map_err(|e| {
                // A regular file refused as input is one over the bound.
                let too_large = e.kind() == std::io::ErrorKind::InvalidInput && path.is_file();
                let hint = if too_large {
                    format!(" (at most {MAX_BENCH_RAYS} rays of {RAY_RECORD} bytes)")
                } else {
                    String::new()
                };
                Failure::input(format!("cannot read '{}': {e}{hint}", path.display()))
            })?;
            if bytes.is_empty() {
                return Err(Failure::input(format!(
                    "'{}' holds no rays: expected 24-byte records of 6 little-endian f32 (origin, direction)",
                    path.display()
                )));
            }
            if bytes.len() % 24 != 0 {
                return Err(Failure::input(format!(
                    "'{}' is {} bytes, not a whole number of 24-byte ray records (6 little-endian f32)",
                    path.display(),
                    bytes.len()
                )));
            }
            let mut rays = Vec::with_capacity(bytes.len() / 24);
            for (i, rec) in bytes.chunks_exact(24).enumerate() {
                let f: Vec<f32> = rec
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect();
                let d = glam::Vec3A::new(f[3], f[4], f[5]);
                if d.length_squared() <= 0.0 || !f.iter().all(|v| v.is_finite()) {
                    return Err(Failure::input(format!(
                        "ray {i} in '{}' has a zero or non-finite direction or origin",
                        path.display()
                    )));
                }
                rays.push(Ray::new(glam::Vec3A::new(f[0], f[1], f[2]), d.normalize()));
            }
            rays
        }
        (None, Some((w, h))) => {
            let cam = Camera::new(CameraSettings::default(), w, h);
            let pixels: Vec<(u32, u32)> = if a.packets {
                // 4×4 blocks, so each packet of 16 is a compact bundle.
                let (bw, bh) = (w.div_ceil(4), h.div_ceil(4));
                (0..bw * bh)
                    .flat_map(|b| {
                        let (bx, by) = (b % bw * 4, b / bw * 4);
                        (0..16).map(move |i| (bx + i % 4, by + i / 4))
                    })
                    .filter(|&(x, y)| x < w && y < h)
                    .collect()
            } else {
                (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).collect()
            };
            pixels
                .into_iter()
                .map(|(x, y)| {
                    let (u, v) = cam.pixel_center(x, y);
                    cam.ray(u, v)
                })
                .collect()
        }
        (None, None) => return Err(Failure::input("give --primary WxH or --rays-file FILE")),
    };
    const BATCH: usize = 512;
    // A whole number of batches, so the batches are those of BATCH rays from the start.
    const CHUNK: usize = 8 * BATCH;
    // Each mode gets a loop of its own (the hot loop's code generation is sensitive enough that
    // a mode test inside it cost the bunny 10 %).
    let count = |hits_of: &(dyn Fn(&[Ray]) -> u64 + Sync)| -> u64 { rays.par_chunks(CHUNK).map(hits_of).sum() };
    let packets = |chunk: &[Ray]| -> u64 {
        chunk
            .chunks(LANES)
            .map(|group| {
                let mut p = RayPacket::default();
                for (i, r) in group.iter().enumerate() {
                    p.set(i, r, f32::INFINITY);
                }
                let h = scene.wide.closest_rays(&mut p, 0.0);
                (0..group.len()).filter(|&i| h.get(i).is_some()).count() as u64
            })
            .sum()
    };
    let alone = |chunk: &[Ray]| -> u64 {
        chunk
            .iter()
            .filter(|r| scene.intersect(r, 0.0, f32::INFINITY).is_some())
            .count() as u64
    };
    let many = |chunk: &[Ray]| -> u64 {
        chunk
            .chunks(BATCH)
            .map(|batch| {
                let mut hits = 0;
                scene.intersect_many(batch, 0.0, f32::INFINITY, |_, h| hits += u64::from(h.is_some()));
                hits
            })
            .sum()
    };
    let trace = || -> (u64, f64) {
        let start = Instant::now();
        let hits = if a.packets {
            count(&packets)
        } else if a.no_interleave {
            count(&alone)
        } else {
            count(&many)
        };
        (hits, start.elapsed().as_secs_f64())
    };
    let (hits, _) = trace(); // warm-up
    let mut times: Vec<f64> = (0..a.repeat).map(|_| trace().1).collect();
    times.sort_by(f64::total_cmp);
    let secs = times[times.len() / 2];
    println!(
        "build: {} primitives in {:.4} s, {} bytes of BVH ({:.1} bytes/triangle incl. triangle data)",
        scene.primitive_count(),
        build,
        scene.wide.memory_bytes(),
        (scene.wide.memory_bytes() + scene.triangles.len() * std::mem::size_of::<rayscope_core::geometry::Triangle>())
            as f64
            / scene.triangles.len().max(1) as f64
    );
    if a.packets {
        println!("mode: ray packets of {LANES}");
    } else if a.no_interleave {
        println!("mode: one ray at a time, walks never interleaved");
    } else {
        let batches = rays.len().div_ceil(BATCH);
        let interleaved = rays.chunks(BATCH).filter(|b| scene.wide.interleaves(b)).count();
        println!("mode: one ray at a time; walks interleaved in {interleaved} of {batches} batches of {BATCH}");
    }
    if a.visits {
        // (hits, visits of hitting rays, visits of missing rays)
        let (hit, hit_visits, miss_visits) = rays
            .par_iter()
            .map(|r| match scene.intersect_with_cost(r) {
                (Some(_), v) => (1u64, u64::from(v), 0u64),
                (None, v) => (0, 0, u64::from(v)),
            })
            .reduce(|| (0, 0, 0), |x, y| (x.0 + y.0, x.1 + y.1, x.2 + y.2));
        let mean = |v: u64, n: u64| if n == 0 { 0.0 } else { v as f64 / n as f64 };
        let miss = rays.len() as u64 - hit;
        println!(
            "visits: per hitting ray {:.2}, per missing ray {:.2} (nodes and leaves tested; a plane or a packet outside the tree counts one)",
            mean(hit_visits, hit),
            mean(miss_visits, miss)
        );
    }
    // Nanoseconds: a handful of rays traces in well under a microsecond, which six decimals
    // printed as zero seconds.
    println!(
        "rays={} hits={hits} seconds={secs:.9} mrays_per_s={:.2} threads={}",
        rays.len(),
        rays.len() as f64 / 1e6 / secs,
        rayon::current_num_threads()
    );
    Ok(ExitCode::SUCCESS)
}
