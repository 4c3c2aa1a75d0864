// rayscope's ray log for the course's C# ray tracer (COMP30019 template): add this file to the
// project, then one line where each kind of ray is cast (see docs/check.md in rayscope). It logs
// nothing, and costs one test of a bool per call, unless the environment variable RAYSCOPE_LOG
// names the log file. C# 7.0; safe under Parallel.For.
using System;
using System.Collections.Generic;
using System.Globalization;
using System.IO;
using System.Runtime.CompilerServices;
using System.Text;

namespace RayTracer
{
    /// <summary>Writes the rays a render casts as rayscope's JSON Lines log, for `rayscope check`.</summary>
    public static class RayLog
    {
        // One logged ray of the current pixel sample.
        sealed class Rec
        {
            public string Kind;            // null: not said (rayscope infers it)
            public int Parent = -1;        // index in the sample's list; -1: none
            public Vector3 Origin, Direction;
            public bool Awaiting;          // cast, its hit not logged yet
            public bool Traced;            // Hit was called for it
            public bool Missed;
            public Vector3 Point, Normal;
            public bool Shadow, Blocked;
            public Vector3 Light;
            public bool HasColor;
            public double R, G, B;
        }

        // One thread's current pixel sample, written whole when the thread starts its next one.
        sealed class Sample
        {
            public bool Active;
            public int X, Y, Index;
            public readonly List<Rec> Recs = new List<Rec>();
        }

        // Read once; the calls test it inline, so a render with logging off pays about one branch a call.
        static readonly bool On = Start();
        static readonly object Gate = new object();
        static readonly List<Sample> Samples = new List<Sample>();
        [ThreadStatic] static Sample mine;
        static TextWriter writer;
        static bool closed;
        static HashSet<long> pixels;
        static int[] rect;
        static int step;
        static HashSet<int> sampleFilter;

        static bool Start()
        {
            string path = Environment.GetEnvironmentVariable("RAYSCOPE_LOG");
            if (string.IsNullOrEmpty(path)) return false;
            try
            {
                string v = Environment.GetEnvironmentVariable("RAYSCOPE_LOG_PIXELS");
                if (!string.IsNullOrEmpty(v))
                {
                    pixels = new HashSet<long>();
                    foreach (string p in v.Split(new[] { ' ', ';' }, StringSplitOptions.RemoveEmptyEntries))
                    {
                        int[] xy = Ints(p, 2, "RAYSCOPE_LOG_PIXELS");
                        pixels.Add(Key(xy[0], xy[1]));
                    }
                }
                v = Environment.GetEnvironmentVariable("RAYSCOPE_LOG_RECT");
                if (!string.IsNullOrEmpty(v)) rect = Ints(v, 4, "RAYSCOPE_LOG_RECT");
                v = Environment.GetEnvironmentVariable("RAYSCOPE_LOG_STEP");
                if (!string.IsNullOrEmpty(v))
                {
                    step = Ints(v, 1, "RAYSCOPE_LOG_STEP")[0];
                    if (step < 1) throw new FormatException("RAYSCOPE_LOG_STEP must be at least 1");
                }
                v = Environment.GetEnvironmentVariable("RAYSCOPE_LOG_SAMPLES");
                if (!string.IsNullOrEmpty(v))
                    sampleFilter = new HashSet<int>(Ints(v, -1, "RAYSCOPE_LOG_SAMPLES"));
                writer = new StreamWriter(path, false, new UTF8Encoding(false), 1 << 16) { NewLine = "\n" };
            }
            catch (Exception e)
            {
                Console.Error.WriteLine("RayLog: not logging: " + e.Message);
                return false;
            }
            AppDomain.CurrentDomain.ProcessExit += (s, e) => Close();
            return true;
        }

        static int[] Ints(string text, int count, string name)
        {
            string[] parts = text.Split(new[] { ',' }, StringSplitOptions.RemoveEmptyEntries);
            if (count >= 0 && parts.Length != count)
                throw new FormatException(name + ": expected " + count + " comma-separated integers in '" + text + "'");
            int[] r = new int[parts.Length];
            for (int i = 0; i < parts.Length; i++)
                if (!int.TryParse(parts[i].Trim(), NumberStyles.Integer, CultureInfo.InvariantCulture, out r[i]))
                    throw new FormatException(name + ": '" + parts[i] + "' is not an integer");
            return r;
        }

        static long Key(int x, int y) { return ((long)x << 32) ^ (uint)y; }

