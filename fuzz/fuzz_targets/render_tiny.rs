//! Scene text → parser → core scene → an 8×8 render. Never panics, never writes NaN or infinity.
//!
//! The first byte picks the stage, ambient light and debug channel; the rest is the scene.
#![no_main]

use std::path::Path;
use std::sync::atomic::AtomicBool;

use libfuzzer_sys::fuzz_target;
use rayscope_core::{render, Channel, RenderSettings, Scene, Stage};
use rayscope_scene::{DVec3, SceneFile, Shape};

fuzz_target!(|data: &[u8]| {
    let Some((&mode, rest)) = data.split_first() else {
        return;
    };
    if rest.len() > 4096 {
        return;
    }
    let text = String::from_utf8_lossy(rest);
    if text.contains("ObjModel") {
        return; // no file system access
    }
    let Ok(file) = rayscope_scene::parse_str(&text, Path::new("fuzz.txt")) else {
        return;
    };
    let scene = Scene::from_file(&file);
    let settings = RenderSettings {
        width: 8,
        height: 8,
        aa: 1,
        max_depth: 4,
        stage: [Stage::Full, Stage::One, Stage::Two][usize::from(mode & 3) % 3],
        ambient: mode & 4 != 0,
        channel: [
            Channel::Color,
            Channel::Color,
            Channel::Color,
            Channel::Normal,
            Channel::Depth,
            Channel::Entity,
            Channel::Albedo,
            Channel::Cost,
        ][usize::from(mode >> 5)],
        ..RenderSettings::default()
    };
    let out = render(&scene, &settings, &|_, _| {}, &AtomicBool::new(false)).expect("not cancelled");
    assert_eq!(out.film.pixels.len(), 64);
    assert!(out.film.pixels.iter().all(|p| p.is_finite()), "non-finite pixel");
    // The render loop replaces NaN and infinite samples by black and counts them. Numbers near
    // the single-precision limit may legitimately overflow; with modest numbers nothing may.
    if largest_number(&file) <= 1e6 {
        assert_eq!(
            out.nonfinite, 0,
            "a sample was NaN or infinite: {:?}",
            out.first_nonfinite
        );
    }
});

/// The largest magnitude of any number in the scene.
fn largest_number(file: &SceneFile) -> f64 {
    let mut m: f64 = 0.0;
    let mut v = |d: DVec3| m = m.max(d.abs().max_element());
    for mat in &file.materials {
        v(mat.color);
        v(DVec3::splat(mat.value));
    }
    for l in &file.lights {
        v(l.position);
        v(l.color);
    }
    for e in &file.entities {
        match &e.shape {
            Shape::Plane { point, .. } => v(*point),
            Shape::Sphere { center, radius } => {
                v(*center);
                v(DVec3::splat(*radius));
            }
            Shape::Triangle { vertices } => vertices.iter().for_each(|p| v(*p)),
            Shape::Mesh { .. } => {}
        }
    }
    m
}
