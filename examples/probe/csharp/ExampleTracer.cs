// A minimal, correct stand-in for the course template's classes, in their shape, so that
// ProbeAdapter.cs can be compiled and tried on its own:
//     mcs -out:probe.exe ProbeAdapter.cs ExampleTracer.cs
//     rayscope probe -f tests/sample_scene_1.txt -- mono probe.exe --probe
// As in the template, Vector3, Color and Ray are values, Material and RayHit are classes, every
// entity keeps its material and shows it through SceneEntity.Material, and the constructors take
// the same arguments. (The template declares its structs `readonly struct`, which Mono's mcs
// accepts only with -langversion:7.2; plain structs with read-only fields behave the same here.)
// Like many students' tracers, each Intersect reads its material (a hit carries the material's
// type and colour), so an entity built without a material throws on every hit.
using System;

namespace RayTracer
{
    public struct Color
    {
        private readonly double r, g, b;
        public Color(double r, double g, double b) { this.r = r; this.g = g; this.b = b; }
        public double R { get { return r; } }
        public double G { get { return g; } }
        public double B { get { return b; } }
    }

    public class Material
    {
        public enum MaterialType { Diffuse, Reflective, Refractive, Emissive, Glossy }
        private readonly MaterialType type;
        private readonly Color color;
        private readonly double refractiveIndex;
        public Material(MaterialType type, Color color, double refractiveIndex = 1)
        {
            this.type = type; this.color = color; this.refractiveIndex = refractiveIndex;
        }
        public MaterialType Type { get { return type; } }
        public Color Color { get { return color; } }
        public double RefractiveIndex { get { return refractiveIndex; } }
    }

    public struct Vector3
    {
        private readonly double x, y, z;
        public Vector3(double x, double y, double z) { this.x = x; this.y = y; this.z = z; }
        public double X { get { return x; } }
        public double Y { get { return y; } }
        public double Z { get { return z; } }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.x + b.x, a.y + b.y, a.z + b.z); }
        public static Vector3 operator -(Vector3 a, Vector3 b) { return new Vector3(a.x - b.x, a.y - b.y, a.z - b.z); }
        public static Vector3 operator *(Vector3 a, double k) { return new Vector3(a.x * k, a.y * k, a.z * k); }
        public double Dot(Vector3 o) { return x * o.x + y * o.y + z * o.z; }
        public Vector3 Cross(Vector3 o) { return new Vector3(y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x); }
        public double Length() { return Math.Sqrt(Dot(this)); }
        public Vector3 Normalized() { return this * (1.0 / Length()); }
    }

    public struct Ray
    {
        private readonly Vector3 origin, direction;
        public Ray(Vector3 origin, Vector3 direction) { this.origin = origin; this.direction = direction; }
        public Vector3 Origin { get { return origin; } }
        public Vector3 Direction { get { return direction; } }
    }

    public class RayHit
    {
        public Vector3 Position { get; private set; }
        public Vector3 Normal { get; private set; }
        public Vector3 Incident { get; private set; }
        public Material Material { get; private set; }
        // What the shading reads later, taken from the material when the hit is made.
        public Material.MaterialType Type { get; private set; }
        public Color Color { get; private set; }
        public RayHit(Vector3 position, Vector3 normal, Vector3 incident, Material material)
        {
            Position = position; Normal = normal; Incident = incident; Material = material;
            Type = material.Type;
            Color = material.Color;
        }
    }

    public interface SceneEntity
    {
        RayHit Intersect(Ray ray);
        Material Material { get; }
    }

    public class Sphere : SceneEntity
    {
        private readonly Vector3 center;
        private readonly double radius;
        private readonly Material material;
        public Sphere(Vector3 center, double radius, Material material) { this.center = center; this.radius = radius; this.material = material; }
        public Material Material { get { return material; } }
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
            return new RayHit(p, (p - center) * (1.0 / radius), ray.Direction, this.Material);
        }
    }

    public class Plane : SceneEntity
    {
        private readonly Vector3 center, normal;
        private readonly Material material;
        public Plane(Vector3 center, Vector3 normal, Material material) { this.center = center; this.normal = normal.Normalized(); this.material = material; }
        public Material Material { get { return material; } }
        public RayHit Intersect(Ray ray)
        {
            double denom = ray.Direction.Dot(normal);
            if (Math.Abs(denom) < 1e-12) return null;
            double t = (center - ray.Origin).Dot(normal) / denom;
            if (t <= 1e-9) return null;
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, this.Material);
        }
    }

    public class Triangle : SceneEntity
    {
        private readonly Vector3 v0, v1, v2, normal;
        private readonly Material material;
        public Triangle(Vector3 v0, Vector3 v1, Vector3 v2, Material material)
        {
            this.v0 = v0; this.v1 = v1; this.v2 = v2; this.material = material;
            normal = (v1 - v0).Cross(v2 - v0).Normalized();
        }
        public Material Material { get { return material; } }
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
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, this.Material);
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
