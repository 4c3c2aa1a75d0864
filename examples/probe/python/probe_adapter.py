#!/usr/bin/env python3
"""Lets `rayscope probe` test the intersectors of a Python ray tracer.

    rayscope probe -f scene.txt -- python3 probe_adapter.py your_tracer.py

rayscope writes one JSON request per line to stdin and reads one JSON answer per line from
stdout. Edit the section below so that it builds *your* classes; nothing else needs changing.
Print any debugging output to stderr: stdout carries the answers.
"""
import importlib.util
import json
import os
import sys

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


def make_primitive(p):
    if p["kind"] == "sphere":
        return tracer.Sphere(vec(p["center"]), p["radius"])
    if p["kind"] == "plane":
        return tracer.Plane(vec(p["point"]), vec(p["normal"]))
    return tracer.Triangle(*[vec(v) for v in p["vertices"]])


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