        static bool Wanted(int x, int y, int s)
        {
            if (pixels != null && !pixels.Contains(Key(x, y))) return false;
            if (rect != null && (x < rect[0] || y < rect[1] || x > rect[2] || y > rect[3])) return false;
            if (step > 0 && (x % step != 0 || y % step != 0)) return false;
            if (sampleFilter != null && !sampleFilter.Contains(s)) return false;
            return true;
        }

        /// <summary>A camera ray for sample `sample` of pixel (x, y), 0-based from the top-left; call it before tracing the ray.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static void Camera(int x, int y, int sample, Ray ray)
        {
            if (On) StartSample(x, y, sample, ray);
        }

        /// <summary>A reflected ray, cast from the hit it leaves; call it before tracing the ray.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static void Reflection(Ray ray)
        {
            if (On) Cast("reflection", ray);
        }

        /// <summary>A refracted ray, cast from the hit it leaves; call it before tracing the ray.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static void Refraction(Ray ray)
        {
            if (On) Cast("refraction", ray);
        }

        /// <summary>What a traced ray hit: the nearest hit, or null for a miss.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static void Hit(Ray ray, RayHit hit)
        {
            if (On) Traced(ray, hit);
        }

        /// <summary>A shadow ray toward the light at `lightPosition`, and whether something blocked it.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static void Shadow(Ray ray, Vector3 lightPosition, bool blocked)
        {
            if (On) ShadowRay(ray, lightPosition, blocked);
        }

        /// <summary>The colour the ray being traced brings back (linear, before clamping); returns it unchanged.</summary>
        [MethodImpl(MethodImplOptions.AggressiveInlining)]
        public static Color Color(Color color)
        {
            if (On) Colored(color);
            return color;
        }

        /// <summary>Writes every buffered sample and closes the log; also done when the process exits.</summary>
        public static void Close()
        {
            if (!On) return;
            lock (Gate)
            {
                if (closed) return;
                foreach (Sample s in Samples) WriteSample(s);
                writer.Flush();
                writer.Dispose();
                closed = true;
            }
        }

        static Sample Current()
        {
            Sample s = mine;
            if (s == null)
            {
                s = mine = new Sample();
                lock (Gate) Samples.Add(s);
            }
            return s;
        }

        static void StartSample(int x, int y, int index, Ray ray)
        {
            Sample s = Current();
            if (s.Recs.Count > 0)
                lock (Gate) WriteSample(s);
            s.Recs.Clear();
            s.Active = Wanted(x, y, index);
            if (!s.Active) return;
            s.X = x;
            s.Y = y;
            s.Index = index;
            s.Recs.Add(new Rec { Kind = "camera", Origin = ray.Origin, Direction = ray.Direction, Awaiting = true });
        }

        static bool Same(Vector3 a, Vector3 b) { return a.X == b.X && a.Y == b.Y && a.Z == b.Z; }

        // The logged ray of the sample whose hit point is nearest `origin`: the ray this one leaves
        // (secondary and shadow rays start at their parent's hit, give or take an offset). The
        // latest of equally near ones, as a recursive tracer's deepest open ray is the latest.
        static int ParentOf(List<Rec> recs, Vector3 origin)
        {
            int best = -1;
            double bestD = double.PositiveInfinity;
            for (int i = recs.Count - 1; i >= 0; i--)
            {
                Rec r = recs[i];
                if (r.Shadow || !r.Traced || r.Missed) continue;
                double dx = r.Point.X - origin.X, dy = r.Point.Y - origin.Y, dz = r.Point.Z - origin.Z;
                double d = dx * dx + dy * dy + dz * dz;
                if (d < bestD) { bestD = d; best = i; }
            }
            return best;
        }

        static void Cast(string kind, Ray ray)
        {
            Sample s = mine;
            if (s == null || !s.Active) return;
            // A tracer that logged the hit first: name that ray.
            for (int i = s.Recs.Count - 1; i >= 0; i--)
            {
                Rec r = s.Recs[i];
                if (r.Kind == null && !r.Shadow && Same(r.Origin, ray.Origin) && Same(r.Direction, ray.Direction))
                {
                    r.Kind = kind;
                    return;
                }
            }
            s.Recs.Add(new Rec
            {
                Kind = kind, Parent = ParentOf(s.Recs, ray.Origin), Origin = ray.Origin, Direction = ray.Direction,
                Awaiting = true,
            });
        }

