//! The command line crate's module graph has no cycle: each command's module builds on the
//! shared ones, never the other way round.

use std::path::Path;

#[test]
fn cli_module_graph_is_acyclic() {
    rayscope_testkit::module_graph::assert_acyclic("rayscope", Path::new(env!("CARGO_MANIFEST_DIR")), 10);
}
