#!/usr/bin/env python3
"""A small student-style Whitted ray tracer for the course's scene format, for rayscope's
`check` tests. Standard library only.

It renders stage 2 as the course describes it (point lights with shadow rays, mirrors, Fresnel
glass with total internal reflection, an N x N sub-pixel grid) and logs every ray it casts in
rayscope's JSON Lines format. `--bug NAME` switches on one realistic mistake:

  refraction-normal  refraction never flips the normal when the ray leaves glass
  shadow-no-offset   shadow rays start exactly on the surface (no offset)
  vertical-fov       the 60 degrees span the image height instead of its width
  fov-degrees        the half angle in degrees given to tan, which takes radians: tan(30) (no catalogue has it)
  fov-not-halved     the tangent of the whole field of view, tan(60 degrees), not of its half
  one-sided          triangles are one-sided (back faces culled)
  aspect             the aspect ratio is applied the wrong way round
  no-tir             refraction without total internal reflection
  pixel-corner       rays through pixel corners instead of centres
  plane-distance     the image plane at z = 2 with the half-width of the plane at z = 1
  aa-column-major    sub-pixel samples numbered column by column (i * N + j): the same picture
  aa-one-cell        every one of a pixel's N x N samples cast through the centre of its first cell
  aa-same-ray        every one of a pixel's N x N samples cast through the pixel's centre
  aa-same-corner     every one of a pixel's N x N samples cast through the pixel's corner
  aa-evenly-spaced   sub-pixel samples at (i + 1) / (N + 1), evenly spaced with gaps at the edges
  aa-reversed        sub-pixel samples numbered from the last cell to the first: the same picture
  pixel-transposed   the image-plane x computed from the row and y from the column
  aa-half-twice      sub-pixel samples at x + i / N + 0.5: the half pixel on top of the cell's corner
  sphere-disc-no-4   sphere quadratic with b = 2 oc.d whose discriminant is b^2 - c, not b^2 - 4c
  shadow-first-light every light's shadow ray cast towards the first light
  shade-normal-radius  N.L on a sphere taken with P - C, not divided by the radius (the logged normal is right)
  shadow-t-dist-squared  the shadow test blocks at t < |light - point|^2, not t < |light - point|
  plane-abs-den      plane test dividing by |n.d|, so t is negative wherever the ray meets the plane's front
  indices-not-swapped n1 = 1 and n2 = index on both sides of the glass (never swapped)
  tir-entering       the critical-angle test applied when entering glass as well
  blocker-name       shadow rays name the surface being shaded as their blocker
  mirror-as-glass    Reflective materials fall through into the glass branch
  reflect-no-2       the reflection formula without its factor 2: d - (d.n) n
  sphere-normal-unnormalised  the sphere normal is point - centre, not divided by the radius
  eta-inverted       eta = n2 / n1 instead of n1 / n2 on both sides of the glass
  near-root-inside   the sphere test returns the near root whenever the far one is ahead,
                     even when the near one is behind the origin (rays starting inside)
  strict-edges       the triangle's inside test rejects hits within 0.02 of an edge
  radius-not-squared the sphere test compares |o - c|^2 with r, not r^2 (no catalogue has it)
  plane-behind       the shadow test's plane intersection accepts t < 0: planes behind the point
                     block the light
  blocked-not-reset  the shadow loop's blocker is set for one light and never reset for the next
                     (no catalogue has it)
  shadow-t-below-1   the shadow test counts blockers at t < 1 instead of t < distance to the light
                     (no catalogue has it)
  parallelogram      the triangle's inside test checks v > 1 instead of u + v > 1: hits past the
                     third edge count (no catalogue has it)
  fresnel-indices-swapped  the Fresnel reflectance computed with n1 and n2 exchanged (Snell's law
                     right) (no catalogue has it)
  shadow-unnormalised the shadow test is given light - point unnormalised, so its spheres' t is
                     off (it logs the normalised direction; no catalogue has it)
  camera-unnormalised camera rays' directions are not normalised, and the sphere test takes a = 1
                     (no catalogue has it)
  light-as-direction the shadow ray's direction is the light's position, normalised: light - point
                     without the point, which N.L uses too (no catalogue has it)
  min-distance       every intersection test ignores hits nearer than t = 0.05
  first-in-list      the nearest-hit loop keeps the first entity hit in the scene's order
  origin-distance    the nearest-hit loop keeps the hit whose point is nearest (0, 0, 0)
  farthest-hit       the nearest-hit loop keeps the farthest hit (no catalogue has it)
  best-t-stale       the nearest-hit loop never updates the nearest t, so the last entity hit wins
  reflect-along-ray  glass's reflected ray starts at p + EPS * d, along the incident ray
  refraction-origin-outside  glass's refracted ray starts at p + EPS * n, on the incoming side
  gamma-out, rounded-out, unclamped-out, byte-average-out, flipped-out, bgr-out, mirrored-out, rotated-out
                     the picture (--image) gamma-corrected, rounded, not clamped (bytes wrap),
                     samples averaged as bytes, rows upside down, red and blue swapped,
                     columns right to left, rows and columns both reversed
  flipped-gamma-out  the picture both upside down and gamma-corrected (two mistakes at once)
  sqrt-out           the picture's colours square-rooted before they are written (no rule has it)
  mirror-glass-black mirrors and glass bring back black and cast no ray (not written yet)
  no-refraction-ray  glass casts its reflected ray, weighted by kr, and never the refracted one
  sphere-no-far-root the sphere test gives up when the near root is behind the origin, so rays
                     inside a sphere never meet it (no catalogue has it)
  skip-own-entity    reflected and refracted rays skip the entity they leave (no catalogue has it)
  light-twice        a diffuse hit multiplies by each light's colour twice (no catalogue has it)
  light-overwrite    each lit light's term replaces the diffuse sum (sum = instead of +=)
  n-dot-view         N.V, the cosine toward the ray's origin, in place of N.L (no catalogue has it)
  times-256-out      the picture's bytes are min(v * 256, 255), truncated, not min(v, 1) * 255
  stale-image        the picture is not made of the logged colours (no catalogue has it)
  stray-pixels-out   one pixel in 97 holds the colour of the pixel written just before it, as a
                     colour shared by a parallel loop's threads leaves it (no catalogue has it)
  accumulator-out    the picture's per-pixel sum of samples is never reset between pixels
  summed-out         the picture's pixels are the sums of their samples, never divided
  last-sample-out    each pixel written inside the sample loop: the last sample's colour alone
  row-accumulator-out  the sum of samples set to black once a row, not once a pixel
  aa-divided-by-n    the picture's pixels are the sums of their N x N samples divided by N, not N^2
  no-fresnel         glass brings back its refracted colour only (kr = 0, still casting the reflection)
  fresnel-swapped    rp written with cos(theta_i) and cos(theta_t) exchanged (kr comes out as rs^2)
  schlick            Schlick's approximation with cos(theta_i) instead of the Fresnel equations
  fresnel-half       glass mixes reflection and refraction half and half
  fresnel-weights-exchanged  glass mixes (1 - kr) R + kr T: the reflectance given to the refracted colour
  glass-sum          glass adds its reflected and refracted colours, R + T, with no weights (no catalogue has it)
  glass-t-unweighted glass brings back kr R + T: the refracted colour not weighted by 1 - kr (no catalogue has it)
  logged-weighted    the picture is right, but the log holds each reflected and refracted ray's colour after
                     its parent glass weighted it (kr R, (1 - kr) T) (no catalogue has it)
  no-clamp           N.L not clamped at 0, and the shadow test skips the surface being shaded
  falloff            each light divided by its squared distance
  ambient            an ambient term of 0.1 x albedo added to every diffuse hit
  skip-shadow-ray    the loop over lights stops before the last one (no shadow ray to it)
  shadow-loop-break  the loop over the lights stops at the first blocked light (break for continue)
  no-reflection-ray  glass casts no reflected ray and drops the reflected share
  cos-twice          the diffuse term multiplied by N.L twice
  l-unnormalised     N.L taken with L = light - point not normalised (no catalogue has it)
  l-from-origin      N.L with L = the light's position normalised, the hit point left out (no catalogue has it)
  refract-cos-sign   the refraction formula given cos(theta_i) = d.n, its sign not turned (no catalogue has it)
  refract-eta-not-squared  cos(theta_t) = sqrt(1 - eta (1 - cos^2)), eta not squared (no catalogue has it)
  refract-no-sqrt    the refraction formula without its square root (no catalogue has it)
  refract-unnormalised-d  camera rays' directions not normalised, every test right for any length
                     but the refraction formula, which needs a unit one (no catalogue has it)
  normal-toward-camera  the normal flipped to face the camera, not the ray (no catalogue has it)
  depth-4            the recursion stops after 4 bounces instead of 8
  limit-colour       a mirror or glass hit at the depth limit returns its material colour, not black
  mirror-tint        a mirror multiplies what it reflects by its material colour
  mirror-dim         a mirror brings back 0.8 of what it reflects (no catalogue has it)
  glass-tint         glass multiplies its Fresnel mix by its material colour
  background         a ray that hits nothing brings back a grey background
  light-colour-ignored  each light taken as white: albedo x N.L (no catalogue has it)
  lights-averaged    the diffuse sum over the lights divided by their number (no catalogue has it)

Every ray but shadow rays logs "color", the linear colour it brought back (--no-colors: none).

Usage: tracer.py -f scene.txt -w 40 -h 30 [-x 2] [--region x0,y0,x1,y1] [--bug NAME]
       [--log rays.jsonl] [--log-samples 0,3] [--log-kinds camera] [--image out.ppm] [--no-colors]
       [--eps 1e-5] [--aim-from-hit]

--eps sets the offset of secondary and shadow rays' origins off the surface; --aim-from-hit aims
shadow rays from the hit point rather than from the offset origin. Neither is a mistake.
"""

