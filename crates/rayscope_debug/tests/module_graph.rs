//! The debugger's top-level modules have no cycle: connections, limits, the server and its API
//! build on each other one way. (The server's API files are its child modules and share its state.)

use std::path::Path;

#[test]
fn debugger_top_level_modules_are_acyclic() {
    rayscope_testkit::module_graph::assert_top_level_acyclic(
        "rayscope_debug",
        Path::new(env!("CARGO_MANIFEST_DIR")),
        5,
    );
}
