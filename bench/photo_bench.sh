#!/usr/bin/env bash
# Photo pipeline benchmark: aerotri and COLMAP (Debian package, CPU) on the
# same real photos from ../shared/data; prints images registered, RMS and the
# time of every stage, and the total, for each tool.
# Usage: bench/photo_bench.sh [set ...]   (default: drone_brighton_beach fixedwing_seneca)
# COLMAP is skipped when not installed (apt-get install colmap) or SKIP_COLMAP=1.
set -euo pipefail
cd "$(dirname "$0")/.."
exe="$(pwd)/build/tools/aerotri"
[ -x "$exe" ] || scripts/build.sh >/dev/null
data="$(pwd)/../shared/data"
sets=("$@")
[ ${#sets[@]} -gt 0 ] || sets=(drone_brighton_beach fixedwing_seneca)
work="${BENCH_WORK:-/tmp/aerotri_photo_bench}"
mkdir -p "$work"
export QT_QPA_PLATFORM=offscreen

now() { date +%s.%N; }
elapsed() { awk "BEGIN{printf \"%.1f\", $2 - $1}"; }

printf "%-22s %-8s %10s %8s %10s %10s %10s %10s %14s %9s %8s\n" set tool registered rms_px features_s matching_s mapping_s georef_s sparse_total_s dense_s rss_MB
for s in "${sets[@]}"; do
  images="$data/$s/images"
  [ -d "$images" ] || { echo "photo_bench: $images is absent" >&2; continue; }
  total_images=$(ls "$images" | wc -l)

  ws="$work/aerotri_$s"
  rm -rf "$ws"
  t0=$(now)
  "$exe" run "$images" -o "$ws" --quiet >/dev/null
  t1=$(now)
  # Peak memory from the run's own timings.json: each stage restarts the
  # kernel's high-water mark, so /usr/bin/time would give the last stage's.
  read -r reg rms tf tm tr tg sparse dense rss < <(/usr/bin/python3 - "$ws" <<'PY'
import json, sys
r = json.load(open(sys.argv[1] + "/report.json"))
t = json.load(open(sys.argv[1] + "/timings.json"))
w = lambda k: t.get(k, {}).get("wall_s", 0.0)
sparse = w("ingest") + w("features") + w("match") + w("reconstruct") + w("georeference")
rss = max(v.get("process_peak_rss_mb", v.get("peak_rss_mb", 0)) for v in t.values())
print(r["images"]["registered"], round(r["adjustment"]["final_rms_px"], 3),
      round(w("ingest") + w("features"), 1), round(w("match"), 1), round(w("reconstruct"), 1),
      round(w("georeference"), 1), round(sparse, 1), round(w("dense") + w("report"), 1), round(rss))
PY
)
  printf "%-22s %-8s %10s %8s %10s %10s %10s %10s %14s %9s %8.0f\n" "$s" aerotri "$reg/$total_images" "$rms" "$tf" "$tm" "$tr" "$tg" \
    "$sparse" "$dense" "$rss"

  { [ -z "${SKIP_COLMAP:-}" ] && command -v colmap >/dev/null; } || continue
  cw="$work/colmap_$s"
  rm -rf "$cw" && mkdir -p "$cw/sparse"
  t0=$(now)
  colmap feature_extractor --database_path "$cw/db.db" --image_path "$images" \
    --SiftExtraction.use_gpu 0 --SiftExtraction.max_image_size 3200 >/dev/null 2>&1
  t1=$(now)
  colmap spatial_matcher --database_path "$cw/db.db" --SiftMatching.use_gpu 0 >/dev/null 2>&1
  t2=$(now)
  colmap mapper --database_path "$cw/db.db" --image_path "$images" --output_path "$cw/sparse" >/dev/null 2>&1 || true
  t3=$(now)
  reg=0
  rms="-"
  if [ -d "$cw/sparse/0" ]; then
    colmap model_converter --input_path "$cw/sparse/0" --output_path "$cw/sparse/0" --output_type TXT >/dev/null 2>&1
    reg=$(grep -v '^#' "$cw/sparse/0/images.txt" | awk 'NR % 2 == 1' | grep -c . || true)
    rms=$(colmap model_analyzer --path "$cw/sparse/0" 2>&1 | sed -nE 's/.*Mean reprojection error: ([0-9.]+)px.*/\1/p' | head -1)
  fi
  printf "%-22s %-8s %10s %8s %10s %10s %10s %10s %14s %9s %8s\n" "$s" colmap "$reg/$total_images" "${rms:--}" \
    "$(elapsed "$t0" "$t1")" "$(elapsed "$t1" "$t2")" "$(elapsed "$t2" "$t3")" "-" "$(elapsed "$t0" "$t3")" "-" "-"
done
echo "(sparse_total_s: photos to adjusted sparse survey, what COLMAP's three steps do; dense_s: aerotri's dense cloud, LAS/PLY, DSM and report)"
echo "(aerotri rms_px: RMS at its working resolution, 1600 px; COLMAP: its mean reprojection error)"
