#!/usr/bin/env bash
# Derive every table of docs/results/peers/README.md: the peers (SysIdentPy NARX, PySINDy,
# deepsysid's LSTM) beside our QLag, LSTM, hybrid and its physics, on the same splits,
# windows and measures.
# Usage (repo root, after `make setup`): docs/results/peers/run.sh [SHARED_REAL] [WORK] [STEP...]
#   STEP: any of snuboat kvlcc2 bykind patrol nanodrone (default all, in that order).
# Time on the 2-core machine, shared with other work: roughly 20-40 min per dataset; a
# second call keeps every finished training and every peer's answer to the same problem.
set -euo pipefail
# The committed figures' CPU kernels, whatever this CPU has (tools/pinned_kernels.env).
set -a; source tools/pinned_kernels.env; set +a
REAL="${1:-../shared/real}"
WORK="${2:-/tmp/peers}"
shift 2 || true
STEPS="${*:-snuboat kvlcc2 bykind patrol nanodrone}"
OUT=docs/results/peers
CONFIGS=docs/results/real/configs
QLAG=ros2_ws/src/hybrid_models/config/table3_qlag.yaml
run() { tools/with_env.sh "$@"; }
has() { [[ " $STEPS " == *" $1 "* ]]; }
mkdir -p "$WORK"
tools/setup.sh bench
# One training at a time on one thread: the machine's two cores are shared.
ours() {  # DATASET STUDY SEEDS [crossval arguments...]
  local ds="$1" study="$2" seeds="$3"; shift 3
  run python offline/crossval.py --dataset "$ds" --out "$study" --seeds "$seeds" --jobs 1 \
    --threads 1 --no-ensemble "$@" > /dev/null
}
# deepsysid's LSTM trains a fixed number of epochs (theirs: 400 + 800); on the shared
# cores it runs an eighth (0.125) or a quarter of them, and on the by-kind folds its
# defaults alone (no grid).
peers() {  # NAME TITLE SEEDS DEEPSYSID_ARGS [peer_benchmark arguments...]
  local name="$1" title="$2" seeds="$3" dsid="$4"; shift 4
  run python offline/peer_benchmark.py --out "$WORK/res/$name" --title "$title" \
    --seeds "$seeds" --peer-option "deepsysid-lstm=$dsid" "$@" > /dev/null
  mkdir -p "$OUT/$name"
  cp "$WORK/res/$name"/{table.md,results.json} "$OUT/$name/"
  # The work folder is the user's: named, not spelled out, in the committed files.
  sed -i "s#$WORK/#\$WORK/#g" "$OUT/$name/results.json"
}
if has snuboat || has bykind; then
  # The snuboat's bags as docs/results/real/snuboat/run.sh converts them (every map
  # check passes; offline/claims.py keeps its figures on every commit).
  run python offline/bag_to_dataset.py "$REAL/snuboat/bags" --vessel snuboat \
    --msg-dir "$REAL/snuboat/msg" --msg-package snumsg_pkg --out "$WORK/snuboat_ds" \
    --jobs 2 --overwrite --quiet 2> "$WORK/snuboat_convert.log"
fi
if has snuboat; then
  ours "$WORK/snuboat_ds" "$WORK/snuboat_ours" 5 --model qlag=$QLAG \
    --model lstm=$CONFIGS/lstm.yaml --model hybrid=$CONFIGS/hybrid.yaml
  peers snuboat_heldout 'snuboat, held-out bags' 5 '--epochs-scale 0.25' --study "$WORK/snuboat_ours"
fi
if has kvlcc2; then
  run python offline/table_to_dataset.py "$REAL/kvlcc2_hsva/raw_data" --vessel kvlcc2_hsva \
    --out "$WORK/kvlcc2_ds" --holdout HSVA_CPMC_KVLCC2_Z_20_10_P HSVA_CPMC_KVLCC2_Z_35_05 \
    --val HSVA_CPMC_KVLCC2_Z_15_05 --overwrite --quiet 2> "$WORK/kvlcc2_convert.log"
  ours "$WORK/kvlcc2_ds" "$WORK/kvlcc2_ours" 5 --model qlag=$QLAG \
    --model lstm=$CONFIGS/lstm.yaml --model hybrid=$CONFIGS/hybrid_mmg.yaml
  peers kvlcc2_heldout 'KVLCC2 HSVA, held-out zig-zags' 5 '--epochs-scale 0.125' --study "$WORK/kvlcc2_ours"
fi
if has bykind; then
  # One fold per manoeuvre kind (free running 7, free running 8, turning), three seeds,
  # as docs/results/real/snuboat/run.sh's by-kind study.
  ours "$WORK/snuboat_ds" "$WORK/snuboat_bykind_ours" 3 \
    --fold-by 'FREE_RUNNING_(7|8|TURNING)' --model qlag=$QLAG \
    --model lstm=$CONFIGS/lstm.yaml --model hybrid=$CONFIGS/hybrid.yaml
  peers snuboat_bykind 'snuboat, manoeuvre kinds held out' 3 '--quick --epochs-scale 0.125' \
    --study "$WORK/snuboat_bykind_ours"
  # Ours per fold (kind): the pooled table hides the kind a model fails on.
  run python docs/results/real/analysis/study_by_fold.py "$WORK/snuboat_bykind_ours" \
    "$WORK/res/snuboat_bykind" > /dev/null
  cp "$WORK/res/snuboat_bykind/by_fold.md" "$OUT/snuboat_bykind/ours_by_fold.md"
fi
if has patrol; then
  # The Table-2 setting (the patrol boat's simulator, 1 h runs at 1 Hz, split 60/10/30,
  # 60 s window, 900 s horizon), reduced from 96 to 20 runs: 12 train, 2 val, 6 test.
  [ -f "$WORK/ship20/manifest.json" ] || run python offline/simulate.py --runs 20 --hours 1 \
    --seed 0 --out "$WORK/ship20" --quiet > /dev/null
  ours "$WORK/ship20" "$WORK/ship20_ours" 5 \
    --model qlag=ros2_ws/src/hybrid_models/config/qlag.yaml \
    --model lstm=ros2_ws/src/hybrid_models/config/lstm.yaml \
    --model hybrid=$OUT/configs/patrol_hybrid.yaml
  peers patrol20 'patrol boat, simulated (20 one-hour runs)' 5 '--epochs-scale 0.125' \
    --study "$WORK/ship20_ours"
fi
if has nanodrone; then
  # The Crazyflie's real flights under the paper's protocol (12/2/6 flights, 0.5 s
  # window, 1 s horizon at 100 Hz). Our rows are Table 3's (docs/results/nanodrone/run.sh
  # WORK paper) when its results are there; else the peers alone. deepsysid at its
  # defaults (no grid) and an eighth of its epochs, as on the by-kind folds.
  ND="$WORK/nanodrone"
  docs/results/nanodrone/run.sh "$ND" convert
  if [ -f docs/results/nanodrone/paper/results.json ]; then
    peers nanodrone_paper 'Crazyflie 2.1 Brushless, real flights (paper protocol)' 5 \
      '--quick --epochs-scale 0.125' --study docs/results/nanodrone/paper \
      --dataset "$ND/paper_ds"
  else
    peers nanodrone_paper 'Crazyflie 2.1 Brushless, real flights (paper protocol)' 5 \
      '--quick --epochs-scale 0.125' --dataset "$ND/paper_ds"
  fi
fi
