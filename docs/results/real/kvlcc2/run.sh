#!/usr/bin/env bash
# Derive every KVLCC2 figure in docs/results/real/README.md from the original tank logs.
# Usage (repo root, after `make setup`): docs/results/real/kvlcc2/run.sh [SHARED_REAL] [WORK]
# About an hour on 2 cores (four trainings of 8 to 20 minutes; --resume continues or skips
# a training that is already there).
set -euo pipefail
REAL="${1:-../shared/real}"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/kvlcc2
CONFIGS=docs/results/real/configs
run() { tools/with_env.sh "$@"; }
# 1. The tank logs as a dataset; whole runs held out (test) and one for validation.
run python offline/table_to_dataset.py "$REAL/kvlcc2_hsva/raw_data" --vessel kvlcc2_hsva \
  --out "$WORK/kvlcc2_ds" --holdout HSVA_CPMC_KVLCC2_Z_20_10_P HSVA_CPMC_KVLCC2_Z_35_05 \
  --val HSVA_CPMC_KVLCC2_Z_15_05 --overwrite --quiet 2> "$OUT/import.log"
# 2. The MMG standard model alone against all 13 zig-zags (mmg_alone.md/.json, figure).
run python docs/results/real/analysis/kvlcc2_mmg.py "$WORK/kvlcc2_ds" "$OUT" > /dev/null
# 3. The diagnosis, blind: identifies on the 11 other runs, judges on the 2 held out.
run python offline/diagnose.py --recordings "$WORK/kvlcc2_ds" --out "$OUT/diagnosis" --quiet
# 4. Hybrids (Hyd regression, nominal MMG, augmented MMG physics) and the LSTM baseline.
for config in hybrid hybrid_mmg hybrid_mmg_augmented lstm; do
  run python offline/train.py "$CONFIGS/$config.yaml" --dataset "$WORK/kvlcc2_ds" \
    --out "$WORK/kvlcc2_runs/$config" --resume --quiet > /dev/null
done
RUNS=("$WORK/kvlcc2_runs/hybrid" "$WORK/kvlcc2_runs/hybrid_mmg" \
      "$WORK/kvlcc2_runs/hybrid_mmg_augmented" "$WORK/kvlcc2_runs/lstm")
# 5. All on the same held-out runs; each hybrid's physics alone; threshold sweeps.
run python offline/evaluate.py "${RUNS[@]}" --dataset "$WORK/kvlcc2_ds" --out "$OUT" \
  --physics-only --sweep hybrid-hyd-2p --thresholds 0.05 0.1 0.15 0.3 0.5 1.0
for label in hybrid-mmg-2p hybrid-mmg-aug-2p; do
  run python offline/evaluate.py "${RUNS[@]:1:2}" --dataset "$WORK/kvlcc2_ds" \
    --out "$OUT/sweep_$label" --sweep "$label" --thresholds 0.05 0.1 0.15 0.3 0.5 1.0
done
# 6. The threshold each physics needs to stay within 5 % of its unconstrained accuracy.
run python docs/results/real/analysis/threshold_needed.py "$OUT/results.json" \
  "$OUT"/sweep_*/results.json > "$OUT/threshold_needed.md"
