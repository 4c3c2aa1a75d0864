//! The checker's top-level modules have no cycle: the reader, the oracle, the judge and the
//! report build on each other one way. (The judge's verdict families are its child modules,
//! methods of one `Judge` over its shared context.)

use std::path::Path;

#[test]
fn checker_top_level_modules_are_acyclic() {
    rayscope_testkit::module_graph::assert_top_level_acyclic(
        "rayscope_check",
        Path::new(env!("CARGO_MANIFEST_DIR")),
        10,
    );
}
