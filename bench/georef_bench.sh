#!/usr/bin/env bash
# The survey adjustment (the georeference stage) per phase, at growing size:
# rendered surveys' models without their photos (`aerotri simulate
# --no-images`: 1200 x 900 px, the sample's flight plan over a larger area,
# GPS at 2 / 4 m, control and check points growing with the area, tie points
# 380 a photo as the scale bench's reconstructions hold), each adjusted by
# `aerotri adjust` with leave-one-out; then `aerotri bal` on a BAL problem of
# the same cameras, points and observations (bench/model_to_bal.py), in the
# same run, as the yardstick: the survey's time over it is the ratio.
#
# Prints per survey: photos, points, observations; per phase wall and CPU
# seconds and resident peak (report.json adjustment.phases); the solves
# (screening, least squares, outlier rounds, variance components) and the
# precision pass; the whole run's wall time and peak (/usr/bin/time); the
# BAL solve's; and the ratio.
#
# Usage: bench/georef_bench.sh [photos ...]   (default: 60 500 1000)
# Env: BENCH_WORK (default /tmp/aerotri_georef_bench), KEEP=1 keeps the
# surveys, AEROTRI=path runs another binary, THREADS (default 2), LOO=off
# leaves leave-one-out out, CERES=1 also runs the same adjustment on Ceres'
# solver (`aerotri adjust --solver ceres`, the reference) and prints its
# phases and the ratio beside aerotri's.
set -euo pipefail
cd "$(dirname "$0")/.."
exe="${AEROTRI:-$(pwd)/build/tools/aerotri}"
[ -x "$exe" ] || scripts/build.sh >/dev/null
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(60 500 1000)
work="${BENCH_WORK:-/tmp/aerotri_georef_bench}"
threads="${THREADS:-2}"
mkdir -p "$work"

for n in "${sizes[@]}"; do
  # About 480 m2 of ground per photo at 60 m with 75 / 65 % overlap; 4:3 area.
  read -r w h control checks points < <(awk -v n="$n" 'BEGIN{
    w = sqrt(n * 480 * 4 / 3); c = int(n / 25); k = int(n / 40);
    printf "%.0f %.0f %d %d %d\n", w, 0.75 * w, (c < 8 ? 8 : (c > 100 ? 100 : c)), (k < 6 ? 6 : (k > 100 ? 100 : k)),
      n * 380 }')
  sim="$work/sim_$n" out="$work/adjust_$n" bal="$work/bal_$n.txt"
  if [ ! -f "$sim/gps.csv" ]; then
    "$exe" simulate -o "$sim" --no-images --seed 7 --width 1200 --height 900 --area-width "$w" --area-height "$h" \
      --control "$control" --checks "$checks" --tie-points "$points" --quiet >/dev/null
  fi
  [ -f "$bal" ] || /usr/bin/python3 bench/model_to_bal.py "$sim" "$bal" >/dev/null
  adjust() {  # solver, output folder, time file
    rm -rf "$2"
    /usr/bin/time -f "%e %M" -o "$3" "$exe" adjust --model "$sim/model" --gps-csv "$sim/gps.csv" \
      --gcp "$sim/gcp_list.txt" --checkpoints "$sim/checkpoints.txt" --leave-one-out "${LOO:-on}" \
      --threads "$threads" --solver "$1" --quiet -o "$2" >/dev/null || true
  }
  adjust auto "$out" "$work/adjust_$n.time"
  /usr/bin/time -f "%e %M" -o "$work/bal_$n.time" "$exe" bal "$bal" --threads "$threads" \
    >"$work/bal_$n.out" 2>/dev/null || true
  ceres_report="" ceres_time=""
  if [ -n "${CERES:-}" ]; then
    adjust ceres "$out.ceres" "$work/adjust_$n.ceres.time"
    ceres_report="$out.ceres/report.json" ceres_time="$work/adjust_$n.ceres.time"
  fi
  /usr/bin/python3 - "$out/report.json" "$work/adjust_$n.time" "$work/bal_$n.time" "$work/bal_$n.out" \
    "$ceres_report" "$ceres_time" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
