//! What the ray recorder costs: the same pixels of `scenes/whitted.txt` (96×96, `-x 4`, stage 2,
//! one thread) traced with the render path's `NoObserver`, with an observer whose hooks run but
//! only count rays, and with the debugger's full `RayRecorder`.
//!
//! `cargo bench -p rayscope_core --bench observer`
//!
//! "Off" costing nothing means `no_observer` and `counting_hooks` time the same: the hook call
//! sites and the bookkeeping behind `RayObserver::ENABLED` vanish when there is nothing to record.

// criterion_group! generates an undocumented `pub fn`.
#![allow(missing_docs)]

use std::path::Path;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3A;
use rayscope_core::integrator::{Counters, Integrator};
use rayscope_core::observer::RayKind;
use rayscope_core::{NoObserver, Ray, RayObserver, RayRecorder, RenderSettings, Scene, Stage};

const SIZE: u32 = 96;

/// Hooks that do the least possible work: count the rays they are told about.
#[derive(Default)]
struct CountingHooks {
    rays: u64,
}

impl RayObserver for CountingHooks {
    const ENABLED: bool = false;

    fn ray(&mut self, _parent: Option<u32>, _kind: RayKind, _depth: u32, _ray: &Ray, _t_max: f32) -> u32 {
        self.rays += 1;
        0
    }
}

fn trace_all<O: RayObserver>(integ: &Integrator<'_, Scene>, spp: u32, obs: &mut O, reset: impl Fn(&mut O)) -> Vec3A {
    let mut c = Counters::default();
    let mut sum = Vec3A::ZERO;
    for y in 0..SIZE {
        for x in 0..SIZE {
            for s in 0..spp {
                reset(obs);
                sum += integ.sample(x, y, s, obs, &mut c);
            }
        }
    }
    sum
}

fn observer(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/whitted.txt");
    let file = rayscope_scene::load(&path).expect("scenes/whitted.txt loads");
    let scene = Scene::from_file(&file);
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        aa: 4,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let integ = Integrator::new(&scene, &settings);
    let spp = integ.samples_per_pixel();
    let mut g = c.benchmark_group("observer");
    g.sample_size(20);
    g.throughput(Throughput::Elements(u64::from(SIZE * SIZE * spp)));
    let reference = trace_all(&integ, spp, &mut NoObserver, |_| {});
    g.bench_function("no_observer", |b| {
        b.iter(|| trace_all(&integ, spp, &mut NoObserver, |_| {}))
    });
    g.bench_function("counting_hooks", |b| {
        b.iter(|| {
            let mut obs = CountingHooks::default();
            let v = trace_all(&integ, spp, &mut obs, |_| {});
            assert!(obs.rays > 0);
            v
        })
    });
    g.bench_function("recorder_on", |b| {
        b.iter(|| {
            let mut obs = RayRecorder::default();
            let v = trace_all(&integ, spp, &mut obs, |o| o.nodes.clear());
            // Recording must not change what is rendered.
            assert_eq!(v, reference);
            v
        })
    });
    g.finish();
}

criterion_group!(benches, observer);
criterion_main!(benches);
