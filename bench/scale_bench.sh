#!/usr/bin/env bash
# Scaling benchmark: renders surveys of growing size (aerotri simulate,
# 1200 x 900 px photos, the sample's flight plan over a larger area, control
# and check points growing with the area) and runs the whole `aerotri run`
# on each. Prints, per survey: photos registered, wall time of every stage,
# time per photo, peak memory (and the stage that reached it), check-point
# RMSE and the workspace's size without its deliverables.
# Usage: bench/scale_bench.sh [photos ...]   (default: 100 250 500 1000)
# Env: BENCH_WORK (default /tmp/aerotri_scale_bench), KEEP=1 keeps workspaces,
# REUSE=1 reuses surveys rendered by an earlier KEEP=1 run,
# AEROTRI=path runs another binary (e.g. a copy of build/tools/aerotri and
# aerotri-photo, side by side, while rebuilding).
set -euo pipefail
cd "$(dirname "$0")/.."
exe="${AEROTRI:-$(pwd)/build/tools/aerotri}"
[ -x "$exe" ] || scripts/build.sh >/dev/null
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(100 250 500 1000)
work="${BENCH_WORK:-/tmp/aerotri_scale_bench}"
mkdir -p "$work"

printf "%6s %9s %8s %8s %8s %8s %8s %8s %8s %9s %9s %8s %-12s %8s %8s %9s\n" \
  target photos render_s feat_s match_s recon_s georef_s dense_s ortho_s total_s s/photo peak_MB peak_stage rmse_h_m rmse_v_m interm_MB
for n in "${sizes[@]}"; do
  # About 480 m2 of ground per photo at 60 m with 75 / 65 % overlap; 4:3 area.
  read -r w h control checks < <(awk -v n="$n" 'BEGIN{
    w = sqrt(n * 480 * 4 / 3); c = int(n / 25); k = int(n / 40);
    printf "%.0f %.0f %d %d\n", w, 0.75 * w, (c < 8 ? 8 : (c > 100 ? 100 : c)), (k < 6 ? 6 : (k > 100 ? 100 : k)) }')
  sim="$work/sim_$n" ws="$work/ws_$n"
  rm -rf "$ws"
  t0=$(date +%s.%N)
  if [ -n "${REUSE:-}" ] && [ -d "$sim/images" ]; then
    t0=0; t1=0  # rendered by an earlier run (render_s 0)
  else
    rm -rf "$sim"
    "$exe" simulate -o "$sim" --seed 7 --width 1200 --height 900 --area-width "$w" --area-height "$h" \
      --control "$control" --checks "$checks" --quiet >/dev/null
    t1=$(date +%s.%N)
  fi
  "$exe" run "$sim/images" --gcp "$sim/gcp_list.txt" --checkpoints "$sim/checkpoints.txt" -o "$ws" \
    --leave-one-out off --quiet >"$work/run_$n.txt" || true
  /usr/bin/python3 - "$ws" "$n" "$(awk -v a="$t0" -v b="$t1" 'BEGIN{print b - a}')" <<'PY'
import json, os, sys
ws, target, render = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
r = json.load(open(ws + "/report.json"))
t = json.load(open(ws + "/timings.json"))
w = lambda k: t.get(k, {}).get("wall_s", 0.0)
photos = r["images"]["total"] if "total" in r["images"] else len(r["images"].get("per_image", []))
reg = r["images"]["registered"]
total = sum(v["wall_s"] for v in t.values())
peak_stage = max(t, key=lambda k: t[k].get("peak_rss_mb", 0))
peak = max(v.get("process_peak_rss_mb", v.get("peak_rss_mb", 0)) for v in t.values())
cp = r.get("check_points", {})
deliverables = {"cloud.las", "cloud.laz", "cloud.copc.laz", "cloud.ply", "dsm.tif", "dtm.tif", "ortho.tif", "contours.gpkg", "report.html",
                "report.json", "cameras.csv", "cameras.gpkg", "exterior_orientation.csv", "sparse"}
interm = 0
for root, dirs, files in os.walk(ws):
    top = os.path.relpath(root, ws).split(os.sep)[0]
    for f in files:
        if (f if top == "." else top) not in deliverables:
            interm += os.path.getsize(os.path.join(root, f))
print("%6d %9s %8.0f %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %9.1f %9.2f %8.0f %-12s %8.4f %8.4f %9.1f" % (
    target, "%d/%d" % (reg, photos), render, w("features") + w("ingest"), w("match"), w("reconstruct"),
    w("georeference"), w("dense"), w("ortho"), total, total / max(reg, 1), peak, peak_stage,
    cp.get("rmse_h_m", float("nan")), cp.get("rmse_z_m", float("nan")), interm / 2**20))
PY
  [ -n "${KEEP:-}" ] || rm -rf "$sim" "$ws"
done
