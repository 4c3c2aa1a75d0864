"""Convert a course scene (course_scene.Scene) into a Mitsuba 3 scene dictionary.

Decisions (also listed in bench/README.md):
- Same world coordinates as rayscope. rayscope's camera looks along +z with +x to the right;
  Mitsuba's camera space has +x to the LEFT, so the sensor's to_world is look_at(0 -> +z, up +y)
  followed by scale(-1, 1, 1). Checked by rendering scenes/emissive.txt: red wall on the left.
- perspective sensor, fov 60 across x, hdrfilm W x H with a box filter (each sample lands in its
  own pixel, like rayscope's -x grid), independent sampler unless another is named; a thin lens
  (`thinlens`) where rayscope's `-r`/`-t` are given.
- Every non-dielectric BSDF is wrapped in `twosided`: rayscope shades both sides of every surface.
- Diffuse -> diffuse(reflectance = colour).
- Reflective -> conductor(material 'none'): a perfect mirror; the colour plays no part.
- Refractive -> dielectric(int_ior = index, ext_ior = 1). Beer's-law absorbance is dropped (the
  benchmark scenes have none).
- Glossy -> roughplastic(GGX, diffuse_reflectance = colour, int_ior 1.5,
  alpha = (1/(1 + max(n, 0)))^2), the closest Mitsuba BSDF to rayscope's coated Lambert.
- Emissive -> area emitter (radiance = colour) on a black diffuse surface. Mitsuba area emitters
  emit on the front side only (the side of (v1-v0)x(v2-v0)); rayscope's are two-sided. With
  two_sided_emitters, emissive triangles get a second, reversed copy 1e-4 behind them.
- Point lights -> point(intensity = colour). NOTE: photometrically not the course's light: the
  course has no inverse-square falloff (and its Lambert term has no 1/pi); the work done per ray
  is what is compared, not the image.
- Planes -> a rectangle scaled to 2*plane_size across, lying on the plane.
- Triangles -> one PLY mesh per material (flat shading, face normals), written to out_dir.
- OBJ models -> `obj` shape (smooth shading from its vn) with to_world =
  translate(offset) * scale(s, s, -s), the course's right-to-left-handed conversion.
"""

from __future__ import annotations

import os
import struct

import numpy as np

import course_scene as cs


def _rgb(c) -> dict:
    return {"type": "rgb", "value": [float(x) for x in c]}


def _bsdf(material: cs.Material) -> dict:
    kind = material.kind
    if kind == "Diffuse":
        inner = {"type": "diffuse", "reflectance": _rgb(material.colour)}
    elif kind == "Reflective":
        inner = {"type": "conductor", "material": "none"}
    elif kind == "Refractive":
        return {"type": "dielectric", "int_ior": float(material.number), "ext_ior": 1.0}
    elif kind == "Emissive":
        inner = {"type": "diffuse", "reflectance": _rgb((0.0, 0.0, 0.0))}
    elif kind == "Glossy":
        rho = 1.0 / (1.0 + max(material.number, 0.0))
        inner = {
            "type": "roughplastic",
            "distribution": "ggx",
            "alpha": max(rho * rho, 0.001),
            "int_ior": 1.5,
            "ext_ior": 1.0,
            "diffuse_reflectance": _rgb(material.colour),
        }
    else:
        raise cs.SceneError(f"material type {kind!r} not supported")
    return {"type": "twosided", "bsdf": inner}


def _attach(shape: dict, material: cs.Material) -> dict:
    shape["bsdf"] = _bsdf(material)
    if material.kind == "Emissive":
        shape["emitter"] = {"type": "area", "radiance": _rgb(material.colour)}
    return shape


def write_ply(path: str, triangles: np.ndarray) -> None:
    """Binary little-endian PLY, three unshared vertices per triangle (keeps flat faces)."""
    n = len(triangles)
    verts = np.ascontiguousarray(triangles.reshape(-1, 3), dtype="<f4")
    faces = np.empty(n, dtype=[("k", "u1"), ("i", "<i4", (3,))])
    faces["k"] = 3
    faces["i"] = np.arange(3 * n, dtype=np.int32).reshape(n, 3)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {3 * n}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {n}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(verts.tobytes())
        f.write(faces.tobytes())


