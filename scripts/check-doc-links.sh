#!/usr/bin/env bash
# Every relative link in README.md and docs/*.md points at a file of the
# repository, and every #anchor at a heading of that file (GitHub's slugs).
# Usage: scripts/check-doc-links.sh   (exit 1 naming each broken link)
set -euo pipefail
cd "$(dirname "$0")/.."
exec python3 - README.md docs/*.md <<'PY'
import os, re, sys

def slug(heading):
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")

def anchors(path):
    out, fence = set(), False
    for line in open(path, encoding="utf-8"):
        if line.startswith("```"):
            fence = not fence
        elif not fence and line.startswith("#"):
            out.add(slug(line.lstrip("#")))
    return out

broken, count = [], 0
for page in sys.argv[1:]:
    fence = False
    for n, line in enumerate(open(page, encoding="utf-8"), 1):
        if line.startswith("```"):
            fence = not fence
            continue
        if fence:
            continue
        for target in re.findall(r"\]\(([^)\s]+)\)", line):
            if re.match(r"[a-z]+:", target):
                continue  # http:, mailto: ...
            count += 1
            path, _, anchor = target.partition("#")
            full = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
            if not os.path.exists(full):
                broken.append(f"{page}:{n}: {target}: no file {full}")
            elif anchor and full.endswith(".md") and anchor not in anchors(full):
                broken.append(f"{page}:{n}: {target}: no heading '#{anchor}' in {full}")
for b in broken:
    print(b, file=sys.stderr)
print(f"{count} relative links checked, {len(broken)} broken")
sys.exit(1 if broken else 0)
PY
