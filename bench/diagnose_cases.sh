#!/usr/bin/env bash
# How long `diagnose` takes per case (issue #42): the test student (crates/rayscope_core/tests/
# student) renders each course scene at 400×400, stage 2, with each mistake it can make and
# without any; each picture is diagnosed with the command line's defaults. Runs the ignored
# test `every_case` of crates/rayscope_core/tests/diagnose_cases.rs in release and prints one
# row per case (seconds of the diagnosis alone, the start of the first line) and the slowest.
#
#   bench/diagnose_cases.sh
#
# Environment: RAYSCOPE_COURSE_DIR (default ../shared/reference), CARGO_TARGET_DIR.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
cd "$here/.."
cargo test --release --quiet -p rayscope_core --test diagnose_cases -- --ignored --exact every_case --nocapture
