"""Generated meshes for the harness's scale section: a closed, bumpy torus with 2 * NU * NV triangles.

    python bench/gen_mesh.py [--out bench/out] [--tris 1000000 4000000]

writes, for each triangle count T, `torus_T.obj` (`v` and `f` lines only, a watertight grid that
wraps in both directions) and `torus_T.txt`, a course scene with one material, one point light
and `ObjModel "Torus" "/abs/path/torus_T.obj" (cx, cy, cz) 1 "M"`. Files that already exist are
kept. The surface is the same for every T (only the sampling differs): a torus of major radius
0.5 and minor radius 0.2, displaced along its normal by a fixed sum of periodic waves (up to
+-0.035, wavelengths down to about 1/80 of the tube's circumference), tilted 35 degrees towards
the camera and centred at (0, -0.35, 2.0) in world space, a little above the bunny's centre
((0.03, -0.64, 2.03)) so that it stays inside the view. It covers about a quarter of the course
camera's image (the bunny covers 4 %), so that primary rays mostly hit triangles.
"""

from __future__ import annotations

import argparse
import math
import os

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))

MAJOR, MINOR = 0.5, 0.2
TILT_DEG = 35.0  # rotation about x: the torus's axis leans from +y towards the camera (-z)
CENTRE = (0.0, -0.35, 2.0)


