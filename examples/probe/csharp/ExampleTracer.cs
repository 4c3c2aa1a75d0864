// A minimal, correct stand-in for the course template's classes, in their shape (a material and
// its colour included), so that ProbeAdapter.cs can be compiled and tried on its own:
//     mcs -out:probe.exe ProbeAdapter.cs ExampleTracer.cs
//     rayscope probe -f tests/sample_scene_1.txt -- mono probe.exe --probe
using System;

namespace RayTracer
{
    // The template's material and colour, as far as the adapter and the entities use them.
    public class Color
    {
        public double R { get; private set; }
        public double G { get; private set; }
        public double B { get; private set; }
        public Color(double r, double g, double b) { R = r; G = g; B = b; }
    }

    public class Material
    {
        public enum MaterialType { Diffuse, Reflective, Refractive, Emissive }
        public MaterialType Type { get; private set; }
        public Color Color { get; private set; }
        public double RefractiveIndex { get; private set; }
        public Material(MaterialType type, Color color, double refractiveIndex = 1)
        {
            Type = type; Color = color; RefractiveIndex = refractiveIndex;
        }
    }

    public class Vector3
    {
        public double X { get; private set; }
        public double Y { get; private set; }
        public double Z { get; private set; }
        public Vector3(double x, double y, double z) { X = x; Y = y; Z = z; }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.X + b.X, a.Y + b.Y, a.Z + b.Z); }
        public static Vector3 operator -(Vector3 a, Vector3 b) { return new Vector3(a.X - b.X, a.Y - b.Y, a.Z - b.Z); }
        public static Vector3 operator *(Vector3 a, double k) { return new Vector3(a.X * k, a.Y * k, a.Z * k); }
        public double Dot(Vector3 o) { return X * o.X + Y * o.Y + Z * o.Z; }
        public Vector3 Cross(Vector3 o) { return new Vector3(Y * o.Z - Z * o.Y, Z * o.X - X * o.Z, X * o.Y - Y * o.X); }
        public double Length() { return Math.Sqrt(Dot(this)); }
        public Vector3 Normalized() { return this * (1.0 / Length()); }
    }

    public class Ray
    {
        public Vector3 Origin { get; private set; }
        public Vector3 Direction { get; private set; }
        public Ray(Vector3 origin, Vector3 direction) { Origin = origin; Direction = direction; }
    }

    public class RayHit
    {
        public Vector3 Position { get; private set; }
        public Vector3 Normal { get; private set; }
        public Vector3 Incident { get; private set; }
        public Material Material { get; private set; }
        // As in many course tracers, a hit reads its material (here its colour), so an entity
        // built without one throws.
        public Color Color { get; private set; }
        public RayHit(Vector3 position, Vector3 normal, Vector3 incident, Material material)
        {
            Position = position; Normal = normal; Incident = incident; Material = material;
            Color = material.Color;
        }
    }

    public interface SceneEntity
    {
        RayHit Intersect(Ray ray);
    }

    public class Sphere : SceneEntity
    {
        Vector3 center; double radius; Material material;
        public Sphere(Vector3 center, double radius, Material material) { this.center = center; this.radius = radius; this.material = material; }
        public RayHit Intersect(Ray ray)
        {
            Vector3 oc = ray.Origin - center;
            double a = ray.Direction.Dot(ray.Direction), b = oc.Dot(ray.Direction), c = oc.Dot(oc) - radius * radius;
            double disc = b * b - a * c;
            if (disc < 0) return null;
            double root = Math.Sqrt(disc);
            double t = (-b - root) / a;
            if (t <= 1e-9) t = (-b + root) / a;
            if (t <= 1e-9) return null;
            Vector3 p = ray.Origin + ray.Direction * t;
            return new RayHit(p, (p - center) * (1.0 / radius), ray.Direction, material);
        }
    }

    public class Plane : SceneEntity
    {
        Vector3 center, normal; Material material;
        public Plane(Vector3 center, Vector3 normal, Material material) { this.center = center; this.normal = normal.Normalized(); this.material = material; }
        public RayHit Intersect(Ray ray)
        {
            double denom = ray.Direction.Dot(normal);
            if (Math.Abs(denom) < 1e-12) return null;
            double t = (center - ray.Origin).Dot(normal) / denom;
            if (t <= 1e-9) return null;
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, material);
        }
    }

    public class Triangle : SceneEntity
    {
        Vector3 v0, v1, v2, normal; Material material;
        public Triangle(Vector3 v0, Vector3 v1, Vector3 v2, Material material)
        {
            this.v0 = v0; this.v1 = v1; this.v2 = v2; this.material = material;
            normal = (v1 - v0).Cross(v2 - v0).Normalized();
        }
        public RayHit Intersect(Ray ray)
        {
            Vector3 e1 = v1 - v0, e2 = v2 - v0, p = ray.Direction.Cross(e2);
            double det = e1.Dot(p);
            if (Math.Abs(det) < 1e-12 * e1.Length() * e2.Length()) return null;
            Vector3 s = ray.Origin - v0, q = s.Cross(e1);
            double u = s.Dot(p) / det, v = ray.Direction.Dot(q) / det;
            if (u < 0 || v < 0 || u + v > 1) return null;
            double t = e2.Dot(q) / det;
            if (t <= 1e-9) return null;
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, material);
        }
    }

    public static class Program
    {
        public static void Main(string[] args)
        {
            if (args.Length > 0 && args[0] == "--probe") { ProbeAdapter.Run(); return; }
            Console.Error.WriteLine("usage: mono probe.exe --probe (rayscope probe starts it)");
        }
    }
}
