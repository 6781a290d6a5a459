#!/usr/bin/env bash
# Import a real ArduSub DataFlash log and derive its account and figure.
# Usage (repo root, after `make setup`): docs/results/real/autopilot/run.sh LOG [WORK]
# LOG: testing/small.BIN of github.com/clydemcqueen/ardusub_log_tools (MIT), e.g.
#   git clone https://github.com/clydemcqueen/ardusub_log_tools && \
#   git -C ardusub_log_tools checkout 2b7c8b137e265b2fc3d75659390628ede9b5b6aa
# This script fetches nothing; the log is never committed.
set -euo pipefail
LOG="${1:?usage: $0 LOG [WORK]}"
WORK="${2:-/tmp/real}"
OUT=docs/results/real/autopilot
run() { tools/with_env.sh "$@"; }
run python offline/log_to_dataset.py "$LOG" --vessel "$OUT/ardusub_rov.yaml" \
  --out "$WORK/ardusub_ds" --split 1,0,0 --overwrite --quiet 2> "$OUT/import.log"
# What the log holds (messages, rates, parameters, arming) and import.png.
run python docs/results/real/analysis/autopilot_import.py "$LOG" "$WORK/ardusub_ds" "$OUT" \
  > "$OUT/log.txt"
