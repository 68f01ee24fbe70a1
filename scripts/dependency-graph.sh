#!/usr/bin/env bash
# The library dependency graph, from CMake's own --graphviz output, as a
# Mermaid block (solid: PUBLIC link, dotted: PRIVATE). docs/architecture.md carries it
# between the dependency-graph markers; --check docs/architecture.md fails when the two
# differ, so the layout and the CMake graph cannot drift apart.
# Usage: scripts/dependency-graph.sh              print the block
#        scripts/dependency-graph.sh --check FILE  exit 1 if FILE's block differs
#        scripts/dependency-graph.sh --update FILE rewrite FILE's block
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

cmake -S "$root" -B "$tmp/build" -DAEROTRI_BUILD_TESTS=OFF --graphviz="$tmp/graph.dot" >/dev/null

# Edge lines end in a comment "// aerotri_a -> aerotri_b"; a dotted style is a
# PRIVATE link. The umbrella aerotri::photo (an INTERFACE list) is left out.
block() {
  echo '```mermaid'
  echo 'graph BT'
  grep -E '// aerotri_[a-z]+ -> aerotri_[a-z]+$' "$tmp/graph.dot" \
    | sed -E 's/.*(\[ style = ([a-z]+) \])?.*\/\/ aerotri_([a-z]+) -> aerotri_([a-z]+)$/\3 \4 &/' \
    | awk '$1 != "photo" && $2 != "photo" {
             style = ($0 ~ /style = dotted/) ? "-.->" : "-->";
             printf "  %s %s %s\n", $1, style, $2 }' \
    | sort -u
  echo '```'
}

begin='<!-- dependency-graph:begin (scripts/dependency-graph.sh --update docs/architecture.md) -->'
end='<!-- dependency-graph:end -->'
case "${1:-}" in
  "") block ;;
  --check|--update)
    file="$2"
    block > "$tmp/block"
    awk -v b="$begin" -v e="$end" -v blk="$tmp/block" '
      $0 == b { print; while ((getline line < blk) > 0) print line; skip = 1; next }
      $0 == e { skip = 0 }
      !skip { print }' "$file" > "$tmp/new"
    grep -qxF "$begin" "$file" || { echo "$file: no line '$begin'" >&2; exit 1; }
    if [ "$1" = --update ]; then
      cp "$tmp/new" "$file"
    elif ! diff -u "$file" "$tmp/new"; then
      echo "$file: the dependency graph differs from CMake's; run scripts/dependency-graph.sh --update $file" >&2
      exit 1
    else
      echo "$file: dependency graph matches CMake's"
    fi ;;
  *) echo "usage: $0 [--check|--update FILE]" >&2; exit 2 ;;
esac
