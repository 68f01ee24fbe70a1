#!/usr/bin/python3
# Camera poses and intrinsics of a finished workspace against the truth of a
# rendered survey (aerotri simulate): camera-centre error (m), rotation error
# (deg) and principal-point offset (px). Both models are COLMAP text in ENU
# frames (the truth at its origin, the workspace at report.json's enu_origin);
# they are compared in ECEF through PROJ (osgeo.osr), never re-derived.
#
# Usage: bench/cameras_vs_truth.py WORKSPACE SURVEY_DIR
# Needs python3-numpy and python3-gdal (Debian): run with /usr/bin/python3.
import json
import sys

import numpy as np
from osgeo import osr


def read_images(path):
    """name -> (R cam_from_world, centre in world)."""
    out = {}
    lines = [l for l in open(path) if not l.startswith("#")]
    for header in lines[0::2]:
        f = header.split()
        if len(f) < 10:
            continue
        qw, qx, qy, qz, tx, ty, tz = map(float, f[1:8])
        R = quat_to_matrix(qw, qx, qy, qz)
        out[f[9]] = (R, -R.T @ np.array([tx, ty, tz]))
    return out


def quat_to_matrix(w, x, y, z):
    n = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def enu_frame(lat, lon, h):
    """(ECEF origin, ECEF-from-ENU rotation) through PROJ."""
    geo = osr.SpatialReference()
    geo.ImportFromEPSG(4979)
    geo.SetAxisMappingStrategy(osr.OAMS_TRADITIONAL_GIS_ORDER)
    ecef = osr.SpatialReference()
    ecef.ImportFromEPSG(4978)
    to_ecef = osr.CoordinateTransformation(geo, ecef)
    origin = np.array(to_ecef.TransformPoint(lon, lat, h))
    la, lo = np.radians(lat), np.radians(lon)
    east = np.array([-np.sin(lo), np.cos(lo), 0.0])
    north = np.array([-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)])
    up = np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])
    return origin, np.column_stack([east, north, up])


def main():
    ws, survey = sys.argv[1], sys.argv[2]
    truth = json.load(open(f"{survey}/truth/truth.json"))
    report = json.load(open(f"{ws}/report.json"))
    o = truth["origin"]
    t_origin, t_rot = enu_frame(o["lat_deg"], o["lon_deg"], o["h_m"])
    e = report["enu_origin"]
    w_origin, w_rot = enu_frame(e["lat_deg"], e["lon_deg"], e["h_m"])
    truth_images = read_images(f"{survey}/truth/model/images.txt")
    ws_images = read_images(f"{ws}/sparse/images.txt")
    d_centre, d_rot = [], []
    for name, (R_w, C_w) in ws_images.items():
        if name not in truth_images:
            continue
        R_t, C_t = truth_images[name]
        c_w = w_origin + w_rot @ C_w
        c_t = t_origin + t_rot @ C_t
        d_centre.append(t_rot.T @ (c_w - c_t))  # in the truth's ENU axes
        # cam_from_ecef for both, then the angle between them
        A = R_w @ w_rot.T
        B = R_t @ t_rot.T
        cos = (np.trace(A @ B.T) - 1) / 2
        d_rot.append(np.degrees(np.arccos(np.clip(cos, -1, 1))))
    d_centre = np.array(d_centre)
    p = report["adjustment"]["intrinsics"][0]["params"]
    tp = dict(zip(truth["camera"]["param_names"], truth["camera"]["params"]))
    print(f"images={len(d_centre)} centre_rmse_m={np.sqrt((d_centre ** 2).sum(1).mean()):.4f} "
          f"centre_mean_enu_m={' '.join(f'{v:+.4f}' for v in d_centre.mean(0))} "
          f"rotation_rms_deg={np.sqrt(np.mean(np.square(d_rot))):.4f} "
          f"df_rel={(p['f'] - tp['f']) / tp['f']:+.5f} dcx_px={p['cx'] - tp['cx']:+.3f} "
          f"dcy_px={p['cy'] - tp['cy']:+.3f}")


if __name__ == "__main__":
    main()