import argparse
import json
import math
import re
import sys

EPS = 1e-5
MAX_DEPTH = 8
AMBIENT = 0.1
BUGS = ("none", "refraction-normal", "shadow-no-offset", "vertical-fov", "fov-degrees", "fov-not-halved", "one-sided", "aspect", "no-tir",
        "pixel-corner", "plane-distance", "aa-column-major", "aa-one-cell", "aa-same-ray", "aa-same-corner", "aa-evenly-spaced", "aa-reversed", "aa-half-twice", "pixel-transposed", "indices-not-swapped", "tir-entering",
        "blocker-name", "mirror-as-glass", "no-fresnel", "fresnel-swapped", "schlick", "fresnel-half", "fresnel-weights-exchanged", "l-unnormalised", "l-from-origin", "refract-cos-sign", "refract-unnormalised-d", "refract-eta-not-squared", "refract-no-sqrt", "normal-toward-camera", "mirror-dim",
        "glass-sum", "glass-t-unweighted", "shadow-loop-break", "logged-weighted",
        "no-clamp", "falloff", "ambient", "light-colour-ignored", "lights-averaged", "skip-shadow-ray", "no-reflection-ray", "cos-twice", "depth-4",
        "limit-colour", "mirror-tint", "glass-tint", "background", "reflect-along-ray", "refraction-origin-outside",
        "mirror-glass-black", "no-refraction-ray", "sphere-no-far-root", "skip-own-entity", "light-twice",
        "light-overwrite", "n-dot-view")
