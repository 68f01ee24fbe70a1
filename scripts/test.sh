#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds aerotri and runs every test.
# Tests that need ../shared/data skip cleanly when it is absent.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/install-deps.sh
scripts/build.sh
scripts/install-test-tools.sh
cd build
ctest --output-on-failure --parallel "$(nproc)"
