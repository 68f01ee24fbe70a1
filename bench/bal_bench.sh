#!/usr/bin/env bash
# BAL benchmark: solves the three shared BAL problems with `aerotri bal`
# (process start to exit) and prints problem, final cost, RMS px, iterations,
# wall seconds and peak RSS, next to the Ceres 2.1 reference of the data README.
# Usage: bench/bal_bench.sh [runs-per-problem (default 3; the best is shown)]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-3}"
data="../shared/data/bal"
exe="build/tools/aerotri"
[ -x "$exe" ] || scripts/build.sh >/dev/null
[ -d "$data" ] || { echo "bal_bench: $data is absent" >&2; exit 1; }
command -v /usr/bin/time >/dev/null || { echo "bal_bench: needs GNU time (apt-get install time)" >&2; exit 1; }

declare -A ref_cost=([problem-49-7776-pre]=1.33443e4 [problem-21-11315-pre]=3.03786e4 [problem-16-22106-pre]=1.80339e4)
declare -A ref_time=([problem-49-7776-pre]=2.35 [problem-21-11315-pre]=0.66 [problem-16-22106-pre]=1.06)
declare -A family=([problem-49-7776-pre]=Ladybug-49 [problem-21-11315-pre]=Trafalgar-21 [problem-16-22106-pre]=Dubrovnik-16)

printf "%-13s %12s %12s %8s %5s %8s %9s %10s %8s\n" problem final_cost ref_cost rms_px iters wall_s ref_wall_s speedup rss_MB
for p in problem-49-7776-pre problem-21-11315-pre problem-16-22106-pre; do
  best=""
  for _ in $(seq "$runs"); do
    line=$( { /usr/bin/time -f "__wall=%e __rss=%M" "$exe" bal "$data/$p.txt.bz2" --quiet; } 2>&1 | tr '\n' ' ')
    wall=$(sed -E 's/.*__wall=([0-9.]+).*/\1/' <<<"$line")
    if [ -z "$best" ] || awk "BEGIN{exit !($wall < $best)}"; then best=$wall; keep=$line; fi
  done
  cost=$(sed -E 's/.*final_cost=([^ ]+).*/\1/' <<<"$keep")
  rms=$(sed -E 's/.*rms_px=([^ ]+).*/\1/' <<<"$keep")
  iters=$(sed -E 's/.*iterations=([^ ]+).*/\1/' <<<"$keep")
  rss=$(sed -E 's/.*__rss=([0-9]+).*/\1/' <<<"$keep")
  printf "%-13s %12s %12s %8s %5s %8s %9s %9.2fx %8.1f\n" "${family[$p]}" "$cost" "${ref_cost[$p]}" "$rms" "$iters" \
    "$best" "${ref_time[$p]}" "$(awk "BEGIN{print ${ref_time[$p]} / $best}")" "$(awk "BEGIN{print $rss / 1024}")"
done
