#!/usr/bin/env python3
"""A stand-in for a user's own renderer, for tests/suite.rs and the README's suite example.

Draws a disc over a gradient; each pixel is the mean of grid x grid sub-samples, so the disc's
edge depends on the sampling grid as a real renderer's would. Writes an uncompressed float32
OpenEXR by hand (no OpenEXR module needed).

usage: standin_render.py OUT --width W --grid G [--perturb D] [--variance VAR] [--nan] [--sleep S]
       [--fail] [--hang] [--no-output] [--seed S --noise SIGMA] [--shift F] [--stamp N]

--seed and --noise make it a Monte Carlo renderer: independent Gaussian noise of standard
deviation SIGMA on every channel of every pixel, drawn from the seed. --shift F multiplies the
image by 1 + F (a regression that moves the mean). --stamp N writes N into the top-left 8x4
pixels (a timestamp that changes from run to run). STANDIN_SHIFT in the environment is the
default of --shift (a regression without changing the command a golden records).
"""
import argparse
import os
import struct
import sys
import time


def write_exr(path, w, h, rgb):
    """Scanline OpenEXR, no compression, channels B G R as FLOAT."""
    def attr(name, typ, data):
        return name.encode() + b"\0" + typ.encode() + b"\0" + struct.pack("<i", len(data)) + data
    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iBBBBii", 2, 0, 0, 0, 0, 1, 1) for c in "BGR") + b"\0"
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    header = (struct.pack("<ii", 20000630, 2)
              + attr("channels", "chlist", chlist)
              + attr("compression", "compression", b"\0")
              + attr("dataWindow", "box2i", box)
              + attr("displayWindow", "box2i", box)
              + attr("lineOrder", "lineOrder", b"\0")
              + attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + attr("screenWindowWidth", "float", struct.pack("<f", 1.0))
              + b"\0")
    line = 8 + w * 3 * 4
    first = len(header) + 8 * h
    table = b"".join(struct.pack("<Q", first + y * line) for y in range(h))
    body = b""
    for y in range(h):
        data = b"".join(struct.pack("<%df" % w, *[rgb[y][x][c] for x in range(w)]) for c in (2, 1, 0))
        body += struct.pack("<ii", y, len(data)) + data
    with open(path, "wb") as f:
        f.write(header + table + body)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("out")
    p.add_argument("--width", type=int, required=True)
    p.add_argument("--grid", type=int, required=True)
    p.add_argument("--perturb", type=float, default=0.0)
    p.add_argument("--variance")
    p.add_argument("--nan", action="store_true")
    p.add_argument("--fail", action="store_true")
    p.add_argument("--hang", action="store_true")
    p.add_argument("--sleep", type=float, default=0.0)
    p.add_argument("--no-output", action="store_true")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--noise", type=float, default=0.0)
    p.add_argument("--shift", type=float, default=float(os.environ.get("STANDIN_SHIFT", "0")))
    p.add_argument("--stamp", type=float)
    a = p.parse_args()
    if a.fail:
        print("standin: out of memory (pretend)", file=sys.stderr)
        sys.exit(3)
    if a.hang:
        time.sleep(3600)
    time.sleep(a.sleep)
    if a.no_output:
        return
    w, g = a.width, a.grid
    h = w * 2 // 3
    cx, cy, r = w / 2, h / 2, h / 3
    img = []
    for y in range(h):
        row = []
        for x in range(w):
            acc = [0.0, 0.0, 0.0]
            for j in range(g):
                for i in range(g):
                    sx, sy = x + (i + 0.5) / g, y + (j + 0.5) / g
                    if (sx - cx) ** 2 + (sy - cy) ** 2 < r * r:
                        c = (0.9, 0.3, 0.1)
                    else:
                        c = (0.5 * sx / w, 0.5 * sy / h, 0.2)
                    acc = [acc[k] + c[k] for k in range(3)]
            px = [v / (g * g) for v in acc]
            if a.perturb and 4 <= x < 12 and 4 <= y < 12:
                px = [v + a.perturb for v in px]
            row.append(px)
        img.append(row)
    if a.noise or a.shift:
        import random
        rng = random.Random(a.seed)
        img = [[[(v + (rng.gauss(0.0, a.noise) if a.noise else 0.0)) * (1.0 + a.shift) for v in px]
                for px in row] for row in img]
    if a.stamp is not None:
        for y in range(min(4, h)):
            for x in range(min(8, w)):
                img[y][x] = [(a.stamp % 997) / 997] * 3
    if a.nan:
        img[0][0] = [float("nan")] * 3
    write_exr(a.out, w, h, img)
    if a.variance:
        write_exr(a.variance, w, h, [[[1e-4] * 3 for _ in range(w)] for _ in range(h)])


if __name__ == "__main__":
    main()
