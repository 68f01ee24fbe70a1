#!/usr/bin/env bash
# The mapper's adjustment schedules side by side on one survey's matches:
# each schedule reconstructs its own copy of the workspace's ingest,
# features and matches, all at once with one thread each (so the machine's
# noise falls on all alike), and prints, per schedule: wall time of the
# reconstruct stage and its ratio to the first schedule's, time and solver
# iterations in global adjustments, time in local adjustments, registered photos, the model's mean reprojection
# error, and, with a survey folder, the check-point RMSE after georeference.
# Usage: bench/mapper_bench.sh WORKSPACE [SURVEY]
#   WORKSPACE: a workspace past `aerotri match` (e.g. a KEEP=1 scale_bench.sh one)
#   SURVEY: the rendered survey (gcp_list.txt, checkpoints.txt): also georeference
# Env: BENCH_WORK (default /tmp/aerotri_mapper_bench), AEROTRI=path (binary),
# SCHEDULES (default below: name:local_ba_images:global_ba_growth:iterative_ba_above[:global_ba_loss],
# global_ba_loss screening (the default) or huber).
set -euo pipefail
cd "$(dirname "$0")/.."
ws="${1:?usage: bench/mapper_bench.sh WORKSPACE [SURVEY]}"
survey="${2:-}"
exe="${AEROTRI:-$(pwd)/build/tools/aerotri}"
[ -x "$exe" ] || scripts/build.sh >/dev/null
work="${BENCH_WORK:-/tmp/aerotri_mapper_bench}"
schedules=(${SCHEDULES:-huber:0:0.25:0:huber screening:0:0.25:0:screening local:6:0.25:0:screening})
for f in ingest.json features matches.bin matches.json; do
  [ -e "$ws/$f" ] || { echo "mapper_bench: $ws/$f missing (run aerotri match first)" >&2; exit 1; }
done
rm -rf "$work"
mkdir -p "$work"
pids=()
for s in "${schedules[@]}"; do
  IFS=: read -r name local growth iterative loss <<<"$s"
  loss="${loss:-screening}"
  mkdir -p "$work/$name"
  cp -r "$ws/ingest.json" "$ws/features" "$ws/matches.bin" "$ws/matches.json" "$work/$name/"
  (
    "$exe" reconstruct -o "$work/$name" --threads 1 --quiet --local-ba-images "$local" \
      --global-ba-growth "$growth" --iterative-ba-above "$iterative" --global-ba-loss "$loss"
    if [ -n "$survey" ]; then
      "$exe" georeference -o "$work/$name" --threads 1 --quiet --gcp "$survey/gcp_list.txt" \
        --checkpoints "$survey/checkpoints.txt" --leave-one-out off >/dev/null
    fi
  ) &
  pids+=($!)
done
for p in "${pids[@]}"; do wait "$p"; done
/usr/bin/python3 - "$work" "${schedules[@]}" <<'PY'
import json, os, sys
work, schedules = sys.argv[1], sys.argv[2:]
print("%-18s %6s %7s %9s %9s %7s %8s %8s %7s %11s %8s %9s %9s" % ("schedule", "local", "growth", "iterative", "loss",
      "recon_s", "ratio", "global_s", "iters", "local_s(n)", "photos", "mean_px", "check_h/v_m"))
first = None
for s in schedules:
    name, local, growth, iterative = s.split(":")[:4]
    loss = (s.split(":") + ["screening"])[4]
    d = os.path.join(work, name)
    rec = json.load(open(os.path.join(d, "reconstruction.json")))
    wall = json.load(open(os.path.join(d, "timings.json")))["reconstruct"]["wall_s"]
    first = first or wall
    errors = []
    for line in open(os.path.join(d, "reconstruction", "points3D.txt")):
        if line.startswith("#") or not line.strip():
            continue
        errors.append(float(line.split()[7]))
    check = ""
    report = os.path.join(d, "report.json")
    if os.path.exists(report):
        cp = json.load(open(report)).get("check_points", {})
        check = "%.4f/%.4f" % (cp.get("rmse_h_m", float("nan")), cp.get("rmse_z_m", float("nan")))
    print("%-18s %6s %7s %9s %9s %7.1f %8.2f %8.1f %7d %11s %8s %9.3f %9s" % (
        name, local, growth, iterative, loss, wall, wall / first, rec.get("adjustment_s", 0.0),
        rec.get("adjustment_iterations", 0),
        "%.1f(%d)" % (rec.get("local_adjustment_s", 0.0), rec.get("local_adjustments", 0)),
        "%d/%d" % (rec["registered"], len(rec["images"])), sum(errors) / max(len(errors), 1), check))
PY
