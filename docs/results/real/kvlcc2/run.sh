#!/usr/bin/env bash
# Derive every KVLCC2 figure in docs/results/real/README.md from the original tank logs.
# Usage (repo root, after `make setup`): docs/results/real/kvlcc2/run.sh [SHARED_REAL] [WORK]
set -euo pipefail
REAL="${1:-../shared/real}"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/kvlcc2
run() { tools/with_env.sh "$@"; }
run python offline/table_to_dataset.py "$REAL/kvlcc2_hsva/raw_data" --vessel kvlcc2_hsva \
  --out "$WORK/kvlcc2_ds" --holdout HSVA_CPMC_KVLCC2_Z_20_10_P HSVA_CPMC_KVLCC2_Z_35_05 \
  --val HSVA_CPMC_KVLCC2_Z_15_05 --overwrite --quiet 2> "$OUT/import.log"
run python offline/train.py docs/results/real/configs/hybrid.yaml --dataset "$WORK/kvlcc2_ds" \
  --out "$WORK/kvlcc2_runs/hybrid" --quiet > /dev/null
run python offline/train.py docs/results/real/configs/lstm.yaml --dataset "$WORK/kvlcc2_ds" \
  --out "$WORK/kvlcc2_runs/lstm" --quiet > /dev/null
run python offline/evaluate.py "$WORK/kvlcc2_runs/hybrid" "$WORK/kvlcc2_runs/lstm" \
  --dataset "$WORK/kvlcc2_ds" --out "$OUT" --physics-only --sweep hybrid-hyd-2p \
  --thresholds 0.05 0.1 0.15 0.3 0.5 1.0
