#!/usr/bin/env bash
# Configures and builds aerotri (Release) into ./build. Idempotent: re-running
# rebuilds only what changed.
# Usage: scripts/build.sh [--target T ...] [extra cmake args]
#   --target T  build only T (repeatable; e.g. aerotri, the command-line
#               programs the sample needs); default: everything, tests included.
set -euo pipefail
cd "$(dirname "$0")/.."
targets=()
cmake_args=()
while [ $# -gt 0 ]; do
  case "$1" in
    --target) targets+=(--target "$2"); shift 2 ;;
    *) cmake_args+=("$1"); shift ;;
  esac
done
generator=()
command -v ninja >/dev/null 2>&1 && generator=(-G Ninja)
if [ ! -f build/CMakeCache.txt ]; then
  cmake -S . -B build "${generator[@]}" -DCMAKE_BUILD_TYPE=Release "${cmake_args[@]}"
fi
cmake --build build --parallel "$(nproc)" "${targets[@]}"
