//! Writes rayscope's own stage-2 trace of a scene as a JSON Lines ray log, for the benchmark:
//!
//! cargo run --profile bench -p rayscope_check --example write_log -- SCENE W H AA OUT.jsonl

use std::io::BufWriter;

use rayscope_core::{RenderSettings, Scene, Stage};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 6 {
        eprintln!("usage: write_log SCENE WIDTH HEIGHT AA OUT.jsonl");
        std::process::exit(2);
    }
    let num = |i: usize| -> u32 {
        args[i].parse().unwrap_or_else(|_| {
            eprintln!("expected a whole number, found '{}'", args[i]);
            std::process::exit(2)
        })
    };
    let file = rayscope_scene::load(std::path::Path::new(&args[1])).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(2)
    });
    let scene = Scene::from_owned_file(file);
    let settings = RenderSettings {
        width: num(2),
        height: num(3),
        aa: num(4),
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let out = std::fs::File::create(&args[5]).unwrap_or_else(|e| {
        eprintln!("cannot create {}: {e}", args[5]);
        std::process::exit(2)
    });
    let mut w = BufWriter::with_capacity(1 << 20, out);
    let t = std::time::Instant::now();
    match rayscope_check::selflog::write_log(&scene, &settings, 0..settings.height, &mut w) {
        Ok(n) => eprintln!("{n} rays written to {} in {:.1} s", args[5], t.elapsed().as_secs_f64()),
        Err(e) => {
            eprintln!("cannot write {}: {e}", args[5]);
            std::process::exit(1)
        }
    }
}
