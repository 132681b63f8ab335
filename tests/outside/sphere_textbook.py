# The textbook ray–sphere quadratic (rayproof's `algebraic`) in Python floats (IEEE doubles),
# audited through `rayproof audit --exec`: one case per input line, one answer per output line.
import math
import sys


def num(s):
    return float(s) if s in ("nan", "inf", "-inf") else float.fromhex(s)


for line in sys.stdin:
    w = line.split()
    x = [num(s) for s in w[1:]]
    o, d, c, r = x[0:3], x[3:6], x[6:9], x[9]
    f = [o[i] - c[i] for i in range(3)]
    a = d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
    b = 2.0 * (d[0] * f[0] + d[1] * f[1] + d[2] * f[2])
    cc = (f[0] * f[0] + f[1] * f[1] + f[2] * f[2]) - r * r
    disc = b * b - 4.0 * a * cc
    if not disc > 0:
        print("0")
        continue
    s = math.sqrt(disc)
    t0, t1 = (-b - s) / (2.0 * a), (-b + s) / (2.0 * a)
    lo, hi = min(t0, t1), max(t0, t1)
    t = lo if lo > 0 else (hi if hi > 0 else None)
    print("0" if t is None else "1 " + t.hex())
