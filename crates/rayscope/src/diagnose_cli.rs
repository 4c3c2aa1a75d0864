//! `rayscope mistakes`, `rayscope diagnose` and the `--mistake` flag's parser.

use std::ffi::OsStr;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::error::ErrorKind;
use clap::parser::ValueSource;
use clap::{Args, CommandFactory};
use rayscope_core::diagnose::{diagnose as run_diagnosis, report_text, DiagnoseError, DiagnoseOptions, Image};
use rayscope_core::mistakes::catalogue_text;
use rayscope_core::Mistakes;

use crate::cli::{Cli, RenderOpts};
use crate::commands::{load_file, read_image, setup_threads, Failure};

/// `rayscope diagnose`.
#[derive(Debug, Clone, Args)]
pub struct DiagnoseArgs {
    /// Scene file the image was rendered from.
    #[arg(short = 'f', long = "file", value_name = "SCENE")]
    pub file: PathBuf,
    /// The image to explain (PNG); its size is the render's unless -w/-h say otherwise.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Try single mistakes and settings only, not pairs.
    #[arg(long = "no-pairs")]
    pub no_pairs: bool,
    #[command(flatten)]
    pub opts: RenderOpts,
}

/// Parses `--mistake` values; `help` prints the catalogue.
#[derive(Debug, Clone, Copy)]
pub struct MistakeParser;

impl clap::builder::TypedValueParser for MistakeParser {
    type Value = Mistakes;

    fn parse_ref(&self, cmd: &clap::Command, _arg: Option<&clap::Arg>, value: &OsStr) -> Result<Mistakes, clap::Error> {
        let s = value.to_string_lossy();
        if s == "help" {
            // Like --help: the catalogue on stdout, exit 0, whatever else the line lacks.
            print!("{}", catalogue_text());
            std::process::exit(0);
        }
        Mistakes::parse(&s).map_err(|e| {
            clap::Error::raw(
                ErrorKind::ValueValidation,
                format!("invalid value for --mistake: {e}\n"),
            )
            .with_cmd(cmd)
        })
    }
}

/// `rayscope mistakes`: the catalogue.
pub fn list() -> Result<ExitCode, Failure> {
    print!("{}", catalogue_text());
    Ok(ExitCode::SUCCESS)
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

/// `rayscope diagnose`: exit 0 when the image matches, 1 with a diagnosis, 2 for bad input.
pub fn diagnose(a: &DiagnoseArgs) -> Result<ExitCode, Failure> {
    let decoded = read_image(&a.image, a.opts.allow_large)?;
    // The alpha channel is judged apart: it may hide colour in a viewer, not in the RGB.
    let alpha: Option<Vec<u8>> = decoded
        .color()
        .has_alpha()
        .then(|| decoded.to_rgba8().pixels().map(|p| p.0[3]).collect());
    let img = decoded.to_rgb8();
    let mut opts = a.opts.clone();
    // The image's size is the render's, unless the flags name one.
    if !given("diagnose", "width") && !given("diagnose", "height") {
        opts.width = img.width();
        opts.height = img.height();
    }
    let settings = opts.settings().map_err(Failure::input)?;
    setup_threads(&opts);
    let file = load_file(&a.file, opts.quiet)?;
    let image = Image {
        width: img.width(),
        height: img.height(),
        rgb: img.as_raw(),
        alpha: alpha.as_deref(),
    };
    let search = DiagnoseOptions {
        pairs: !a.no_pairs,
        ..DiagnoseOptions::default()
    };
    let d = run_diagnosis(&file, &settings, image, &search).map_err(|e| match e {
        DiagnoseError::Size { .. } => Failure::input(format!("{}: {e}", a.image.display())),
        DiagnoseError::Buffer(_) => Failure::input(format!("{}: {e}", a.image.display())),
    })?;
    crate::set_verdict(u8::from(!d.matches));
    if a.json {
        let s = serde_json::to_string_pretty(&d).map_err(|e| Failure::failed(e.to_string()))?;
        println!("{s}");
    } else {
        print!("{}", report_text(&d, &a.file.display().to_string()));
    }
    Ok(if d.matches {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
