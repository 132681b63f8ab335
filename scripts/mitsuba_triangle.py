#!/usr/bin/env python3
"""Mitsuba 3's ray-triangle test as a `rayproof --exec` child (the line protocol: `rayproof header --exec`).

    python3 scripts/mitsuba_triangle.py triangle   # Mesh.ray_intersect_triangle, the mesh's own test
    python3 scripts/mitsuba_triangle.py scene      # the triangle in a scene: Scene.ray_intersect_preliminary

Each input line is `PRECISION ox oy oz dx dy dz p0x p0y p0z p1x p1y p1z p2x p2y p2z` in hex floats
(f32 only: variant scalar_rgb); each answer line is `1 T` for a hit at T or `0` for a miss. Each
triangle is a one-triangle mesh (and, for `scene`, a scene of that mesh), built once and kept for
the cases that share it. Mitsuba's log goes to stderr, never to stdout, where a stray line would
stop the audit. Invalid input (NaN or Inf, a zero direction, a degenerate triangle) is answered
`0` without asking Mitsuba.
"""
import math
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)  # warnings would go to stdout

mode = sys.argv[1] if len(sys.argv) > 1 else "triangle"
if mode not in ("triangle", "scene"):
    sys.exit(f"mitsuba_triangle.py: mode {mode!r}: give 'triangle' or 'scene'")

kept = {}


def target(p):
    """The mesh (or its scene) of triangle p (9 floats), built once."""
    s = kept.get(p)
    if s is None:
        if len(kept) > 8192:
            kept.clear()
        m = mi.Mesh("t", 3, 1)
        params = mi.traverse(m)
        params["vertex_positions"] = list(p)
        params["faces"] = [0, 1, 2]
        params.update()
        s = m if mode == "triangle" else mi.load_dict({"type": "scene", "t": m})
        kept[p] = s
    return s


def degenerate(p):
    a, b, c = p[0:3], p[3:6], p[6:9]
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    return not any(n)


for line in sys.stdin:
    f = line.split()
    if f[0] != "f32":
        sys.exit(f"mitsuba_triangle.py: precision {f[0]}: scalar_rgb is f32 only")
    v = [float.fromhex(x) for x in f[1:]]
    o, d, p = v[0:3], v[3:6], tuple(v[6:15])
    if not all(math.isfinite(x) for x in v) or not any(d) or degenerate(p):
        print(0)
        continue
    ray = mi.Ray3f(mi.Point3f(*o), mi.Vector3f(*d))
    s = target(p)
    pi = s.ray_intersect_triangle(0, ray) if mode == "triangle" else s.ray_intersect_preliminary(ray)
    t = float(pi.t)
    print(f"1 {t.hex()}" if pi.is_valid() and math.isfinite(t) else 0)