def grid_for(tris: int) -> tuple[int, int]:
    """NU (around the axis) x NV (around the tube), NU about 2 NV, 2 NU NV = tris where it can be
    (1M: 1000 x 500, 4M: 2000 x 1000), else the nearest below."""
    nv = max(3, int(round(math.sqrt(tris / 4))))
    nu = max(3, tris // (2 * nv))
    return nu, nv


def displacement(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A fixed sum of waves with integer frequencies (periodic in u and v, so the seams close)."""
    rng = np.random.default_rng(7)
    d = np.zeros(np.broadcast(u, v).shape)
    for _ in range(40):
        m = int(rng.integers(-60, 61))
        n = int(rng.integers(-30, 31))
        f = math.hypot(m / 2.0, n) + 1.0
        d += 0.012 / f**0.6 * np.sin(m * u + n * v + rng.uniform(0, 2 * math.pi))
    return d


def torus(tris: int) -> tuple[np.ndarray, np.ndarray]:
    nu, nv = grid_for(tris)
    u = np.arange(nu) * (2 * math.pi / nu)
    v = np.arange(nv) * (2 * math.pi / nv)
    uu, vv = np.meshgrid(u, v, indexing="ij")  # vertex (i, j) -> index i * nv + j
    r = MINOR + displacement(uu, vv)
    x = (MAJOR + r * np.cos(vv)) * np.cos(uu)
    z = (MAJOR + r * np.cos(vv)) * np.sin(uu)
    y = r * np.sin(vv)
    t = math.radians(TILT_DEG)
    # World offsets from the centre: rotate about x; y' = y cos t + z sin t, z' = -y sin t + z cos t.
    wy = y * math.cos(t) + z * math.sin(t)
    wz = -y * math.sin(t) + z * math.cos(t)
    # The course maps an OBJ vertex to (s x + ox, s y + oy, -s z + oz): store -wz.
    verts = np.stack([x.ravel(), wy.ravel(), -wz.ravel()], axis=1)

    i = np.arange(nu)[:, None]
    j = np.arange(nv)[None, :]
    a = i * nv + j
    b = ((i + 1) % nu) * nv + j
    c = ((i + 1) % nu) * nv + (j + 1) % nv
    d = i * nv + (j + 1) % nv
    faces = np.concatenate(
        [np.stack([a, b, c], axis=-1).reshape(-1, 3), np.stack([a, c, d], axis=-1).reshape(-1, 3)]
    )
    return verts, faces + 1  # OBJ indices are 1-based


def _write_lines(f, fmt: str, rows: np.ndarray, chunk: int = 1 << 18) -> None:
    for k in range(0, len(rows), chunk):
        block = rows[k:k + chunk].tolist()
        f.write("".join(fmt % tuple(r) for r in block))


def write_obj(path: str, verts: np.ndarray, faces: np.ndarray) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="ascii") as f:
        f.write(f"# bench/gen_mesh.py: bumpy torus, {len(verts)} vertices, {len(faces)} triangles\n")
        _write_lines(f, "v %.6f %.6f %.6f\n", verts)
        _write_lines(f, "f %d %d %d\n", faces)
    os.replace(tmp, path)


# The scenes' one point light, above and to the right of the camera.
LIGHT = 'PointLight "L" (0.6, 0.9, 0.5) (1, 1, 1)'


def write_scene(path: str, obj_path: str) -> None:
    cx, cy, cz = CENTRE
    with open(path, "w", encoding="ascii") as f:
        f.write('Material "M" Diffuse (0.8, 0.8, 0.8) 1\n')
        f.write(LIGHT + "\n")
        f.write(f'ObjModel "Torus" "{os.path.abspath(obj_path)}" ({cx}, {cy}, {cz}) 1 "M"\n')


def ensure(out_dir: str, tris: int) -> tuple[str, str]:
    """Writes torus_T.obj and torus_T.txt into out_dir unless present; returns (scene, obj)."""
    os.makedirs(out_dir, exist_ok=True)
    obj = os.path.join(out_dir, f"torus_{tris}.obj")
    scene = os.path.join(out_dir, f"torus_{tris}.txt")
    if not os.path.exists(obj):
        verts, faces = torus(tris)
        write_obj(obj, verts, faces)
    if not os.path.exists(scene):
        write_scene(scene, obj)
    return scene, obj


def read_obj(path: str) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and triangles (0-based; polygons as fans) of an OBJ's `v` and `f` lines."""
    verts, faces = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            t = line.split()
            if not t:
                continue
            if t[0] == "v":
                verts.append([float(x) for x in t[1:4]])
            elif t[0] == "f":
                idx = [int(x.split("/")[0]) for x in t[1:]]
                idx = [i - 1 if i > 0 else len(verts) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    return np.asarray(verts, dtype=np.float64), np.asarray(faces, dtype=np.int64)


def subdivide(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Splits every triangle into four at its edge midpoints: the same flat surface, 4x the
    triangles, winding kept, midpoints shared between neighbours."""
    a, b, c = faces.T
    edges = np.concatenate([np.stack([a, b], 1), np.stack([b, c], 1), np.stack([c, a], 1)])
    edges.sort(axis=1)
    keys = edges[:, 0] * len(verts) + edges[:, 1]
    uniq, inv = np.unique(keys, return_inverse=True)
    lo, hi = uniq // len(verts), uniq % len(verts)
    mids = (verts[lo] + verts[hi]) / 2
    m = inv.reshape(3, -1) + len(verts)
    mab, mbc, mca = m
    new = np.concatenate([
        np.stack([a, mab, mca], 1),
        np.stack([mab, b, mbc], 1),
        np.stack([mca, mbc, c], 1),
        np.stack([mab, mbc, mca], 1),
    ])
    return np.vstack([verts, mids]), new


def ensure_subdivided(out_dir: str, source_obj: str, levels: int) -> str:
    """Writes `bunny_sub{levels}.obj`, the course bunny split `levels` times (4^levels x its
    triangles, the same shape), unless present; returns its path."""
    os.makedirs(out_dir, exist_ok=True)
    obj = os.path.join(out_dir, f"bunny_sub{levels}.obj")
    if not os.path.exists(obj):
        verts, faces = read_obj(source_obj)
        for _ in range(levels):
            verts, faces = subdivide(verts, faces)
        tmp = obj + ".tmp"
        with open(tmp, "w", encoding="ascii") as f:
            f.write(f"# bench/gen_mesh.py: the course bunny subdivided {levels} times, {len(faces)} triangles\n")
            _write_lines(f, "v %.7f %.7f %.7f\n", verts)
            _write_lines(f, "f %d %d %d\n", faces + 1)
        os.replace(tmp, obj)
    return obj


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(HERE, "out"))
    ap.add_argument("--tris", type=int, nargs="+", default=[1_000_000, 4_000_000])
    args = ap.parse_args()
    for t in args.tris:
        scene, obj = ensure(args.out, t)
        print(f"{scene}  ({os.path.getsize(obj) / 1e6:.0f} MB OBJ)")


if __name__ == "__main__":
    main()
