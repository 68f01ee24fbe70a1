#!/usr/bin/env bash
# No function in libphoto/, georef/, camera_models/ or tools/ longer than
# the limit (150 lines): a long function is steps without names.
# Usage: scripts/check-function-length.sh [limit]   (exit 1 naming each;
#        77 when Universal Ctags is missing: the test then skips)
set -euo pipefail
cd "$(dirname "$0")/.."
limit="${1:-150}"
ctags=$(command -v ctags-universal || command -v ctags || true)
if [ -z "$ctags" ] || ! "$ctags" --version 2>/dev/null | grep -q 'Universal Ctags'; then
  echo "check-function-length: Universal Ctags not found (apt-get install universal-ctags)" >&2
  exit 77
fi
long=$("$ctags" -R --fields=+ne --kinds-c++=f -x --_xformat='%{line} %{end} %{name} %{input}' \
         libphoto georef camera_models tools | awk -v limit="$limit" '$2 - $1 + 1 > limit {
           printf "%s:%d: %s is %d lines (at most %d)\n", $4, $1, $3, $2 - $1 + 1, limit }' | sort)
if [ -n "$long" ]; then
  echo "$long" >&2
  exit 1
fi
echo "no function longer than $limit lines"
