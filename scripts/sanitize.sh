#!/usr/bin/env bash
# Builds aerotri with AddressSanitizer + UndefinedBehaviorSanitizer into
# ./build-sanitize and runs the unit tier there; any report fails the run.
# Usage: scripts/sanitize.sh   (after scripts/install-deps.sh)
set -euo pipefail
cd "$(dirname "$0")/.."
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
if [ ! -f build-sanitize/CMakeCache.txt ]; then
  cmake -S . -B build-sanitize "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DAEROTRI_SANITIZE=ON
fi
cmake --build build-sanitize --parallel "$(nproc)"
# Leaks in third-party singletons (GDAL, PROJ contexts) are not ours to chase
# here; memory errors and undefined behaviour are.
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1:strict_string_checks=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
cd build-sanitize
ctest -L unit --output-on-failure --parallel "$(nproc)" --timeout 900
