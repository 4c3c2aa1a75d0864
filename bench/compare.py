"""rayscope against Mitsuba 3 and Embree on identical work. Started by bench/run; see bench/README.md.

Every row runs the peer and rayscope alternately (peer, rayscope, peer, rayscope, ...) for --reps
repetitions and reports medians. Ratios are rayscope / peer: for times below 1 means rayscope is
faster, for throughput above 1 means rayscope is faster.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import multiprocessing as mp
import os
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import course_scene as cs  # noqa: E402
import gen_mesh  # noqa: E402
import to_mitsuba as tm  # noqa: E402

ROOT = os.path.dirname(HERE)
REFERENCE = os.path.normpath(os.path.join(ROOT, "..", "shared", "reference", "tests"))
SCENE_1 = os.path.join(REFERENCE, "sample_scene_1.txt")
SCENE_2 = os.path.join(REFERENCE, "sample_scene_2.txt")
SCENE_OBJ = os.path.join(REFERENCE, "sample_scene_obj.txt")
SCENE_BOX = os.path.join(ROOT, "scenes", "emissive.txt")


def log(msg: str) -> None:
    print(msg, file=sys.stderr, flush=True)


def median(xs):
    return statistics.median(xs)


# Dr.Jit's worker threads go on spinning for a few tens of milliseconds after a render returns, and
# on a 2-core machine they take a core from whatever runs next: rayscope's scene-2 render measured
# 0.110 s started straight after a Mitsuba `llvm_ad_rgb` render and 0.097 s after a 50 ms pause
# (0.098 s alone). So every timed run, the peer's and rayscope's alike, starts after a pause.
SETTLE_S = 0.2


def settle():
    """Waits for the previous run's threads to go idle before the next timed run."""
    time.sleep(SETTLE_S)


# ----------------------------------------------------------------------------------------------
# rayscope


class Rayscope:
    def __init__(self, exe: str, tmp: str):
        self.exe = exe
        self.tmp = tmp
        self.gnu_time = "/usr/bin/time" if os.access("/usr/bin/time", os.X_OK) else None

    def render(self, scene: str, out_name: str, flags: list[str]) -> tuple[float, str]:
        """Whole-process wall time of one render; returns (seconds, output path)."""
        out = os.path.join(self.tmp, out_name)
        cmd = [self.exe, "-f", scene, "-o", out, *flags, "--quiet"]
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        return time.perf_counter() - t0, out

    def bench_rays(self, scene: str, rays_file: str, threads: int, passes: int) -> dict:
        cmd = [
            self.exe, "bench", "rays", "-f", scene, "--rays-file", rays_file,
            "--threads", str(threads), "--repeat", str(passes),
        ]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        last = out.strip().splitlines()[-1]
        fields = dict(kv.split("=", 1) for kv in last.split())
        return {
            "rays": int(fields["rays"]),
            "hits": int(fields["hits"]),
            "seconds": float(fields["seconds"]),
            "mrays": float(fields["mrays_per_s"]),
            "threads": int(fields["threads"]),
        }

    def bench_rays_rss(self, scene: str, rays_file: str, threads: int, passes: int) -> dict:
        """bench_rays plus the build line (seconds, bytes per triangle) and rayscope's peak RSS (OBJ
        parsing, the rays and the BVH included), from GNU time's %M. Without /usr/bin/time it falls
        back to wait4's ru_maxrss, which is an upper bound: Linux carries the high-water mark of
        the forking process (this Python, with Mitsuba loaded) across exec."""
        cmd = [
            self.exe, "bench", "rays", "-f", scene, "--rays-file", rays_file,
            "--threads", str(threads), "--repeat", str(passes),
        ]
        rss_file = os.path.join(self.tmp, "maxrss.txt")
        if self.gnu_time:
            cmd = [self.gnu_time, "-f", "%M", "-o", rss_file, *cmd]
        with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
            proc = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
            _, status, usage = os.wait4(proc.pid, 0)
            proc.returncode = os.waitstatus_to_exitcode(status)
            out.seek(0)
            err.seek(0)
            text, errtext = out.read(), err.read()
        if proc.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{errtext}")
        if self.gnu_time:
            with open(rss_file, encoding="ascii") as f:
                maxrss_kb = int(f.read().split()[-1])
        else:
            maxrss_kb = usage.ru_maxrss  # Linux: kilobytes
        lines = (text + "\n" + errtext).splitlines()
        build = next(l for l in lines if l.startswith("build:"))
        m = re.match(r"build: (\d+) primitives in ([0-9.]+) s, (\d+) bytes of BVH \(([0-9.]+) bytes/triangle", build)
        assert m, build
        fields = dict(kv.split("=", 1) for kv in text.strip().splitlines()[-1].split())
        return {
            "prims": int(m.group(1)),
            "build_s": float(m.group(2)),
            "bvh_bytes": int(m.group(3)),
            "bytes_per_tri": float(m.group(4)),
            "rays": int(fields["rays"]),
            "hits": int(fields["hits"]),
            "mrays": float(fields["mrays_per_s"]),
            "threads": int(fields["threads"]),
            "rss": maxrss_kb * 1024,
        }

    def visits(self, scene: str, rays_file: str, threads: int) -> tuple[float, float]:
        """`bench rays --visits`: the mean nodes and leaves a closest-hit walk tests, per hitting and
        per missing ray (deterministic, so one run)."""
        cmd = [
            self.exe, "bench", "rays", "-f", scene, "--rays-file", rays_file,
            "--threads", str(threads), "--repeat", "1", "--visits",
        ]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        line = next(l for l in out.splitlines() if l.startswith("visits:"))
        m = re.match(r"visits: per hitting ray ([0-9.]+), per missing ray ([0-9.]+)", line)
        assert m, line
        return float(m.group(1)), float(m.group(2))

    def bench_render(self, scene: str, flags: list[str], threads: int, repeat: int) -> dict:
        """`rayscope bench render`: the render loop's median time and throughput."""
        cmd = [self.exe, "bench", "render", "-f", scene, *flags, "--threads", str(threads), "--repeat", str(repeat)]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        fields = dict(kv.split("=", 1) for kv in out.strip().splitlines()[-1].split())
        return {"seconds": float(fields["median_s"]), "mrays": float(fields["mrays_per_s"])}

    def primary_hits(self, scene: str, side: int) -> int:
        cmd = [self.exe, "bench", "rays", "-f", scene, "--primary", f"{side}x{side}", "--repeat", "1"]
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        last = out.strip().splitlines()[-1]
        return int(dict(kv.split("=", 1) for kv in last.split())["hits"])