a_wall, a_kb = (float(x) for x in open(sys.argv[2]).read().split()[-2:])
b_wall, b_kb = (float(x) for x in open(sys.argv[3]).read().split()[-2:])
bal = open(sys.argv[4]).read().split()
adj = r["adjustment"]
cp = r.get("check_points", {})
print("\n%d photos, %d points, %d observations, %d control, %d check points: status %s, sigma0 %.3f, "
      "check RMSE H / V %.4f / %.4f m" % (adj["images"], adj["points"], adj["observations"], adj["gcp_priors"],
      cp.get("count", 0), r.get("status", "?"), adj["sigma0"], cp.get("rmse_h_m", float("nan")),
      cp.get("rmse_z_m", float("nan"))))
print("  %-34s %9s %9s %9s" % ("phase", "wall_s", "cpu_s", "peak_MB"))
for p in adj.get("phases", []):
    print("  %-34s %9.2f %9.2f %9.0f" % (p["phase"], p["wall_s"], p["cpu_s"], p["peak_rss_mb"]))
for s in adj.get("solves", []):
    print("    solve: %-28s %9.2f s %4d iterations" % (s["kind"], s["time_s"], s["iterations"]))
prec = adj.get("precision", {})
print("    precision pass (the last)          %9.2f s" % prec.get("time_s", 0.0))
loo = r.get("leave_one_out", {})
if loo.get("computed"):
    print("    leave-one-out: %d points, %d updated, %.2f s" % (loo.get("count", len(loo.get("points", []))),
          loo["updated"], loo["time_s"]))
# The phases restart the kernel's high-water mark, which getrusage (and so
# /usr/bin/time) then reports from: the run's peak is the largest phase's.
a_mb = max([a_kb / 1024] + [p["peak_rss_mb"] for p in adj.get("phases", [])])
print("  %-34s %9.2f %9s %9.0f" % ("aerotri adjust (whole run)", a_wall, "", a_mb))
print("  %-34s %9.2f %9s %9.0f   %s" % ("aerotri bal, same size", b_wall, "", b_kb / 1024,
      " ".join(w for w in bal if w.startswith(("iterations=", "rms_px=")))))
print("  ratio adjust / bal: %.2f (wall), %.2f (peak memory)" % (a_wall / max(b_wall, 1e-9), a_mb * 1024 / max(b_kb, 1)))
print("  solver: %s" % adj.get("linear_solver", "?"))
if sys.argv[5]:
    c = json.load(open(sys.argv[5]))
    c_wall, c_kb = (float(x) for x in open(sys.argv[6]).read().split()[-2:])
    cadj = c["adjustment"]
    ours = {p["phase"]: p for p in adj.get("phases", [])}
    print("  Ceres' solver (--solver ceres: %s), the same adjustment:" % cadj.get("linear_solver", "?"))
    print("  %-34s %9s %9s %9s %9s" % ("phase", "wall_s", "peak_MB", "aerotri_s", "ratio"))
    for p in cadj.get("phases", []):
        o = ours.get(p["phase"])
        print("  %-34s %9.2f %9.0f %9s %9s" % (p["phase"], p["wall_s"], p["peak_rss_mb"],
              "%.2f" % o["wall_s"] if o else "-", "%.2f" % (o["wall_s"] / p["wall_s"]) if o and p["wall_s"] > 0 else "-"))
    c_mb = max([c_kb / 1024] + [p["peak_rss_mb"] for p in cadj.get("phases", [])])
    print("  %-34s %9.2f %9.0f %9.2f %9.2f" % ("whole run", c_wall, c_mb, a_wall, a_wall / max(c_wall, 1e-9)))
    print("  sigma0 %.6f / %.6f, check RMSE H %.5f / %.5f m (aerotri / Ceres)" % (adj["sigma0"], cadj["sigma0"],
          r.get("check_points", {}).get("rmse_h_m", float("nan")), c.get("check_points", {}).get("rmse_h_m", float("nan"))))
PY
  [ -n "${KEEP:-}" ] || rm -rf "$sim" "$out" "$out.ceres" "$bal"
done
