#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds aerotri and runs the main job on
# the bundled sample survey: photos (with EXIF GPS), ground control and check
# points in, adjusted georeferenced survey and report out.
# Output goes to ./sample_output (or the folder given as the first argument).
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-sample_output}"
sample=sample_surveys/synthetic_meadow
scripts/install-deps.sh
scripts/build.sh --target aerotri  # the programs only; scripts/test.sh builds the rest
build/tools/aerotri run "$sample/images" \
  --gcp "$sample/gcp_list.txt" --checkpoints "$sample/checkpoints.txt" \
  --output "$out"
echo "survey written to $out (report: $out/report.json)" >&2
