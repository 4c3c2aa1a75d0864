"""A small reader for the COMP30019 scene format, written for the comparison harness.

It reads what the harness needs (materials, point lights, planes, spheres, triangles and OBJ
models) and resolves OBJ paths the way rayscope does: the current directory first, then the
scene file's folder and each of its ancestors. It is deliberately independent of rayscope's
Rust parser so that a disagreement between the two shows up as a benchmark failure.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field

import numpy as np

_SEPARATORS = re.compile(r'[\s,"()]+')


@dataclass
class Material:
    name: str
    kind: str  # Diffuse, Reflective, Refractive, Emissive, Glossy
    colour: tuple[float, float, float]
    number: float


@dataclass
class PointLight:
    name: str
    position: tuple[float, float, float]
    colour: tuple[float, float, float]


@dataclass
class Plane:
    name: str
    point: tuple[float, float, float]
    normal: tuple[float, float, float]
    material: str


@dataclass
class Sphere:
    name: str
    centre: tuple[float, float, float]
    radius: float
    material: str


@dataclass
class Triangle:
    name: str
    v0: tuple[float, float, float]
    v1: tuple[float, float, float]
    v2: tuple[float, float, float]
    material: str


@dataclass
class ObjModel:
    name: str
    path: str  # resolved, absolute
    offset: tuple[float, float, float]
    scale: float
    material: str


@dataclass
class Scene:
    path: str
    materials: dict[str, Material] = field(default_factory=dict)
    lights: list[PointLight] = field(default_factory=list)
    planes: list[Plane] = field(default_factory=list)
    spheres: list[Sphere] = field(default_factory=list)
    triangles: list[Triangle] = field(default_factory=list)
    objs: list[ObjModel] = field(default_factory=list)


class SceneError(Exception):
    pass


def _resolve_obj(path: str, scene_path: str) -> str:
    if os.path.isabs(path):
        candidates = [path]
    else:
        candidates = [os.path.abspath(path)]
        folder = os.path.dirname(os.path.abspath(scene_path))
        while True:
            candidates.append(os.path.join(folder, path))
            parent = os.path.dirname(folder)
            if parent == folder:
                break
            folder = parent
    for candidate in candidates:
        if os.path.isfile(candidate):
            return candidate
    raise SceneError(f"OBJ file {path!r} not found; tried {candidates}")


def parse_scene(scene_path: str) -> Scene:
    scene = Scene(path=os.path.abspath(scene_path))
    with open(scene_path, encoding="utf-8") as f:
        lines = f.read().splitlines()
    for number, line in enumerate(lines, start=1):
        tokens = [t for t in _SEPARATORS.split(line) if t]
        if not tokens or tokens[0].startswith("#"):
            continue
        command, args = tokens[0], tokens[1:]
        pos = 0

        def word() -> str:
            nonlocal pos
            if pos >= len(args):
                raise SceneError(f"{scene_path}:{number}: missing token")
            pos += 1
            return args[pos - 1]

        def num() -> float:
            return float(word())

        def vec() -> tuple[float, float, float]:
            return (num(), num(), num())

        def material_ref() -> str:
            name = word()
            if name not in scene.materials:
                raise SceneError(f"{scene_path}:{number}: undefined material {name!r}")
            return name

        if command == "Material":
            name, kind = word(), word()
            colour = vec()
            scene.materials[name] = Material(name, kind, colour, num())
        elif command == "PointLight":
            scene.lights.append(PointLight(word(), vec(), vec()))
        elif command == "Plane":
            scene.planes.append(Plane(word(), vec(), vec(), material_ref()))
        elif command == "Sphere":
            scene.spheres.append(Sphere(word(), vec(), num(), material_ref()))
        elif command == "Triangle":
            scene.triangles.append(Triangle(word(), vec(), vec(), vec(), material_ref()))
        elif command == "ObjModel":
            name, path = word(), word()
            offset, scale = vec(), num()
            scene.objs.append(
                ObjModel(name, _resolve_obj(path, scene_path), offset, scale, material_ref())
            )
        else:
            raise SceneError(f"{scene_path}:{number}: unknown command {command!r}")
    return scene


def load_obj_triangles(model: ObjModel) -> np.ndarray:
    """The model's triangles in scene space, shape (n, 3, 3), float32.

    Polygons become fans; negative indices count from the end. The course's conversion from
    right-handed OBJ space: p = (s*x + ox, s*y + oy, -s*z + oz).
    """
    vertices: list[tuple[float, float, float]] = []
    faces: list[tuple[int, int, int]] = []
    with open(model.path, encoding="utf-8", errors="replace") as f:
        for line in f:
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append((float(parts[1]), float(parts[2]), float(parts[3])))
            elif parts[0] == "f":
                idx = []
                for p in parts[1:]:
                    i = int(p.split("/")[0])
                    idx.append(i - 1 if i > 0 else len(vertices) + i)
                for k in range(1, len(idx) - 1):
                    faces.append((idx[0], idx[k], idx[k + 1]))
    v = np.asarray(vertices, dtype=np.float64)
    s = model.scale
    ox, oy, oz = model.offset
    v = np.stack([s * v[:, 0] + ox, s * v[:, 1] + oy, -s * v[:, 2] + oz], axis=1)
    return v[np.asarray(faces, dtype=np.int64)].astype(np.float32)


def write_bunny_only_scene(scene: Scene, out_path: str) -> None:
    """A scene file with only the scene's OBJ models and their materials (no planes, spheres,
    triangles or lights), for closest-hit benchmarks on the mesh alone."""
    with open(out_path, "w", encoding="utf-8") as f:
        for name in dict.fromkeys(model.material for model in scene.objs):
            m = scene.materials[name]
            c = ", ".join(repr(x) for x in m.colour)
            f.write(f'Material "{m.name}" {m.kind} ({c}) {m.number!r}\n')
        for model in scene.objs:
            o = ", ".join(repr(x) for x in model.offset)
            f.write(f'ObjModel "{model.name}" "{model.path}" ({o}) {model.scale!r} "{model.material}"\n')