# Mistakes in how rays meet surfaces and leave them.
# Mistakes in turning colours into the picture's bytes (--image).
OUTPUT_BUGS = ("gamma-out", "rounded-out", "unclamped-out", "byte-average-out", "flipped-out", "bgr-out",
               "stale-image", "accumulator-out", "summed-out", "last-sample-out", "row-accumulator-out", "aa-divided-by-n", "mirrored-out", "rotated-out",
               "flipped-gamma-out", "stray-pixels-out", "sqrt-out", "times-256-out")
GEOMETRY_BUGS = ("shadow-unnormalised", "plane-behind", "reflect-no-2", "sphere-normal-unnormalised", "eta-inverted", "near-root-inside",
                 "strict-edges", "radius-not-squared", "camera-unnormalised", "light-as-direction", "min-distance", "first-in-list", "origin-distance",
                 "farthest-hit", "best-t-stale", "sphere-disc-no-4", "plane-abs-den", "shadow-first-light", "shadow-t-dist-squared", "shade-normal-radius", "blocked-not-reset", "shadow-t-below-1", "parallelogram", "fresnel-indices-swapped")


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
    n = math.sqrt(dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n)


def hadamard(a, b):
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


class Entity:
    def __init__(self, name, kind, material, **geo):
        self.name = name
        self.kind = kind
        self.material = material
        self.__dict__.update(geo)


