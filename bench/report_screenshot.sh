#!/usr/bin/env bash
# Renders a workspace's report.html in headless Chromium (Debian's
# `chromium`): a full-page screenshot to look at, and the print-to-PDF the
# print stylesheet shapes. Nothing is fetched: the report is self-contained.
# Usage: bench/report_screenshot.sh WORKSPACE [OUT_PREFIX (default WORKSPACE/report)]
#   writes OUT_PREFIX.png (1100 px wide) and OUT_PREFIX.pdf (A4)
set -euo pipefail
ws="${1:?usage: bench/report_screenshot.sh WORKSPACE [OUT_PREFIX]}"
out="${2:-$ws/report}"
html="$(cd "$ws" && pwd)/report.html"
[ -f "$html" ] || { echo "report_screenshot: $html is absent (run aerotri run or aerotri report first)" >&2; exit 1; }
command -v chromium >/dev/null || { echo "report_screenshot: needs chromium (apt-get install chromium)" >&2; exit 1; }
profile=$(mktemp -d)
trap 'rm -rf "$profile"' EXIT
flags=(--headless --no-sandbox --disable-gpu --disable-quic --no-first-run --disable-background-networking
       --disable-component-update --disable-sync --hide-scrollbars "--user-data-dir=$profile")
chromium "${flags[@]}" --window-size=1100,9000 "--screenshot=$out.png" "file://$html" 2>/dev/null
chromium "${flags[@]}" --no-pdf-header-footer "--print-to-pdf=$out.pdf" "file://$html" 2>/dev/null
ls -l "$out.png" "$out.pdf" >&2
