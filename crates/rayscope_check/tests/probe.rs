//! `rayscope_check::probe` on a student-style intersector with a mistake of rayscope's catalogue:
//! the report names the mistake, from the catalogue, and the catalogue names only findings the
//! probe can make.

use std::path::{Path, PathBuf};
use std::process::Command;

use rayscope_check::probe::{self, judge::Verdict, parse_catalogue_code, Options, Outcome};
use rayscope_core::mistakes::Mistake;

/// The student intersector's switch for each catalogue mistake that `probe` can see
/// (crates/rayscope/tests/probe/student_tracer.py).
const STUDENT_SWITCHES: &[(Mistake, &str)] = &[
    (Mistake::OneSidedTriangles, "triangle-one-sided"),
    (Mistake::ReversedNormals, "triangle-reversed-normals"),
    (Mistake::SphereNormalUnnormalised, "sphere-normal-unnormalised"),
    (Mistake::SphereNearRootBehind, "sphere-inside"),
    (Mistake::PlaneHitsBehind, "plane-behind"),
];

fn manifest(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Probes the Python student intersector with `mistakes` on our `basic.txt` (spheres, a plane
/// and triangles).
fn probe_student(mistakes: &str) -> (PathBuf, Outcome) {
    let python = Command::new("python3")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    assert!(python, "the probe tests need python3 (standard library only) on PATH");
    let scene = rayscope_testkit::scene("basic.txt");
    let file = rayscope_scene::load(&scene).expect("scene");
    let command: Vec<String> = [
        "env".to_string(),
        format!("PROBE_MISTAKES={mistakes}"),
        "python3".into(),
        manifest("../../examples/probe/python/probe_adapter.py")
            .display()
            .to_string(),
        manifest("../rayscope/tests/probe/student_tracer.py")
            .display()
            .to_string(),
    ]
    .into();
    let opts = Options {
        scene: &scene,
        command: &command,
        mesh_triangles: 8,
        rays_per_case: 6,
        seed: 0,
        timeout: 30.0,
        startup_timeout: 60.0,
    };
    let outcome = probe::run(&opts, &file, &mut |_| {}).expect("the probe runs");
    (scene, outcome)
}

#[test]
fn a_catalogued_mistake_of_an_intersector_is_named_from_the_catalogue() {
    let with_probe: Vec<Mistake> = Mistake::ALL
        .into_iter()
        .filter(|m| !m.info().probe.is_empty())
        .collect();
    let switched: Vec<Mistake> = STUDENT_SWITCHES.iter().map(|s| s.0).collect();
    assert_eq!(
        with_probe, switched,
        "each catalogue mistake with probe findings needs a switch of the student intersector here"
    );
    for &(mistake, switch) in STUDENT_SWITCHES {
        let info = mistake.info();
        let (scene, outcome) = probe_student(switch);
        assert!(!outcome.passed(), "{switch}: passed");
        let found = outcome.findings();
        for code in info.probe {
            let (kind, case, verdict) = parse_catalogue_code(code).expect("a real probe code");
            assert!(
                found.iter().any(|f| kind.is_none_or(|k| k.name() == f.0)
                    && case.is_none_or(|c| c.id() == f.1)
                    && f.2 == verdict.code()),
                "{switch}: no finding {code} among {found:?}"
            );
        }
        let mut text = String::new();
        outcome.text(&scene, false, &mut |part| text.push_str(part));
        let named = format!(
            "rayscope's catalogue (`rayscope mistakes`): '{}', a tracer that {}",
            info.name, info.wrong
        );
        assert!(
            text.contains(&named),
            "{switch}: the report does not name {}:\n{text}",
            info.name
        );
        let json: serde_json::Value = serde_json::from_str(&outcome.json(&scene, &[])).expect("JSON report");
        let named_in_json = json["findings"]
            .as_array()
            .expect("findings")
            .iter()
            .filter(|f| {
                f["mistakes"]
                    .as_array()
                    .is_some_and(|m| m.iter().any(|n| n == info.name))
            })
            .count();
        assert!(
            named_in_json > 0,
            "{switch}: no finding names {} in the JSON:\n{json:#}",
            info.name
        );
    }
}

#[test]
fn a_correct_intersector_is_named_no_mistake() {
    let (scene, outcome) = probe_student("");
    assert!(outcome.passed(), "{:?}", outcome.findings());
    let mut text = String::new();
    outcome.text(&scene, false, &mut |part| text.push_str(part));
    assert!(!text.contains("rayscope's catalogue"), "{text}");
}

#[test]
fn the_catalogue_names_only_findings_the_probe_makes() {
    for m in Mistake::ALL {
        for code in m.info().probe {
            assert!(
                parse_catalogue_code(code).is_some(),
                "{}: '{code}' is no probe finding (PRIMITIVE[ CASE]: VERDICT)",
                m.name()
            );
        }
    }
    // What a code may not say.
    for bad in [
        "triangle back-hit: missing",
        "sphere back-hit: missed",
        "cone: missed",
        "triangle back-hit missed",
        "triangle  back-hit: missed",
    ] {
        assert_eq!(parse_catalogue_code(bad), None, "{bad}");
    }
    assert_eq!(
        parse_catalogue_code("wrong-root").map(|c| c.2),
        Some(Verdict::WrongRoot)
    );
}
