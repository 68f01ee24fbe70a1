#!/usr/bin/env bash
# Installs the build tree into a temporary prefix, then builds the consumer
# project twice -- with find_package(aerotri) and with pkg-config -- and runs
# each on a BAL problem. Usage: check_install.sh BUILD_DIR SOURCE_DIR WORK_DIR
set -euo pipefail
build=$1 src=$2 work=$3
rm -rf "$work"
mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" >/dev/null
test -x "$prefix/bin/aerotri" || { echo "no binary installed" >&2; exit 1; }
test -f "$prefix/share/doc/aerotri/LICENSE" || { echo "no LICENSE installed" >&2; exit 1; }
"$prefix/bin/aerotri" --version

problem=$src/tests/data/bal_tiny.txt
expect() {  # expect <label> <output>
  echo "$1: $2"
  [[ $2 =~ ^cameras=[0-9]+\ rms_px=0\.5[0-9]*$ ]] || { echo "$1: unexpected output" >&2; exit 1; }
}

# find_package(aerotri) with imported targets and their dependencies.
cmake -S "$src/tests/package/consumer" -B "$work/cmake-build" -DCMAKE_PREFIX_PATH="$prefix" \
      -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build "$work/cmake-build" >/dev/null
expect find_package "$("$work/cmake-build/consumer" "$problem")"

# pkg-config.
export PKG_CONFIG_PATH=$prefix/lib/pkgconfig
# shellcheck disable=SC2046
c++ -std=c++17 -O1 "$src/tests/package/consumer/main.cc" -o "$work/consumer-pc" \
    $(pkg-config --cflags --libs aerotri)
expect pkg-config "$("$work/consumer-pc" "$problem")"
