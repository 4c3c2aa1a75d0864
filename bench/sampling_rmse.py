#!/usr/bin/env python3
"""RMSE at equal samples of two rayscope builds (two samplers) against a converged reference.

For each scene, a reference is rendered once with `--ref` (-x 2 -q REF_Q), then both builds
render it at -x 2 -q Q with several seeds; the table gives each build's RMSE against the
reference (mean over the seeds) and their ratio. Run with a Python that has Mitsuba (it reads
the EXR files), e.g. bench/.venv/bin/python bench/sampling_rmse.py --old A --new B.
"""

import argparse
import os
import subprocess
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COURSE = os.environ.get("RAYSCOPE_COURSE_DIR", os.path.join(ROOT, "..", "shared", "reference"))

SCENES = [
    ("emitter box -l", os.path.join(ROOT, "scenes", "emissive.txt"), ["-l"]),
    ("ambient.txt -l", os.path.join(ROOT, "scenes", "ambient.txt"), ["-l"]),
    ("course OBJ scene -l", os.path.join(COURSE, "tests", "sample_scene_obj.txt"), ["-l"]),
    ("dof.txt -r 0.1 -t 3.6", os.path.join(ROOT, "scenes", "dof.txt"), ["-r", "0.1", "-t", "3.6"]),
]


def read_exr(path: str) -> np.ndarray:
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def render(exe: str, scene: str, out: str, size: int, q: int, seed: int, flags: list[str]) -> float:
    cmd = [exe, "-f", scene, "-o", out, "-w", str(size), "-h", str(size), "-x", "2", "-q", str(q)]
    cmd += ["--seed", str(seed), "--quiet", *flags]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--old", required=True, help="rayscope build with the sampler to compare against")
    ap.add_argument("--new", required=True, help="rayscope build with the sampler measured")
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--q", type=int, default=2, help="-q of the measured renders (-x 2: 4 * 2^q spp)")
    ap.add_argument("--ref-q", type=int, default=9, help="-q of the reference (-x 2)")
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--out", default="/tmp/rayscope_sampling")
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)
    spp, ref_spp = 4 << args.q, 4 << args.ref_q
    print(f"{args.size}x{args.size}, {spp} spp (-x 2 -q {args.q}), mean over {args.seeds} seeds; "
          f"reference: the new build at {ref_spp} spp\n")
    print("| scene | old sampler RMSE | new sampler RMSE | new / old |")
    print("|---|---|---|---|")
    for name, scene, flags in SCENES:
        tag = name.split()[0].replace(".txt", "")
        ref_path = os.path.join(args.out, f"ref_{tag}_{args.size}_{ref_spp}.exr")
        if not os.path.exists(ref_path):
            render(args.new, scene, ref_path, args.size, args.ref_q, 1000, flags)
        ref = read_exr(ref_path)
        errs = {}
        for build in ("old", "new"):
            e = []
            for seed in range(args.seeds):
                out = os.path.join(args.out, f"{build}_{tag}_{seed}.exr")
                render(getattr(args, build), scene, out, args.size, args.q, seed, flags)
                e.append(float(np.sqrt(((read_exr(out) - ref) ** 2).mean())))
            errs[build] = float(np.mean(e))
        print(f"| {name} | {errs['old']:.4f} | {errs['new']:.4f} | {errs['new'] / errs['old']:.2f} |", flush=True)


if __name__ == "__main__":
    main()
