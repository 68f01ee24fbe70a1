#!/usr/bin/env bash
# Builds what the unit tier runs (the `unit_tier` target) with AddressSanitizer
# + UndefinedBehaviorSanitizer into ./build-sanitize and runs the unit tier
# there; any report fails the run (exit non-zero).
# Usage: scripts/sanitize.sh   (after scripts/install-deps.sh)
#
# -O1 keeps the instrumented build and run affordable (about 15 and 5 minutes
# on 2 cores); assertions stay on (no NDEBUG), so Eigen's and ours check too.
set -euo pipefail
cd "$(dirname "$0")/.."
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
if [ ! -f build-sanitize/CMakeCache.txt ]; then
  cmake -S . -B build-sanitize "${generator[@]}" -DCMAKE_BUILD_TYPE=Debug \
    -DCMAKE_CXX_FLAGS_DEBUG="-O1 -g1" -DCMAKE_C_FLAGS_DEBUG="-O1 -g1" -DAEROTRI_SANITIZE=ON
fi
cmake --build build-sanitize --target unit_tier --parallel "$(nproc)"
# Leaks in third-party singletons (GDAL, PROJ contexts) are not ours to chase
# here; memory errors and undefined behaviour are.
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cd build-sanitize
ctest -L unit --output-on-failure --parallel "$(nproc)" --timeout 900
