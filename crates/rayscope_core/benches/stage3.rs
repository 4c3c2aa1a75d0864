//! Renderer benchmarks: the course's bunny scene in stage 2, a BVH build over a generated
//! one-million-triangle mesh, a path-traced emitter-lit box, and the course's scene 2 (a mirror
//! and glass) path traced.
//!
//! `cargo bench -p rayscope_core --bench stage3`

// criterion_group! generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use glam::Vec3;
use rayscope_core::accel::{BuildPrim, Bvh};
use rayscope_core::geometry::Triangle;
use rayscope_core::scene::TriangleInfo;
use rayscope_core::{render, RenderSettings, Scene, Stage};
use rayscope_scene::{Mesh, MeshTriangle, Shape};

#[path = "../tests/common/mod.rs"]
mod common;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Why a benchmark of the course's scenes did not run.
fn no_course() -> String {
    format!(
        "no course folder with tests/ and images/ at {} (set {})",
        rayscope_testkit::course_dir().display(),
        rayscope_testkit::COURSE_DIR_VAR
    )
}

fn bunny(c: &mut Criterion) {
    let Some(course) = rayscope_testkit::Course::find() else {
        eprintln!("bunny benchmark skipped: {}", no_course());
        return;
    };
    let file = rayscope_scene::load(&course.scene("sample_scene_obj.txt")).expect("the course's scene loads");
    let scene = Scene::from_file(&file);
    let s = RenderSettings {
        aa: 4,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let mut g = c.benchmark_group("bunny");
    g.sample_size(10);
    g.throughput(Throughput::Elements(400 * 400 * 16));
    g.bench_function("stage2_400x400_x4", |b| {
        b.iter(|| render(&scene, &s, &|_, _| {}, &AtomicBool::new(false)).unwrap())
    });
    g.finish();
}

/// A wavy height field of `n`×`n` quads (2n² triangles).
fn height_field(n: u32) -> Mesh {
    let mut m = Mesh::default();
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32, j as f32 / n as f32);
            let y = 0.05 * ((x * 40.0).sin() + (z * 33.0).cos());
            m.positions.push(Vec3::new(x * 10.0 - 5.0, y, z * 10.0));
        }
    }
    let w = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = j * w + i;
            m.triangles.push(MeshTriangle {
                positions: [a, a + 1, a + w + 1],
                normals: None,
            });
            m.triangles.push(MeshTriangle {
                positions: [a, a + w + 1, a + w],
                normals: None,
            });
        }
    }
    m
}

fn bvh_build(c: &mut Criterion) {
    let mesh = height_field(708); // 1,002,528 triangles
    let file = common::one_material_file(vec![Shape::Mesh {
        source: "field.obj".into(),
        offset: glam::DVec3::ZERO,
        scale: 1.0,
        mesh,
    }]);
    let scene = Scene::from_file(&file);
    let tris = scene.triangles.len();
    let bytes =
        scene.wide.memory_bytes() + tris * (std::mem::size_of::<Triangle>() + std::mem::size_of::<TriangleInfo>());
    eprintln!(
        "1M-triangle mesh: {tris} triangles, BVH {} bytes, {:.1} bytes/triangle (BVH + triangles + shading data)",
        scene.wide.memory_bytes(),
        bytes as f64 / tris as f64
    );
    let prims: Vec<BuildPrim> = scene
        .triangles
        .iter()
        .enumerate()
        .map(|(i, t)| BuildPrim::new(i as u32, t.bounds()))
        .collect();
    let mut g = c.benchmark_group("bvh");
    g.sample_size(10);
    g.throughput(Throughput::Elements(tris as u64));
    g.bench_function("build_1m_triangles", |b| {
        b.iter_batched(|| prims.clone(), Bvh::build, BatchSize::LargeInput)
    });
    g.bench_function("scene_from_file_1m_triangles", |b| b.iter(|| Scene::from_file(&file)));
    g.finish();
}

fn path_traced_box(c: &mut Criterion) {
    let path = workspace().join("scenes/emissive.txt");
    let file = rayscope_scene::load(&path).expect("scenes/emissive.txt loads");
    let scene = Scene::from_file(&file);
    // 64 paths per pixel (-q 6), full path tracing (-l). 128×128 keeps criterion's ten runs
    // short on two cores; samples/s is the figure to compare (400×400 is 9.8× the work).
    let s = RenderSettings {
        width: 128,
        height: 128,
        quality: 6,
        ambient: true,
        ..RenderSettings::default()
    };
    let mut g = c.benchmark_group("emitter_box");
    g.sample_size(10);
    g.throughput(Throughput::Elements(128 * 128 * 64));
    g.bench_function("path_traced_128x128_64spp", |b| {
        b.iter(|| render(&scene, &s, &|_, _| {}, &AtomicBool::new(false)).unwrap())
    });
    g.finish();
}

fn path_traced_scene_2(c: &mut Criterion) {
    let Some(course) = rayscope_testkit::Course::find() else {
        eprintln!("scene 2 benchmark skipped: {}", no_course());
        return;
    };
    let file = rayscope_scene::load(&course.scene("sample_scene_2.txt")).expect("the course's scene loads");
    let scene = Scene::from_file(&file);
    // `-l -x 4` at 200×200: paths through the mirror and the glass, which is seen directly.
    let s = RenderSettings {
        width: 200,
        height: 200,
        aa: 4,
        ambient: true,
        ..RenderSettings::default()
    };
    let mut g = c.benchmark_group("scene_2");
    g.sample_size(10);
    g.throughput(Throughput::Elements(200 * 200 * 16));
    g.bench_function("path_traced_200x200_x4", |b| {
        b.iter(|| render(&scene, &s, &|_, _| {}, &AtomicBool::new(false)).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bunny, bvh_build, path_traced_box, path_traced_scene_2);
criterion_main!(benches);