def load_scene(path):
    materials, lights, entities = {}, [], []
    with open(path) as f:
        for line in f:
            tok = [t for t in re.split(r'[\s,"()]+', line) if t]
            if not tok or tok[0].startswith("#"):
                continue
            cmd, a = tok[0], tok[1:]
            num = lambda i, n: tuple(float(x) for x in a[i:i + n])
            if cmd == "Material":
                materials[a[0]] = {"type": a[1], "color": num(2, 3), "value": float(a[5])}
            elif cmd == "PointLight":
                lights.append({"name": a[0], "pos": num(1, 3), "color": num(4, 3)})
            elif cmd == "Plane":
                entities.append(Entity(a[0], "plane", materials[a[7]], p=num(1, 3), n=normalize(num(4, 3))))
            elif cmd == "Sphere":
                entities.append(Entity(a[0], "sphere", materials[a[5]], c=num(1, 3), r=float(a[4])))
            elif cmd == "Triangle":
                v0, v1, v2 = num(1, 3), num(4, 3), num(7, 3)
                e1, e2 = sub(v1, v0), sub(v2, v0)
                entities.append(Entity(a[0], "triangle", materials[a[10]], v0=v0, e1=e1, e2=e2,
                                       n=normalize(cross(e1, e2))))
            else:
                sys.exit(f"{path}: unsupported command {cmd}")
    return materials, lights, entities


