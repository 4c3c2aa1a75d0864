"""Drives kits/python/raylog.py through the call orders a tracer may use (see kits.rs,
`the_kits_work_out_the_tree_whatever_the_call_order`); the C# and C++ twins make the same calls."""

import raylog


class V:
    """A student's own vector class: the kit reads x, y, z."""

    def __init__(self, x, y, z):
        self.x, self.y, self.z = x, y, z


raylog.camera(1, 2, 3, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
raylog.hit((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), V(0.0, 0.0, 5.0), V(0.0, 0.0, -1.0))
# The hit logged before the kind.
raylog.hit((0.0, 0.0, 4.99999), (0.0, 1.0, 0.0), (0.0, 3.0, 5.0), (0.0, -1.0, 0.0))
raylog.reflection((0.0, 0.0, 4.99999), (0.0, 1.0, 0.0))
# A hit() in the nearest-hit search that the shadow test runs too.
raylog.hit((0.0, 2.99999, 5.0), (1.0, 0.0, 0.0), None, None)
raylog.shadow((0.0, 2.99999, 5.0), (1.0, 0.0, 0.0), (4.0, 3.0, 5.0), False)
raylog.color((0.5, 0.5, 0.5))
raylog.refraction((0.0, 0.0, 5.00001), (0.0, 0.0, 1.0))
raylog.hit((0.0, 0.0, 5.00001), (0.0, 0.0, 1.0), None, None)
raylog.color((0.0, 0.0, 0.0))
raylog.color((0.25, 0.25, 0.25))
# A pixel the filter leaves out, then calls after close(): nothing written.
raylog.camera(0, 0, 0, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
raylog.hit((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), None, None)
raylog.color((1.0, 1.0, 1.0))
raylog.close()
raylog.camera(1, 2, 0, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
raylog.hit((0.0, 0.0, 0.0), (0.0, 0.0, 1.0), None, None)
raylog.close()
