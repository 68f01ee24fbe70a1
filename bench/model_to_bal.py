#!/usr/bin/python3
"""A BAL problem of the same size as a rendered survey's model: the same
cameras, points and observations (`aerotri simulate` writes the model and its
truth), for setting the survey adjustment's time beside `aerotri bal`'s on a
problem of equal size (bench/georef_bench.sh).

Each observation is its point's true projection through its camera's true
pose as a BAL (Snavely) camera of the true focal length without distortion,
plus Gaussian noise of --noise px; the start is the simulated model's
(perturbed) cameras and points, in that model's own frame and scale, with
f the true focal length and k1 = k2 = 0. BAL's conventions: P = R X + t,
p = -P / P_z, image origin at the centre, y up.

Usage: /usr/bin/python3 bench/model_to_bal.py SIM_DIR OUT.txt [--noise 0.3] [--seed 1]
Prints the problem's size (cameras, points, observations) on stdout.
"""
import argparse
import sys

import numpy as np


def read_model(folder):
    cameras = {}
    with open(folder + "/cameras.txt") as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = line.split()
            cameras[int(v[0])] = [float(x) for x in v[4:]]
    images = {}
    with open(folder + "/images.txt") as f:
        lines = [l for l in f if not l.startswith("#")]
    for k in range(0, len(lines) - 1, 2):
        v = lines[k].split()
        if not v:
            continue
        images[int(v[0])] = (np.array([float(x) for x in v[1:5]]), np.array([float(x) for x in v[5:8]]), int(v[8]))
    points = {}
    tracks = {}
    with open(folder + "/points3D.txt") as f:
        for line in f:
            if line.startswith("#") or not line.strip():
                continue
            v = line.split()
            pid = int(v[0])
            points[pid] = np.array([float(x) for x in v[1:4]])
            tracks[pid] = [int(x) for x in v[8::2]]
    return cameras, images, points, tracks


def rotation(q):
    w, x, y, z = q / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def angle_axis(R):
    c = np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)
    theta = np.arccos(c)
    if theta < 1e-12:
        return np.zeros(3)
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if np.pi - theta < 1e-6:  # near a half turn: the axis from the symmetric part
        axis = np.sqrt(np.maximum((np.diag(R) + 1) / 2, 0.0))
        axis[1:] *= np.sign(np.where(w[1:] == 0, 1.0, w[1:]) * np.sign(w[0] if w[0] != 0 else 1.0))
        return theta * axis / np.linalg.norm(axis)
    return theta * w / (2 * np.sin(theta))


def main():
    a = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    a.add_argument("sim")
    a.add_argument("out")
    a.add_argument("--noise", type=float, default=0.3)
    a.add_argument("--seed", type=int, default=1)
    args = a.parse_args()
    rng = np.random.default_rng(args.seed)
    tcams, timgs, tpts, tracks = read_model(args.sim + "/truth/model")
    _, simgs, spts, _ = read_model(args.sim + "/model")
    flip = np.diag([1.0, -1.0, -1.0])  # COLMAP's camera (z forward, y down) to BAL's (looks down -z, y up)
    image_ids = sorted(i for i in timgs if i in simgs)
    point_ids = sorted(p for p in tpts if p in spts)
    if not image_ids or not point_ids:
        sys.exit("model_to_bal: %s/model and its truth share no images or points" % args.sim)
    cam_index = {i: k for k, i in enumerate(image_ids)}
    pose = {i: (rotation(timgs[i][0]), timgs[i][1]) for i in image_ids}
    obs = []
    for k, pid in enumerate(point_ids):
        X = tpts[pid]
        for i in tracks[pid]:
            if i not in cam_index:
                continue
            R, t = pose[i]
            P = R @ X + t
            if P[2] <= 0:
                continue
            f = tcams[timgs[i][2]][0]
            obs.append((cam_index[i], k, f * P[0] / P[2], -f * P[1] / P[2]))
    obs = np.array(obs)
    obs[:, 2:] += rng.normal(0.0, args.noise, (len(obs), 2))
    with open(args.out, "w") as out:
        out.write("%d %d %d\n" % (len(image_ids), len(point_ids), len(obs)))
        for c, p, x, y in obs:
            out.write("%d %d %.6f %.6f\n" % (c, p, x, y))
        for i in image_ids:
            R = flip @ rotation(simgs[i][0])
            t = flip @ simgs[i][1]
            f = tcams[timgs[i][2]][0]
            for v in list(angle_axis(R)) + list(t) + [f, 0.0, 0.0]:
                out.write("%.17g\n" % v)
        for pid in point_ids:
            for v in spts[pid]:
                out.write("%.17g\n" % v)
    print(len(image_ids), len(point_ids), len(obs))


if __name__ == "__main__":
    main()
