#!/usr/bin/env python3
"""A rendered survey whose GPS scatters 12 m while its file states 3 m.

Usage: poor_gps.py AEROTRI SAMPLE_DIR WORK_DIR

The bundled sample's GPS (sample_surveys/synthetic_meadow/gps.csv) with
12 m of Gaussian noise added per axis (seeded) and sigma columns of 3 m,
adjusted by `aerotri adjust` without control. A consumer GPS is poor, not
inconsistent: the survey must be delivered (exit 0, status "warnings", no
error), the adjustment's estimate of the GPS sigma must lie within 30 % of
the 12 m injected, and the report must state the placement it rests on.
Exits 1 naming what failed.
"""
import csv
import json
import math
import os
import random
import subprocess
import sys

NOISE_M, STATED_M, SEED = 12.0, 3.0, 1


def fail(message):
    print("FAIL: " + message)
    sys.exit(1)


def main():
    exe, sample, work = sys.argv[1], sys.argv[2], sys.argv[3]
    os.makedirs(work, exist_ok=True)
    noisy = os.path.join(work, "gps_12m.csv")
    rng = random.Random(SEED)
    with open(os.path.join(sample, "gps.csv")) as f, open(noisy, "w") as out:
        rows = list(csv.reader(f))
        out.write("name,lat,lon,alt,sigma_h,sigma_v\n")
        for name, lat, lon, alt in rows[1:]:
            lat, lon, alt = float(lat), float(lon), float(alt)
            de, dn, du = (rng.gauss(0.0, NOISE_M) for _ in range(3))
            lat2 = lat + math.degrees(dn / 6378137.0)
            lon2 = lon + math.degrees(de / (6378137.0 * math.cos(math.radians(lat))))
            out.write(f"{name},{lat2:.10f},{lon2:.10f},{alt + du:.4f},{STATED_M},{STATED_M}\n")
    output = os.path.join(work, "adjusted")
    run = subprocess.run([exe, "adjust", "--model", os.path.join(sample, "model"), "--gps-csv", noisy,
                          "--checkpoints", os.path.join(sample, "checkpoints.txt"), "-o", output, "--quiet"],
                         capture_output=True, text=True)
    print(run.stdout + run.stderr)
    if run.returncode != 0:
        fail(f"exit code {run.returncode}: a poor GPS is not a failed survey")
    report = json.load(open(os.path.join(output, "report.json")))
    if report["status"] != "warnings" or report["errors"]:
        fail(f"status {report['status']}, errors {report['errors']}")
    groups = {g["group"]: g for g in report["adjustment"]["variance_components"]["groups"]}
    for name in ("gps_horizontal", "gps_vertical"):
        estimated = groups[name]["estimated_sigma"]
        print(f"{name}: estimated {estimated:.2f} m (injected {NOISE_M}, stated {STATED_M})")
        if not (0.7 * NOISE_M < estimated < 1.3 * NOISE_M):
            fail(f"{name} estimated {estimated:.2f} m, not within 30 % of {NOISE_M} m")
    if "placement" not in report:
        fail("report.json states no placement")
    placement = report["placement"]
    print(f"placement: {placement['sigma_h_m']:.2f} m horizontally, {placement['sigma_v_m']:.2f} m vertically")
    if not any(w["code"] == "SIGMAS_OPTIMISTIC" and "placement" in w["message"] for w in report["warnings"]):
        fail("no warning states the placement the GPS gives")
    codes = {w["code"] for w in report["warnings"]}
    for code in ("GPS_INCONSISTENT", "PRIORS_INCONSISTENT"):
        if code in codes:
            fail(f"{code}: a poor GPS judged against its stated sigma")
    print("ok")


if __name__ == "__main__":
    main()
