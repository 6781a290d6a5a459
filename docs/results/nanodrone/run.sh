#!/usr/bin/env bash
# Derive every nanodrone result of this folder from the shared flights (Table 3 under the
# paper's protocol and under the benchmark's, with the benchmark's own models as rows).
# Usage (repo root, after `make setup`): docs/results/nanodrone/run.sh [WORK] [STEP...]
#   WORK: where datasets and trainings go (default /tmp/real/nanodrone); STEP: any of
#   convert peers paper benchmark simulate sim sim_benchmark physics (default all, in
#   that order).
#   Nothing of the flights is committed; re-running resumes the trainings. SEEDS=n
#   (default 5) trains fewer seeds per model, for a shorter run.
# Time on the 2-core machine: conversion seconds, peers ~2 min, simulation ~1 min, each
# Table 3 ~1-1.5 h.
set -euo pipefail
# The committed figures' CPU kernels, whatever this CPU has (tools/pinned_kernels.env).
set -a; source tools/pinned_kernels.env; set +a
WORK="${1:-/tmp/real/nanodrone}"
shift || true
STEPS="${*:-convert peers paper benchmark simulate sim sim_benchmark physics}"
SEEDS="${SEEDS:-5}"
OUT=docs/results/nanodrone
REAL=../shared/real/nanodrone
run() { tools/with_env.sh "$@"; }
has() { [[ " $STEPS " == *" $1 "* ]]; }
mkdir -p "$WORK"
# The 20 usable flights: melon_20251017_run2_na is refused by the map checks (its motion
# capture stops and the estimate diverges: import.md).
FLIGHTS=$(ls "$REAL"/*/*.parquet | grep -v '_na\.parquet$')
MELON="melon_20251017_run1 melon_20251017_run4 melon_20251017_run5"
if has convert; then
  # The paper's protocol: a seeded 60/10/30 split by flight (12/2/6).
  run python offline/table_to_dataset.py $FLIGHTS --vessel crazyflie_brushless \
    --out "$WORK/paper_ds" --overwrite --quiet 2> "$OUT/paper_convert.log"
  # The benchmark's: train on square, random and multisine (chirp), test on melon; its
  # source's test/ folder's other flights validate.
  run python offline/table_to_dataset.py $FLIGHTS --vessel crazyflie_brushless \
    --out "$WORK/benchmark_ds" --holdout $MELON --val multisine_20251017_run4 \
    random1_20251017_run4 random2_20251017_run4 square_20251017_run5 --split 1,0,0 \
    --overwrite --quiet 2> "$OUT/benchmark_convert.log"
fi
if has peers; then
  tools/setup.sh bench
  .venv-bench/bin/python offline/peers/nanodrone_benchmark.py \
    --flights $(for m in $MELON; do ls "$REAL"/*/"$m".parquet; done) --horizon 50 --stride 1 \
    --out "$WORK/peers.npz"
fi
if has paper; then
  run python offline/reproduce_table3.py --dataset "$WORK/paper_ds" --out "$OUT/paper" \
    --work "$WORK/paper_runs" --seeds "$SEEDS"
fi
if has benchmark; then
  run python offline/reproduce_table3.py --dataset "$WORK/benchmark_ds" \
    --out "$OUT/benchmark" --work "$WORK/benchmark_runs" --seeds "$SEEDS" --horizon 50 \
    --stride 1 --peers "$WORK/peers.npz"
fi
# Simulated flights of the same craft (the multirotor simulator, docs/simulator.md): 30
# flights of 60 s, the benchmark's kinds mixed; a seeded 60/10/30 split for the paper's
# protocol, the melon flights held out for the benchmark's.
if has simulate; then
  run python offline/simulate.py --vessel crazyflie_brushless --runs 30 --seconds 60 \
    --seed 0 --out "$WORK/sim_ds" --overwrite --quiet
  run python offline/simulate.py --vessel crazyflie_brushless --runs 30 --seconds 60 \
    --seed 0 --test-kinds melon --out "$WORK/sim_benchmark_ds" --overwrite --quiet
fi
if has sim; then
  run python offline/reproduce_table3.py --dataset "$WORK/sim_ds" --out "$OUT/sim" \
    --work "$WORK/sim_runs" --seeds "$SEEDS"
fi
if has sim_benchmark; then
  run python offline/reproduce_table3.py --dataset "$WORK/sim_benchmark_ds" \
    --out "$OUT/sim_benchmark" --work "$WORK/sim_benchmark_runs" --seeds "$SEEDS" --horizon 50
fi
# The same hybrid on rotorpy's file and on the diagnosis's augmented one (diagnosis.md),
# paper protocol: does better physics let the bound shrink?
if has physics; then
  run python offline/compare_physics.py --dataset "$WORK/paper_ds" \
    --physics nominal=ros2_ws/src/vessel_physics/config/crazyflie_brushless_multirotor.yaml \
    augmented=$OUT/diagnosis/nominal/augmented_physics.yaml \
    --config ros2_ws/src/hybrid_models/config/table3_hybrid.yaml --stride 10 --jobs 2 \
    --out "$WORK/compare_physics"
  cp "$WORK"/compare_physics/{report.md,results.json,table.md,threshold_comparison.png} \
    "$OUT/compare_physics/"
fi
