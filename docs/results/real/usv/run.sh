#!/usr/bin/env bash
# Import the USV turning test (GPS, compass heading, rudder only) and derive its figure.
# Usage (repo root, after `make setup`): docs/results/real/usv/run.sh [SHARED_REAL] [WORK]
set -euo pipefail
REAL="${1:-../shared/real}"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/usv
run() { tools/with_env.sh "$@"; }
# No velocity columns: body velocities come from the track and the heading (usv.yaml).
run python offline/table_to_dataset.py "$REAL/usv/turnningdata_xy.csv" --vessel usv \
  --out "$WORK/usv_ds" --split 1,0,0 --overwrite --quiet 2> "$OUT/import.log"
# The units established from the data (usv_import.md) and track_heading_drift.png.
run python docs/results/real/analysis/usv_import.py "$WORK/usv_ds" "$REAL" "$OUT" \
  > "$OUT/established.txt"
