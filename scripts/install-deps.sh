#!/usr/bin/env bash
# Installs aerotri's build and test dependencies from Debian 12 packages.
# Idempotent: packages already present are left alone; safe to run again.
# Usage: scripts/install-deps.sh   (as root, or with sudo available)
set -euo pipefail

packages=(
  build-essential cmake ninja-build pkg-config git
  libeigen3-dev libceres-dev libsuitesparse-dev
  libopencv-dev
  libgeographiclib-dev geographiclib-tools
  libproj-dev proj-bin proj-data
  libgdal-dev gdal-bin
  libgtest-dev googletest
  libcli11-dev nlohmann-json3-dev libbz2-dev
  time universal-ctags
  snakemake
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages already installed" >&2
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "install-deps: done" >&2
