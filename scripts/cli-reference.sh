#!/usr/bin/env bash
# docs/cli.md from the binary's own help: `aerotri --help`, then each
# command's `--help`, verbatim.
# Usage: scripts/cli-reference.sh AEROTRI                 print the page
#        scripts/cli-reference.sh AEROTRI --check FILE    exit 1 if FILE differs
#        scripts/cli-reference.sh AEROTRI --update FILE   rewrite FILE
set -euo pipefail
exe="${1:?usage: $0 AEROTRI [--check|--update FILE]}"
page() {
  echo "# Command-line reference"
  echo
  echo "Generated from the binary's own help by \`scripts/cli-reference.sh build/tools/aerotri --update docs/cli.md\`;"
  echo "the unit test \`docs/cli_reference_matches_binary\` fails when the two differ. How to use the"
  echo "commands: [user-guide.md](user-guide.md)."
  echo
  echo '## `aerotri --help`'
  echo
  echo '```'
  "$exe" --help
  echo '```'
  # The commands, as the top-level help lists them ("  name  description").
  for cmd in $("$exe" --help | awk '/^Subcommands:/ {on = 1; next} on && /^  [a-z]/ {print $1} on && /^$/ {exit}'); do
    echo
    echo "## \`aerotri $cmd\`"
    echo
    echo '```'
    "$exe" "$cmd" --help
    echo '```'
  done
}
case "${2:-}" in
  "") page ;;
  --check)
    if ! diff -u "$3" <(page); then
      echo "$3 differs from the binary's help; run scripts/cli-reference.sh $exe --update $3" >&2
      exit 1
    fi
    echo "$3 matches the binary's help" ;;
  --update) page > "$3.tmp" && mv "$3.tmp" "$3" ;;
  *) echo "usage: $0 AEROTRI [--check|--update FILE]" >&2; exit 2 ;;
esac
