#!/usr/bin/env python3
"""Mitsuba 3's own spawn rule as a `rayproof spawn --exec` child (issue 47).

One query per line on stdin (`rayproof header --spawn`): the precision, then the hit point P,
its error bound E, the geometric normal N, the new direction W, the primary hit's T and ray.
Mitsuba's `SurfaceInteraction3f.spawn_ray(W)` is called with `si.p = P`, `si.n = N` (the
interaction's geometric normal, which its offset uses); the answer is the ray's origin and
t_min 0 (Mitsuba 3's rays have no t_min: the origin is moved). The variant is `scalar_rgb`
(single precision): f64 queries are refused (exit 2), so run it with `--precision f32`.

    rayproof spawn --precision f32 --exec "python3 scripts/mitsuba_spawn.py" --name mitsuba3
"""
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")


def main():
    si = mi.SurfaceInteraction3f()
    out = sys.stdout
    for line in sys.stdin:
        w = line.split()
        if not w:
            continue
        if w[0] != "f32":
            print(f"mitsuba_spawn.py: variant scalar_rgb is single precision; got a {w[0]} query",
                  file=sys.stderr)
            sys.exit(2)
        v = [float.fromhex(x) for x in w[1:]]
        si.p = mi.Point3f(v[0], v[1], v[2])
        si.n = mi.Normal3f(v[6], v[7], v[8])
        ray = si.spawn_ray(mi.Vector3f(v[9], v[10], v[11]))
        o = ray.o
        out.write(f"1 {float(o[0]).hex()} {float(o[1]).hex()} {float(o[2]).hex()} 0\n")
        out.flush()


if __name__ == "__main__":
    main()