class Tracer:
    def __init__(self, scene, args, log):
        self.materials, self.lights, self.entities = scene
        self.bug = args.bug
        self.log = log
        self.colors = args.colors
        # A tracer shaped like the course's template knows no names and no t: hits are logged by
        # point and normal, lights by position, blockers only as blocked.
        self.names = args.names
        # The current sample's records: a ray's colour is known only once its children are traced.
        self.pending = []
        # Shadow rays aimed from the hit point, before the origin is offset (--aim-from-hit).
        self.aim_from_hit = args.aim_from_hit
        # The sample numbers logged (--log-samples), as the logging kit's RAYSCOPE_LOG_SAMPLES.
        self.samples = None if args.log_samples is None else {int(k) for k in args.log_samples.split(",")}
        # The kinds of ray logged (--log-kinds): a tracer that logs its camera rays alone.
        self.kinds = None if args.log_kinds is None else set(args.log_kinds.split(","))
        self.next_id = 0
        self.pixel = (0, 0)
        self.sample = 0

    # --- intersection -------------------------------------------------------------------
    def intersect(self, e, o, d):
        """Nearest t > 0 (or > 0.05 with min-distance) of the ray with entity e, or None."""
        t = self.intersect_any(e, o, d)
        if t is not None and self.bug == "min-distance" and t <= 0.05:
            return self.intersect_any(e, add(o, mul(d, 0.05)), d, 0.05)
        return t

    def intersect_any(self, e, o, d, already=0.0):
        """Nearest t > 0 of the ray with entity e (plus `already`), or None."""
        t = self.intersect_from(e, o, d)
        return None if t is None else t + already

    def intersect_from(self, e, o, d):
        if e.kind == "plane":
            den = dot(e.n, d)
            if self.bug == "plane-abs-den":
                den = abs(den)
            if den == 0:
                return None
            t = dot(sub(e.p, o), e.n) / den
            return t if t > 0 else None
        if e.kind == "sphere" and self.bug == "refract-unnormalised-d":
            # The general quadratic, right for a direction of any length.
            oc = sub(o, e.c)
            a, b, c = dot(d, d), dot(oc, d), dot(oc, oc) - e.r * e.r
            disc = b * b - a * c
            if disc < 0:
                return None
            ts = [(-b - math.sqrt(disc)) / a, (-b + math.sqrt(disc)) / a]
            return next((t for t in ts if t > 0), None)
        if e.kind == "sphere":
            oc = sub(o, e.c)
            b = dot(oc, d)
            c = dot(oc, oc) - (e.r if self.bug == "radius-not-squared" else e.r * e.r)
            disc = b * b - c
            if self.bug == "sphere-disc-no-4":
                # The full quadratic's b is 2 oc.d; its discriminant lost the 4 of 4ac.
                disc = ((2 * b) ** 2 - c) / 4
            if disc < 0:
                return None
            s = math.sqrt(disc)
            if self.bug == "near-root-inside" and -b + s > 0:
                return -b - s
            if self.bug == "sphere-no-far-root":
                return -b - s if -b - s > 0 else None
            for t in (-b - s, -b + s):
                if t > 0:
                    return t
            return None
        # Moller-Trumbore; det > 0 on the front face.
        p = cross(d, e.e2)
        det = dot(e.e1, p)
        if self.bug == "one-sided":
            if det < 1e-12:
                return None
        elif abs(det) < 1e-12:
            return None
        inv = 1.0 / det
        s = sub(o, e.v0)
        u = dot(s, p) * inv
        m = 0.02 if self.bug == "strict-edges" else 0.0
        if u < m or u > 1 - m:
            return None
        q = cross(s, e.e1)
        v = dot(d, q) * inv
        if v < m or (v if self.bug == "parallelogram" else u + v) > 1 - m:
            return None
        t = dot(e.e2, q) * inv
        return t if t > 0 else None

    def closest(self, o, d, skip=None):
        best = None
        for e in self.entities:
            if e is skip:
                continue
            t = self.intersect(e, o, d)
            if t is None:
                continue
            if best is None:
                best = (t, e)
            elif self.bug == "first-in-list":
                pass
            elif self.bug == "best-t-stale":
                best = (t, e)
            elif self.bug == "origin-distance":
                if dot(add(o, mul(d, t)), add(o, mul(d, t))) < dot(add(o, mul(d, best[0])), add(o, mul(d, best[0]))):
                    best = (t, e)
            elif self.bug == "farthest-hit":
                if t > best[0]:
                    best = (t, e)
            elif t < best[0]:
                best = (t, e)
        return best

    def blocker(self, o, d, dist, skip=None):
        for e in self.entities:
            if e is skip:
                continue
            t = self.intersect(e, o, d)
            if self.bug == "plane-behind" and e.kind == "plane" and dot(e.n, d) != 0:
                # The plane test without its t > 0 check: planes behind the point block too.
                t = dot(sub(e.p, o), e.n) / dot(e.n, d)
                t = t if abs(t) > 1e-9 else None
            if t is not None and t < dist:
                return e
        return None

    def normal(self, e, p):
        if e.kind == "sphere":
            if self.bug == "sphere-normal-unnormalised":
                return sub(p, e.c)
            return normalize(sub(p, e.c))
        return e.n

    # --- logging ------------------------------------------------------------------------
    def new_id(self):
        self.next_id += 1
        return self.next_id

    def emit(self, rec):
        if self.log and not self.names:
            if rec.get("hit"):
                rec["hit"].pop("entity")
                rec["hit"].pop("t")
            if "light" in rec:
                rec["light"] = list(next(l["pos"] for l in self.lights if l["name"] == rec["light"]))
                rec["blocked_by"] = True if rec["blocked_by"] else None
        if self.log:
            rec["pixel"] = list(self.pixel)
            rec["sample"] = self.sample
            self.pending.append(rec)

    def flush(self):
        if self.samples is None or self.sample in self.samples:
            for rec in self.pending:
                if self.kinds is None or rec["kind"] in self.kinds:
                    self.log.write(json.dumps(rec) + "\n")
        self.pending = []

    def colored(self, rec, col):
        if self.colors:
            rec["color"] = list(col)
        return col

    # --- shading ------------------------------------------------------------------------
    def trace(self, o, d, depth, parent, kind, leaving=None):
        rid = self.new_id()
        h = self.closest(o, d, leaving if self.bug == "skip-own-entity" else None)
        rec = {"id": rid, "parent": parent, "kind": kind, "origin": list(o), "direction": list(d)}
        if h is None:
            rec["hit"] = None
            self.emit(rec)
            return self.colored(rec, (0.2, 0.2, 0.2) if self.bug == "background" else (0.0, 0.0, 0.0))
        t, e = h
        p = add(o, mul(d, t))
        n = self.normal(e, p)
        front = dot(n, d) < 0
        nf = n if front else mul(n, -1)
        rec["hit"] = {"t": t, "point": list(p), "normal": list(nf), "entity": e.name}
        self.emit(rec)
        if self.bug == "normal-toward-camera":
            # Shaded with the normal flipped to face the camera at the origin rather than the
            # ray (the one logged faces the ray): inside glass it faces out.
            nf = n if dot(n, mul(p, -1)) > 0 else mul(n, -1)
        m = e.material
        if m["type"] in ("Diffuse", "Emissive", "Glossy"):
            self.incoming = d
            return self.colored(rec, self.diffuse(p, nf, m, rid, e))
        if depth >= (4 if self.bug == "depth-4" else MAX_DEPTH):
            return self.colored(rec, m["color"] if self.bug == "limit-colour" else (0.0, 0.0, 0.0))
        if self.bug == "mirror-glass-black":
            return self.colored(rec, (0.0, 0.0, 0.0))
        if m["type"] == "Reflective" and self.bug != "mirror-as-glass":
            r = normalize(sub(d, mul(nf, (1 if self.bug == "reflect-no-2" else 2) * dot(d, nf))))
            col = self.trace(add(p, mul(nf, EPS)), r, depth + 1, rid, "reflection", e)
            if self.bug == "mirror-dim":
                col = mul(col, 0.8)
            return self.colored(rec, hadamard(col, m["color"]) if self.bug == "mirror-tint" else col)
        g = self.glass(d, p, n, nf, front, m, depth, rid, e)
        if self.bug == "glass-tint":
            g = hadamard(g, m["color"])
        return self.colored(rec, g)

    def diffuse(self, p, nf, m, rid, shaded):
        col = (0.0, 0.0, 0.0)
        lights = self.lights[:-1] if self.bug == "skip-shadow-ray" else self.lights
        b = None
        for light in lights:
            so = p if self.bug == "shadow-no-offset" else add(p, mul(nf, EPS))
            aim = self.lights[0]["pos"] if self.bug == "shadow-first-light" else light["pos"]
            to = aim if self.bug == "light-as-direction" else sub(aim, p if self.aim_from_hit else so)
            dist = math.sqrt(dot(to, to))
            ldir = mul(to, 1 / dist)
            reach = min(dist, 1.0) if self.bug == "shadow-t-below-1" else dist * dist if self.bug == "shadow-t-dist-squared" else dist
            found = self.blocker(so, to if self.bug == "shadow-unnormalised" else ldir, reach, shaded if self.bug == "no-clamp" else None)
            b = (found or b) if self.bug == "blocked-not-reset" else found
            self.emit({"id": self.new_id(), "parent": rid, "kind": "shadow", "origin": list(so),
                       "direction": list(ldir), "light": light["name"],
                       "blocked_by": (shaded.name if self.bug == "blocker-name" else b.name) if b else None})
            if b is not None and self.bug == "shadow-loop-break":
                break
            if b is None:
                ns = mul(nf, shaded.r) if self.bug == "shade-normal-radius" and shaded.kind == "sphere" else nf
                lshade = normalize(light["pos"]) if self.bug == "l-from-origin" else to if self.bug == "l-unnormalised" else ldir
                cos = dot(ns, ldir) if self.bug == "no-clamp" else max(0.0, dot(ns, lshade))
                if self.bug == "n-dot-view":
                    cos = max(0.0, -dot(ns, self.incoming))
                if self.bug == "cos-twice":
                    cos *= cos
                if self.bug == "falloff":
                    cos /= dist * dist
                lc = (1.0, 1.0, 1.0) if self.bug == "light-colour-ignored" else light["color"]
                if self.bug == "light-twice":
                    lc = hadamard(lc, light["color"])
                term = mul(hadamard(m["color"], lc), cos)
                col = term if self.bug == "light-overwrite" else add(col, term)
        if self.bug == "lights-averaged":
            col = mul(col, 1 / len(self.lights))
        if self.bug == "ambient":
            col = add(col, mul(m["color"], AMBIENT))
        return col

    def glass(self, d, p, n, nf, front, m, depth, rid, e):
        ior = m["value"] if m["type"] == "Refractive" else 1.5
        n1, n2 = (1.0, ior) if front or self.bug == "indices-not-swapped" else (ior, 1.0)
        if self.bug == "eta-inverted":
            n1, n2 = n2, n1
        nn = n if self.bug == "refraction-normal" else nf
        eta = n1 / n2
        cosi = -dot(d, nn)
        k = 1 - eta * eta * (1 - cosi * cosi)
        # Fresnel (unpolarised) with the facing normal's cosine.
        ci = abs(cosi)
        if k < 0:
            kr = 1.0
        elif self.bug == "no-fresnel":
            kr = 0.0
        elif self.bug == "fresnel-half":
            kr = 0.5
        elif self.bug == "schlick":
            r0 = ((n1 - n2) / (n1 + n2)) ** 2
            kr = r0 + (1 - r0) * (1 - ci) ** 5
        elif self.bug == "fresnel-indices-swapped":
            # The reflectance of the other side: n1 and n2 exchanged, and cos(theta_t) with them.
            k2 = 1 - (n2 / n1) ** 2 * (1 - ci * ci)
            if k2 < 0:
                kr = 1.0
            else:
                ct = math.sqrt(k2)
                rs = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
                rp = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
                kr = 0.5 * (rs * rs + rp * rp)
        else:
            ct = math.sqrt(k)
            rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
            if self.bug == "fresnel-swapped":
                rp = (n2 * ct - n1 * ci) / (n2 * ct + n1 * ci)
            else:
                rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
            kr = 0.5 * (rs * rs + rp * rp)
            if self.bug == "fresnel-weights-exchanged":
                kr = 1 - kr
        if self.bug == "glass-sum":
            kr = 1.0
        r = normalize(sub(d, mul(nf, 2 * dot(d, nf))))
        if self.bug == "no-reflection-ray":
            col = (0.0, 0.0, 0.0)
        else:
            ro = add(p, mul(d, EPS)) if self.bug == "reflect-along-ray" else add(p, mul(nf, EPS))
            col = self.weighted(lambda: self.trace(ro, r, depth + 1, rid, "reflection", e), kr)
        if k < 0 and self.bug != "no-tir":
            return col
        if self.bug == "no-refraction-ray":
            return col
        if self.bug == "tir-entering" and 1 - cosi * cosi > 1 / (ior * ior):
            return col
        k = max(k, 0.0)
        if self.bug == "refract-cos-sign":
            # cos θi taken as d·n: the sign not turned for a normal facing the ray.
            c = dot(d, nn)
            k = max(1 - eta * eta * (1 - c * c), 0.0)
            tdir = normalize(add(mul(d, eta), mul(nn, eta * c - math.sqrt(k))))
        elif self.bug == "refract-eta-not-squared":
            tdir = normalize(add(mul(d, eta), mul(nn, eta * cosi - math.sqrt(max(1 - eta * (1 - cosi * cosi), 0.0)))))
        elif self.bug == "refract-no-sqrt":
            tdir = normalize(add(mul(d, eta), mul(nn, eta * cosi - k)))
        else:
            tdir = normalize(add(mul(d, eta), mul(nn, eta * cosi - math.sqrt(k))))
        ro = add(p, mul(nn, EPS)) if self.bug == "refraction-origin-outside" else sub(p, mul(nn, EPS))
        sub_col = self.weighted(lambda: self.trace(ro, tdir, depth + 1, rid, "refraction", e), 1.0 if self.bug in ("glass-sum", "glass-t-unweighted") else 1 - kr)
        return add(col, sub_col)

    def weighted(self, trace, w):
        """What a glass child brings back times its share `w`; under logged-weighted the child's logged
        colour is the weighted one."""
        first = len(self.pending)
        col = mul(trace(), w)
        if self.bug == "logged-weighted" and self.log and self.colors and len(self.pending) > first:
            self.pending[first]["color"] = list(col)
        return col


