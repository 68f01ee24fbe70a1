#!/usr/bin/env python3
# Regenerates bal_tiny.txt (run from this folder): 6 cameras on a circle of
# radius 10 looking at 60 points near the origin, Snavely cameras (f 800,
# k1 -0.05, k2 0.01), 0.5 px Gaussian noise on every observation, and
# perturbed initial cameras (f 780, no distortion) and points. Deterministic.
import math
import random

random.seed(7)


def rodrigues(w):
    th = math.sqrt(sum(x * x for x in w))
    if th < 1e-12:
        return [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
    k = [x / th for x in w]
    c, s = math.cos(th), math.sin(th)
    kx = [[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]]
    return [[(1 if i == j else 0) + s * kx[i][j] +
             (1 - c) * sum(kx[i][m] * kx[m][j] for m in range(3))
             for j in range(3)] for i in range(3)]


cams = []
for i in range(6):
    a = 2 * math.pi * i / 6
    w = [0.0, -a, 0.0]  # BAL cameras look down -z: this turns -z to the origin
    r = rodrigues(w)
    c = [10 * math.sin(a), 0.5 * random.gauss(0, 1), 10 * math.cos(a)]
    t = [-sum(r[row][k] * c[k] for k in range(3)) for row in range(3)]
    cams.append((w, t, r))
pts = [[random.uniform(-2, 2) for _ in range(3)] for _ in range(60)]
obs = []
for ci, (w, t, r) in enumerate(cams):
    for pi, x in enumerate(pts):
        p3 = [sum(r[row][k] * x[k] for k in range(3)) + t[row] for row in range(3)]
        if p3[2] >= 0:
            continue
        p = [-p3[0] / p3[2], -p3[1] / p3[2]]
        r2 = p[0] ** 2 + p[1] ** 2
        s = 800 * (1 - 0.05 * r2 + 0.01 * r2 * r2)
        obs.append((ci, pi, s * p[0] + random.gauss(0, 0.5), s * p[1] + random.gauss(0, 0.5)))
with open("bal_tiny.txt", "w") as f:
    f.write(f"{len(cams)} {len(pts)} {len(obs)}\n")
    for o in obs:
        f.write(f"{o[0]} {o[1]} {o[2]:.6f} {o[3]:.6f}\n")
    for (w, t, r) in cams:
        for v in [w[0] + random.gauss(0, 0.01), w[1] + random.gauss(0, 0.01),
                  w[2] + random.gauss(0, 0.01), t[0] + random.gauss(0, 0.05),
                  t[1] + random.gauss(0, 0.05), t[2] + random.gauss(0, 0.05), 780.0, 0.0, 0.0]:
            f.write(f"{v:.9g}\n")
    for x in pts:
        f.write(" ".join(f"{v + random.gauss(0, 0.05):.9g}" for v in x) + "\n")
