#!/usr/bin/env bash
# Disk-full test: the sample survey runs with a file-size limit (ulimit -f,
# the same EFBIG a full disk or a quota gives a writer) that the dense
# stage's first large file exceeds. The run must exit 1 naming the file,
# leave no product a rerun would take as done and no temporary file; once
# the limit is lifted the rerun resumes from the stages that finished and
# completes. Usage: disk_full.sh AEROTRI SAMPLE_DIR WORK_DIR
set -euo pipefail
exe=$1 sample=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
args=("$sample/images" --gcp "$sample/gcp_list.txt" --checkpoints "$sample/checkpoints.txt"
      --max-dimension 800 --dense-resolution 0.3 --leave-one-out off -o "$work/ws")
status=0
fail() { echo "FAIL: $*" >&2; status=1; }

# 2.5 MiB per file: features, matches and the sparse model (1.8 MB) fit; the
# dense stage's depth points (3-5 MB per pair) do not.
set +e
(ulimit -f 2560; exec "$exe" run "${args[@]}") >"$work/full.out" 2>"$work/full.log"
code=$?
set -e
error=$(grep -E 'error: ' "$work/full.log" | head -1)
echo "with the limit: exit $code; $error"
[ "$code" = 1 ] || fail "exit code $code, expected 1"
echo "$error" | grep -Eq "error: $work/ws/depth/[^ ]+: write failed: File too large" ||
  fail "the error does not name the file and the failure: $error"
for f in cloud.laz cloud.ply dsm.tif dtm.tif ortho.tif dense.json; do
  [ ! -e "$work/ws/$f" ] || fail "$f exists after the failed dense stage"
done
[ -f "$work/ws/report.json" ] || fail "the georeference stage's report.json is missing"
left=$(find "$work/ws" -name '*.tmp.*' -o -name '_*_work.tif')
[ -z "$left" ] || fail "temporary files left: $left"

# Space is back: the rerun resumes (the sparse stages are not redone) and completes.
"$exe" run "${args[@]}" >"$work/resumed.out" 2>"$work/resumed.log" || fail "the rerun failed: $(tail -3 "$work/resumed.log")"
grep -q 'status=ok' "$work/resumed.out" || fail "the rerun's status: $(cat "$work/resumed.out")"
grep -q '^georeference: done already' "$work/resumed.log" || fail "the rerun redid the georeference stage"
for f in cloud.laz dsm.tif dtm.tif contours.gpkg ortho.tif report.html; do
  [ -s "$work/ws/$f" ] || fail "$f missing after the rerun"
done
cat "$work/resumed.out"
exit $status