# ----------------------------------------------------------------------------------------------
# Mitsuba


def mitsuba_scene(mi, scene_path: str, out_dir: str, tag: str, integrator: dict, size: int, spp: int, **kw):
    scene = cs.parse_scene(scene_path)
    d = tm.to_mitsuba(mi, scene, out_dir, tag, integrator, size, size, spp, **kw)
    return mi.load_dict(d)


def mitsuba_render(mi, dr, scene, spp: int, seed: int = 0):
    """Times mi.render plus the evaluation it schedules (the llvm variant is lazy)."""
    t0 = time.perf_counter()
    img = mi.render(scene, spp=spp, seed=seed)
    dr.eval(img)
    dr.sync_thread()
    return time.perf_counter() - t0, img


def read_exr(path: str) -> np.ndarray:
    import mitsuba as mi

    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def write_exr(path: str, img) -> None:
    import mitsuba as mi

    mi.Bitmap(np.asarray(img, dtype=np.float32)).write(path)


def rmse(a: np.ndarray, b: np.ndarray, keep: np.ndarray | None = None) -> float:
    sq = ((a - b) ** 2).mean(axis=-1)
    return float(np.sqrt(sq[keep].mean() if keep is not None else sq.mean()))


def away_from_emitters(*refs: np.ndarray, threshold: float = 2.0) -> np.ndarray:
    """Pixels more than one pixel away from any pixel that shows an emitter (a channel >= threshold
    in any reference). Away from emitters the RMSE measures noise alone; on an emitter's edge a
    pixel's value depends on how each renderer spreads samples over the pixel (both box-filter:
    Mitsuba with its box reconstruction filter, rayscope by jittering paths within -x cells)."""
    bright = np.zeros(refs[0].shape[:2], dtype=bool)
    for r in refs:
        bright |= r.max(axis=-1) >= threshold
    grown = bright.copy()
    h, w = bright.shape
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            shifted = np.zeros_like(bright)
            shifted[max(dy, 0):h + min(dy, 0), max(dx, 0):w + min(dx, 0)] = bright[
                max(-dy, 0):h + min(-dy, 0), max(-dx, 0):w + min(-dx, 0)
            ]
            grown |= shifted
    return ~grown


# ----------------------------------------------------------------------------------------------
# Rays for the closest-hit benchmark


