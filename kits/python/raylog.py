"""rayscope's ray log for a student's Python ray tracer: put this file beside the tracer,
`import raylog`, then add one line where each kind of ray is cast (see docs/check.md in
rayscope). Standard library only. It logs nothing, and costs one test of a bool per call, unless
the environment variable RAYSCOPE_LOG names the log file. Safe with threads.

Vectors and colours may be tuples or lists of three numbers, or objects with x, y, z (colours:
r, g, b) attributes.
"""

import atexit
import os
import sys
import threading

__all__ = ["camera", "reflection", "refraction", "hit", "shadow", "color", "close"]


def _ints(text, count, name):
    parts = [p for p in text.split(",") if p.strip()]
    if count is not None and len(parts) != count:
        raise ValueError(f"{name}: expected {count} comma-separated integers in {text!r}")
    try:
        return [int(p) for p in parts]
    except ValueError:
        raise ValueError(f"{name}: {text!r} is not a list of integers") from None


def _start():
    path = os.environ.get("RAYSCOPE_LOG")
    if not path:
        return None
    env = os.environ.get
    try:
        f = {}
        if env("RAYSCOPE_LOG_PIXELS"):
            f["pixels"] = {tuple(_ints(p, 2, "RAYSCOPE_LOG_PIXELS"))
                           for p in env("RAYSCOPE_LOG_PIXELS").replace(";", " ").split()}
        if env("RAYSCOPE_LOG_RECT"):
            f["rect"] = _ints(env("RAYSCOPE_LOG_RECT"), 4, "RAYSCOPE_LOG_RECT")
        if env("RAYSCOPE_LOG_STEP"):
            f["step"] = _ints(env("RAYSCOPE_LOG_STEP"), 1, "RAYSCOPE_LOG_STEP")[0]
            if f["step"] < 1:
                raise ValueError("RAYSCOPE_LOG_STEP must be at least 1")
        if env("RAYSCOPE_LOG_SAMPLES"):
            f["samples"] = set(_ints(env("RAYSCOPE_LOG_SAMPLES"), None, "RAYSCOPE_LOG_SAMPLES"))
        f["out"] = open(path, "w", encoding="utf-8", newline="\n")
    except (ValueError, OSError) as e:
        print(f"raylog: not logging: {e}", file=sys.stderr)
        return None
    return f


_cfg = _start()
_ON = _cfg is not None
_lock = threading.Lock()
_samples = []  # every thread's current sample, for close()
_local = threading.local()
_closed = False


class _Sample:
    __slots__ = ("active", "x", "y", "index", "recs")

    def __init__(self):
        self.active = False
        self.x = self.y = self.index = 0
        self.recs = []


class _Rec:
    __slots__ = ("kind", "parent", "origin", "direction", "awaiting", "traced", "point", "normal",
                 "shadow", "light", "blocked", "color")

    def __init__(self, kind, parent, origin, direction, awaiting=False):
        self.kind = kind
        self.parent = parent
        self.origin = origin
        self.direction = direction
        self.awaiting = awaiting
        self.traced = False
        self.point = self.normal = None
        self.shadow = False
        self.light = None
        self.blocked = False
        self.color = None


def _v(a):
    if hasattr(a, "x"):
        return (float(a.x), float(a.y), float(a.z))
    x, y, z = a
    return (float(x), float(y), float(z))


def _c(c):
    if hasattr(c, "r"):
        return (float(c.r), float(c.g), float(c.b))
    return _v(c)


def _wanted(x, y, s):
    f = _cfg
    if "pixels" in f and (x, y) not in f["pixels"]:
        return False
    if "rect" in f:
        x0, y0, x1, y1 = f["rect"]
        if not (x0 <= x <= x1 and y0 <= y <= y1):
            return False
    if "step" in f and (x % f["step"] or y % f["step"]):
        return False
    return "samples" not in f or s in f["samples"]


def _current():
    s = getattr(_local, "sample", None)
    if s is None:
        s = _local.sample = _Sample()
        with _lock:
            _samples.append(s)
    return s


def _active():
    s = getattr(_local, "sample", None)
    return s if s is not None and s.active else None


def _parent(recs, origin):
    # The logged ray whose hit point is nearest the new ray's origin: secondary and shadow rays
    # start at their parent's hit, give or take an offset. The latest of equally near ones, as a
    # recursive tracer's deepest open ray is the latest.
    best, best_d = None, float("inf")
    for i in range(len(recs) - 1, -1, -1):
        r = recs[i]
        if r.shadow or r.point is None:
            continue
        p = r.point
        d = (p[0] - origin[0]) ** 2 + (p[1] - origin[1]) ** 2 + (p[2] - origin[2]) ** 2
        if d < best_d:
            best, best_d = i, d
    return best


def camera(x, y, sample, origin, direction):
    """A camera ray for sample `sample` of pixel (x, y), 0-based from the top-left; call it before
    tracing the ray."""
    if _ON:
        _start_sample(x, y, sample, origin, direction)