def _plane_matrix(point, normal, size: float) -> list[list[float]]:
    n = np.asarray(normal, dtype=np.float64)
    n /= np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    t1 = np.cross(helper, n)
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(n, t1)  # t1 x t2 = n: the rectangle's +z normal maps onto n
    m = np.eye(4)
    m[:3, 0] = t1 * size
    m[:3, 1] = t2 * size
    m[:3, 2] = n
    m[:3, 3] = point
    return m.tolist()


def camera_dict(mi, width: int, height: int, spp: int, sampler: str = "independent", lens=None) -> dict:
    """The sensor; `lens` = (aperture radius, focus distance) makes it a thin lens, as rayscope's
    `-r` and `-t` (its plane of focus lies `-t` along the view axis)."""
    to_world = (
        mi.ScalarTransform4f()
        .look_at(origin=[0, 0, 0], target=[0, 0, 1], up=[0, 1, 0])
        .scale([-1, 1, 1])
    )
    d = {
        "type": "perspective" if lens is None else "thinlens",
        "fov": 60.0,
        "fov_axis": "x",
        "near_clip": 1e-4,
        "far_clip": 1e5,
        "to_world": to_world,
        "film": {
            "type": "hdrfilm",
            "width": width,
            "height": height,
            "rfilter": {"type": "box"},
            "pixel_format": "rgb",
        },
        "sampler": {"type": sampler, "sample_count": spp},
    }
    if lens is not None:
        d["aperture_radius"], d["focus_distance"] = float(lens[0]), float(lens[1])
    return d


def to_mitsuba(
    mi,
    scene: cs.Scene,
    out_dir: str,
    tag: str,
    integrator: dict,
    width: int = 400,
    height: int = 400,
    spp: int = 16,
    plane_size: float = 1000.0,
    two_sided_emitters: bool = False,
    sampler: str = "independent",
    lens=None,
) -> dict:
    os.makedirs(out_dir, exist_ok=True)
    sensor = camera_dict(mi, width, height, spp, sampler, lens)
    d: dict = {"type": "scene", "integrator": integrator, "sensor": sensor}
    T = mi.ScalarTransform4f
    for i, light in enumerate(scene.lights):
        d[f"light_{i}"] = {
            "type": "point",
            "position": [float(x) for x in light.position],
            "intensity": _rgb(light.colour),
        }
    for i, plane in enumerate(scene.planes):
        shape = {"type": "rectangle", "to_world": T(_plane_matrix(plane.point, plane.normal, plane_size))}
        d[f"plane_{i}"] = _attach(shape, scene.materials[plane.material])
    for i, sphere in enumerate(scene.spheres):
        shape = {"type": "sphere", "center": [float(x) for x in sphere.centre], "radius": float(sphere.radius)}
        d[f"sphere_{i}"] = _attach(shape, scene.materials[sphere.material])
    by_material: dict[str, list] = {}
    for tri in scene.triangles:
        by_material.setdefault(tri.material, []).append((tri.v0, tri.v1, tri.v2))
    for i, (name, tris) in enumerate(by_material.items()):
        material = scene.materials[name]
        arr = np.asarray(tris, dtype=np.float32)
        sides = [arr]
        if material.kind == "Emissive" and two_sided_emitters:
            # Reversed winding emits on the other side. Lifted by 1e-4 along its own normal so
            # that the two copies never tie: each side's rays meet the copy facing them first.
            back = arr[:, ::-1, :].astype(np.float64)
            nrm = np.cross(back[:, 1] - back[:, 0], back[:, 2] - back[:, 0])
            nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            sides.append((back + 1e-4 * nrm[:, None, :]).astype(np.float32))
        for k, side in enumerate(sides):
            ply = os.path.join(out_dir, f"{tag}_mesh{i}_{k}.ply")
            write_ply(ply, side)
            shape = {"type": "ply", "filename": ply, "face_normals": True}
            d[f"mesh_{i}_{k}"] = _attach(shape, material)
    for i, model in enumerate(scene.objs):
        s = float(model.scale)
        to_world = T().translate([float(x) for x in model.offset]).scale([s, s, -s])
        shape = {"type": "obj", "filename": model.path, "to_world": to_world}
        d[f"obj_{i}"] = _attach(shape, scene.materials[model.material])
    return d
