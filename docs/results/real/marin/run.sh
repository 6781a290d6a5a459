#!/usr/bin/env bash
# A KVLCC2 campaign nobody on this team ran, at another scale: MARIN's free-running tests
# of the full-scale ship (SIMMAN 2008), used as a user would use our tools on it.
# Usage (repo root, after `make setup`): docs/results/real/marin/run.sh MARIN_DIR [WORK]
# MARIN_DIR holds MARIN_FREE_KVLCC2_{tc_35,tc_-35,zz_10,zz_-10,zz_20,zz_-20}_m.dat of the
# public repository martinlarsalbert/System-identification-of-Vessel-Manoeuvring-Models
# (MIT licence), data/01_raw/kvlcc2/, commit 4b7ce53; they are not committed here.
# About an hour on 2 cores (90 trainings of a minute or less).
set -euo pipefail
# The committed figures' CPU kernels, whatever this CPU has (tools/pinned_kernels.env).
set -a; source tools/pinned_kernels.env; set +a
MARIN="$1"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/marin
CONFIGS=docs/results/real/configs
run() { tools/with_env.sh "$@"; }
# 1. The 7 m model's MMG file, Froude-scaled to the 320 m ship in sea water.
run python offline/scale_physics.py kvlcc2_hsva_mmg --vessel "$OUT/kvlcc2_marin.yaml" \
  --rho 1025 --out "$OUT/kvlcc2_marin_mmg.yaml" > /dev/null
# 2. The six logs as a dataset (every map check passes on the coarse columns).
run python offline/table_to_dataset.py "$MARIN" --vessel "$OUT/kvlcc2_marin.yaml" \
  --out "$WORK/marin_ds" --overwrite 2> "$OUT/import.log"
# 3. Diagnose, augment, retrain, compare, every run held out once (six folds), 5 seeds,
#    each hybrid's seeds also served as one ensemble.
run python offline/workflow.py --dataset "$WORK/marin_ds" --out "$WORK/marin_loo" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --lstm "$CONFIGS/lstm.yaml" --seeds 5 --folds 6 \
  > /dev/null
mkdir -p "$OUT/loo"
cp "$WORK/marin_loo"/{report.md,table.md,results.json,position_error_over_horizon.png} \
  "$OUT/loo/"
# The work folder is the user's: named, not spelled out, in the committed files.
sed -i "s#$WORK/#\$WORK/#g" "$OUT/loo"/*.md "$OUT/loo/results.json" "$OUT/import.log"
