#!/usr/bin/env bash
# `diagnose`'s match rule on correct pictures (issue #42, point 2): an independent student tracer
# (crates/rayscope_core/tests/student, f64, brute force) renders every course scene at -x 1 and
# -x 4, 400×400 and 400×300, and each picture must match rayscope's render by the ties of its
# rays. Runs the ignored test `full_matrix` of crates/rayscope_core/tests/ties.rs in release and
# prints per case the pixels that differ, those within their tie bounds, those beyond, the
# largest distance in levels outside the bounds, the seconds of the student's render and diagnose
# together, and of diagnose alone. Exits non-zero if any case does not match.
#
#   bench/diagnose_ties.sh
#
# Environment: RAYSCOPE_COURSE_DIR (default ../shared/reference), CARGO_TARGET_DIR.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
cd "$root"
cargo test --release --quiet -p rayscope_core --test ties -- --ignored --exact full_matrix --nocapture
