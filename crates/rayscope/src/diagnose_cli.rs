//! `rayscope mistakes` and `rayscope diagnose`.

use std::process::ExitCode;

use rayscope_core::diagnose::{diagnose as run_diagnosis, report_text, DiagnoseError, DiagnoseOptions, Image};
use rayscope_core::mistakes::catalogue_text;

use crate::cli::DiagnoseArgs;
use crate::shared::{given, load_file, read_image, setup_threads, Failure};

/// `rayscope mistakes`: the catalogue.
pub fn list() -> Result<ExitCode, Failure> {
    print!("{}", catalogue_text());
    Ok(ExitCode::SUCCESS)
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
