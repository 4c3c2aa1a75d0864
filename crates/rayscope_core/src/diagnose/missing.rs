//! Entities a picture leaves out, recognised by rendering the scene without them: every entity
//! of one kind (all the spheres, say: an intersection test that never hits) or one entity alone
//! (its line read wrong). Where rayscope's render without them reproduces the picture's
//! difference, the picture is said to lack them, whatever mistake in the tracer did it — a
//! statement of what the picture shows, not a name from the catalogue.

use std::collections::BTreeMap;

use rayscope_scene::SceneFile;

use super::acne::Recognised;
use super::explained::{Explained, Traced};

/// Most entities tried alone: those of the largest parts of the difference.
const MAX_SINGLE: usize = 3;

/// How an entity set is left out: all the entities of one kind, or one entity.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Left {
    /// Every entity declared by this command (`Sphere`).
    Kind(&'static str),
    /// One entity.
    One,
}

/// The entity sets to try leaving out, each with how it is chosen: every entity of one kind
/// where the scene has entities of another kind too, then the entities of the largest directly
/// seen parts of the difference, alone. No set is tried twice.
fn candidates(file: &SceneFile, traced: &Traced) -> Vec<(Left, Vec<usize>)> {
    let mut out: Vec<(Left, Vec<usize>)> = Vec::new();
    for command in ["Sphere", "Plane", "Triangle", "ObjModel"] {
        let of: Vec<usize> = (0..file.entities.len())
            .filter(|&i| file.entities[i].shape.command() == command)
            .collect();
        if !of.is_empty() && of.len() < file.entities.len() {
            out.push((Left::Kind(command), of));
        }
    }
    let mut singles = 0;
    for part in traced
        .parts
        .iter()
        .filter(|p| p.seen_in.is_empty() && !p.material.is_empty())
    {
        if singles == MAX_SINGLE {
            break;
        }
        let Some(i) = file.entities.iter().position(|e| e.name == part.entity) else {
            continue;
        };
        singles += 1;
        if !out.iter().any(|(_, set)| set == &[i]) {
            out.push((Left::One, vec![i]));
        }
    }
    out
}

/// The noun one entity of a kind goes by in a sentence, with its article.
fn singular(command: &str) -> &'static str {
    match command {
        "Sphere" => "a sphere",
        "Plane" => "a plane",
        "Triangle" => "a triangle",
        _ => "an OBJ model",
    }
}

/// The plural a kind's entities go by in a sentence.
pub(crate) fn plural(command: &str) -> &'static str {
    match command {
        "Sphere" => "spheres",
        "Plane" => "planes",
        "Triangle" => "triangles",
        _ => "OBJ models",
    }
}

/// The entities the picture lacks, where rayscope's render without them (from `without`, the
/// full image for a set of the file's entity indices) explains the difference between `image`
/// and `ours` at least in part ([`Explained::shows_part`]), the set explaining the most differing
/// pixels, with what its render explains; `None` otherwise. Beside it, what each set tried
/// explains, whether or not it shows a part.
#[allow(clippy::too_many_arguments)]
pub(crate) fn recognise(
    file: &SceneFile,
    without: &dyn Fn(&[usize]) -> Vec<u8>,
    ours: &[u8],
    image: &[u8],
    size: (u32, u32),
    threshold: u8,
    differs: &[bool],
    traced: &Traced,
) -> (Option<(Recognised, Explained)>, Vec<Explained>) {
    let tried: Vec<(Left, Vec<usize>, Explained)> = candidates(file, traced)
        .into_iter()
        .map(|(left, set)| {
            let render = without(&set);
            let e = Explained::of(&render, ours, image, size, threshold, differs, traced);
            (left, set, e)
        })
        .collect();
    let all: Vec<Explained> = tried.iter().map(|(.., e)| e.clone()).collect();
    let best = tried
        .into_iter()
        .filter(|(.., e)| e.shows_part())
        .max_by(|a, b| (a.2.shows_all(), a.2.pixels).cmp(&(b.2.shows_all(), b.2.pixels)));
    let Some((left, set, e)) = best else {
        return (None, all);
    };
    let names: Vec<String> = set.iter().map(|&i| file.entities[i].name.clone()).collect();
    let quoted: Vec<String> = names.iter().map(|n| format!("'{n}'")).collect();
    let full = e.shows_all();
    // "sphere" for the test's name: the noun without its article.
    let kind = |command: &str| singular(command).split_once(' ').map_or("", |(_, noun)| noun);
    let text = match (left, full) {
        (Left::Kind(command), true) => format!(
            "Your picture is rayscope's render without its {} ({}): they are not seen, cast no shadows and show in no mirror, as if your tracer never found a hit on {}. Look at your {} intersection test: work one ray out by hand and compare, or let `rayscope probe` try it on rays whose answers are known (docs/probe.md).",
            plural(command),
            super::acne::list(&names, 6),
            singular(command),
            kind(command),
        ),
        (Left::Kind(command), false) => format!(
            "Where your picture differs, much of it is what rayscope's render without its {} ({}) shows: in places your picture shows what lies behind them, as if your tracer missed them there. Look at your {} intersection test and at how your tracer reads their lines of the scene file: work one ray out by hand and compare, or let `rayscope probe` try it on rays whose answers are known (docs/probe.md).",
            plural(command),
            super::acne::list(&names, 6),
            kind(command),
        ),
        (Left::One, _) => {
            let entity = &file.entities[set[0]];
            let command = entity.shape.command();
            let others = file
                .entities
                .iter()
                .filter(|o| o.shape.command() == command && o.name != entity.name)
                .count();
            let like = if others > 0 {
                format!(
                    " The scene's other {} are in your picture, so look at what sets this one apart: its line in the scene file (line {}) as your tracer reads it, its size and place, its material.",
                    plural(command),
                    entity.line
                )
            } else {
                format!(
                    " It is the scene's only {}: look at your {} intersection test, and at how your tracer reads its line of the scene file (line {}).",
                    kind(command),
                    kind(command),
                    entity.line
                )
            };
            let shape = singular(command);
            if full {
                format!(
                    "Your picture is rayscope's render without {} ({shape}): it is not seen, casts no shadow and shows in no mirror, as if your tracer never found a hit on it.{like}",
                    quoted[0]
                )
            } else {
                format!(
                    "Where your picture differs, much of it is what rayscope's render without {} ({shape}) shows: in places your picture shows what lies behind it, as if your tracer missed it there.{like}",
                    quoted[0]
                )
            }
        }
    };
    let mut numbers = BTreeMap::new();
    numbers.insert("entities", set.len() as f64);
    numbers.insert("percent_explained", e.percent);
    numbers.insert("error_removed_percent", e.error_percent);
    let found = Recognised {
        code: "entities-missing",
        mistake: "",
        text,
        entities: names,
        pixels: e.pixels,
        share: e.percent / 100.0,
        numbers,
    };
    (Some((found, e)), all)
}