        static void Traced(Ray ray, RayHit hit)
        {
            Sample s = mine;
            if (s == null || !s.Active) return;
            // The ray cast last with these numbers, or else the ray cast last.
            Rec target = null, latest = null;
            for (int i = s.Recs.Count - 1; i >= 0 && target == null; i--)
            {
                Rec r = s.Recs[i];
                if (!r.Awaiting) continue;
                if (latest == null) latest = r;
                if (Same(r.Origin, ray.Origin) && Same(r.Direction, ray.Direction)) target = r;
            }
            target = target ?? latest;
            if (target == null)
            {
                target = new Rec { Parent = ParentOf(s.Recs, ray.Origin), Origin = ray.Origin, Direction = ray.Direction };
                s.Recs.Add(target);
            }
            target.Awaiting = false;
            target.Traced = true;
            target.Missed = hit == null;
            if (hit != null)
            {
                target.Point = hit.Position;
                target.Normal = hit.Normal;
            }
        }

        static void ShadowRay(Ray ray, Vector3 light, bool blocked)
        {
            Sample s = mine;
            if (s == null || !s.Active) return;
            // A tracer whose Hit call sits in the nearest-hit search it also runs for shadow rays
            // has just logged this ray as a traced one: it is this shadow ray.
            int last = s.Recs.Count - 1;
            if (last >= 0 && s.Recs[last].Kind == null && !s.Recs[last].Shadow && Same(s.Recs[last].Origin, ray.Origin)
                && Same(s.Recs[last].Direction, ray.Direction))
                s.Recs.RemoveAt(last);
            s.Recs.Add(new Rec
            {
                Kind = "shadow", Shadow = true, Parent = ParentOf(s.Recs, ray.Origin), Origin = ray.Origin,
                Direction = ray.Direction, Light = light, Blocked = blocked,
            });
        }

        // The colour belongs to the latest ray without one: in a recursive tracer whose every
        // return goes through Color, the rays cast below this one have theirs already.
        static void Colored(Color c)
        {
            Sample s = mine;
            if (s == null || !s.Active) return;
            for (int i = s.Recs.Count - 1; i >= 0; i--)
            {
                Rec r = s.Recs[i];
                if (r.Shadow || r.HasColor) continue;
                r.HasColor = true;
                r.R = c.R;
                r.G = c.G;
                r.B = c.B;
                return;
            }
        }

        static void Num(StringBuilder b, double v)
        {
            if (double.IsNaN(v) || double.IsInfinity(v)) b.Append("null");
            // "R" does not always round-trip on Mono; "G17" does, and is faster.
            else b.Append(v.ToString("G17", CultureInfo.InvariantCulture));
        }

        static void Vec(StringBuilder b, double x, double y, double z)
        {
            b.Append('[');
            Num(b, x);
            b.Append(',');
            Num(b, y);
            b.Append(',');
            Num(b, z);
            b.Append(']');
        }

        static void Vec(StringBuilder b, Vector3 v) { Vec(b, v.X, v.Y, v.Z); }

        // Called under Gate.
        static void WriteSample(Sample s)
        {
            if (closed || s.Recs.Count == 0) return;
            var b = new StringBuilder();
            for (int i = 0; i < s.Recs.Count; i++)
            {
                Rec r = s.Recs[i];
                b.Append("{\"pixel\":[").Append(s.X).Append(',').Append(s.Y).Append("],\"sample\":").Append(s.Index);
                b.Append(",\"id\":").Append(i).Append(",\"parent\":");
                if (r.Parent < 0) b.Append("null");
                else b.Append(r.Parent);
                if (r.Kind != null) b.Append(",\"kind\":\"").Append(r.Kind).Append('"');
                b.Append(",\"origin\":");
                Vec(b, r.Origin);
                b.Append(",\"direction\":");
                Vec(b, r.Direction);
                if (r.Shadow)
                {
                    b.Append(",\"light\":");
                    Vec(b, r.Light);
                    b.Append(",\"blocked_by\":").Append(r.Blocked ? "true" : "null");
                }
                else if (r.Traced)
                {
                    b.Append(",\"hit\":");
                    if (r.Missed) b.Append("null");
                    else
                    {
                        b.Append("{\"point\":");
                        Vec(b, r.Point);
                        b.Append(",\"normal\":");
                        Vec(b, r.Normal);
                        b.Append('}');
                    }
                }
                if (r.HasColor)
                {
                    b.Append(",\"color\":");
                    Vec(b, r.R, r.G, r.B);
                }
                b.Append("}\n");
            }
            writer.Write(b.ToString());
            s.Recs.Clear();
        }
    }
}
