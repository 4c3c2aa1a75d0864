//! The core's module graph has no cycle, and the acceleration structures depend on no part of a
//! render (the graph is read by [`rayscope_testkit::module_graph`]).
//!
//! The same references show what `accel` (the BVHs and their walks) reaches: primitives, rays and
//! lanes, never the scene, the camera, the integrators, the render loop or the lights, which all
//! build on it; a reference to one of those from outside `accel`'s test modules fails the check,
//! naming the file, the line and the import.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use rayscope_testkit::module_graph::{describe, find_cycle, graph, module_of, read_sources, within, Edge};

/// Modules the acceleration structures must not reach (nor any module inside them).
const ACCEL_MUST_NOT_USE: [&str; 5] = ["scene", "camera", "integrator", "render", "lights"];

/// Every reference from `accel`'s code outside its test modules to a module of
/// [`ACCEL_MUST_NOT_USE`], as a line naming the file, the line, the source text and the module
/// reached (the module that defines the item, when the path goes through a re-export).
fn accel_forbidden_refs(files: &[(String, String)], edges: &BTreeSet<Edge>) -> Vec<String> {
    let file_of: BTreeMap<String, &(String, String)> = files.iter().map(|f| (module_of(&f.0), f)).collect();
    edges
        .iter()
        .filter(|e| within(&e.from, "accel") && ACCEL_MUST_NOT_USE.iter().any(|f| within(&e.to, f)))
        .map(|e| {
            let (rel, src) = file_of[&e.from];
            let text = src.lines().nth(e.line - 1).unwrap_or("").trim();
            format!("  src/{rel} line {}: `{text}` reaches crate::{}", e.line, e.to)
        })
        .collect()
}

#[test]
fn accel_depends_on_no_part_of_a_render() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_sources(&src, &src, &mut files);
    let (_, edges) = graph(&files);
    assert!(
        edges
            .iter()
            .any(|e| within(&e.from, "accel") && within(&e.to, "geometry")),
        "the graph reader found no reference from accel to geometry: {edges:?}"
    );
    let bad = accel_forbidden_refs(&files, &edges);
    assert!(
        bad.is_empty(),
        "the acceleration structures (src/accel) must not use crate::{{{}}} outside their test modules:\n{}",
        ACCEL_MUST_NOT_USE.join(", "),
        bad.join("\n")
    );
}

#[test]
fn core_module_graph_is_acyclic() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    read_sources(&src, &src, &mut files);
    let (nodes, edges) = graph(&files);
    assert!(
        nodes.len() > 10 && edges.len() > 20,
        "the graph reader found too little: {nodes:?} {edges:?}"
    );
    if let Some(cycle) = find_cycle(&nodes, &edges) {
        panic!("{}", describe("rayscope_core", &cycle, &edges));
    }
}

fn files(list: &[(&str, &str)]) -> Vec<(String, String)> {
    list.iter().map(|(p, s)| (p.to_string(), s.to_string())).collect()
}

#[test]
fn a_cycle_is_found_and_named() {
    let nodes: BTreeSet<String> = ["a", "b", "c", "d"].iter().map(|s| s.to_string()).collect();
    let edge = |from: &str, to: &str| Edge {
        from: from.into(),
        to: to.into(),
        line: 1,
    };
    let dag: BTreeSet<Edge> = [edge("a", "b"), edge("b", "c"), edge("a", "c"), edge("d", "a")].into();
    assert_eq!(find_cycle(&nodes, &dag), None);
    let mut cyclic = dag.clone();
    cyclic.insert(edge("c", "a"));
    let cycle = find_cycle(&nodes, &cyclic).expect("a → b → c → a is a cycle");
    assert_eq!(cycle.first(), cycle.last());
    assert!(cycle.len() >= 3);
    assert!(describe("x", &cycle, &cyclic).contains("c -> a"));
}

