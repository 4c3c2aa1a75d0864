//! The test student's picture diagnosed as a student runs `rayscope diagnose` on it.

use std::path::Path;

use rayscope_core::diagnose::{diagnose, report_text, DiagnoseOptions, Diagnosis, Image};
use rayscope_core::{RenderSettings, Stage};

use crate::student::{Options, Student};

/// The flags the student gives `diagnose` beside the picture's size, and how wide it searches.
#[derive(Debug, Clone, Copy)]
pub struct Flags {
    /// `-x` as the student's command line says it (their picture may have another level).
    pub aa: u32,
    pub stage: Stage,
    /// The command line's search (pairs of mistakes included), or the quick one: no pairs and a
    /// coarser first pass.
    pub full_search: bool,
}

impl Flags {
    /// Stage 2 at the picture's own `-x`, with the quick search.
    pub fn of(opts: Options) -> Self {
        Self {
            aa: opts.aa,
            stage: Stage::Two,
            full_search: false,
        }
    }
}

/// The diagnosis of the student's picture of `path` with `bugs` and `opts` under `flags`, and
/// its report (naming the scene `scene.txt`).
pub fn diagnosed(path: &Path, bugs: &[&'static str], opts: Options, flags: Flags) -> (Diagnosis, String) {
    diagnosed_edited(path, &|_| {}, bugs, opts, flags)
}

/// As [`diagnosed`], with the student's tracer reading the scene with `edit` made to it (a
/// value read wrong, an entity given another material), and `diagnose` the scene as it is.
#[allow(dead_code)]
pub fn diagnosed_edited(
    path: &Path,
    edit: &dyn Fn(&mut rayscope_scene::SceneFile),
    bugs: &[&'static str],
    opts: Options,
    flags: Flags,
) -> (Diagnosis, String) {
    let file = rayscope_scene::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut read = file.clone();
    edit(&mut read);
    let img = Student::new(&read, bugs, opts).render();
    let image = Image {
        width: opts.width,
        height: opts.height,
        rgb: &img,
        alpha: None,
    };
    let settings = RenderSettings {
        width: opts.width,
        height: opts.height,
        aa: flags.aa,
        stage: flags.stage,
        ..RenderSettings::default()
    };
    let search = if flags.full_search {
        DiagnoseOptions::default()
    } else {
        DiagnoseOptions {
            pairs: false,
            coarse_samples: 2_400,
            ..DiagnoseOptions::default()
        }
    };
    let d = diagnose(&file, &settings, image, &search).expect("the sizes agree");
    let text = report_text(&d, "scene.txt");
    (d, text)
}
