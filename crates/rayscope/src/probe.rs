//! `rayscope probe`: the flags handed to [`rayscope_check::probe`], whose report is printed and
//! whose verdict is the exit status.

use std::process::ExitCode;

use rayscope_check::probe;

use crate::cli::ProbeArgs;
use crate::shared::{load_file, Failure};

/// Runs `rayscope probe`.
pub fn run(a: &ProbeArgs) -> Result<ExitCode, Failure> {
    probe::check_timeouts(a.timeout, a.startup_timeout).map_err(Failure::input)?;
    let file = load_file(&a.file, a.json)?;
    let opts = probe::Options {
        scene: &a.file,
        command: &a.command,
        mesh_triangles: a.mesh_triangles,
        rays_per_case: a.rays_per_case,
        seed: a.seed,
        timeout: a.timeout,
        startup_timeout: a.startup_timeout,
    };
    let outcome = probe::run(&opts, &file, &mut |pid| {
        // The program runs in a process group of its own, which Ctrl-C in the terminal does not
        // reach: stop it on the way out.
        let _ = ctrlc::set_handler(move || {
            probe::kill_group(pid);
            std::process::exit(130);
        });
    })
    .map_err(Failure::input)?;
    crate::set_verdict(u8::from(!outcome.passed()));
    if a.json {
        println!("{}", outcome.json(&a.file, &a.command));
    } else {
        // Written as it is made: with --all-examples the text grows with the battery.
        outcome.text(&a.file, a.all_examples, &mut |part| print!("{part}"));
    }
    Ok(if outcome.passed() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
