// A small ray tracer in the shape of the course's C# template (namespace RayTracer, the entities
// behind the SceneEntity interface, RayHit without a distance, rows rendered with Parallel.For)
// with rayscope's kit (kits/csharp/RayLog.cs) added as a student adds it: the lines that call
// RayLog. It renders stage 2 of the course and writes a PPM picture. `--bug NAME` switches on one
// mistake:
//   shadow-no-offset   shadow rays start exactly on the surface
//   reflect-no-2       the reflection formula without its factor 2: d - (d.n) n
//   refraction-normal  leaving glass, the refraction uses the outward normal (not flipped)
// and mistakes found in real students' tracers, for `diagnose`:
//   min-distance       every Intersect ignores hits nearer than t = 0.05
//   first-in-list      the closest-hit loop compares the lengths of the hits' unit incident
//                      directions (all 1), so the first entity hit in the scene's order is kept
//   origin-distance    the closest-hit loop compares the hits' positions' lengths
//   reflect-along-ray  glass's reflected ray starts at p + d * Eps, along the incident ray
//   reflect-outward    glass's reflected ray starts at p + N * Eps with the outward normal N
//   accumulator        the sum of a pixel's samples is never reset (use with --serial)
//   schlick            glass mixes by Schlick's approximation
//   integer-aspect     the aspect ratio computed as width / height in integers (80 / 60 is 1)
//   fov-vertical       the 60 degrees span the image's height (Unity's camera)
//   depth-all-3        every material returns black from depth 3 on
// Its structs are plain (the template's are readonly, C# 7.2) so that it builds as C# 7.0, as the kit must:
//     mcs -langversion:7 -out:tracer.exe kits/csharp/RayLog.cs Tracer.cs
// Usage: mono tracer.exe -f scene.txt [-w 400] [-h 400] [-x 1] [-o out.ppm] [--bug NAME] [--serial]
using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;
using System.Threading.Tasks;

namespace RayTracer
{
    public struct Vector3
    {
        private readonly double x, y, z;
        public Vector3(double x, double y, double z) { this.x = x; this.y = y; this.z = z; }
        public double X { get { return x; } }
        public double Y { get { return y; } }
        public double Z { get { return z; } }
        public double Length() { return Math.Sqrt(Dot(this)); }
        public Vector3 Normalized() { return this / Length(); }
        public double Dot(Vector3 o) { return x * o.x + y * o.y + z * o.z; }
        public Vector3 Cross(Vector3 o) { return new Vector3(y * o.z - z * o.y, z * o.x - x * o.z, x * o.y - y * o.x); }
        public static Vector3 operator +(Vector3 a, Vector3 b) { return new Vector3(a.x + b.x, a.y + b.y, a.z + b.z); }
        public static Vector3 operator -(Vector3 a) { return new Vector3(-a.x, -a.y, -a.z); }
        public static Vector3 operator -(Vector3 a, Vector3 b) { return new Vector3(a.x - b.x, a.y - b.y, a.z - b.z); }
        public static Vector3 operator *(Vector3 a, double k) { return new Vector3(a.x * k, a.y * k, a.z * k); }
        public static Vector3 operator *(double k, Vector3 a) { return a * k; }
        public static Vector3 operator /(Vector3 a, double k) { return new Vector3(a.x / k, a.y / k, a.z / k); }
    }

    public struct Color
    {
        private readonly double r, g, b;
        public Color(double r, double g, double b) { this.r = r; this.g = g; this.b = b; }
        public double R { get { return r; } }
        public double G { get { return g; } }
        public double B { get { return b; } }
        public static Color operator *(Color a, double k) { return new Color(a.r * k, a.g * k, a.b * k); }
        public static Color operator *(Color a, Color b) { return new Color(a.r * b.r, a.g * b.g, a.b * b.b); }
        public static Color operator +(Color a, Color b) { return new Color(a.r + b.r, a.g + b.g, a.b + b.b); }
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
        private readonly Vector3 position, normal, incident;
        public RayHit(Vector3 position, Vector3 normal, Vector3 incident, Material material)
        {
            this.position = position; this.normal = normal; this.incident = incident;
        }
        public Vector3 Position { get { return position; } }
        public Vector3 Normal { get { return normal; } }
        public Vector3 Incident { get { return incident; } }
    }

