#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz/fuzz_*.cc: every parser of user
# files) with clang, ASan and UBSan into ./build-fuzz and runs each for the
# given time, in turn, from its seed corpus. Prints per target the
# executions, the corpus size and the findings; a finding (crash, sanitizer
# report, leak of the parser's own, timeout, out of memory) is written to
# build-fuzz/findings/<target>/ -- fix it, then copy the input into
# tests/fuzz/regressions/<target>/, where ctest replays it in every build.
# Usage: scripts/fuzz.sh [seconds per target (default 60)] [target ...]
#   targets: bal gcp colmap gps camera_file exif (default: all)
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(bal gcp colmap gps camera_file exif)
command -v clang++ >/dev/null || { echo "fuzz: needs clang++ (apt-get install clang)" >&2; exit 1; }
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
if [ ! -f build-fuzz/CMakeCache.txt ]; then
  CC=clang CXX=clang++ cmake -S . -B build-fuzz "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DAEROTRI_FUZZ=ON
fi
cmake --build build-fuzz --parallel "$(nproc)" --target $(printf 'fuzz_%s ' "${targets[@]}")
# Third-party singletons (GDAL, PROJ) keep memory to the end: not the parsers' leaks.
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
summary=()
for t in "${targets[@]}"; do
  corpus="build-fuzz/corpus/$t"
  findings="build-fuzz/findings/$t"
  mkdir -p "$corpus" "$findings"
  # libFuzzer takes folders: the seeds (files and folders) are copied in once.
  while IFS= read -r seed; do
    [ -n "$seed" ] || continue
    if [ -d "$seed" ]; then cp -n "$seed"/* "$corpus"/ 2>/dev/null || true; else cp -n "$seed" "$corpus"/; fi
  done <"build-fuzz/tests/fuzz/seeds_$t.txt"
  log="build-fuzz/fuzz_$t.log"
  echo "fuzz: $t for $seconds s (log $log)" >&2
  set +e
  "build-fuzz/tests/fuzz/fuzz_$t" "$corpus" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2560 \
    -max_len=65536 -print_final_stats=1 -artifact_prefix="$findings/" >"$log" 2>&1
  rc=$?
  set -e
  execs=$(grep -m1 -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  found=$(find "$findings" -type f | wc -l)
  summary+=("$(printf '%-12s %6s s %12s execs %6s corpus files %3s findings (exit %s)' "$t" "$seconds" "$execs" \
    "$(find "$corpus" -type f | wc -l)" "$found" "$rc")")
done
printf '%s\n' "${summary[@]}"
