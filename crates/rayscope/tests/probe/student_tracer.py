"""A student-style set of intersectors with switchable, realistic mistakes, for the probe tests.

PROBE_MISTAKES (comma-separated) picks the mistakes:
  sphere-inside        returns the smaller root even when it is behind the origin
  triangle-one-sided   rejects a negative determinant (back faces never hit)
  plane-parallel       divides by d . n without checking it (ZeroDivisionError in Python)
  plane-parallel-inf   the same division done the C# way: t becomes +-infinity and is returned
  triangle-strict      Moller-Trumbore with > / < where >= / <= belong (edges and corners miss)
  normal-unnormalised  sphere normal P - C, triangle normal (v1 - v0) x (v2 - v0) not normalised
"""
import math
import os

MISTAKES = set(filter(None, os.environ.get("PROBE_MISTAKES", "").split(",")))
EPSILON = 1e-9


class Vector3:
    def __init__(self, x, y, z):
        self.x, self.y, self.z = x, y, z

    def __add__(self, o):
        return Vector3(self.x + o.x, self.y + o.y, self.z + o.z)

    def __sub__(self, o):
        return Vector3(self.x - o.x, self.y - o.y, self.z - o.z)

    def __mul__(self, k):
        return Vector3(self.x * k, self.y * k, self.z * k)

    def dot(self, o):
        return self.x * o.x + self.y * o.y + self.z * o.z

    def cross(self, o):
        return Vector3(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)

    def length(self):
        return math.sqrt(self.dot(self))

    def normalized(self):
        return self * (1.0 / self.length())


class Ray:
    def __init__(self, origin, direction):
        self.origin, self.direction = origin, direction


class RayHit:
    def __init__(self, position, normal, incident):
        self.position, self.normal, self.incident = position, normal, incident


class Sphere:
    def __init__(self, center, radius):
        self.center, self.radius = center, radius

    def intersect(self, ray):
        oc = ray.origin - self.center
        a = ray.direction.dot(ray.direction)
        b = 2 * oc.dot(ray.direction)
        c = oc.dot(oc) - self.radius * self.radius
        disc = b * b - 4 * a * c
        if disc < 0:
            return None
        t0 = (-b - math.sqrt(disc)) / (2 * a)
        t1 = (-b + math.sqrt(disc)) / (2 * a)
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
        if "normal-unnormalised" not in MISTAKES:
            n = n * (1.0 / self.radius)
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
            t = num / denom
        else:
            if abs(denom) < 1e-12:
                return None
            t = num / denom
        if not t > EPSILON:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction)


class Triangle:
    def __init__(self, v0, v1, v2):
        self.v0, self.v1, self.v2 = v0, v1, v2
        n = (v1 - v0).cross(v2 - v0)
        self.normal = n if "normal-unnormalised" in MISTAKES else n.normalized()

    def intersect(self, ray):
        e1, e2 = self.v1 - self.v0, self.v2 - self.v0
        p = ray.direction.cross(e2)
        det = e1.dot(p)
        tiny = 1e-12 * e1.length() * e2.length()
        if "triangle-one-sided" in MISTAKES:
            if det < tiny:
                return None
        elif abs(det) < tiny:
            return None
        s = ray.origin - self.v0
        u = s.dot(p) / det
        q = s.cross(e1)
        v = ray.direction.dot(q) / det
        if "triangle-strict" in MISTAKES:
            if not (u > 0 and v > 0 and u + v < 1):
                return None
        elif not (u >= 0 and v >= 0 and u + v <= 1):
            return None
        t = e2.dot(q) / det
        if t <= EPSILON:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction)