    public class Material
    {
        public enum MaterialType { Diffuse, Reflective, Refractive, Emissive, Glossy }
        public Material(MaterialType type, Color color, double refractiveIndex = 1)
        {
            Type = type; Color = color; RefractiveIndex = refractiveIndex;
        }
        public MaterialType Type { get; }
        public Color Color { get; }
        public double RefractiveIndex { get; }
    }

    public interface SceneEntity
    {
        RayHit Intersect(Ray ray);
        Material Material { get; }
    }

    public static class Student
    {
        // The smallest t the Intersect methods accept (the min-distance mistake raises it).
        public static double MinT = 0;
    }

    public class Sphere : SceneEntity
    {
        private readonly Vector3 center;
        private readonly double radius;
        public Sphere(Vector3 center, double radius, Material material) { this.center = center; this.radius = radius; Material = material; }
        public Material Material { get; }
        public RayHit Intersect(Ray ray)
        {
            Vector3 oc = ray.Origin - center;
            double b = oc.Dot(ray.Direction), c = oc.Dot(oc) - radius * radius;
            double disc = b * b - c;
            if (disc < 0) return null;
            double root = Math.Sqrt(disc);
            double t = -b - root;
            if (t <= Student.MinT) t = -b + root;
            if (t <= Student.MinT) return null;
            Vector3 p = ray.Origin + ray.Direction * t;
            return new RayHit(p, (p - center).Normalized(), ray.Direction, Material);
        }
    }