#[test]
fn source_references_become_edges() {
    let src = files(&[
        ("lib.rs", "pub mod a; pub mod b; pub mod c;\npub use b::Thing;"),
        (
            "a.rs",
            "use crate::c::{self, X as Y};\nuse crate::b::K;\nfn f() { let _ = crate::Thing; }",
        ),
        (
            "b.rs",
            "mod inner { use super::super::c::Z; }\nmod kid;\npub use kid::K;\nfn f() -> kid::K { todo!() }\n#[cfg(test)]\nmod checks;",
        ),
        ("b/kid.rs", "use super::Thing;"),
        ("b/checks.rs", "use crate::a::A;"),
        (
            "c.rs",
            "// use crate::a::Nothing;\nconst S: &str = \"crate::a::X\";\npub use crate::a::Alias;\n#[cfg(test)]\nmod tests { use crate::a::T; }",
        ),
    ]);
    let (nodes, edges) = graph(&src);
    let pairs: BTreeSet<(String, String)> = edges.iter().map(|e| (e.from.clone(), e.to.clone())).collect();
    let want: BTreeSet<(String, String)> = [
        ("a", "c"),
        ("a", "b"),
        ("a", "b::kid"),
        ("b", "c"),
        ("b", "b::kid"),
        ("b::kid", "b"),
    ]
    .iter()
    .map(|(f, t)| (f.to_string(), t.to_string()))
    .collect();
    assert_eq!(pairs, want);
    let cycle = find_cycle(&nodes, &edges).expect("b and b::kid refer to each other");
    assert!(cycle.contains(&"b".to_string()) && cycle.contains(&"b::kid".to_string()));
    // Without the child's reference to its parent, the graph is acyclic.
    let mut fixed = src.clone();
    assert_eq!(fixed[3].0, "b/kid.rs");
    fixed[3].1 = "use crate::c::Z;".into();
    let (nodes, edges) = graph(&fixed);
    assert_eq!(find_cycle(&nodes, &edges), None);
}

#[test]
fn accel_references_to_a_render_are_named() {
    let src = files(&[
        (
            "lib.rs",
            "pub mod accel; pub mod geometry; pub mod lights; pub mod scene;\npub use scene::Scene;",
        ),
        ("accel.rs", "mod checks;\nmod walk;\nuse crate::geometry::Tri;"),
        (
            "accel/walk.rs",
            "use crate::geometry::Tri;\nfn f(_: &crate::Scene) {}\n#[cfg(test)]\nmod tests { use crate::lights::L; }",
        ),
        ("accel/checks.rs", "use crate::lights::L;"),
        ("geometry.rs", "pub struct Tri;"),
        ("lights.rs", "use crate::accel::Bvh;"),
        ("scene.rs", "pub struct Scene;\nuse crate::lights::L;"),
    ]);
    let (_, edges) = graph(&src);
    let bad = accel_forbidden_refs(&src, &edges);
    assert_eq!(
        bad,
        [
            "  src/accel/checks.rs line 1: `use crate::lights::L;` reaches crate::lights",
            "  src/accel/walk.rs line 2: `fn f(_: &crate::Scene) {}` reaches crate::scene",
        ]
    );
    // Without those two references (the test module's may stay), nothing is reported.
    let mut fixed = src.clone();
    fixed[2].1 = fixed[2].1.replace("&crate::Scene", "&()");
    fixed.remove(3);
    let (_, edges) = graph(&fixed);
    assert!(accel_forbidden_refs(&fixed, &edges).is_empty());
}

#[test]
fn top_level_layering_ignores_a_module_and_its_children_but_not_siblings() {
    let dir = std::env::temp_dir().join(format!("rayscope-graph-{}", std::process::id()));
    let write = |rel: &str, src: &str| {
        let p = dir.join("src").join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, src).unwrap();
    };
    write("lib.rs", "mod a; mod b;");
    write("a.rs", "mod kid; pub struct S; fn f(_: kid::K) {}");
    write("a/kid.rs", "use super::S; pub struct K;");
    write("b.rs", "use crate::a::S;");
    rayscope_testkit::module_graph::assert_top_level_acyclic("x", &dir, 1);
    write("a.rs", "mod kid; pub struct S; fn f(_: kid::K, _: crate::b::T) {}");
    write("b.rs", "use crate::a::S; pub struct T;");
    let sibling = std::panic::catch_unwind(|| rayscope_testkit::module_graph::assert_top_level_acyclic("x", &dir, 1));
    std::fs::remove_dir_all(&dir).unwrap();
    let message = *sibling
        .expect_err("a and b refer to each other")
        .downcast::<String>()
        .unwrap();
    assert!(message.contains("a -> b") && message.contains("b -> a"), "{message}");
}
