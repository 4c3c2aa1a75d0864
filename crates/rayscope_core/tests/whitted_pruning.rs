//! Pruning of negligible Whitted glass branches must be invisible in 8-bit output.

use rayscope_core::integrator::{Counters, Integrator};
use rayscope_core::{NoObserver, RenderSettings, Scene, Stage};

#[test]
fn pruned_branches_change_no_pixel_by_more_than_one_level() {
    let p = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/reference/tests/sample_scene_2.txt"
    );
    let file = rayscope_scene::load(std::path::Path::new(p)).expect("course scene 2");
    let scene = Scene::from_file(&file);
    let settings = RenderSettings {
        width: 80,
        height: 80,
        stage: Stage::Two,
        ..RenderSettings::default()
    };
    let pruned = Integrator::new(&scene, &settings);
    assert!(pruned.branch_cutoff > 0.0, "stage-2 renders prune");
    let mut full = Integrator::new(&scene, &settings);
    full.branch_cutoff = 0.0;
    let (mut cp, mut cf) = (Counters::default(), Counters::default());
    let mut worst = 0.0f32;
    for y in 0..80 {
        for x in 0..80 {
            let a = pruned.sample(x, y, 0, &mut NoObserver, &mut cp);
            let b = full.sample(x, y, 0, &mut NoObserver, &mut cf);
            worst = worst.max((a - b).abs().max_element());
        }
    }
    assert!(worst < 1.0 / 255.0, "largest change {worst}");
    assert!(
        cp.total() < cf.total() * 9 / 10,
        "pruning saves rays: {} vs {}",
        cp.total(),
        cf.total()
    );
}
