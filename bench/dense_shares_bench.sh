#!/usr/bin/env bash
# The dense stage in one process against the same stage as a split
# workflow's jobs (aerotri dense --depth-share K/N, --fuse-share K/N,
# --from-shares N), one after the other on one georeferenced workspace, and
# prints per job its wall time and peak memory, the totals and their ratio to
# the one-process stage, and whether both made the same cloud (points, depth
# points, pairs, fusion tiles) and the same DSM (cell for cell).
# Usage: bench/dense_shares_bench.sh WORKSPACE [N]
#   WORKSPACE: a workspace past `aerotri georeference` (e.g. a KEEP=1 scale_bench.sh one);
#   its dense products are rewritten. N: shares (default 4).
# Env: AEROTRI=path (binary; aerotri-photo beside it), THREADS (default 2).
set -euo pipefail
cd "$(dirname "$0")/.."
ws="${1:?usage: bench/dense_shares_bench.sh WORKSPACE [N]}"
n="${2:-4}"
threads="${THREADS:-2}"
exe="${AEROTRI:-$(pwd)/build/tools/aerotri}"
[ -x "$exe" ] || scripts/build.sh >/dev/null
[ -e "$ws/georeferenced/images.txt" ] || { echo "dense_shares_bench: $ws is not georeferenced" >&2; exit 1; }
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# wall seconds and peak RSS (MB) of one command, appended to $work/jobs
job() {
  local name="$1"
  shift
  /usr/bin/time -f "%e %M" -o "$work/t" "$@" --quiet --threads "$threads"
  read -r wall kb <"$work/t"
  echo "$name $wall $((kb / 1024))" >>"$work/jobs"
}
job "dense (one process)" "$exe" dense -o "$ws" --force
cp "$ws/dense.json" "$work/whole.json"
cp "$ws/dsm.tif" "$work/whole_dsm.tif"
for k in $(seq 1 "$n"); do job "depth $k/$n" "$exe" dense -o "$ws" --depth-share "$k/$n" --force; done
for k in $(seq 1 "$n"); do job "fuse $k/$n" "$exe" dense -o "$ws" --fuse-share "$k/$n" --force; done
job "products from $n" "$exe" dense -o "$ws" --from-shares "$n" --force
/usr/bin/python3 - "$work" "$ws" <<'EOF'
import json, sys
from osgeo import gdal
work, ws = sys.argv[1], sys.argv[2]
jobs = [l.rsplit(" ", 2) for l in open(f"{work}/jobs").read().splitlines()]
print("| job | wall s | peak MB |\n|---|---|---|")
for name, wall, mb in jobs:
    print(f"| {name} | {float(wall):.1f} | {mb} |")
whole = float(jobs[0][1])
shares = sum(float(w) for _, w, _ in jobs[1:])
print(f"\nshares total {shares:.1f} s = {shares / whole:.2f} x the one-process stage; "
      f"largest job {max(int(m) for _, _, m in jobs[1:])} MB against {jobs[0][2]} MB")
a, b = json.load(open(f"{work}/whole.json")), json.load(open(f"{ws}/dense.json"))
for key in ["points", "depth_points", "pairs", "pairs_failed", "tiles"]:
    print(f"{key}: one process {a[key]}, shares {b[key]}{'' if a[key] == b[key] else '  DIFFERENT'}")
x = gdal.Open(f"{work}/whole_dsm.tif").ReadAsArray()
y = gdal.Open(f"{ws}/dsm.tif").ReadAsArray()
print(f"DSM {x.shape[1]} x {x.shape[0]}: " +
      (f"{int((x != y).sum())} cells differ" if x.shape == y.shape else f"shares' is {y.shape[1]} x {y.shape[0]}"))
EOF
