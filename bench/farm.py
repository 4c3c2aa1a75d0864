#!/usr/bin/env python3
"""Farm renders measured: one render against its N parts run one after another.

For each N it runs `rayscope --part K/N` for K = 0 … N-1 (each process alone, all threads), then
`rayscope merge`, and reports the total work (the parts' wall times summed, against the single
render's), the balance (the longest part's share of that total, against the ideal 1/N) and the
merge time, and checks that the merged PNG is byte for byte the single render. Every time is the
whole process (parsing, BVH build, rendering and writing), as wall time and as CPU time (user +
system), which a busy machine disturbs less.

    bench/farm.py [--rayscope target/release/rayscope] [--scene scenes/showcase.txt]
                  [--flags "-w 400 -h 300 -x 2 -q 4 -l"] [--parts 1,2,4,8]
"""

import argparse
import filecmp
import os
import resource
import shlex
import subprocess
import sys
import tempfile
import time


def cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run(cmd):
    """Runs cmd; returns (wall seconds, CPU seconds)."""
    start, c0 = time.perf_counter(), cpu()
    p = subprocess.run(cmd, capture_output=True, text=True)
    secs, cpu_secs = time.perf_counter() - start, cpu() - c0
    if p.returncode != 0:
        sys.exit(f"failed ({p.returncode}): {shlex.join(cmd)}\n{p.stderr}")
    return secs, cpu_secs


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap.add_argument("--rayscope", default=os.path.join(root, "target/release/rayscope"))
    ap.add_argument("--scene", default=os.path.join(root, "scenes/showcase.txt"))
    ap.add_argument("--flags", default="-w 400 -h 300 -x 2 -q 4 -l")
    ap.add_argument("--parts", default="1,2,4,8")
    a = ap.parse_args()
    flags = shlex.split(a.flags)
    base = [a.rayscope, "-f", a.scene, "--quiet", *flags]
    with tempfile.TemporaryDirectory() as tmp:
        single_png = os.path.join(tmp, "single.png")
        single, single_cpu = run([*base, "-o", single_png])
        print(f"scene: {os.path.relpath(a.scene, root)} {a.flags}; threads: {os.cpu_count()}")
        print(f"single render: {single:.2f} s wall, {single_cpu:.2f} s CPU\n")
        print(
            "| parts N | total wall (s) | / single | total CPU (s) | / single | longest part's share (wall) "
            "| longest part's share (CPU) | ideal | merge (s) | merged = single |"
        )
        print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|:---:|")
        for n in [int(x) for x in a.parts.split(",")]:
            d = os.path.join(tmp, f"n{n}")
            os.mkdir(d)
            times, cpus, parts = [], [], []
            for k in range(n):
                p = os.path.join(d, f"part_{k}.exr")
                wall, c = run([*base, "-o", p, "--part", f"{k}/{n}"])
                times.append(wall)
                cpus.append(c)
                parts.append(p)
            out = os.path.join(d, "merged.png")
            merge, _ = run([a.rayscope, "merge", *parts, "-o", out, "--quiet"])
            same = filecmp.cmp(out, single_png, shallow=False)
            total, total_cpu = sum(times), sum(cpus)
            print(
                f"| {n} | {total:.2f} | {total / single:.3f} | {total_cpu:.2f} | {total_cpu / single_cpu:.3f} | "
                f"{max(times) / total:.3f} | {max(cpus) / total_cpu:.3f} | {1 / n:.3f} | {merge:.3f} | "
                f"{'yes' if same else 'NO'} |"
            )
            if not same:
                sys.exit("the merged image differs from the single render")


if __name__ == "__main__":
    main()