def reflection(origin, direction):
    """A reflected ray, cast from the hit it leaves; call it before tracing the ray."""
    if _ON:
        _cast("reflection", origin, direction)


def refraction(origin, direction):
    """A refracted ray, cast from the hit it leaves; call it before tracing the ray."""
    if _ON:
        _cast("refraction", origin, direction)


def hit(origin, direction, point, normal=None):
    """What a traced ray hit: its nearest hit point and normal, or point None for a miss."""
    if _ON:
        _traced(origin, direction, point, normal)


def shadow(origin, direction, light, blocked):
    """A shadow ray toward the light at position `light`, and whether something blocked it."""
    if _ON:
        _shadow(origin, direction, light, blocked)


def color(c):
    """The colour the ray being traced brings back (linear, before clamping); returns it unchanged."""
    if _ON:
        _colored(c)
    return c


def close():
    """Writes every buffered sample and closes the log; also done when the program exits."""
    global _closed
    if not _ON:
        return
    with _lock:
        if _closed:
            return
        for s in _samples:
            _write(s)
        _cfg["out"].close()
        _closed = True


def _start_sample(x, y, index, origin, direction):
    s = _current()
    if s.recs:
        with _lock:
            _write(s)
    s.recs = []
    s.active = _wanted(x, y, index)
    if s.active:
        s.x, s.y, s.index = x, y, index
        s.recs.append(_Rec("camera", None, _v(origin), _v(direction), awaiting=True))


def _cast(kind, origin, direction):
    s = _active()
    if s is None:
        return
    o, d = _v(origin), _v(direction)
    # A tracer that logged the hit first: name that ray.
    for r in reversed(s.recs):
        if r.kind is None and not r.shadow and r.origin == o and r.direction == d:
            r.kind = kind
            return
    s.recs.append(_Rec(kind, _parent(s.recs, o), o, d, awaiting=True))


def _traced(origin, direction, point, normal):
    s = _active()
    if s is None:
        return
    o, d = _v(origin), _v(direction)
    # The ray cast last with these numbers, or else the ray cast last.
    target = latest = None
    for r in reversed(s.recs):
        if not r.awaiting:
            continue
        if latest is None:
            latest = r
        if r.origin == o and r.direction == d:
            target = r
            break
    target = target or latest
    if target is None:
        target = _Rec(None, _parent(s.recs, o), o, d)
        s.recs.append(target)
    target.awaiting = False
    target.traced = True
    if point is not None:
        target.point = _v(point)
        target.normal = None if normal is None else _v(normal)


def _shadow(origin, direction, light, blocked):
    s = _active()
    if s is None:
        return
    o, d = _v(origin), _v(direction)
    # A tracer whose hit() call sits in the nearest-hit search it also runs for shadow rays has
    # just logged this ray as a traced one: it is this shadow ray.
    if s.recs and s.recs[-1].kind is None and s.recs[-1].origin == o and s.recs[-1].direction == d:
        s.recs.pop()
    r = _Rec("shadow", _parent(s.recs, o), o, d)
    r.shadow = True
    r.light = _v(light)
    r.blocked = bool(blocked)
    s.recs.append(r)


def _colored(c):
    # The colour belongs to the latest ray without one: in a recursive tracer whose every return
    # goes through color(), the rays cast below this one have theirs already.
    s = _active()
    if s is None:
        return
    for r in reversed(s.recs):
        if not r.shadow and r.color is None:
            r.color = _c(c)
            return


def _num(v):
    return repr(v) if v == v and abs(v) != float("inf") else "null"


def _vec(v):
    return f"[{_num(v[0])},{_num(v[1])},{_num(v[2])}]"


def _write(s):
    # Called under _lock.
    if _closed or not s.recs:
        return
    lines = []
    for i, r in enumerate(s.recs):
        parent = "null" if r.parent is None else str(r.parent)
        line = f'{{"pixel":[{s.x},{s.y}],"sample":{s.index},"id":{i},"parent":{parent}'
        if r.kind is not None:
            line += f',"kind":"{r.kind}"'
        line += f',"origin":{_vec(r.origin)},"direction":{_vec(r.direction)}'
        if r.shadow:
            line += f',"light":{_vec(r.light)},"blocked_by":{"true" if r.blocked else "null"}'
        elif r.traced:
            if r.point is None:
                line += ',"hit":null'
            elif r.normal is None:
                line += f',"hit":{{"point":{_vec(r.point)}}}'
            else:
                line += f',"hit":{{"point":{_vec(r.point)},"normal":{_vec(r.normal)}}}'
        if r.color is not None:
            line += f',"color":{_vec(r.color)}'
        lines.append(line + "}\n")
    _cfg["out"].write("".join(lines))
    s.recs = []


if _ON:
    atexit.register(close)