def to_byte(v):
    """The course's conversion: clamp to [0, 1], then truncate v * 255."""
    return int(min(max(v, 0.0), 1.0) * 255)


def out_pixel(c, bug):
    if bug == "bgr-out":
        return (c[2], c[1], c[0])
    if bug == "stale-image":
        # The picture of an older run: every colour a little darker and greyer than the one logged.
        return tuple(v * 0.9 + 0.03 for v in c)
    return c


def out_byte(v, bug):
    if bug == "byte-average-out":
        return v
    if bug in ("gamma-out", "flipped-gamma-out"):
        return to_byte(max(v, 0.0) ** (1 / 2.2))
    if bug == "sqrt-out":
        return to_byte(math.sqrt(max(v, 0.0)))
    if bug == "rounded-out":
        return int(round(min(max(v, 0.0), 1.0) * 255))
    if bug == "times-256-out":
        return int(min(max(v, 0.0) * 256, 255))
    if bug == "unclamped-out":
        return int(max(v, 0.0) * 255) % 256
    return to_byte(v)


def main():
    global EPS
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("-f", required=True)
    ap.add_argument("-w", type=int, default=400)
    ap.add_argument("-h", type=int, default=400)
    ap.add_argument("-x", type=int, default=1)
    ap.add_argument("--region", default=None)
    ap.add_argument("--log-samples", default=None)
    ap.add_argument("--log-kinds", default=None)
    ap.add_argument("--eps", type=float, default=1e-5)
    ap.add_argument("--aim-from-hit", action="store_true")
    ap.add_argument("--bug", default="none")
    ap.add_argument("--log", default="-")
    ap.add_argument("--image", default=None)
    ap.add_argument("--no-colors", dest="colors", action="store_false")
    ap.add_argument("--no-names", dest="names", action="store_false")
    args = ap.parse_args()
    EPS = args.eps
    if args.bug not in BUGS and args.bug not in GEOMETRY_BUGS and args.bug not in OUTPUT_BUGS:
        sys.exit(f"unknown bug {args.bug}")
    w, h, n = args.w, args.h, args.x
    x0, y0, x1, y1 = 0, 0, w, h
    if args.region:
        x0, y0, x1, y1 = (int(v) for v in args.region.split(","))
    log = sys.stdout if args.log == "-" else open(args.log, "w")
    tr = Tracer(load_scene(args.f), args, log)
    t = math.tan(30) if args.bug == "fov-degrees" else math.tan(math.radians(60)) if args.bug == "fov-not-halved" else math.tan(math.radians(60) / 2)
    hx, hy = t, t * h / w
    if args.bug == "vertical-fov":
        hx, hy = t * w / h, t
    elif args.bug == "aspect":
        hx, hy = t, t * w / h
    image = {}
    total = (0.0, 0.0, 0.0)
    for y in range(y0, y1):
        if args.bug == "row-accumulator-out":
            total = (0.0, 0.0, 0.0)
        for x in range(x0, x1):
            if args.bug not in ("accumulator-out", "row-accumulator-out"):
                total = (0.0, 0.0, 0.0)
            byte_total = [0, 0, 0]
            for j in range(n):
                for i in range(n):
                    tr.pixel, tr.sample = (x, y), (i * n + j if args.bug == "aa-column-major" else j * n + i)
                    if args.bug == "aa-reversed":
                        tr.sample = n * n - 1 - tr.sample
                    c = 0.0 if args.bug == "pixel-corner" else 0.5
                    u = (x + (i + c) / n) / w
                    v = (y + (j + c) / n) / h
                    if args.bug == "aa-same-ray":
                        u, v = (x + 0.5) / w, (y + 0.5) / h
                    elif args.bug == "aa-one-cell":
                        u, v = (x + 0.5 / n) / w, (y + 0.5 / n) / h
                    elif args.bug == "aa-same-corner":
                        u, v = x / w, y / h
                    elif args.bug == "pixel-transposed":
                        u, v = v * h / w, u * w / h
                    elif args.bug == "aa-half-twice":
                        u, v = (x + i / n + 0.5) / w, (y + j / n + 0.5) / h
                    elif args.bug == "aa-evenly-spaced":
                        u, v = (x + (i + 1) / (n + 1)) / w, (y + (j + 1) / (n + 1)) / h
                    z = 2.0 if args.bug == "plane-distance" else 1.0
                    d = ((2 * u - 1) * hx, (1 - 2 * v) * hy, z)
                    if args.bug not in ("camera-unnormalised", "refract-unnormalised-d"):
                        d = normalize(d)
                    col = tr.trace((0.0, 0.0, 0.0), d, 0, None, "camera")
                    total = add(total, col)
                    byte_total = [b + to_byte(v) for b, v in zip(byte_total, col)]
                    if log:
                        tr.flush()
            image[(x, y)] = mul(total, 1 if args.bug == "summed-out" else 1 / n if args.bug == "aa-divided-by-n" else 1 / (n * n))
            if args.bug == "last-sample-out":
                image[(x, y)] = col
            if args.bug == "byte-average-out":
                image[(x, y)] = tuple(b // (n * n) for b in byte_total)
    if log is not sys.stdout:
        log.close()
    if args.image:
        with open(args.image, "w") as f:
            f.write(f"P3\n{x1 - x0} {y1 - y0}\n255\n")
            rows = range(y1 - 1, y0 - 1, -1) if args.bug in ("flipped-out", "rotated-out", "flipped-gamma-out") else range(y0, y1)
            cols = range(x1 - 1, x0 - 1, -1) if args.bug in ("mirrored-out", "rotated-out") else range(x0, x1)
            written = None
            for y in rows:
                line = []
                for x in cols:
                    # A colour shared by the threads: now and then a pixel gets its neighbour's.
                    stray = args.bug == "stray-pixels-out" and written is not None and (y * (x1 - x0) + x) % 97 == 0
                    written = written if stray else image[(x, y)]
                    line.append(" ".join(str(out_byte(c, args.bug)) for c in out_pixel(written, args.bug)))
                f.write(" ".join(line) + "\n")


if __name__ == "__main__":
    main()
