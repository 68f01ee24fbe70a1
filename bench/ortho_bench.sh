#!/usr/bin/env bash
# Orthomosaic benchmark: the ortho stage alone (aerotri ortho --force) on the
# bundled sample survey and on the real beach set (../shared/data, skipped
# when absent), each on a finished workspace (made first when missing).
# Prints photos, ortho size, wall time, time per photo, peak memory of the
# ortho process, the ratio of its time to the same workspace's dense stage
# (both measured on this machine: a ratio survives a noisy machine better
# than seconds), and where the survey has check points, the orthomosaic's
# horizontal RMSE at the located targets against the GSD.
# Usage: bench/ortho_bench.sh [sample|beach ...]   (default: both)
set -euo pipefail
cd "$(dirname "$0")/.."
exe="$(pwd)/build/tools/aerotri"
[ -x "$exe" ] || scripts/build.sh >/dev/null
work="${BENCH_WORK:-/tmp/aerotri_ortho_bench}"
mkdir -p "$work"
sets=("$@")
[ ${#sets[@]} -gt 0 ] || sets=(sample beach)

printf "%-8s %6s %12s %8s %9s %8s %16s %12s %8s\n" set photos ortho_cells ortho_s s_per_photo rss_MB ortho_s/dense_s rmse_h_m gsd_m
for s in "${sets[@]}"; do
  case $s in
    sample) images=sample_surveys/synthetic_meadow/images
            extra=(--gcp sample_surveys/synthetic_meadow/gcp_list.txt
                   --checkpoints sample_surveys/synthetic_meadow/checkpoints.txt) ;;
    beach) images=../shared/data/drone_brighton_beach/images; extra=() ;;
    *) echo "ortho_bench: unknown set $s (sample, beach)" >&2; continue ;;
  esac
  [ -d "$images" ] || { echo "ortho_bench: $images is absent; $s skipped" >&2; continue; }
  ws="$work/$s"
  [ -f "$ws/ortho.json" ] || "$exe" run "$images" "${extra[@]}" -o "$ws" --quiet >/dev/null
  /usr/bin/time -f "%M %e" -o "$work/time.txt" "$exe" ortho --survey "$ws" --force --quiet
  read -r rss_kb wall < "$work/time.txt"
  /usr/bin/python3 - "$ws" "$s" "$rss_kb" "$wall" <<'PY'
import json, sys
ws, name, rss_kb, wall = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
o = json.load(open(ws + "/ortho.json"))["ortho"]
r = json.load(open(ws + "/report.json"))
dense = r["timings"]["dense"]["wall_s"]
photos = r["images"]["registered"]
cp = r.get("ortho", {}).get("check_points", {})
rmse = "%.4f" % cp["rmse_h_m"] if cp.get("count", 0) > 0 else "n/a"
print("%-8s %6d %12s %8.1f %9.2f %8.0f %16.2f %12s %8.4f" % (
    name, photos, "%dx%d" % (o["width"], o["height"]), wall, wall / photos, rss_kb / 1024.0, wall / dense,
    rmse, r["gsd_m"]))
PY
done
