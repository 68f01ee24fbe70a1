#!/usr/bin/python3
"""A BAL problem of any size ("Bundle Adjustment in the Large" text format),
for timing `aerotri bal` and Ceres at the sizes of the BAL families the
shared data does not hold (Trafalgar 225, Dubrovnik 308, Venice 1,776 and
Final 4,585 cameras).

The scene: Snavely cameras (BAL's model: P = R X + t, p = -P / P_z,
f (1 + k1 |p|^2 + k2 |p|^4) p) in a lawn-mower block over gently rolling
ground, looking down with 2 degrees of random tilt, a 2000 x 1500 px image
at f = 1500 px; points on the ground, each seen by 2 to 8 of the cameras
whose image holds it (uniform), its observations the true projections plus
Gaussian noise of --noise px. The start is the truth perturbed (cameras by
--camera-noise m and 0.5 degrees, points by --point-noise m), as BAL's "pre"
problems start from an incremental reconstruction's estimate.

Usage: /usr/bin/python3 bench/bal_generate.py CAMERAS POINTS OUT.txt
           [--noise 0.5] [--seed 1] [--camera-noise 0.3] [--point-noise 0.3]
Prints the problem's size (cameras, points, observations) on stdout.
"""
import argparse
import math
import sys

import numpy as np


def rotation_from_angle_axis(w):
    theta = np.linalg.norm(w, axis=1, keepdims=True)
    k = np.where(theta > 0, w / np.maximum(theta, 1e-300), 0.0)
    kx, ky, kz = k[:, 0], k[:, 1], k[:, 2]
    zero = np.zeros_like(kx)
    K = np.stack([np.stack([zero, -kz, ky], 1), np.stack([kz, zero, -kx], 1), np.stack([-ky, kx, zero], 1)], 1)
    s = np.sin(theta)[:, :, None]
    c = np.cos(theta)[:, :, None]
    return np.eye(3)[None] + s * K + (1 - c) * (K @ K)


def project(R, t, f, k1, k2, X):
    P = np.einsum("nij,nj->ni", R, X) + t
    p = -P[:, :2] / P[:, 2:3]
    r2 = (p ** 2).sum(1)
    return (f * (1 + k1 * r2 + k2 * r2 * r2))[:, None] * p, P[:, 2]


def main():
    a = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("cameras", type=int)
    a.add_argument("points", type=int)
    a.add_argument("out")
    a.add_argument("--noise", type=float, default=0.5)
    a.add_argument("--seed", type=int, default=1)
    a.add_argument("--camera-noise", type=float, default=0.3)
    a.add_argument("--point-noise", type=float, default=0.3)
    args = a.parse_args()
    if args.cameras < 4 or args.points < 1:
        sys.exit("bal_generate: expected at least 4 cameras and 1 point")
    rng = np.random.default_rng(args.seed)

    # The block: strips 60 m apart, photos 40 m apart along them, at 150 m
    # (a 200 x 150 m footprint: 80 % forward, 60 % side overlap).
    height, f, half_w, half_h = 150.0, 1500.0, 1000.0, 750.0
    strips = max(2, int(round(math.sqrt(args.cameras * 40.0 / 60.0))))
    per_strip = int(math.ceil(args.cameras / strips))
    centres = []
    for s in range(strips):
        for k in range(per_strip):
            if len(centres) == args.cameras:
                break
            kk = k if s % 2 == 0 else per_strip - 1 - k
            centres.append((kk * 40.0, s * 60.0, height))
    C = np.array(centres) + rng.normal(0.0, 1.0, (args.cameras, 3))
    tilt = rng.normal(0.0, math.radians(2.0), (args.cameras, 3))
    R = rotation_from_angle_axis(tilt)
    t = -np.einsum("nij,nj->ni", R, C)
    k1, k2 = -0.05, 0.01

    # Points over the photographed ground, each seen by 2-8 cameras.
    lo, hi = C[:, :2].min(0) - 60.0, C[:, :2].max(0) + 60.0
    cam_of, pt_of, xy = [], [], []
    X = np.empty((args.points, 3))
    made = 0
    camera_xy = C[:, :2]
    while made < args.points:
        batch = min(200000, 2 * (args.points - made))
        g = rng.uniform(lo, hi, (batch, 2))
        z = 3.0 * np.sin(g[:, 0] / 50.0) * np.cos(g[:, 1] / 70.0)
        cand = np.column_stack([g, z])
        for j in range(batch):
            if made == args.points:
                break
            near = np.nonzero(np.abs(camera_xy - cand[j, :2]).max(1) < 95.0)[0]
            if near.size < 2:
                continue
            obs, P_z = project(R[near], t[near], f, k1, k2, np.repeat(cand[j][None], near.size, 0))
            inside = (np.abs(obs[:, 0]) < half_w) & (np.abs(obs[:, 1]) < half_h) & (P_z < 0)
            near, obs = near[inside], obs[inside]
            if near.size < 2:
                continue
            n = int(rng.integers(2, min(8, near.size) + 1))
            pick = rng.choice(near.size, n, replace=False)
            X[made] = cand[j]
            for q in pick:
                cam_of.append(near[q])
                pt_of.append(made)
                xy.append(obs[q] + rng.normal(0.0, args.noise, 2))
            made += 1

    cam_of = np.array(cam_of)
    pt_of = np.array(pt_of)
    xy = np.array(xy)
    order = np.lexsort((cam_of, pt_of))
    # The start: the truth perturbed.
    w0 = tilt + rng.normal(0.0, math.radians(0.5), tilt.shape)
    R0 = rotation_from_angle_axis(w0)
    C0 = C + rng.normal(0.0, args.camera_noise, C.shape)
    t0 = -np.einsum("nij,nj->ni", R0, C0)
    X0 = X + rng.normal(0.0, args.point_noise, X.shape)
    with open(args.out, "w") as out:
        out.write(f"{args.cameras} {args.points} {len(order)}\n")
        np.savetxt(out, np.column_stack([cam_of[order], pt_of[order], xy[order]]), fmt="%d %d %.6f %.6f")
        cams = np.column_stack([w0, t0, np.full(args.cameras, f), np.full(args.cameras, k1), np.full(args.cameras, k2)])
        np.savetxt(out, cams.reshape(-1), fmt="%.12e")
        np.savetxt(out, X0.reshape(-1), fmt="%.12e")
    print(f"cameras={args.cameras} points={args.points} observations={len(order)} noise_px={args.noise}")


if __name__ == "__main__":
    main()
