#!/usr/bin/env bash
# Installs the independent tools some tests check aerotri's files with, into
# build/node_modules: copc.js (npm "copc", an LAS 1.4 reader) and
# puppeteer-core (drives the review page marks.html in Debian's Chromium,
# which this script installs too when run as root or with sudo).
# Idempotent; when npm, its registry or the package archive is unavailable,
# the tests that need them skip (exit code 77).
set -uo pipefail
cd "$(dirname "$0")/.."
mkdir -p build

if ! command -v chromium >/dev/null 2>&1; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "install-test-tools: installing Debian's chromium for the review page test" >&2
  ( export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq && timeout 900 $SUDO apt-get install -y -qq --no-install-recommends chromium ) >/dev/null 2>&1 \
    || echo "install-test-tools: chromium could not be installed; the review page test will be skipped" >&2
fi

packages=(copc@0.0.8 puppeteer-core@24.43.1)
if [ -d build/node_modules/copc ] && [ -d build/node_modules/puppeteer-core ]; then exit 0; fi
if ! command -v npm >/dev/null 2>&1; then
  echo "install-test-tools: npm not found; the LAS reader and review page checks will be skipped" >&2
  exit 0
fi
# puppeteer-core downloads no browser (it drives the one installed above).
( cd build && timeout 300 npm install --no-audit --no-fund --loglevel=error "${packages[@]}" >/dev/null 2>&1 ) \
  || echo "install-test-tools: npm install failed; the LAS reader and review page checks will be skipped" >&2
exit 0
