"""A student-style set of intersectors with switchable, realistic mistakes, for the probe tests.

PROBE_MISTAKES (comma-separated) picks the mistakes:
  sphere-inside        returns the smaller root even when it is behind the origin
  sphere-far-root      takes the larger root whenever it is in front (t0 and t1 swapped)
  triangle-one-sided   rejects a negative determinant (back faces never hit)
  plane-parallel       divides by d . n without checking it (ZeroDivisionError in Python)
  plane-parallel-inf   the same division done the C# way: t becomes +-infinity and is returned
  triangle-strict      Moller-Trumbore with > / < where >= / <= belong (edges and corners miss)
  normal-unnormalised  sphere normal P - C, triangle normal (v1 - v0) x (v2 - v0) not normalised
  sphere-normal-unnormalised  sphere normal P - C only (triangles' normals normalised)
  plane-behind         the plane test checks only that d . n is not 0: hits behind the origin too
  triangle-reversed-normals  triangle normal (v2 - v0) x (v1 - v0), never turned towards the ray
and, not a mistake,
  float32              every operation rounded to single precision, like a tracer using float
"""
import math
import os
import struct

MISTAKES = set(filter(None, os.environ.get("PROBE_MISTAKES", "").split(",")))
EPSILON = 1e-9

if "float32" in MISTAKES:
    def r(x):
        try:
            return struct.unpack("f", struct.pack("f", x))[0]
        except OverflowError:
            return math.copysign(math.inf, x)
else:
    def r(x):
        return x


def sqrt(x):
    return r(math.sqrt(x))


class Vector3:
    def __init__(self, x, y, z):
        self.x, self.y, self.z = r(x), r(y), r(z)

    def __add__(self, o):
        return Vector3(self.x + o.x, self.y + o.y, self.z + o.z)

    def __sub__(self, o):
        return Vector3(self.x - o.x, self.y - o.y, self.z - o.z)

    def __mul__(self, k):
        return Vector3(self.x * k, self.y * k, self.z * k)

    def dot(self, o):
        return r(r(r(self.x * o.x) + r(self.y * o.y)) + r(self.z * o.z))

    def cross(self, o):
        return Vector3(
            r(self.y * o.z) - r(self.z * o.y), r(self.z * o.x) - r(self.x * o.z), r(self.x * o.y) - r(self.y * o.x)
        )

    def length(self):
        return sqrt(self.dot(self))

    def normalized(self):
        return self * r(1.0 / self.length())


class Ray:
    def __init__(self, origin, direction):
        self.origin, self.direction = origin, direction


class RayHit:
    def __init__(self, position, normal, incident):
        self.position, self.normal, self.incident = position, normal, incident


class Sphere:
    def __init__(self, center, radius):
        self.center, self.radius = center, r(radius)

    def intersect(self, ray):
        # The textbook quadratic, as most students write it.
        oc = ray.origin - self.center
        a = ray.direction.dot(ray.direction)
        b = r(2 * oc.dot(ray.direction))
        c = r(oc.dot(oc) - r(self.radius * self.radius))
        disc = r(r(b * b) - r(r(4 * a) * c))
        if disc < 0:
            return None
        t0 = r(r(-b - sqrt(disc)) / r(2 * a))
        t1 = r(r(-b + sqrt(disc)) / r(2 * a))
        if "sphere-far-root" in MISTAKES:
            t0, t1 = t1, t0
        if "sphere-inside" in MISTAKES:
            if t1 <= EPSILON:
                return None
            t = t0
        elif t0 > EPSILON:
            t = t0
        elif t1 > EPSILON:
            t = t1
        else:
            return None
        p = ray.origin + ray.direction * t
        n = p - self.center
        if "normal-unnormalised" not in MISTAKES and "sphere-normal-unnormalised" not in MISTAKES:
            n = n * r(1.0 / self.radius)
        return RayHit(p, n, ray.direction)


class Plane:
    def __init__(self, point, normal):
        self.point, self.normal = point, normal.normalized()

    def intersect(self, ray):
        denom = ray.direction.dot(self.normal)
        num = (self.point - ray.origin).dot(self.normal)
        if "plane-parallel-inf" in MISTAKES and denom == 0:
            t = math.copysign(math.inf, num) if num != 0 else math.nan
        elif "plane-parallel" in MISTAKES or "plane-parallel-inf" in MISTAKES:
            t = r(num / denom)
        else:
            if abs(denom) < 1e-12:
                return None
            t = r(num / denom)
        if not t > EPSILON and "plane-behind" not in MISTAKES:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction)


class Triangle:
    def __init__(self, v0, v1, v2):
        self.v0, self.v1, self.v2 = v0, v1, v2
        n = (v1 - v0).cross(v2 - v0)
        if "triangle-reversed-normals" in MISTAKES:
            n = (v2 - v0).cross(v1 - v0)
        self.normal = n if "normal-unnormalised" in MISTAKES else n.normalized()

    def intersect(self, ray):
        e1, e2 = self.v1 - self.v0, self.v2 - self.v0
        p = ray.direction.cross(e2)
        det = e1.dot(p)
        tiny = 1e-12 * e1.length() * e2.length()  # parallel, at any scale
        if "triangle-one-sided" in MISTAKES:
            if det < tiny:
                return None
        elif abs(det) < tiny:
            return None
        s = ray.origin - self.v0
        u = r(s.dot(p) / det)
        q = s.cross(e1)
        v = r(ray.direction.dot(q) / det)
        if "triangle-strict" in MISTAKES:
            if not (u > 0 and v > 0 and r(u + v) < 1):
                return None
        elif not (u >= 0 and v >= 0 and r(u + v) <= 1):
            return None
        t = r(e2.dot(q) / det)
        if t <= EPSILON:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction)
