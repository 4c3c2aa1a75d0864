#!/usr/bin/env bash
# `rayscope check` on the logs of a correct student tracer (the tests' C++ tracer,
# crates/rayscope_check/tests/student/tracer.cpp) for every course scene, -x 1 and -x 4, 400×400
# and 400×300, every pixel logged (issue #41, point 4). Prints per case the rays, the verdicts,
# the ties and the times; exits 1 if any case gets a verdict, 2 if a tool fails.
#
#   bench/check_course_scenes.sh                 # the full matrix (several GB of log per -x 4 case)
#   bench/check_course_scenes.sh sample_scene_1  # only the scenes named
#
# Environment: RAYSCOPE_COURSE_DIR (default ../shared/reference), CARGO_TARGET_DIR, TMPDIR (where
# each case's log is written and deleted after its check), THREADS (check's --threads, default 2),
# RAYSCOPE (a rayscope binary to use instead of building one in release).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"
course="${RAYSCOPE_COURSE_DIR:-$root/../shared/reference}"
threads="${THREADS:-2}"
scenes=("$@")
if [[ ${#scenes[@]} -eq 0 ]]; then
    scenes=(sample_scene_1 sample_scene_2 sample_scene_2_2021 sample_scene_obj)
fi
for s in "${scenes[@]}"; do
    [[ -f "$course/tests/$s.txt" ]] || { echo "no scene $course/tests/$s.txt" >&2; exit 2; }
done

if [[ -z "${RAYSCOPE:-}" ]]; then
    (cd "$root" && cargo build --release --quiet -p rayscope --bin rayscope)
    RAYSCOPE="${CARGO_TARGET_DIR:-$root/target}/release/rayscope"
fi

work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
g++ -O2 -std=c++17 -o "$work/tracer" "$root/crates/rayscope_check/tests/student/tracer.cpp"

# Seconds since the epoch, to the millisecond.
now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

failed=0
printf '%-20s %-8s %-4s %12s %9s %6s %9s %9s %9s\n' scene size aa rays verdicts ties "log MB" "trace s" "check s"
for s in "${scenes[@]}"; do
    scene="$course/tests/$s.txt"
    for aa in 1 4; do
        for size in 400x400 400x300; do
            w="${size%x*}"
            h="${size#*x}"
            log="$work/rays.jsonl"
            t0="$(now)"
            "$work/tracer" -f "$scene" -w "$w" -h "$h" -x "$aa" --log "$log" || { echo "tracer failed on $s" >&2; exit 2; }
            t1="$(now)"
            mb=$(( $(stat -c %s "$log") / 1000000 ))
            rc=0
            "$RAYSCOPE" check -f "$scene" --rays "$log" -w "$w" -h "$h" -x "$aa" --stage 2 \
                --threads "$threads" --quiet >"$work/report.txt" 2>"$work/err.txt" || rc=$?
            t2="$(now)"
            rm -f "$log"
            if [[ $rc -ne 0 && $rc -ne 1 ]]; then
                echo "check failed on $s ($size -x $aa):" >&2
                cat "$work/err.txt" "$work/report.txt" >&2
                exit 2
            fi
            # "checked N rays (C camera rays): A agree, D disagree, T ties (…)"
            line="$(grep -m1 '^checked ' "$work/report.txt")"
            rays="$(sed -E 's/^checked ([0-9]+) rays.*/\1/' <<<"$line")"
            verdicts="$(sed -E 's/.* ([0-9]+) disagree.*/\1/' <<<"$line")"
            ties="$(sed -E 's/.* ([0-9]+) ties.*/\1/' <<<"$line")"
            printf '%-20s %-8s %-4s %12s %9s %6s %9s %9s %9s\n' "$s" "$size" "-x $aa" "$rays" "$verdicts" \
                "$ties" "$mb" "$(elapsed "$t0" "$t1")" "$(elapsed "$t1" "$t2")"
            if [[ $rc -ne 0 || "$verdicts" != 0 ]]; then
                failed=1
                keep="${TMPDIR:-/tmp}/check_${s}_${size}_x${aa}.txt"
                cp "$work/report.txt" "$keep" && echo "  report kept in $keep"
                head -n 3 "$work/report.txt" | sed 's/^/  /'
            fi
        done
    done
done
if [[ $failed -ne 0 ]]; then
    echo "FAILED: the correct tracer got verdicts (see above)"
    exit 1
fi
echo "every case: no verdict"
