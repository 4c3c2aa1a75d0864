// Lets `rayscope probe` test the intersectors of your C# ray tracer (the course template's
// classes). Add this file to your project and make Main start it when asked:
//
//     if (args.Length > 0 && args[0] == "--probe") { ProbeAdapter.Run(); return; }
//
// then run:  rayscope probe -f tests/sample_scene_1.txt -- dotnet run -- --probe
// Only the marked section depends on your classes. Debug output must go to Console.Error.
using System;
using System.Globalization;
using System.Linq;
using System.Text.RegularExpressions;

namespace RayTracer
{
    public static class ProbeAdapter
    {
        // ---- connect your tracer here: n holds the primitive's numbers in request order ----
        // Every primitive gets a real material (white, diffuse), since intersection code may
        // read it: a hit often carries the material or its colour.
        static readonly Material Probe = new Material(Material.MaterialType.Diffuse, new Color(1, 1, 1));
        static SceneEntity Make(string kind, double[] n)
        {
            Func<int, Vector3> v = i => new Vector3(n[i], n[i + 1], n[i + 2]);
            if (kind == "sphere") return new Sphere(v(0), n[3], Probe);
            if (kind == "plane") return new Plane(v(0), v(3), Probe);
            return new Triangle(v(0), v(3), v(6), Probe);
        }
        // -------------------------------------------------------------------------------------

        static readonly Regex Number = new Regex(@"-?\d+(\.\d+)?([eE][-+]?\d+)?");
        static readonly Regex Kind = new Regex("\"kind\":\"(\\w+)\"");
        static string F(double x) { return x.ToString("R", CultureInfo.InvariantCulture); }
        static string V(Vector3 v) { return "[" + F(v.X) + "," + F(v.Y) + "," + F(v.Z) + "]"; }

        public static void Run()
        {
            string line;
            while ((line = Console.ReadLine()) != null)
            {
                string reply = "{\"ready\":true}";
                if (!line.Contains("\"hello\""))
                {
                    // rayscope writes the numbers in a fixed order: the id, the ray's origin and
                    // direction, then the primitive's; so no JSON library is needed.
                    double[] n = Number.Matches(line).Cast<Match>()
                        .Select(m => double.Parse(m.Value, CultureInfo.InvariantCulture)).ToArray();
                    string id = "{\"id\":" + ((long)n[0]).ToString(CultureInfo.InvariantCulture);
                    try
                    {
                        var ray = new Ray(new Vector3(n[1], n[2], n[3]), new Vector3(n[4], n[5], n[6]));
                        RayHit hit = Make(Kind.Match(line).Groups[1].Value, n.Skip(7).ToArray()).Intersect(ray);
                        reply = id + ",\"hit\":" + (hit == null ? "null"
                            : "{\"point\":" + V(hit.Position) + ",\"normal\":" + V(hit.Normal) + "}") + "}";
                    }
                    catch (Exception e)
                    {
                        reply = id + ",\"error\":\"" + e.GetType().Name + "\"}";
                    }
                }
                Console.WriteLine(reply);
                Console.Out.Flush();
            }
        }
    }
}
