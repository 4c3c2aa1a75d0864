//! Pruning of negligible Whitted glass branches must be invisible in 8-bit output.

use rayscope_core::integrator::{Counters, Integrator};
use rayscope_core::{NoObserver, RenderSettings, Scene, Stage};

#[test]
fn pruned_branches_change_no_pixel_by_more_than_one_level() {
    // Our room's glass and mirror balls, and the course's scene 2 where its files are.
    pruning_is_invisible(&rayscope_testkit::scene("room.txt"));
    let Some(course) = rayscope_testkit::course_part() else {
        return;
    };
    pruning_is_invisible(&course.scene("sample_scene_2.txt"));
}

fn pruning_is_invisible(path: &std::path::Path) {
    let file = rayscope_scene::load(path).expect("scene loads");
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
    assert!(worst < 1.0 / 255.0, "{}: largest change {worst}", path.display());
    assert!(
        cp.total() < cf.total() * 9 / 10,
        "{}: pruning saves rays: {} vs {}",
        path.display(),
        cp.total(),
        cf.total()
    );
}
