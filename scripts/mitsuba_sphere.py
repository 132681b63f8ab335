#!/usr/bin/env python3
"""Mitsuba 3's sphere as an `rayproof audit --exec` child (the line protocol: `rayproof header --exec`).

Each input line is `PRECISION ox oy oz dx dy dz cx cy cz r` in hex floats; each answer line is
`1 T` for a hit at T (Mitsuba's `ray_intersect_preliminary`, variant scalar_rgb, which computes
the sphere in double) or `0` for a miss. Mitsuba's log goes to stderr, never to stdout, where a
stray line would stop the audit. Invalid input (NaN or Inf, a zero direction, r <= 0) is answered
`0` without asking Mitsuba (it treats a negative radius as |r|: left to rayproof to judge would
be a false hit).
"""
import math
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)  # warnings would go to stdout

shapes = {}


def sphere(c, r):
    key = (c, r)
    s = shapes.get(key)
    if s is None:
        if len(shapes) > 4096:
            shapes.clear()
        s = mi.load_dict({"type": "sphere", "center": list(c), "radius": r})
        shapes[key] = s
    return s


for line in sys.stdin:
    f = line.split()
    v = [float.fromhex(x) for x in f[1:]]
    o, d, c, r = v[0:3], v[3:6], tuple(v[6:9]), v[9]
    if not all(math.isfinite(x) for x in v) or r <= 0 or not any(d):
        print(0)
        continue
    ray = mi.Ray3f(mi.Point3f(*o), mi.Vector3f(*d))
    pi = sphere(c, r).ray_intersect_preliminary(ray)
    t = float(pi.t)
    print(f"1 {t.hex()}" if math.isfinite(t) else 0)
