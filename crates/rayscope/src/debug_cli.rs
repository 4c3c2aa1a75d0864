//! `rayscope debug` and `rayscope view`: thin wrappers over the rayscope_debug library.

use std::process::ExitCode;

use super::Failure;
use crate::cli::{DebugArgs, ViewArgs};

/// `rayscope debug`.
pub fn debug(_a: &DebugArgs) -> Result<ExitCode, Failure> {
    Err(Failure::failed("the debugger is not built yet (issue 3)"))
}

/// `rayscope view`.
pub fn view(_a: &ViewArgs) -> Result<ExitCode, Failure> {
    Err(Failure::failed("the scene view is not built yet (issue 3)"))
}
