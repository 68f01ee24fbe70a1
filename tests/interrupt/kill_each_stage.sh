#!/usr/bin/env bash
# Interruption test: runs the sample survey once uninterrupted, then again
# with SIGKILL at the start of every stage in turn (each rerun resumes, gets
# one stage further and is killed there), then lets it finish; the resumed
# survey's deliverables must equal the uninterrupted one's, and no temporary
# file may remain. Usage: kill_each_stage.sh AEROTRI SAMPLE_DIR WORK_DIR
set -euo pipefail
exe=$1 sample=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
# A reduced working resolution and dense spacing, and no leave-one-out
# adjustments, keep the run under a minute.
args=("$sample/images" --gcp "$sample/gcp_list.txt" --checkpoints "$sample/checkpoints.txt"
      --max-dimension 800 --dense-resolution 0.3 --leave-one-out off)

"$exe" run "${args[@]}" -o "$work/reference" 2>"$work/reference.log" >"$work/reference.out" ||
  { cat "$work/reference.log" >&2; echo "the uninterrupted run failed" >&2; exit 1; }

# stage: the stderr prefix that shows it has started (report prints none of
# its own: it starts when the ortho stage's last line is out).
kills=0
for stage in ingest features match reconstruct georeference dense ortho report; do
  marker="^$stage:"
  [ "$stage" = report ] && marker='^ortho: [0-9]+ x [0-9]+ at'
  log=$work/killed_at_$stage.log
  "$exe" run "${args[@]}" -o "$work/resumed" 2>"$log" >/dev/null &
  pid=$!
  while kill -0 "$pid" 2>/dev/null && ! grep -Eq "$marker" "$log"; do sleep 0.02; done
  if kill -9 "$pid" 2>/dev/null; then
    kills=$((kills + 1))
    echo "killed at the start of $stage: $(grep -E "$marker" "$log" | head -1)"
  else
    echo "$stage: the run ended before the kill"
  fi
  wait "$pid" 2>/dev/null || true
done
[ "$kills" -ge 5 ] || { echo "only $kills of 8 kills landed" >&2; exit 1; }

"$exe" run "${args[@]}" -o "$work/resumed" 2>"$work/final.log" >"$work/resumed.out" ||
  { cat "$work/final.log" >&2; echo "the resumed run failed" >&2; exit 1; }

# Multi-threaded solves are not bit-for-bit repeatable (the last digits of a
# sum depend on its order), so the deliverables are compared to within what
# that explains: cameras to 1 mm; DSM cells to 1 mm but for one in a thousand,
# and none beyond 5 cm (cameras a micrometre apart can move a fused point
# across a cell or voxel boundary, which changes that cell by the local
# relief); point counts to 1 in 10,000.
status=0
max_diff() {  # max_diff FILE_A FILE_B FIRST_COLUMN LAST_COLUMN (comma- or space-separated numbers)
  paste -d'|' "$1" "$2" | awk -F'|' -v a="$3" -v b="$4" '
    { n = split($1, x, /[ ,]+/); split($2, y, /[ ,]+/)
      for (i = a; i <= b && i <= n; ++i) { d = x[i] - y[i]; if (d < 0) d = -d; if (d > m) m = d } }
    END { printf "%.6f", m + 0 }'
}
beyond() {  # beyond FILE_A FILE_B COLUMN TOLERANCE: the fraction of lines that differ by more
  paste -d'|' "$1" "$2" | awk -F'|' -v c="$3" -v t="$4" '
    { split($1, x, /[ ,]+/); split($2, y, /[ ,]+/); d = x[c] - y[c]; if (d < 0) d = -d; n++; if (d > t) k++ }
    END { printf "%.6f", n ? k / n : 1 }'
}
within() {  # within LABEL VALUE LIMIT
  if awk -v v="$2" -v l="$3" 'BEGIN { exit !(v <= l) }'; then
    echo "$1: max difference $2 (limit $3)"
  else
    echo "$1: max difference $2 exceeds $3" >&2
    status=1
  fi
}
tail -n +2 "$work/reference/cameras.csv" >"$work/cameras_a"
tail -n +2 "$work/resumed/cameras.csv" >"$work/cameras_b"
within "cameras.csv (m)" "$(max_diff "$work/cameras_a" "$work/cameras_b" 2 4)" 0.001
gdal_translate -q -of XYZ "$work/reference/dsm.tif" "$work/dsm_a.xyz"
gdal_translate -q -of XYZ "$work/resumed/dsm.tif" "$work/dsm_b.xyz"
[ "$(wc -l <"$work/dsm_a.xyz")" = "$(wc -l <"$work/dsm_b.xyz")" ] || { echo "DSM sizes differ" >&2; status=1; }
within "dsm.tif (m)" "$(max_diff "$work/dsm_a.xyz" "$work/dsm_b.xyz" 1 3)" 0.05
within "dsm.tif cells beyond 1 mm (fraction)" "$(beyond "$work/dsm_a.xyz" "$work/dsm_b.xyz" 3 0.001)" 0.001
las_points() { od -An -t u8 -j 247 -N 8 "$1" | tr -d ' '; }  # LAS / LAZ 1.4: number of point records
a=$(las_points "$work/reference/cloud.laz") b=$(las_points "$work/resumed/cloud.laz")
echo "cloud.laz: $a and $b points"
# Cameras a micrometre apart (threaded solves) can move a fused point across
# a voxel boundary: counts agree to 1 in 10,000, not to the point.
[ "$a" -gt 0 ] && [ $(( (a > b ? a - b : b - a) * 10000 )) -le "$a" ] ||
  { echo "cloud.laz point counts differ by more than 0.01 %" >&2; status=1; }
# The orthomosaic and the terrain products are there, on the same grids.
for f in ortho.tif dtm.tif contours.gpkg; do
  [ -s "$work/resumed/$f" ] || { echo "resumed run lacks $f" >&2; status=1; }
done
size() { gdalinfo "$1" | grep '^Size is'; }
[ "$(size "$work/reference/ortho.tif")" = "$(size "$work/resumed/ortho.tif")" ] ||
  { echo "ortho.tif sizes differ" >&2; status=1; }
# stdout's figures line, without the report path.
ref=$(sed 's/^report=[^ ]* //' "$work/reference.out")
res=$(sed 's/^report=[^ ]* //' "$work/resumed.out")
echo "uninterrupted: $ref"
echo "resumed:       $res"
[ "$ref" = "$res" ] || { echo "the figures differ" >&2; status=1; }
left=$(find "$work/resumed" -name '*.tmp.*' -o -name '_*_work.tif')
[ -z "$left" ] || { echo "temporary files left: $left" >&2; status=1; }
exit $status
