//! What several commands use: failures and their exit codes, loading scenes and images within
//! their limits, the thread pool, and which flags the command line gave.

use std::path::Path;

use clap::parser::ValueSource;
use clap::CommandFactory;
use rayscope_core::{RenderSettings, Scene};

use crate::cli::{Cli, RenderOpts};

/// A failure with the exit code it maps to (1: failure, 2: usage or input, 130: interrupted).
#[derive(Debug)]
pub struct Failure {
    /// Exit code.
    pub code: u8,
    /// Message, printed once after "error: ".
    pub message: String,
    /// The message is a complete diagnostic that carries its own "error:" heading.
    pub diagnostic: bool,
}

impl Failure {
    /// A usage or input error (exit 2).
    pub(crate) fn input(message: impl Into<String>) -> Self {
        Self {
            code: 2,
            message: message.into(),
            diagnostic: false,
        }
    }
    /// A failure (exit 1).
    pub(crate) fn failed(message: impl Into<String>) -> Self {
        Self {
            code: 1,
            message: message.into(),
            diagnostic: false,
        }
    }
}

/// Builds the thread pool for `--threads` (global, once).
pub fn setup_threads(opts: &RenderOpts) {
    if let Some(n) = opts.threads {
        // Fails only if a pool was already built, which cannot happen in this process.
        let _ = rayon::ThreadPoolBuilder::new().num_threads(n as usize).build_global();
    }
}

/// Loads and converts a scene, printing warnings unless quiet. Input errors exit with 2. The
/// file's meshes are freed before the BVH build (see [`Scene::from_owned_file`]).
pub fn load_scene(path: &Path, quiet: bool) -> Result<Scene, Failure> {
    Ok(Scene::from_owned_file(load_file(path, quiet)?))
}

/// [`load_scene`] with the OBJ mistakes of `settings` made while loading.
pub(crate) fn load_scene_for(path: &Path, quiet: bool, settings: &RenderSettings) -> Result<Scene, Failure> {
    let mut file = load_file(path, quiet)?;
    settings.mistakes.apply_to_file(&mut file);
    Ok(Scene::from_owned_file(file))
}

/// Loads a scene file, printing warnings unless quiet. Input errors exit with 2.
pub fn load_file(path: &Path, quiet: bool) -> Result<rayscope_scene::SceneFile, Failure> {
    let file = rayscope_scene::load(path).map_err(|e| match e {
        rayscope_scene::SceneError::Invalid(d) => Failure {
            code: 2,
            message: d.to_string(),
            diagnostic: true,
        },
        other => Failure::input(other.to_string()),
    })?;
    if !quiet {
        for w in &file.warnings {
            eprintln!("{w}");
        }
    }
    Ok(file)
}

pub(crate) fn settings(opts: &RenderOpts) -> Result<RenderSettings, Failure> {
    opts.settings().map_err(Failure::input)
}

/// Most pixels of an image `diff` and `diagnose` read: a render's budget without `--allow-large`
/// (with it, a render's largest image).
pub const MAX_IMAGE_PIXELS: u64 = 1 << 26;

/// Reads the image at `path` as 8-bit RGB: a regular file only, its size read from its header and
/// checked against [`MAX_IMAGE_PIXELS`] (or 2^30 with `allow_large`) before it is decoded.
pub fn read_rgb8(path: &Path, allow_large: bool) -> Result<image::RgbImage, Failure> {
    Ok(read_image(path, allow_large)?.to_rgb8())
}

/// An image file as decoded, alpha channel and all, with [`read_rgb8`]'s checks and messages.
pub fn read_image(path: &Path, allow_large: bool) -> Result<image::DynamicImage, Failure> {
    let cannot = |e: &dyn std::fmt::Display| Failure::input(format!("cannot read image '{}': {e}", path.display()));
    let meta = std::fs::metadata(path).map_err(|e| cannot(&e))?;
    if let Some(what) = rayscope_scene::input::not_a_file(&meta) {
        return Err(cannot(&format!("it is {what}, not a file")));
    }
    let open = || {
        image::ImageReader::open(path)
            .and_then(image::ImageReader::with_guessed_format)
            .map_err(|e| cannot(&e))
    };
    let (w, h) = open()?.into_dimensions().map_err(|e| cannot(&e))?;
    let max = if allow_large { 1 << 30 } else { MAX_IMAGE_PIXELS };
    if u64::from(w) * u64::from(h) > max {
        let hint = if allow_large {
            ""
        } else {
            " (--allow-large raises it to 2^30 where the command has it)"
        };
        return Err(cannot(&format!(
            "its header says {w}×{h} = {} pixels, over the limit of {max}{hint}",
            u64::from(w) * u64::from(h)
        )));
    }
    open()?.decode().map_err(|e| cannot(&e))
}

/// True when the command line set `id` on the subcommand `sub` itself.
pub(crate) fn given(sub: &str, id: &str) -> bool {
    Cli::command()
        .try_get_matches()
        .ok()
        .and_then(|m| {
            m.subcommand_matches(sub)
                .map(|d| d.value_source(id) == Some(ValueSource::CommandLine))
        })
        .unwrap_or(false)
}