def primary_rays(side: int) -> np.ndarray:
    """The course camera's primary rays through pixel centres of a side x side image, row 0 on
    top: image plane at z = 1, horizontal FOV 60 degrees, +x right, +y up."""
    half = math.tan(math.radians(30.0))
    c = (np.arange(side, dtype=np.float64) + 0.5) / side
    x = (2.0 * c - 1.0) * half
    y = (1.0 - 2.0 * c) * half
    xx, yy = np.meshgrid(x, y)  # row index = image row
    d = np.stack([xx.ravel(), yy.ravel(), np.ones(side * side)], axis=1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.zeros_like(d)
    return np.concatenate([o, d], axis=1).astype(np.float32)


def incoherent_rays(n: int, seed: int = 20240605) -> np.ndarray:
    """Origins uniform in [-1,1] x [-1,1] x [0,3], directions uniform on the sphere."""
    rng = np.random.default_rng(seed)
    o = rng.uniform([-1.0, -1.0, 0.0], [1.0, 1.0, 3.0], size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.concatenate([o, d], axis=1).astype(np.float32)


def write_rays(path: str, rays: np.ndarray) -> None:
    np.ascontiguousarray(rays, dtype="<f4").tofile(path)


# Embree runs its single-ray loop (embreex's run(): rtcIntersect1 per ray, holding the GIL) in
# worker processes, one per thread, each over a contiguous share of the rays. Each worker builds
# its own scene and warms up; a barrier starts the timed passes together; a pass takes from the
# first start to the last finish (CLOCK_MONOTONIC is shared by all processes).

_EMBREE_TRIS = None
_EMBREE_RAYS = None


def _embree_worker(conn, barrier, lo: int, hi: int):
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, _EMBREE_TRIS)
    o = np.ascontiguousarray(_EMBREE_RAYS[lo:hi, :3])
    d = np.ascontiguousarray(_EMBREE_RAYS[lo:hi, 3:])
    scene.run(o, d, query="INTERSECT")  # commit (BVH build) and warm-up pass
    conn.send("ready")
    while True:
        msg = conn.recv()
        if msg == "stop":
            break
        barrier.wait()
        t0 = time.perf_counter()
        ids = scene.run(o, d, query="INTERSECT")
        t1 = time.perf_counter()
        conn.send((t0, t1, int(np.count_nonzero(ids != -1))))
    conn.close()


class EmbreeWorkers:
    def __init__(self, triangles: np.ndarray, rays: np.ndarray, threads: int):
        global _EMBREE_TRIS, _EMBREE_RAYS
        _EMBREE_TRIS, _EMBREE_RAYS = triangles, rays
        self.n_rays = len(rays)
        ctx = mp.get_context("fork")
        barrier = ctx.Barrier(threads)
        bounds = np.linspace(0, len(rays), threads + 1).astype(int)
        self.procs, self.conns = [], []
        for k in range(threads):
            parent, child = ctx.Pipe()
            p = ctx.Process(target=_embree_worker, args=(child, barrier, bounds[k], bounds[k + 1]))
            p.start()
            self.procs.append(p)
            self.conns.append(parent)
        for c in self.conns:
            assert c.recv() == "ready"

    def one_pass(self) -> tuple[float, int]:
        for c in self.conns:
            c.send("go")
        results = [c.recv() for c in self.conns]
        start = min(r[0] for r in results)
        end = max(r[1] for r in results)
        return end - start, sum(r[2] for r in results)

    def mrays(self, passes: int) -> tuple[float, int]:
        """Median Mrays/s of `passes` passes after a settle, and the hit count (the same every pass)."""
        settle()
        times, hits = [], set()
        for _ in range(passes):
            t, h = self.one_pass()
            times.append(t)
            hits.add(h)
        assert len(hits) == 1, hits
        return self.n_rays / 1e6 / median(times), hits.pop()

    def close(self):
        for c in self.conns:
            c.send("stop")
        for p in self.procs:
            p.join()


def check_hits(what: str, embree: int, ours: int) -> None:
    """Stops the run when Embree's and rayscope's hit counts differ by more than 0.01 %."""
    rel = abs(embree - ours) / max(embree, 1)
    if rel > 1e-4:
        raise SystemExit(f"hit counts disagree by {rel:.4%} on {what}: Embree {embree}, rayscope {ours}")


# ----------------------------------------------------------------------------------------------
# Table


class Table:
    def __init__(self):
        self.sections: list[tuple[str, list[str], list[list[str]]]] = []

    def section(self, title: str, header: list[str]):
        self.sections.append((title, header, []))

    def row(self, cells: list):
        self.sections[-1][2].append([str(c) for c in cells])
        title, header, rows = self.sections[-1]
        log("  " + " | ".join(f"{h}={c}" for h, c in zip(header, rows[-1])))

    def markdown(self) -> str:
        out = []
        for title, header, rows in self.sections:
            out.append(f"### {title}\n")
            out.append("| " + " | ".join(header) + " |")
            out.append("|" + "|".join("---" for _ in header) + "|")
            for r in rows:
                out.append("| " + " | ".join(r) + " |")
            out.append("")
        return "\n".join(out)


def fmt_s(x: float) -> str:
    return f"{x:.3f} s"


# ----------------------------------------------------------------------------------------------


def bench_direct(args, rs: Rayscope, table: Table, notes: list[str]):
    import drjit as dr
    import mitsuba as mi

    size, spp, aa = args.size, 16, 4
    table.section(
        f"Whitted / direct lighting, {size}x{size}, 16 spp (rayscope: whole process `-x 4 --stage 2`; "
        "Mitsuba: `direct` integrator, mi.render only, after a warm-up render)",
        ["scene", "peer", "peer median", "rayscope median", "rayscope / peer (time)"],
    )
    scenes = [("course scene 1", SCENE_1), ("course scene 2", SCENE_2), ("course bunny scene", SCENE_OBJ)]
    for variant in args.variants:
        mi.set_variant(variant)
        for name, path in scenes:
            tag = os.path.splitext(os.path.basename(path))[0]
            scene = mitsuba_scene(mi, path, args.out, tag, {"type": "direct"}, size, spp)
            mitsuba_render(mi, dr, scene, spp)  # warm-up: JIT compilation
            peer, ours = [], []
            for _ in range(args.reps):
                settle()
                peer.append(mitsuba_render(mi, dr, scene, spp)[0])
                settle()
                ours.append(
                    rs.render(path, f"{tag}.png", ["-w", str(size), "-h", str(size), "-x", str(aa), "--stage", "2"])[0]
                )
            p, o = median(peer), median(ours)
            table.row([name, f"Mitsuba {variant} direct", fmt_s(p), fmt_s(o), f"{o / p:.2f}"])
            del scene
        if args.scene2_path:
            scene = mitsuba_scene(mi, SCENE_2, args.out, "sample_scene_2", {"type": "path", "max_depth": 5}, size, spp)
            mitsuba_render(mi, dr, scene, spp)
            peer, ours = [], []
            for _ in range(args.reps):
                settle()
                peer.append(mitsuba_render(mi, dr, scene, spp)[0])
                settle()
                ours.append(
                    rs.render(SCENE_2, "s2.png", ["-w", str(size), "-h", str(size), "-x", str(aa), "--stage", "2"])[0]
                )
            p, o = median(peer), median(ours)
            table.row(["course scene 2", f"Mitsuba {variant} path, max_depth 5", fmt_s(p), fmt_s(o), f"{o / p:.2f}"])
            del scene


def reference_images(args, rs: Rayscope, notes: list[str]):
    """Converged renders of the emitter-lit box by both renderers, cached in bench/out."""
    import drjit as dr
    import mitsuba as mi

    size, ref_spp = args.size, args.ref_spp
    q = int(round(math.log2(ref_spp / 4)))
    assert 4 * 2**q == ref_spp, "--ref-spp must be 4 * 2^q"
    mi_ref = os.path.join(args.out, f"ref_box_mitsuba_{size}_{ref_spp}spp.exr")
    rs_ref = os.path.join(args.out, f"ref_box_rayscope_{size}_{ref_spp}spp_jitter.exr")
    if not os.path.exists(mi_ref):
        log(f"rendering the Mitsuba reference ({ref_spp} spp, once; cached as {mi_ref})")
        mi.set_variant("llvm_ad_rgb")
        scene = mitsuba_scene(mi, SCENE_BOX, args.out, "box", _box_integrator(), size, 64, two_sided_emitters=True)
        chunk = min(64, ref_spp)
        acc = np.zeros((size, size, 3))
        for k in range(ref_spp // chunk):
            _, img = mitsuba_render(mi, dr, scene, chunk, seed=1000 + k)
            acc += np.array(img, dtype=np.float64)
        write_exr(mi_ref, acc / (ref_spp // chunk))
    if not os.path.exists(rs_ref):
        log(f"rendering the rayscope reference ({ref_spp} spp: -x 2 -q {q} -l, once; cached as {rs_ref})")
        tmp = rs_ref + ".tmp.exr"
        rs.render(SCENE_BOX, tmp, ["-w", str(size), "-h", str(size), "-x", "2", "-q", str(q), "-l"])
        os.replace(tmp, rs_ref)
    return read_exr(mi_ref), read_exr(rs_ref)


def _box_integrator() -> dict:
    # rayscope: at most 64 bounces, Russian roulette after 3 bounces. Mitsuba counts path
    # vertices: max_depth 65 allows 64 bounces; rr_depth 4 starts roulette at the 4th vertex.
    return {"type": "path", "max_depth": 65, "rr_depth": 4}


def bench_path(args, rs: Rayscope, table: Table, notes: list[str]):
    import drjit as dr
    import mitsuba as mi

    size, spp = args.size, 64
    ref_mi, ref_rs = reference_images(args, rs, notes)
    keep = away_from_emitters(ref_mi, ref_rs)
    mean_mi, mean_rs = ref_mi.reshape(-1, 3).mean(0), ref_rs.reshape(-1, 3).mean(0)
    rel = mean_rs / mean_mi - 1.0
    rel_keep = ref_rs[keep].mean(0) / ref_mi[keep].mean(0) - 1.0
    notes.append(
        f"Converged emitter-lit box ({args.ref_spp} spp each), mean linear RGB: Mitsuba "
        f"({mean_mi[0]:.4f}, {mean_mi[1]:.4f}, {mean_mi[2]:.4f}), rayscope "
        f"({mean_rs[0]:.4f}, {mean_rs[1]:.4f}, {mean_rs[2]:.4f}): rayscope/Mitsuba - 1 = "
        f"({rel[0]:+.2%}, {rel[1]:+.2%}, {rel[2]:+.2%}) over all pixels, "
        f"({rel_keep[0]:+.2%}, {rel_keep[1]:+.2%}, {rel_keep[2]:+.2%}) away from emitters "
        f"({int(keep.sum())} of {keep.size} pixels). RMSE between the two references: "
        f"{rmse(ref_mi, ref_rs):.4f} over all pixels, {rmse(ref_mi, ref_rs, keep):.4f} away from emitters."
    )
    if np.max(np.abs(rel_keep)) > 0.03:
        log("WARNING: the converged images disagree by more than 3% in mean colour; RMSE is not meaningful")
    table.section(
        f"Path tracing the emitter-lit box (`scenes/emissive.txt`), {size}x{size}, 64 spp "
        f"(rayscope: whole process `-x 2 -q 4 -l`, EXR; Mitsuba: `path`, max_depth 65, rr_depth 4, "
        f"mi.render only). RMSE in linear RGB against the Mitsuba {args.ref_spp}-spp reference: "
        "all pixels / away from emitters",
        ["peer", "peer median", "rayscope median", "rayscope / peer (time)", "peer RMSE", "rayscope RMSE"],
    )
    for variant in args.variants:
        mi.set_variant(variant)
        scene = mitsuba_scene(mi, SCENE_BOX, args.out, "box", _box_integrator(), size, spp, two_sided_emitters=True)
        mitsuba_render(mi, dr, scene, spp)
        peer, ours = [], []
        img_peer = img_ours = None
        for _ in range(args.reps):
            settle()
            t, img = mitsuba_render(mi, dr, scene, spp)
            peer.append(t)
            img_peer = np.array(img, dtype=np.float64)
            settle()
            t, path = rs.render(SCENE_BOX, "box64.exr", ["-w", str(size), "-h", str(size), "-x", "2", "-q", "4", "-l"])
            ours.append(t)
            img_ours = read_exr(path)
        p, o = median(peer), median(ours)
        table.row([
            f"Mitsuba {variant} path",
            fmt_s(p),
            fmt_s(o),
            f"{o / p:.2f}",
            f"{rmse(img_peer, ref_mi):.4f} / {rmse(img_peer, ref_mi, keep):.4f}",
            f"{rmse(img_ours, ref_mi):.4f} / {rmse(img_ours, ref_mi, keep):.4f}",
        ])
        del scene


# Scenes of the sampling section: (name, scene file, rayscope flags, Mitsuba integrator, lens).
def _sampling_scenes() -> list[tuple[str, str, list[str], dict, tuple | None]]:
    path = _box_integrator()
    direct = {"type": "direct", "emitter_samples": 1, "bsdf_samples": 1}
    return [
        ("emitter box -l", SCENE_BOX, ["-l"], path, None),
        ("ambient.txt -l", os.path.join(ROOT, "scenes", "ambient.txt"), ["-l"], path, None),
        ("course OBJ scene -l", SCENE_OBJ, ["-l"], path, None),
        ("dof.txt -r 0.1 -t 3.6", os.path.join(ROOT, "scenes", "dof.txt"), ["-r", "0.1", "-t", "3.6"], direct, (0.1, 3.6)),
    ]


def relative_rmse(img: np.ndarray, ref: np.ndarray) -> float:
    """RMSE over the reference's root mean square: comparable between renderers whose converged
    images differ in brightness (Mitsuba's point lights are not the course's)."""
    return rmse(img, ref) / float(np.sqrt((ref**2).mean()))


def bench_sampling(args, rs: Rayscope, table: Table, notes: list[str]):
    """Noise at equal samples and at equal time: rayscope's sampler against Mitsuba's
    `independent` and its low-discrepancy samplers, each renderer against its own converged
    reference (so only noise is measured, not the renderers' differences)."""
    import drjit as dr
    import mitsuba as mi

    size, spp, ref_spp = args.sampling_size, 64, args.sampling_ref_spp
    q, ref_q = 4, int(round(math.log2(ref_spp / 4)))
    samplers = ["independent", "ldsampler", "multijitter"]
    table.section(
        f"Sampling: noise at equal samples and equal time, {size}x{size}, {spp} spp (rayscope: whole "
        f"process `-x 2 -q {q}`; Mitsuba {args.variants[0]}, mi.render only). Relative RMSE (RMSE / "
        f"RMS of the reference) against each renderer's own {ref_spp}-spp reference, mean over "
        f"{args.reps} seeds; at equal time = relative RMSE x sqrt(time / rayscope's time)",
        ["scene", "renderer / sampler", "median time", "rel. RMSE, equal spp", "rel. RMSE, equal time",
         "rayscope / this, equal time"],
    )
    mi.set_variant(args.variants[0])
    for name, path, flags, integrator, lens in _sampling_scenes():
        tag = "sampling_" + name.split()[0].replace(".txt", "")
        wh = ["-w", str(size), "-h", str(size), "-x", "2"]
        rs_ref_path = os.path.join(args.out, f"ref_{tag}_rayscope_{size}_{ref_spp}.exr")
        if not os.path.exists(rs_ref_path):
            log(f"{name}: rendering the rayscope reference ({ref_spp} spp)")
            _, out = rs.render(path, "ref.exr", [*wh, "-q", str(ref_q), "--seed", "1000", *flags])
            os.replace(out, rs_ref_path)
        rs_ref = read_exr(rs_ref_path)
        times, errs = [], []
        for seed in range(args.reps):
            settle()
            t, out = rs.render(path, "s.exr", [*wh, "-q", str(q), "--seed", str(seed), *flags])
            times.append(t)
            errs.append(relative_rmse(read_exr(out), rs_ref))
        t_rs, e_rs = median(times), float(np.mean(errs))
        rows = [("rayscope (Sobol)", t_rs, e_rs)]
        mi_ref_path = os.path.join(args.out, f"ref_{tag}_mitsuba_{size}_{ref_spp}.exr")
        kw = {"two_sided_emitters": True, "lens": lens}
        if not os.path.exists(mi_ref_path):
            log(f"{name}: rendering the Mitsuba reference ({ref_spp} spp)")
            scene = mitsuba_scene(mi, path, args.out, tag, integrator, size, 64, **kw)
            acc = np.zeros((size, size, 3))
            for k in range(ref_spp // 64):
                acc += np.array(mitsuba_render(mi, dr, scene, 64, seed=1000 + k)[1], dtype=np.float64)
            write_exr(mi_ref_path, acc / (ref_spp // 64))
        mi_ref = read_exr(mi_ref_path)
        for sampler in samplers:
            scene = mitsuba_scene(mi, path, args.out, tag, integrator, size, spp, sampler=sampler, **kw)
            mitsuba_render(mi, dr, scene, spp)  # warm-up: JIT compilation
            times, errs = [], []
            for seed in range(args.reps):
                settle()
                t, img = mitsuba_render(mi, dr, scene, spp, seed=seed)
                times.append(t)
                errs.append(relative_rmse(np.array(img, dtype=np.float64), mi_ref))
            rows.append((f"Mitsuba {sampler}", median(times), float(np.mean(errs))))
            del scene
        for who, t, e in rows:
            at_time = e * math.sqrt(t / t_rs)
            table.row([name, who, fmt_s(t), f"{e:.4f}", f"{at_time:.4f}", f"{e_rs / at_time:.2f}"])
    notes.append(
        "Sampling section: equal time scales each renderer's relative RMSE by sqrt(its time / "
        "rayscope's time), the Monte Carlo rate; low-discrepancy samplers converge faster than "
        "that, so it slightly flatters whichever renderer is slower."
    )


def ray_sets(args) -> list[tuple[str, str, np.ndarray]]:
    """The closest-hit ray files (primary side x side, incoherent side^2), written to args.out."""
    side = args.primary_side
    n = side * side
    sets = []
    path = os.path.join(args.out, f"rays_primary_{side}.bin")
    rays = primary_rays(side)
    write_rays(path, rays)
    sets.append((f"primary, {side}x{side}", path, rays))
    path = os.path.join(args.out, f"rays_incoherent_{n}.bin")
    rays = incoherent_rays(n)
    write_rays(path, rays)
    sets.append((f"incoherent, {n:,}", path, rays))
    return sets


def bench_rays(args, rs: Rayscope, table: Table, notes: list[str]):
    scene = cs.parse_scene(SCENE_OBJ)
    mesh_scene = os.path.join(args.out, "bunny_only.txt")
    cs.write_bunny_only_scene(scene, mesh_scene)
    triangles = np.concatenate([cs.load_obj_triangles(m) for m in scene.objs])
    side = args.primary_side
    n = side * side
    sets = ray_sets(args)

    ours_primary = rs.primary_hits(mesh_scene, side)
    notes.append(
        f"Closest hit: the bunny alone ({len(triangles)} triangles; the bunny scene's planes and "
        f"box triangles left out), scene `{os.path.relpath(mesh_scene, ROOT)}`. rayscope's own "
        f"`--primary {side}x{side}` camera gives {ours_primary} hits; our primary-ray file gives "
        "the count in the table."
    )
    # The binding's floor: rays that miss the bunny's bounding box cost only embreex's per-ray
    # loop and Embree's entry and root-box test.
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    probe = rtcore_scene.EmbreeScene()
    TriangleMesh(probe, triangles)
    o = np.zeros((n, 3), dtype=np.float32)
    d = np.zeros((n, 3), dtype=np.float32)
    d[:, 2] = -1.0
    probe.run(o, d, query="INTERSECT")
    floor = []
    for _ in range(3):
        t0 = time.perf_counter()
        ids = probe.run(o, d, query="INTERSECT")
        floor.append(time.perf_counter() - t0)
    assert np.all(ids == -1)
    del probe
    notes.append(
        f"Embree through embreex has a per-ray floor: {n:,} rays that all miss the bunny's bounds "
        f"take {min(floor) / n * 1e9:.1f} ns a ray on 1 thread ({n / 1e6 / min(floor):.1f} Mrays/s "
        "at best), the binding's loop plus rtcIntersect1's entry; a C caller with ray streams would "
        "pay less."
    )
    table.section(
        "Closest hit on the course bunny (rayscope `bench rays --rays-file`, traversal only; Embree 4 "
        "via embreex, rtcIntersect1 per ray, intersect call only). Median Mrays/s",
        ["rays", "threads", "Embree", "rayscope", "rayscope / Embree", "hits Embree", "hits rayscope"],
    )
    for label, path, rays in sets:
        for threads in args.threads:
            workers = EmbreeWorkers(triangles, rays, threads)
            peer, ours, hits_peer, hits_ours = [], [], set(), set()
            try:
                for _ in range(args.reps):
                    speed, h = workers.mrays(args.ray_passes)
                    peer.append(speed)
                    hits_peer.add(h)
                    settle()
                    r = rs.bench_rays(mesh_scene, path, threads, args.ray_passes)
                    assert r["threads"] == threads and r["rays"] == len(rays), r
                    ours.append(r["mrays"])
                    hits_ours.add(r["hits"])
            finally:
                workers.close()
            assert len(hits_peer) == 1 and len(hits_ours) == 1, (hits_peer, hits_ours)
            hp, ho = hits_peer.pop(), hits_ours.pop()
            p, o = median(peer), median(ours)
            table.row([label, threads, f"{p:.2f}", f"{o:.2f}", f"{o / p:.2f}", hp, ho])
            check_hits(label, hp, ho)


# The enlarged bunny of the scale section: 2.5 x the course's scale (0.35), placed so that it
# covers about as much of the course camera's image as the generated torus (about a quarter).
BIG_BUNNY_FACTOR = 2.5
BIG_BUNNY_OFFSET = (-0.07, -0.85, 2.0)


def bench_scale(args, rs: Rayscope, table: Table, notes: list[str]):
    """Generated tori of --scale-tris triangles against the course bunny (and the bunny enlarged to
    the torus's screen coverage) on the closest-hit ray files, --scale-threads threads."""
    threads = args.scale_threads
    scene = cs.parse_scene(SCENE_OBJ)
    bunny = os.path.join(args.out, "bunny_only.txt")
    cs.write_bunny_only_scene(scene, bunny)
    (model,) = scene.objs
    m = scene.materials[model.material]

    def write_big_bunny(path: str, obj: str) -> None:
        """The bunny scene's model alone, enlarged BIG_BUNNY_FACTOR times, from OBJ file `obj`."""
        with open(path, "w", encoding="utf-8") as f:
            f.write(f'Material "{m.name}" {m.kind} ({", ".join(repr(x) for x in m.colour)}) {m.number!r}\n')
            o = ", ".join(repr(x) for x in BIG_BUNNY_OFFSET)
            f.write(f'ObjModel "{model.name}" "{obj}" ({o}) {model.scale * BIG_BUNNY_FACTOR!r} "{m.name}"\n')

    big_bunny = os.path.join(args.out, "bunny_big.txt")
    write_big_bunny(big_bunny, model.path)
    scenes = [("bunny (course)", bunny), (f"bunny x{BIG_BUNNY_FACTOR:g}", big_bunny)]
    # The same enlarged bunny with every triangle split into 4^levels: the shape and the screen
    # coverage stay, only the triangle count grows, which isolates what size costs.
    for levels in args.scale_subdiv:
        t0 = time.perf_counter()
        obj = gen_mesh.ensure_subdivided(args.out, model.path, levels)
        if time.perf_counter() - t0 > 0.5:
            log(f"generated {os.path.relpath(obj, ROOT)} in {time.perf_counter() - t0:.1f} s")
        sub = os.path.join(args.out, f"bunny_big_sub{levels}.txt")
        write_big_bunny(sub, obj)
        scenes.append((f"bunny x{BIG_BUNNY_FACTOR:g}, {4 ** levels}x triangles", sub))
    big_model = dataclasses.replace(model, offset=BIG_BUNNY_OFFSET, scale=model.scale * BIG_BUNNY_FACTOR)
    # The meshes Embree traces too, as functions so each is made only while it is measured.
    embree_meshes = [(f"bunny x{BIG_BUNNY_FACTOR:g}", lambda: cs.load_obj_triangles(big_model))]
    for tris in args.scale_tris:
        embree_meshes.append((f"torus {tris / 1e6:g}M", lambda tris=tris: torus_triangles(tris)))
    for tris in args.scale_tris:
        t0 = time.perf_counter()
        path, obj = gen_mesh.ensure(args.out, tris)
        if time.perf_counter() - t0 > 0.5:
            log(f"generated {os.path.relpath(obj, ROOT)} in {time.perf_counter() - t0:.1f} s")
        scenes.append((f"torus {tris / 1e6:g}M", path))
    sets = [(label, path) for label, path, _ in ray_sets(args)]

    # results[(scene, set)] = list of runs; scenes alternate, the order rotating every repetition.
    results: dict[tuple[str, str], list[dict]] = {(s, r): [] for s, _ in scenes for r, _ in sets}
    for rep in range(args.reps):
        for set_label, rays_file in sets:
            k = rep % len(scenes)
            for name, path in scenes[k:] + scenes[:k]:
                r = rs.bench_rays_rss(path, rays_file, threads, args.ray_passes)
                assert r["threads"] == threads, r
                results[(name, set_label)].append(r)
        log(f"  scale: repetition {rep + 1}/{args.reps} done")
    # How far each walk goes, which explains most of the throughput ratios: counted once, untimed.
    visits = {(name, set_label): rs.visits(path, rays_file, threads) for name, path in scenes for set_label, rays_file in sets}

    # Rendering: the same scenes lit by the tori's point light, so each render traces camera
    # rays (as packets) and a shadow ray from every hit, as users' renders of such meshes do.
    side = args.primary_side
    render_flags = ["-w", str(side), "-h", str(side), "-x", "1", "--stage", "2"]
    lit = []
    for name, path in scenes:
        with open(path, encoding="utf-8") as f:
            lines = f.read().splitlines()
        if not any(l.startswith("PointLight") for l in lines):
            lines.insert(1, gen_mesh.LIGHT)
        lit_path = os.path.join(args.out, os.path.basename(path).replace(".txt", "_lit.txt"))
        with open(lit_path, "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")
        lit.append((name, lit_path))
    renders: dict[str, list[dict]] = {name: [] for name, _ in lit}
    for rep in range(args.reps):
        k = rep % len(lit)
        for name, path in lit[k:] + lit[:k]:
            renders[name].append(rs.bench_render(path, render_flags, threads, args.ray_passes))
        log(f"  scale, rendering: repetition {rep + 1}/{args.reps} done")

    def med(name, key, set_label=None):
        runs = [x for (s, r), xs in results.items() if s == name and set_label in (None, r) for x in xs]
        return median([x[key] for x in runs])

    def hits(name, set_label):
        hs = {x["hits"] for x in results[(name, set_label)]}
        assert len(hs) == 1, (name, set_label, hs)
        return hs.pop()

    def per_ray(name, set_label):
        """Mean visits over all rays of the set."""
        vh, vm = visits[(name, set_label)]
        f = hits(name, set_label) / results[(name, set_label)][0]["rays"]
        return f * vh + (1 - f) * vm

    bunny_rss = med(scenes[0][0], "rss")
    table.section(
        f"Scale: BVH build and memory (rayscope `bench rays`, {threads} threads; build time as printed by "
        "rayscope, OBJ parsing not included; peak RSS of the rayscope process"
        f"{'' if rs.gnu_time else ' (upper bound: no /usr/bin/time, wait4 ru_maxrss)'}, OBJ parsing and "
        "1,048,576 rays included). Medians over all runs of the throughput table",
        ["scene", "triangles", "build", "build s per M triangles (target <= 1)", "BVH incl. triangles, bytes/triangle",
         "peak RSS", "peak RSS above the bunny's, bytes/triangle"],
    )
    for name, _ in scenes:
        n = results[(name, sets[0][0])][0]["prims"]
        b = med(name, "build_s")
        rss = med(name, "rss")
        above = f"{(rss - bunny_rss) / n:.0f}" if n > 100_000 else "-"
        table.row([name, f"{n:,}", f"{b:.3f} s", f"{b / n * 1e6:.3f}", f"{med(name, 'bytes_per_tri'):.1f}",
                   f"{rss / 2**20:.0f} MiB", above])
    table.section(
        f"Scale: closest-hit throughput, {threads} threads, median Mrays/s of --reps runs (each the median "
        f"of {args.ray_passes} passes). Target: torus >= 0.5 x the course bunny",
        ["rays", "scene", "hits (fraction)", "Mrays/s", "/ bunny (course)", f"/ bunny x{BIG_BUNNY_FACTOR:g}",
         "visits per hitting / missing ray", f"bunny x{BIG_BUNNY_FACTOR:g}'s visits per ray / these"],
    )
    for set_label, _ in sets:
        base = med(scenes[0][0], "mrays", set_label)
        big = med(scenes[1][0], "mrays", set_label)
        for name, _ in scenes:
            h = hits(name, set_label)
            n_rays = results[(name, set_label)][0]["rays"]
            mr = med(name, "mrays", set_label)
            vh, vm = visits[(name, set_label)]
            table.row([set_label, name, f"{h:,} ({h / n_rays:.1%})", f"{mr:.2f}", f"{mr / base:.2f}", f"{mr / big:.2f}",
                       f"{vh:.2f} / {vm:.2f}", f"{per_ray(scenes[1][0], set_label) / per_ray(name, set_label):.2f}"])
    # Embree on the same meshes and ray files: how much of its small-mesh speed it keeps.
    ray_data = {label: rays for label, _, rays in ray_sets(args)}
    table.section(
        f"Scale: Embree 4 (embreex, rtcIntersect1 per ray) on the same meshes and rays, {threads} threads, "
        f"median Mrays/s of --reps runs (each the median of {args.ray_passes} passes); rayscope's figures are "
        "those of the throughput table above",
        ["rays", "scene", "Embree", "rayscope", "rayscope / Embree", f"Embree / its bunny x{BIG_BUNNY_FACTOR:g}",
         f"rayscope / its bunny x{BIG_BUNNY_FACTOR:g}", "hits Embree", "hits rayscope"],
    )
    for set_label, _ in sets:
        rays = ray_data[set_label]
        embree_big = None
        for name, make in embree_meshes:
            workers = EmbreeWorkers(make(), rays, threads)
            try:
                runs = [workers.mrays(args.ray_passes) for _ in range(args.reps)]
            finally:
                workers.close()
            peer_hits = {h for _, h in runs}
            assert len(peer_hits) == 1, (name, set_label, peer_hits)
            speeds = [speed for speed, _ in runs]
            hp, ho = peer_hits.pop(), hits(name, set_label)
            p, o = median(speeds), med(name, "mrays", set_label)
            embree_big = embree_big or p
            table.row([set_label, name, f"{p:.2f}", f"{o:.2f}", f"{o / p:.2f}", f"{p / embree_big:.2f}",
                       f"{o / med(scenes[1][0], 'mrays', set_label):.2f}", hp, ho])
            check_hits(f"{name}, {set_label}", hp, ho)
        log(f"  scale, Embree: {set_label} done")
    table.section(
        f"Scale: rendering (rayscope `bench render {' '.join(render_flags)}`, {threads} threads, the render "
        f"loop only: camera rays as packets and a shadow ray to the point light from every hit), median of "
        f"--reps runs (each the median of {args.ray_passes})",
        ["scene", "render loop", "Mrays/s", f"speed / bunny x{BIG_BUNNY_FACTOR:g} (its time / this one's)"],
    )
    big_render = median([r["seconds"] for r in renders[scenes[1][0]]])
    for name, _ in lit:
        secs = median([r["seconds"] for r in renders[name]])
        mr = median([r["mrays"] for r in renders[name]])
        table.row([name, fmt_s(secs), f"{mr:.1f}", f"{big_render / secs:.2f}"])
    notes.append(
        f"Scale: the tori are `bench/gen_mesh.py`'s closed bumpy torus (scenes `bench/out/torus_N.txt`), "
        f"centred at {gen_mesh.CENTRE}; the course bunny (4968 triangles) covers "
        f"{hits(scenes[0][0], sets[0][0]) / args.primary_side**2:.1%} of the primary rays, so most of its rays "
        f"miss cheaply; `bunny x{BIG_BUNNY_FACTOR:g}` (scale {model.scale * BIG_BUNNY_FACTOR:g}, offset "
        f"{BIG_BUNNY_OFFSET}) covers about as much of the image as the tori and compares like with like."
    )


def torus_triangles(tris: int) -> np.ndarray:
    """`gen_mesh`'s torus of `tris` triangles in scene space, shape (n, 3, 3), float32, placed as
    its scene places it (scale 1 at gen_mesh.CENTRE, the course's z flip)."""
    verts, faces = gen_mesh.torus(tris)
    scene = verts * np.array([1.0, 1.0, -1.0]) + np.array(gen_mesh.CENTRE)
    return scene[faces - 1].astype(np.float32)


SECTIONS = ["direct", "path", "sampling", "rays", "scale"]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rayscope", default=os.path.join(ROOT, "target", "release", "rayscope"))
    ap.add_argument("--reps", type=int, default=5, help="alternating repetitions per row (default 5)")
    ap.add_argument("--size", type=int, default=400, help="image width and height (default 400)")
    ap.add_argument("--ref-spp", type=int, default=4096, help="samples per pixel of the cached references")
    ap.add_argument("--primary-side", type=int, default=1024, help="primary rays: side x side (default 1024)")
    ap.add_argument("--ray-passes", type=int, default=3, help="timed passes per closest-hit repetition")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--variants", nargs="+", default=["llvm_ad_rgb", "scalar_rgb"])
    ap.add_argument("--only", nargs="+", choices=SECTIONS, default=SECTIONS)
    ap.add_argument(
        "--scale-tris", type=int, nargs="+", default=[1_000_000, 4_000_000],
        help="scale section: triangle counts of the generated tori (default 1000000 4000000)",
    )
    ap.add_argument(
        "--scale-subdiv", type=int, nargs="*", default=[4, 5],
        help="scale section: also the enlarged bunny split 4^L times for each L (default 4 5: 1.27M, 5.09M)",
    )
    ap.add_argument("--scale-threads", type=int, default=2, help="scale section: threads (default 2)")
    ap.add_argument("--sampling-size", type=int, default=64, help="sampling section: image side (default 64)")
    ap.add_argument("--sampling-ref-spp", type=int, default=1024, help="sampling section: reference spp (4 * 2^q)")
    ap.add_argument("--no-scene2-path", dest="scene2_path", action="store_false")
    ap.add_argument("--out", default=os.path.join(HERE, "out"))
    args = ap.parse_args()
    os.makedirs(args.out, exist_ok=True)

    import drjit
    import embreex
    import mitsuba

    started = time.perf_counter()
    load_start = os.getloadavg()[0]
    table, notes = Table(), []
    with tempfile.TemporaryDirectory(prefix="rayscope-bench-") as tmp:
        rs = Rayscope(args.rayscope, tmp)
        if "direct" in args.only:
            bench_direct(args, rs, table, notes)
        if "path" in args.only:
            bench_path(args, rs, table, notes)
        if "sampling" in args.only:
            bench_sampling(args, rs, table, notes)
        if "rays" in args.only:
            bench_rays(args, rs, table, notes)
        if "scale" in args.only:
            bench_scale(args, rs, table, notes)
    wall = time.perf_counter() - started

    version = subprocess.run([args.rayscope, "--version"], capture_output=True, text=True).stdout.strip()
    header = [
        "## rayscope vs Mitsuba 3 and Embree",
        "",
        f"{version}; Mitsuba {mitsuba.__version__}, Dr.Jit {drjit.__version__}, embreex "
        f"{embreex.__version__}, Python {platform.python_version()}; {os.cpu_count()} CPUs "
        f"({platform.processor() or platform.machine()}); --reps {args.reps}; total {wall:.0f} s; "
        f"1-minute load average {load_start:.2f} at the start, {os.getloadavg()[0]:.2f} at the end.",
        "",
    ]
    text = "\n".join(header) + table.markdown() + "\n" + "\n".join(f"- {n}" for n in notes) + "\n"
    with open(os.path.join(args.out, "results.md"), "w", encoding="utf-8") as f:
        f.write(text)
    print(text)


if __name__ == "__main__":
    main()
