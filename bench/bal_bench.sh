#!/usr/bin/env bash
# BAL benchmark: `aerotri bal` against Ceres at its best, side by side in one
# run, on the three shared BAL problems.
#
# The reference is Ceres' API configured as Ceres 2.1's
# examples/bundle_adjuster (bench/ceres_bal_reference.cc: normalised problem,
# autodiff Snavely residuals, DENSE_SCHUR, points eliminated first, 2
# threads), stopped by an oracle at the first iteration within 0.1 % of the
# best known cost. aerotri runs with its defaults and stops by its own rule.
# Both read the same plain-text file (decompressed beforehand, untimed);
# aerotri on the .bz2 is shown too. Times are process start to exit, the
# median of interleaved runs; peak RSS from GNU time.
#
# The best known cost is measured first (untimed): the lower of aerotri and
# the Ceres reference each run to convergence.
#
# Usage: bench/bal_bench.sh [runs (default 7)]
set -euo pipefail
cd "$(dirname "$0")/.."
runs="${1:-7}"
data="../shared/data/bal"
aerotri="build/tools/aerotri"
ceres="build/bench/ceres_bal_reference"
[ -x "$aerotri" ] && [ -x "$ceres" ] || scripts/build.sh >/dev/null
[ -d "$data" ] || { echo "bal_bench: $data is absent" >&2; exit 1; }
command -v /usr/bin/time >/dev/null || { echo "bal_bench: needs GNU time (apt-get install time)" >&2; exit 1; }
threads=2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

problems=(problem-49-7776-pre problem-21-11315-pre problem-16-22106-pre)
declare -A family=([problem-49-7776-pre]=Ladybug-49 [problem-21-11315-pre]=Trafalgar-21 [problem-16-22106-pre]=Dubrovnik-16)
declare -A best target

field() { sed -E "s/.*$1=([^ ]+).*/\1/" <<<"$2"; }

# One timed run: prints "<wall_s> <rss_kb> <stdout line>".
timed() {
  local t0 t1 out
  t0=$(date +%s%N)
  out=$( { /usr/bin/time -f "__rss=%M" "$@"; } 2>&1 | grep -E "final_cost=|__rss=" | tr '\n' ' ')
  t1=$(date +%s%N)
  echo "$(awk "BEGIN{printf \"%.4f\", ($t1 - $t0) / 1e9}") $(field __rss "$out") $out"
}

echo "bal_bench: decompressing and finding the best known costs (untimed)" >&2
for p in "${problems[@]}"; do
  bzip2 -dc "$data/$p.txt.bz2" >"$tmp/$p.txt"
  a=$("$aerotri" bal "$tmp/$p.txt" --quiet --threads $threads --optimality-gap 0 --function-tolerance 1e-12 \
      --parameter-tolerance 1e-12 --max-iterations 300 | grep final_cost=)
  c=$("$ceres" "$tmp/$p.txt" --threads $threads --max-iterations 300)
  best[$p]=$(awk "BEGIN{a=$(field final_cost "$a"); c=$(field final_cost "$c"); printf \"%.7e\", (a < c ? a : c)}")
  target[$p]=$(awk "BEGIN{printf \"%.7e\", ${best[$p]} * 1.001}")
done

declare -A wall_a wall_z wall_c rss_a rss_c cost_a cost_c it_a it_c
for r in $(seq "$runs"); do
  echo "bal_bench: run $r of $runs" >&2
  for p in "${problems[@]}"; do
    read -r w rss line < <(timed "$ceres" "$tmp/$p.txt" --threads $threads --target-cost "${target[$p]}")
    wall_c[$p]+="$w "; rss_c[$p]=$rss; cost_c[$p]=$(field final_cost "$line"); it_c[$p]=$(field iterations "$line")
    read -r w rss line < <(timed "$aerotri" bal "$tmp/$p.txt" --quiet --threads $threads)
    wall_a[$p]+="$w "; rss_a[$p]=$rss; cost_a[$p]=$(field final_cost "$line"); it_a[$p]=$(field iterations "$line")
    read -r w rss line < <(timed "$aerotri" bal "$data/$p.txt.bz2" --quiet --threads $threads)
    wall_z[$p]+="$w "
  done
done

median() { tr ' ' '\n' <<<"$1" | grep -v '^$' | sort -g | awk '{v[NR]=$1} END{print (NR%2 ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2)}'; }

printf "\nmedian of %d interleaved runs, %d threads; target = best known cost x 1.001\n" "$runs" "$threads"
printf "%-13s %12s | %12s %5s %8s %7s | %12s %5s %8s %7s | %7s %9s\n" problem best_cost \
  ceres_cost iters wall_s rss_MB aerotri_cost iters wall_s rss_MB ratio bz2_wall_s
for p in "${problems[@]}"; do
  wc=$(median "${wall_c[$p]}"); wa=$(median "${wall_a[$p]}"); wz=$(median "${wall_z[$p]}")
  within=$(awk "BEGIN{print (${cost_a[$p]} <= ${target[$p]}) ? \"\" : \" (above target!)\"}")
  printf "%-13s %12s | %12s %5s %8.3f %7.1f | %12s %5s %8.3f %7.1f | %6.2fx %9.3f%s\n" "${family[$p]}" "${best[$p]}" \
    "${cost_c[$p]}" "${it_c[$p]}" "$wc" "$(awk "BEGIN{print ${rss_c[$p]}/1024}")" \
    "${cost_a[$p]}" "${it_a[$p]}" "$wa" "$(awk "BEGIN{print ${rss_a[$p]}/1024}")" \
    "$(awk "BEGIN{print $wa / $wc}")" "$wz" "$within"
done
echo "ratio = aerotri wall / Ceres wall (below 1: aerotri is faster)"
