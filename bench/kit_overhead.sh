#!/usr/bin/env bash
# What the C# logging kit (kits/csharp/RayLog.cs) costs a render under Mono: the tests'
# template-shaped tracer built without the kit (its RayLog lines removed), with the kit but
# logging off, logging five pixels, and logging every 8th pixel. Runs alternate, on one thread
# (--serial); CPU time (user + system, steadier than wall time on a shared machine) and wall
# time, the minimum and the median of RUNS runs. Wall and CPU times on a shared machine move by
# several per cent from run to run, so where valgrind is installed the script also counts the
# instructions each render executes (callgrind; deterministic to a few in a million) at two
# image sizes, which separates the per-sample cost from the fixed cost of starting the kit.
#
#   bench/kit_overhead.sh [scene] [width] [height] [aa] [runs]
#   bench/kit_overhead.sh ../shared/reference/tests/sample_scene_2.txt 240 240 2 7
set -euo pipefail
cd "$(dirname "$0")/.."
scene=${1:-../shared/reference/tests/sample_scene_2.txt}
w=${2:-240}
h=${3:-240}
aa=${4:-2}
runs=${5:-7}
src=crates/rayscope_check/tests/student/kit/Tracer.cs
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Without the kit: the lines that call it dropped, RayLog.Color(x) turned back into (x).
grep -v '^ *RayLog\.' "$src" | sed 's/RayLog\.Color(/(/g' > "$tmp/Plain.cs"
if grep -v '^ *//' "$tmp/Plain.cs" | grep -q RayLog; then
    echo "kit_overhead: RayLog left in the plain tracer" >&2
    exit 1
fi
mcs -langversion:7 -optimize+ -out:"$tmp/plain.exe" "$tmp/Plain.cs" >/dev/null
mcs -langversion:7 -optimize+ -out:"$tmp/kit.exe" kits/csharp/RayLog.cs "$src" >/dev/null

args=(-f "$scene" -w "$w" -h "$h" -x "$aa" --serial)
run() { # exe [env...]: one render's CPU time (user + system) and wall time, in seconds
    local exe=$1
    shift
    env -u RAYSCOPE_LOG -u RAYSCOPE_LOG_PIXELS -u RAYSCOPE_LOG_STEP "$@" \
        /usr/bin/time -f '%U %S %e' -o "$tmp/time" mono "$exe" "${args[@]}" -o "$tmp/out.ppm"
    awk '{printf "%.2f/%.2f", $1 + $2, $3}' "$tmp/time"
}

names=(plain off five step8)
declare -A times
for ((i = 0; i < runs; i++)); do
    times[plain]+="$(run "$tmp/plain.exe") "
    cp "$tmp/out.ppm" "$tmp/plain.ppm"
    times[off]+="$(run "$tmp/kit.exe") "
    cmp -s "$tmp/out.ppm" "$tmp/plain.ppm" || { echo "kit_overhead: the kit changed the picture" >&2; exit 1; }
    times[five]+="$(run "$tmp/kit.exe" RAYSCOPE_LOG="$tmp/five.jsonl" \
        RAYSCOPE_LOG_PIXELS="10,10 40,80 80,80 120,40 150,150") "
    times[step8]+="$(run "$tmp/kit.exe" RAYSCOPE_LOG="$tmp/step8.jsonl" RAYSCOPE_LOG_STEP=8) "
done

# field 1: CPU seconds, field 2: wall seconds
col() { tr ' ' '\n' | grep . | cut -d/ -f"$1" | sort -g; }
stat() { awk '{a[NR]=$1} END {printf "min %.2f s  median %.2f s", a[1], a[int((NR+1)/2)]}'; }
med() { awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
base=$(echo "${times[plain]}" | col 1 | med)
echo "scene $scene, ${w}x${h} -x $aa, mono, one thread, $runs runs each"
for n in "${names[@]}"; do
    m=$(echo "${times[$n]}" | col 1 | med)
    printf '%-6s CPU %s (median %+.1f %% vs plain)   wall %s\n' "$n" "$(echo "${times[$n]}" | col 1 | stat)" \
        "$(echo "($m / $base - 1) * 100" | bc -l)" "$(echo "${times[$n]}" | col 2 | stat)"
done
echo "logged: five pixels $(wc -l < "$tmp/five.jsonl") rays; every 8th pixel $(wc -l < "$tmp/step8.jsonl") rays"

command -v valgrind >/dev/null || { echo "valgrind not found: no instruction counts"; exit 0; }
count() { # size exe [env...]: instructions executed
    local size=$1 exe=$2
    shift 2
    env -u RAYSCOPE_LOG -u RAYSCOPE_LOG_PIXELS -u RAYSCOPE_LOG_STEP "$@" valgrind --tool=callgrind \
        --callgrind-out-file="$tmp/cg" mono "$exe" -f "$scene" -w "$size" -h "$size" -x "$aa" --serial \
        -o "$tmp/out.ppm" 2>&1 | sed -n 's/.*Collected : //p'
}
declare -A ir
for size in 60 120; do
    ir[plain$size]=$(count $size "$tmp/plain.exe")
    ir[off$size]=$(count $size "$tmp/kit.exe")
    ir[five$size]=$(count $size "$tmp/kit.exe" RAYSCOPE_LOG="$tmp/five.jsonl" RAYSCOPE_LOG_PIXELS="10,10 40,50 50,50")
done
samples=$(((120 * 120 - 60 * 60) * aa * aa))
echo "instructions (callgrind), ${aa}x$aa samples a pixel: 60x60 image, 120x120 image; per sample = the difference / $samples samples"
for n in plain off five; do
    a=${ir[${n}60]} b=${ir[${n}120]}
    per=$(((b - a) / samples))
    base=$(((${ir[plain120]} - ${ir[plain60]}) / samples))
    printf '%-6s %12d %12d   per sample %6d (%+.2f %% vs plain)   fixed %+d vs plain\n' "$n" "$a" "$b" "$per" \
        "$(echo "($per / $base - 1) * 100" | bc -l)" "$((a - ${ir[plain60]} - (per - base) * 60 * 60 * aa * aa))"
done
