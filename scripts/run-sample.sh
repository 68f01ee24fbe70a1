#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds aerotri and runs the main job on
# the bundled sample. Output goes to ./sample_output (or the folder given).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-sample_output}"
scripts/install-deps.sh
scripts/build.sh
mkdir -p "$out"
# The bundle adjuster on the project's own small BAL problem
# (tests/data/make_bal_tiny.py regenerates it).
build/tools/aerotri bal tests/data/bal_tiny.txt --output "$out/bal_tiny_solved.txt"
echo "solved problem written to $out/bal_tiny_solved.txt" >&2
