#!/usr/bin/env bash
# Derive every snuboat figure in docs/results/real/README.md from the original bags.
# Usage (repo root, after `make setup`): docs/results/real/snuboat/run.sh [SHARED_REAL] [WORK]
set -euo pipefail
REAL="${1:-../shared/real}"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/snuboat
run() { tools/with_env.sh "$@"; }
# All 106 bags; the 0.9 s lag of the tracked position and velocities is in the vessel
# file (delay_s), so every map check passes without --accept-checks. convert.log is the
# per-bag report (repository-relative paths when REAL is).
run python offline/bag_to_dataset.py "$REAL/snuboat/bags" --vessel snuboat \
  --msg-dir "$REAL/snuboat/msg" --msg-package snumsg_pkg --out "$WORK/snuboat_ds" \
  --jobs 2 --overwrite --quiet 2> "$OUT/convert.log"
run python offline/train.py docs/results/real/configs/hybrid.yaml --dataset "$WORK/snuboat_ds" \
  --out "$WORK/snuboat_runs/hybrid" --quiet > /dev/null
run python offline/train.py docs/results/real/configs/lstm.yaml --dataset "$WORK/snuboat_ds" \
  --out "$WORK/snuboat_runs/lstm" --quiet > /dev/null
run python offline/evaluate.py "$WORK/snuboat_runs/hybrid" "$WORK/snuboat_runs/lstm" \
  --dataset "$WORK/snuboat_ds" --out "$OUT" --physics-only --sweep hybrid-hyd-2p \
  --thresholds 0.05 0.1 0.15 0.3 0.5 1.0
