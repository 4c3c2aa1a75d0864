// Drives kits/csharp/RayLog.cs through the call orders a tracer may use (see kits.rs,
// `the_kits_work_out_the_tree_whatever_the_call_order`), with Tracer.cs's template types; the
// Python and C++ twins make the same calls.
//     mcs -langversion:7 -main:RayTracer.Orders -out:orders.exe RayLog.cs Tracer.cs Orders.cs
namespace RayTracer
{
    public static class Orders
    {
        static Vector3 V(double x, double y, double z) { return new Vector3(x, y, z); }

        static RayHit H(Vector3 p, Vector3 n) { return new RayHit(p, n, V(0, 0, 1), null); }

        public static void Main()
        {
            RayLog.Camera(1, 2, 3, new Ray(V(0, 0, 0), V(0, 0, 1)));
            RayLog.Hit(new Ray(V(0, 0, 0), V(0, 0, 1)), H(V(0, 0, 5), V(0, 0, -1)));
            // The hit logged before the kind.
            RayLog.Hit(new Ray(V(0, 0, 4.99999), V(0, 1, 0)), H(V(0, 3, 5), V(0, -1, 0)));
            RayLog.Reflection(new Ray(V(0, 0, 4.99999), V(0, 1, 0)));
            // A Hit in the nearest-hit search that the shadow test runs too.
            RayLog.Hit(new Ray(V(0, 2.99999, 5), V(1, 0, 0)), null);
            RayLog.Shadow(new Ray(V(0, 2.99999, 5), V(1, 0, 0)), V(4, 3, 5), false);
            RayLog.Color(new Color(0.5, 0.5, 0.5));
            RayLog.Refraction(new Ray(V(0, 0, 5.00001), V(0, 0, 1)));
            RayLog.Hit(new Ray(V(0, 0, 5.00001), V(0, 0, 1)), null);
            RayLog.Color(new Color(0, 0, 0));
            RayLog.Color(new Color(0.25, 0.25, 0.25));
            // A pixel the filter leaves out, then calls after Close: nothing written.
            RayLog.Camera(0, 0, 0, new Ray(V(0, 0, 0), V(0, 0, 1)));
            RayLog.Hit(new Ray(V(0, 0, 0), V(0, 0, 1)), null);
            RayLog.Color(new Color(1, 1, 1));
            RayLog.Close();
            RayLog.Camera(1, 2, 0, new Ray(V(0, 0, 0), V(0, 0, 1)));
            RayLog.Hit(new Ray(V(0, 0, 0), V(0, 0, 1)), null);
            RayLog.Close();
        }
    }
}
