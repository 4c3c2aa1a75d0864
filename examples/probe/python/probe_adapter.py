#!/usr/bin/env python3
"""Lets `rayscope probe` test the intersectors of a Python ray tracer.

    rayscope probe -f scene.txt -- python3 probe_adapter.py your_tracer.py

rayscope writes one JSON request per line to stdin and reads one JSON answer per line from
stdout. Edit the section below so that it builds *your* classes; nothing else needs changing.
Print any debugging output to stderr: stdout carries the answers.
"""
import importlib.util
import inspect
import json
import os
import sys
from types import SimpleNamespace

here = os.path.dirname(os.path.abspath(__file__))
path = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "example_tracer.py")
spec = importlib.util.spec_from_file_location("tracer", path)
tracer = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tracer)

# ---- connect your tracer here -----------------------------------------------------------------
def vec(a):
    return tracer.Vector3(*a)


def make_ray(origin, direction):
    return tracer.Ray(vec(origin), vec(direction))


def make_material():
    """A white diffuse material, since intersection code may read it (a hit often carries the
    material or its colour): your Material(MaterialType.Diffuse, Color(1, 1, 1)) where your module
    has those classes, as the course template does, else a stand-in with the same fields."""
    material, color = getattr(tracer, "Material", None), getattr(tracer, "Color", None)
    kinds = getattr(material, "MaterialType", None) or getattr(tracer, "MaterialType", None)
    diffuse = next((getattr(kinds, n) for n in ("Diffuse", "DIFFUSE", "diffuse") if hasattr(kinds, n)), None)
    if material is not None and color is not None and diffuse is not None:
        return material(diffuse, color(1.0, 1.0, 1.0))
    white = SimpleNamespace(r=1.0, g=1.0, b=1.0)
    return SimpleNamespace(type="Diffuse", color=white, refractive_index=1.0)


MATERIAL = make_material()


def build(cls, *geometry):
    """cls(*geometry, material) when its constructor takes a material after the geometry, as the
    course template's do, else cls(*geometry)."""
    try:
        inspect.signature(cls).bind(*geometry, MATERIAL)
    except (TypeError, ValueError):
        return cls(*geometry)
    return cls(*geometry, MATERIAL)


def make_primitive(p):
    if p["kind"] == "sphere":
        return build(tracer.Sphere, vec(p["center"]), p["radius"])
    if p["kind"] == "plane":
        return build(tracer.Plane, vec(p["point"]), vec(p["normal"]))
    return build(tracer.Triangle, *[vec(v) for v in p["vertices"]])


def answer(hit):
    """Your intersect()'s result as the protocol's hit: None for a miss."""
    if hit is None:
        return None
    p, n = hit.position, hit.normal
    return {"point": [p.x, p.y, p.z], "normal": [n.x, n.y, n.z]}
# -----------------------------------------------------------------------------------------------

for line in sys.stdin:
    request = json.loads(line)
    if "hello" in request:
        reply = {"ready": True}
    else:
        try:
            ray = make_ray(request["ray"]["origin"], request["ray"]["direction"])
            reply = {"id": request["id"], "hit": answer(make_primitive(request["primitive"]).intersect(ray))}
        except Exception as e:  # a crash on one ray is a finding, not the end of the run
            reply = {"id": request["id"], "error": f"{type(e).__name__}: {e}"}
    print(json.dumps(reply), flush=True)
