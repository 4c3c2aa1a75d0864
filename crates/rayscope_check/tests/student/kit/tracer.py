#!/usr/bin/env python3
"""A small student-style ray tracer (stage 2 of the course) with rayscope's kit,
kits/python/raylog.py, added as a student adds it: `import raylog` and the lines that call the
kit. Standard library only; run it with kits/python on PYTHONPATH. `--bug NAME` switches on one
mistake:

  shadow-no-offset   shadow rays start exactly on the surface
  reflect-no-2       the reflection formula without its factor 2: d - (d.n) n
  refraction-normal  leaving glass, the refraction uses the outward normal (not flipped)

Usage: tracer.py -f scene.txt [-w 400] [-h 400] [-x 1] [--bug NAME]
"""

import argparse
import math
import re
import sys

import raylog

EPS = 1e-5
MAX_DEPTH = 8
BUGS = ("none", "shadow-no-offset", "reflect-no-2", "refraction-normal")


def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    return mul(a, 1 / math.sqrt(dot(a, a)))


class Sphere:
    def __init__(self, c, r, material):
        self.c, self.r, self.material = c, r, material

    def intersect(self, o, d):
        oc = sub(o, self.c)
        b = dot(oc, d)
        disc = b * b - (dot(oc, oc) - self.r * self.r)
        if disc < 0:
            return None
        s = math.sqrt(disc)
        t = -b - s if -b - s > 0 else -b + s
        if t <= 0:
            return None
        p = add(o, mul(d, t))
        return t, p, normalize(sub(p, self.c))


class Plane:
    def __init__(self, p, n, material):
        self.p, self.n, self.material = p, normalize(n), material

    def intersect(self, o, d):
        den = dot(self.n, d)
        if den == 0:
            return None
        t = dot(sub(self.p, o), self.n) / den
        return (t, add(o, mul(d, t)), self.n) if t > 0 else None


class Triangle:
    def __init__(self, v0, v1, v2, material):
        self.v0, self.e1, self.e2, self.material = v0, sub(v1, v0), sub(v2, v0), material
        self.n = normalize(cross(self.e1, self.e2))

    def intersect(self, o, d):
        p = cross(d, self.e2)
        det = dot(self.e1, p)
        if abs(det) < 1e-12:
            return None
        s = sub(o, self.v0)
        u = dot(s, p) / det
        if u < 0 or u > 1:
            return None
        q = cross(s, self.e1)
        v = dot(d, q) / det
        if v < 0 or u + v > 1:
            return None
        t = dot(self.e2, q) / det
        return (t, add(o, mul(d, t)), self.n) if t > 0 else None


def load(path):
    materials, lights, entities = {}, [], []
    with open(path) as f:
        for line in f:
            t = [x for x in re.split(r'[\s,"()]+', line) if x]
            if not t or t[0].startswith("#"):
                continue
            num = lambda i: tuple(float(x) for x in t[i:i + 3])
            if t[0] == "Material":
                materials[t[1]] = (t[2], num(3), float(t[6]))
            elif t[0] == "PointLight":
                lights.append((num(2), num(5)))
            elif t[0] == "Plane":
                entities.append(Plane(num(2), num(5), materials[t[8]]))
            elif t[0] == "Sphere":
                entities.append(Sphere(num(2), float(t[5]), materials[t[6]]))
            elif t[0] == "Triangle":
                entities.append(Triangle(num(2), num(5), num(8), materials[t[11]]))
            else:
                sys.exit(f"{path}: unsupported command {t[0]}")
    return lights, entities


class Tracer:
    def __init__(self, lights, entities, bug):
        self.lights, self.entities, self.bug = lights, entities, bug

    def closest(self, o, d):
        best = None
        for e in self.entities:
            h = e.intersect(o, d)
            if h is not None and (best is None or h[0] < best[0][0]):
                best = (h, e)
        return best

    def trace(self, o, d, depth):
        found = self.closest(o, d)
        raylog.hit(o, d, found and found[0][1], found and found[0][2])
        if found is None:
            return raylog.color((0.0, 0.0, 0.0))
        return raylog.color(self.shade(o, d, found[0][1], found[0][2], found[1].material, depth))

    def shade(self, o, d, p, n, material, depth):
        kind, albedo, index = material
        front = dot(n, d) < 0
        nf = n if front else mul(n, -1)
        if kind == "Reflective":
            return (0.0, 0.0, 0.0) if depth >= MAX_DEPTH else self.trace(*self.reflect(d, p, nf), depth + 1)
        if kind == "Refractive":
            return (0.0, 0.0, 0.0) if depth >= MAX_DEPTH else self.glass(d, p, n, nf, front, index, depth)
        col = (0.0, 0.0, 0.0)
        for pos, light in self.lights:
            so = p if self.bug == "shadow-no-offset" else add(p, mul(nf, EPS))
            to = sub(pos, so)
            dist = math.sqrt(dot(to, to))
            ldir = mul(to, 1 / dist)
            b = self.closest(so, ldir)
            blocked = b is not None and b[0][0] < dist
            raylog.shadow(so, ldir, pos, blocked)
            if not blocked:
                k = max(0.0, dot(nf, ldir))
                col = add(col, (albedo[0] * light[0] * k, albedo[1] * light[1] * k, albedo[2] * light[2] * k))
        return col

    def reflect(self, d, p, nf):
        k = 1 if self.bug == "reflect-no-2" else 2
        ro, rd = add(p, mul(nf, EPS)), normalize(sub(d, mul(nf, k * dot(d, nf))))
        raylog.reflection(ro, rd)
        return ro, rd

    def glass(self, d, p, n, nf, front, index, depth):
        n1, n2 = (1.0, index) if front else (index, 1.0)
        nn = n if self.bug == "refraction-normal" else nf
        eta, cosi = n1 / n2, -dot(d, nn)
        k = 1 - eta * eta * (1 - cosi * cosi)
        refl = self.trace(*self.reflect(d, p, nf), depth + 1)
        if k < 0:
            return refl
        ci, ct = abs(cosi), math.sqrt(k)
        rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
        rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
        kr = 0.5 * (rs * rs + rp * rp)
        to, td = sub(p, mul(nn, EPS)), normalize(add(mul(d, eta), mul(nn, eta * cosi - ct)))
        raylog.refraction(to, td)
        return add(mul(refl, kr), mul(self.trace(to, td, depth + 1), 1 - kr))


def main():
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("-f", required=True)
    ap.add_argument("-w", type=int, default=400)
    ap.add_argument("-h", type=int, default=400)
    ap.add_argument("-x", type=int, default=1)
    ap.add_argument("--bug", default="none", choices=BUGS)
    args = ap.parse_args()
    w, h, n = args.w, args.h, args.x
    tracer = Tracer(*load(args.f), args.bug)
    half = math.tan(math.pi / 6)
    for y in range(h):
        for x in range(w):
            for j in range(n):
                for i in range(n):
                    u, v = (x + (i + 0.5) / n) / w, (y + (j + 0.5) / n) / h
                    d = normalize(((2 * u - 1) * half, (1 - 2 * v) * half * h / w, 1.0))
                    raylog.camera(x, y, j * n + i, (0.0, 0.0, 0.0), d)
                    tracer.trace((0.0, 0.0, 0.0), d, 0)


if __name__ == "__main__":
    main()