    public class Plane : SceneEntity
    {
        private readonly Vector3 center, normal;
        public Plane(Vector3 center, Vector3 normal, Material material) { this.center = center; this.normal = normal.Normalized(); Material = material; }
        public Material Material { get; }
        public RayHit Intersect(Ray ray)
        {
            double den = ray.Direction.Dot(normal);
            if (den == 0) return null;
            double t = (center - ray.Origin).Dot(normal) / den;
            if (t <= Student.MinT) return null;
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, Material);
        }
    }

    public class Triangle : SceneEntity
    {
        private readonly Vector3 v0, e1, e2, normal;
        public Triangle(Vector3 v0, Vector3 v1, Vector3 v2, Material material)
        {
            this.v0 = v0; e1 = v1 - v0; e2 = v2 - v0; normal = e1.Cross(e2).Normalized(); Material = material;
        }
        public Material Material { get; }
        public RayHit Intersect(Ray ray)
        {
            Vector3 p = ray.Direction.Cross(e2);
            double det = e1.Dot(p);
            if (Math.Abs(det) < 1e-12) return null;
            Vector3 s = ray.Origin - v0;
            double u = s.Dot(p) / det;
            if (u < 0 || u > 1) return null;
            Vector3 q = s.Cross(e1);
            double v = ray.Direction.Dot(q) / det;
            if (v < 0 || u + v > 1) return null;
            double t = e2.Dot(q) / det;
            if (t <= Student.MinT) return null;
            return new RayHit(ray.Origin + ray.Direction * t, normal, ray.Direction, Material);
        }
    }

    public struct PointLight
    {
        public PointLight(Vector3 position, Color color) { Position = position; Color = color; }
        public Vector3 Position { get; }
        public Color Color { get; }
    }

    public class Scene
    {
        const double Eps = 1e-5;
        const int MaxDepth = 8;
        private readonly List<SceneEntity> entities = new List<SceneEntity>();
        private readonly List<PointLight> lights = new List<PointLight>();
        public string Bug = "none";
        public bool Serial;

        public void AddEntity(SceneEntity entity) { entities.Add(entity); }
        public void AddPointLight(PointLight light) { lights.Add(light); }

        public Color[,] Render(int width, int height, int n)
        {
            var image = new Color[width, height];
            double half = Math.Tan(Math.PI / 6);
            Color carried = new Color(0, 0, 0);
            Action<int> row = y =>
            {
                for (int x = 0; x < width; x++)
                {
                    Color sum = Bug == "accumulator" ? carried : new Color(0, 0, 0);
                    for (int j = 0; j < n; j++)
                        for (int i = 0; i < n; i++)
                        {
                            double u = (x + (i + 0.5) / n) / width, v = (y + (j + 0.5) / n) / height;
                            double sx = half, sy = half * height / width;
                            if (Bug == "integer-aspect")
                            {
                                double aspect = width / height;
                                sy = half / aspect;
                            }
                            if (Bug == "fov-vertical") { sx = half * width / height; sy = half; }
                            var dir = new Vector3((2 * u - 1) * sx, (1 - 2 * v) * sy, 1);
                            var ray = new Ray(new Vector3(0, 0, 0), dir.Normalized());
                            RayLog.Camera(x, y, j * n + i, ray);
                            sum = sum + Trace(ray, 0);
                        }
                    carried = sum;
                    image[x, y] = sum * (1.0 / (n * n));
                }
            };
            if (Serial)
                for (int y = 0; y < height; y++) row(y);
            else
                Parallel.For(0, height, row);
            return image;
        }

        private RayHit ClosestHit(Ray ray, out SceneEntity closest)
        {
            RayHit best = null;
            double bestDist = double.PositiveInfinity;
            closest = null;
            foreach (SceneEntity e in entities)
            {
                RayHit hit = e.Intersect(ray);
                if (hit == null) continue;
                double d = (hit.Position - ray.Origin).Length();
                if (Bug == "first-in-list") d = hit.Incident.Length();
                if (Bug == "origin-distance") d = hit.Position.Length();
                if (d < bestDist) { best = hit; bestDist = d; closest = e; }
            }
            return best;
        }

        private Color Trace(Ray ray, int depth)
        {
            RayHit hit = ClosestHit(ray, out SceneEntity entity);
            RayLog.Hit(ray, hit);
            if (hit == null) return RayLog.Color(new Color(0, 0, 0));
            return RayLog.Color(Shade(ray, hit, entity.Material, depth));
        }

        private Color Shade(Ray ray, RayHit hit, Material material, int depth)
        {
            if (Bug == "depth-all-3" && depth >= 3) return new Color(0, 0, 0);
            Vector3 d = ray.Direction, p = hit.Position;
            bool front = hit.Normal.Dot(d) < 0;
            Vector3 nf = front ? hit.Normal : -hit.Normal;
            switch (material.Type)
            {
                case Material.MaterialType.Reflective:
                    if (depth >= MaxDepth) return new Color(0, 0, 0);
                    return Trace(Reflect(ray, p, nf), depth + 1);
                case Material.MaterialType.Refractive:
                    if (depth >= MaxDepth) return new Color(0, 0, 0);
                    return Glass(ray, hit, material, nf, front, depth);
                default:
                    return Diffuse(p, nf, material);
            }
        }

        private Ray Reflect(Ray ray, Vector3 p, Vector3 nf)
        {
            return Reflect(ray, p + nf * Eps, p, nf);
        }

        private Ray Reflect(Ray ray, Vector3 origin, Vector3 p, Vector3 nf)
        {
            Vector3 d = ray.Direction;
            double k = Bug == "reflect-no-2" ? 1 : 2;
            var reflected = new Ray(origin, (d - nf * (k * d.Dot(nf))).Normalized());
            RayLog.Reflection(reflected);
            return reflected;
        }

        private Color Diffuse(Vector3 p, Vector3 nf, Material material)
        {
            Color sum = new Color(0, 0, 0);
            foreach (PointLight light in lights)
            {
                Vector3 origin = Bug == "shadow-no-offset" ? p : p + nf * Eps;
                Vector3 toLight = light.Position - origin;
                double dist = toLight.Length();
                var shadowRay = new Ray(origin, toLight / dist);
                RayHit blocker = ClosestHit(shadowRay, out SceneEntity _);
                bool blocked = blocker != null && (blocker.Position - origin).Length() < dist;
                RayLog.Shadow(shadowRay, light.Position, blocked);
                if (!blocked)
                    sum = sum + material.Color * light.Color * Math.Max(0, nf.Dot(toLight / dist));
            }
            return sum;
        }

        private Color Glass(Ray ray, RayHit hit, Material material, Vector3 nf, bool front, int depth)
        {
            Vector3 d = ray.Direction, p = hit.Position;
            double n1 = front ? 1 : material.RefractiveIndex, n2 = front ? material.RefractiveIndex : 1;
            Vector3 nn = Bug == "refraction-normal" ? hit.Normal : nf;
            double eta = n1 / n2, cosi = -d.Dot(nn);
            double k = 1 - eta * eta * (1 - cosi * cosi);
            Vector3 from = p + nf * Eps;
            if (Bug == "reflect-along-ray") from = p + d * Eps;
            if (Bug == "reflect-outward") from = p + hit.Normal * Eps;
            Color reflected = Trace(Reflect(ray, from, p, nf), depth + 1);
            if (k < 0) return reflected;
            double ci = Math.Abs(cosi), ct = Math.Sqrt(k);
            double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct), rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct);
            double kr = 0.5 * (rs * rs + rp * rp);
            if (Bug == "schlick")
            {
                double r0 = (n1 - n2) / (n1 + n2);
                r0 *= r0;
                double c = n1 <= n2 ? ci : ct;
                kr = r0 + (1 - r0) * Math.Pow(1 - c, 5);
            }
            var refracted = new Ray(p - nn * Eps, (d * eta + nn * (eta * cosi - ct)).Normalized());
            RayLog.Refraction(refracted);
            return reflected * kr + Trace(refracted, depth + 1) * (1 - kr);
        }
    }

    public static class Program
    {
        static Vector3 V(string[] t, int i)
        {
            return new Vector3(D(t[i]), D(t[i + 1]), D(t[i + 2]));
        }

        static double D(string s) { return double.Parse(s, CultureInfo.InvariantCulture); }

        static Scene Load(string path)
        {
            var scene = new Scene();
            var materials = new Dictionary<string, Material>();
            char[] seps = { ' ', '\t', ',', '"', '(', ')' };
            foreach (string line in File.ReadAllLines(path))
            {
                string[] t = line.Split(seps, StringSplitOptions.RemoveEmptyEntries);
                if (t.Length == 0 || t[0].StartsWith("#")) continue;
                switch (t[0])
                {
                    case "Material":
                        var type = (Material.MaterialType)Enum.Parse(typeof(Material.MaterialType), t[2]);
                        Vector3 c = V(t, 3);
                        materials[t[1]] = new Material(type, new Color(c.X, c.Y, c.Z), D(t[6]));
                        break;
                    case "PointLight":
                        Vector3 lc = V(t, 5);
                        scene.AddPointLight(new PointLight(V(t, 2), new Color(lc.X, lc.Y, lc.Z)));
                        break;
                    case "Plane":
                        scene.AddEntity(new Plane(V(t, 2), V(t, 5), materials[t[8]]));
                        break;
                    case "Sphere":
                        scene.AddEntity(new Sphere(V(t, 2), D(t[5]), materials[t[6]]));
                        break;
                    case "Triangle":
                        scene.AddEntity(new Triangle(V(t, 2), V(t, 5), V(t, 8), materials[t[11]]));
                        break;
                    default:
                        throw new Exception(path + ": unsupported command " + t[0]);
                }
            }
            return scene;
        }

        public static int Main(string[] args)
        {
            string file = null, output = null, bug = "none";
            int w = 400, h = 400, n = 1;
            bool serial = false;
            for (int i = 0; i < args.Length; i++)
            {
                switch (args[i])
                {
                    case "-f": file = args[++i]; break;
                    case "-o": output = args[++i]; break;
                    case "-w": w = int.Parse(args[++i]); break;
                    case "-h": h = int.Parse(args[++i]); break;
                    case "-x": n = int.Parse(args[++i]); break;
                    case "--bug": bug = args[++i]; break;
                    case "--serial": serial = true; break;
                    default: Console.Error.WriteLine("unknown argument " + args[i]); return 2;
                }
            }
            if (file == null) { Console.Error.WriteLine("usage: tracer.exe -f scene.txt [-w W] [-h H] [-x N] [-o out.ppm] [--bug NAME] [--serial]"); return 2; }
            var bugs = new[] { "none", "shadow-no-offset", "reflect-no-2", "refraction-normal", "min-distance", "first-in-list", "origin-distance", "reflect-along-ray", "reflect-outward", "accumulator", "schlick", "integer-aspect", "fov-vertical", "depth-all-3" };
            if (Array.IndexOf(bugs, bug) < 0)
            {
                Console.Error.WriteLine("unknown bug " + bug);
                return 2;
            }
            Scene scene = Load(file);
            scene.Bug = bug;
            if (bug == "min-distance") Student.MinT = 0.05;
            scene.Serial = serial;
            Color[,] image = scene.Render(w, h, n);
            if (output != null)
                using (var o = new StreamWriter(output))
                {
                    o.Write("P3\n" + w + " " + h + "\n255\n");
                    for (int y = 0; y < h; y++)
                        for (int x = 0; x < w; x++)
                        {
                            Color c = image[x, y];
                            o.Write((int)(Math.Min(Math.Max(c.R, 0), 1) * 255) + " " + (int)(Math.Min(Math.Max(c.G, 0), 1) * 255) + " " + (int)(Math.Min(Math.Max(c.B, 0), 1) * 255) + "\n");
                        }
                }
            return 0;
        }
    }
}
