//! The `rayscope` binary: parses flags into validated settings and calls the libraries.

// The binary's printing macros replace std's, so that no command can panic on its output: a
// closed pipe (`rayscope trace --json | head`) ends the process quietly, a full disk is reported,
// and messages to a closed standard error are dropped instead of turning exit code 2 into 101.
// They are defined before the modules so that every module's `println!` and `eprintln!` is these.

/// Prints to standard output; see [`stdout_failed`] for what happens when it cannot be written.
macro_rules! println {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = writeln!(std::io::stdout(), $($t)*) {
            $crate::stdout_failed(e);
        }
    }};
}

/// Prints to standard output without a newline, like [`println!`].
macro_rules! print {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        if let Err(e) = write!(std::io::stdout(), $($t)*) {
            $crate::stdout_failed(e);
        }
    }};
}

/// Prints a line to standard error, dropping it if standard error cannot be written.
macro_rules! eprintln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

mod check_cli;
mod cli;
mod commands;
mod debug_cli;
mod diagnose_cli;
mod diff_cli;
mod probe;
mod shared;
mod trace_text;

use std::process::ExitCode;
use std::sync::atomic::{AtomicU8, Ordering};

use clap::Parser;

/// The exit status when standard output turns out to be closed: 0 for commands that only print,
/// the verdict for those whose exit status is their verdict (see [`set_verdict`]).
static CLOSED_STDOUT_STATUS: AtomicU8 = AtomicU8::new(0);

/// Records a command's verdict (0 pass, 1 fail) before it prints its report, so that a reader
/// that goes away (`rayscope check … | head -1`) cannot turn a failure into success.
pub(crate) fn set_verdict(code: u8) {
    CLOSED_STDOUT_STATUS.store(code, Ordering::SeqCst);
}

/// Ends the process when standard output fails: quietly when the reader went away (a closed
/// pipe), with the verdict [`set_verdict`] recorded (0 if none), else with a message and
/// status 1.
pub(crate) fn stdout_failed(e: std::io::Error) -> ! {
    if e.kind() == std::io::ErrorKind::BrokenPipe {
        std::process::exit(i32::from(CLOSED_STDOUT_STATUS.load(Ordering::SeqCst)));
    }
    eprintln!("error: cannot write to standard output: {e}");
    std::process::exit(1);
}

fn main() -> ExitCode {
    let cli = match cli::Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            // clap prints help/version to stdout (exit 0) and usage errors to stderr (exit 2).
            if let Err(err) = e.print() {
                if !e.use_stderr() {
                    stdout_failed(err);
                }
            }
            return ExitCode::from(if e.use_stderr() { 2 } else { 0 });
        }
    };
    match commands::run(cli) {
        Ok(code) => code,
        Err(e) if e.diagnostic => {
            eprintln!("{}", e.message.trim_end());
            ExitCode::from(e.code)
        }
        Err(e) => {
            eprintln!("error: {}", e.message);
            ExitCode::from(e.code)
        }
    }
}
