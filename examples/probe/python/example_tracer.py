"""A minimal, correct set of intersectors shaped like a course project, for probe_adapter.py.

As in the course template, each primitive is built from its geometry and a Material, and its
intersect(ray) returns a RayHit (position, normal, incident, material) or None; the hit reads the
material's type and colour, so a primitive built without a material fails on every hit.
"""
import math
from enum import Enum

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

    def __neg__(self):
        return Vector3(-self.x, -self.y, -self.z)

    def dot(self, o):
        return self.x * o.x + self.y * o.y + self.z * o.z

    def cross(self, o):
        return Vector3(self.y * o.z - self.z * o.y, self.z * o.x - self.x * o.z, self.x * o.y - self.y * o.x)

    def length(self):
        return math.sqrt(self.dot(self))

    def normalized(self):
        return self * (1.0 / self.length())


class Color:
    def __init__(self, r, g, b):
        self.r, self.g, self.b = r, g, b


class Material:
    class MaterialType(Enum):
        Diffuse = 0
        Reflective = 1
        Refractive = 2
        Emissive = 3
        Glossy = 4

    def __init__(self, type, color, refractive_index=1.0):
        self.type, self.color, self.refractive_index = type, color, refractive_index


class Ray:
    def __init__(self, origin, direction):
        self.origin, self.direction = origin, direction


class RayHit:
    def __init__(self, position, normal, incident, material):
        self.position, self.normal, self.incident = position, normal, incident
        # What the shading reads later, taken from the material when the hit is made.
        self.type, self.color = material.type, material.color


class Sphere:
    def __init__(self, center, radius, material):
        self.center, self.radius, self.material = center, radius, material

    def intersect(self, ray):
        oc = ray.origin - self.center
        a = ray.direction.dot(ray.direction)
        b = oc.dot(ray.direction)
        c = oc.dot(oc) - self.radius * self.radius
        disc = b * b - a * c
        if disc < 0:
            return None
        root = math.sqrt(disc)
        for t in ((-b - root) / a, (-b + root) / a):
            if t > EPSILON:
                p = ray.origin + ray.direction * t
                return RayHit(p, (p - self.center) * (1.0 / self.radius), ray.direction, self.material)
        return None


class Plane:
    def __init__(self, point, normal, material):
        self.point, self.normal, self.material = point, normal.normalized(), material

    def intersect(self, ray):
        denom = ray.direction.dot(self.normal)
        if abs(denom) < 1e-12:
            return None
        t = (self.point - ray.origin).dot(self.normal) / denom
        if t <= EPSILON:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction, self.material)


class Triangle:
    def __init__(self, v0, v1, v2, material):
        self.v0, self.v1, self.v2, self.material = v0, v1, v2, material
        self.normal = (v1 - v0).cross(v2 - v0).normalized()

    def intersect(self, ray):
        # Moller-Trumbore, two-sided.
        e1, e2 = self.v1 - self.v0, self.v2 - self.v0
        p = ray.direction.cross(e2)
        det = e1.dot(p)
        if abs(det) < 1e-12 * e1.length() * e2.length():  # parallel (relative: any scale works)
            return None
        s = ray.origin - self.v0
        u = s.dot(p) / det
        if u < 0 or u > 1:
            return None
        q = s.cross(e1)
        v = ray.direction.dot(q) / det
        if v < 0 or u + v > 1:
            return None
        t = e2.dot(q) / det
        if t <= EPSILON:
            return None
        return RayHit(ray.origin + ray.direction * t, self.normal, ray.direction, self.material)
