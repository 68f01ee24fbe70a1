#!/usr/bin/env bash
# Installs the independent readers some tests compare aerotri's files with:
# copc.js (npm "copc", an LAS 1.4 reader) into build/node_modules. Idempotent; when npm
# or its registry is unavailable the tests that need it skip (exit code 77).
set -uo pipefail
cd "$(dirname "$0")/.."
mkdir -p build
if [ -d build/node_modules/copc ]; then exit 0; fi
if ! command -v npm >/dev/null 2>&1; then
  echo "install-test-tools: npm not found; the LAS reader check will be skipped" >&2
  exit 0
fi
( cd build && timeout 300 npm install --no-audit --no-fund --loglevel=error \
    copc@0.0.8 >/dev/null 2>&1 ) \
  || echo "install-test-tools: npm install failed; the LAS reader check will be skipped" >&2
exit 0
