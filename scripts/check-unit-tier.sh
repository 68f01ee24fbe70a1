#!/usr/bin/env bash
# Fails when a unit-tier test runs a program that the `unit_tier` target does
# not build. scripts/sanitize.sh builds only that target, so such a test shows
# as "Not Run" there and nowhere else; this check catches it in every build.
# Usage: scripts/check-unit-tier.sh BUILD_DIR
# (BUILD_DIR/executables.txt and unit_tier_executables.txt: tests/CMakeLists.txt)
set -euo pipefail
build=${1:?usage: check-unit-tier.sh BUILD_DIR}
for list in executables.txt unit_tier_executables.txt; do
  [ -f "$build/$list" ] || { echo "check-unit-tier: $build/$list is missing (configure first)" >&2; exit 1; }
done
commands=$(cd "$build" && ctest -N -V -L unit | sed -n 's/^[0-9]*: Test command: //p')
if [ -z "$commands" ]; then
  echo "check-unit-tier: ctest lists no unit-tier test in $build" >&2
  exit 1
fi
missing=0
checked=0
while IFS= read -r exe; do
  [ -n "$exe" ] || continue
  # The program as a word of a command: the command itself or an argument
  # (cmake -P scripts get the aerotri binary as -DAEROTRI=...).
  if grep -Eq "(^|[ =\"])${exe}([ \"]|$)" <<<"$commands"; then
    checked=$((checked + 1))
    if ! grep -Fxq "$exe" "$build/unit_tier_executables.txt"; then
      echo "FAIL: a unit-tier test runs $exe, which the unit_tier target does not build" >&2
      missing=$((missing + 1))
    fi
  fi
done < "$build/executables.txt"
echo "check-unit-tier: $checked programs run by unit-tier tests, $missing not built by unit_tier"
[ "$missing" -eq 0 ]
