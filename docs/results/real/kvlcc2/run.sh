#!/usr/bin/env bash
# Derive every KVLCC2 figure in docs/results/real/kvlcc2/README.md from the original tank logs.
# Usage (repo root, after `make setup`): docs/results/real/kvlcc2/run.sh [SHARED_REAL] [WORK]
# The current results are written into docs/results/real/kvlcc2 (import.log, mmg_alone,
# diagnosis/, heldout_warm/, cv5_noleak/); the studies measured and not kept stay in WORK
# (the page names each one's folder there).
# About eight hours on 2 cores: 15 + 10 trainings on the held-out split and
# 75 + 30 + 50 + 25 + 25 + 30 + 50 over five folds, one to three minutes each (a second call
# keeps every finished training).
set -euo pipefail
# The committed figures' CPU kernels, whatever this CPU has (tools/pinned_kernels.env).
set -a; source tools/pinned_kernels.env; set +a
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
sed -i "s#$WORK/#\$WORK/#g" "$OUT"/diagnosis/*.{md,json,yaml}
# 4. The whole workflow on the held-out split, five seeds: the diagnosis identifies on the
#    training runs and judges on the validation run; the MMG hybrid on the nominal and on
#    the augmented physics and the LSTM are trained, and all are compared on Z_20_10_P
#    and Z_35_05 with each physics alone.
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_heldout" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --lstm "$CONFIGS/lstm.yaml" --seeds 5 > /dev/null
# 5. The same over five folds: every one of the 13 runs held out once (folds of equal
#    counts of runs, as this study was made before folds were balanced by samples).
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_cv5" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --lstm "$CONFIGS/lstm.yaml" --seeds 5 --folds 5 \
  --fold-balance recordings > /dev/null
# 6. The hybrid with the Hyd regression physics (no MMG) on the held-out split, five seeds.
run python offline/crossval.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_hyd" \
  --seeds 5 --model "hybrid, Hyd regression physics=$CONFIGS/hybrid.yaml" > /dev/null
# 7. The five folds run by run: each held-out run's error per model, the seeds' ensemble.
run python docs/results/real/analysis/workflow_folds.py "$WORK/kvlcc2_cv5" "$WORK/kvlcc2_cv5" \
  > /dev/null
# 8. Measured, not kept: the physics alone on unfamiliar input windows (post hoc), and
#    smaller or weight-decayed corrections on folds 2 and 4 (the mild zig-zags; weight
#    decay 0.0001, the data's residual scale and no teacher phase on all five folds),
#    3 seeds.
run python docs/results/real/analysis/envelope_guard.py "$WORK/kvlcc2_cv5" "$WORK/kvlcc2_cv5/guard" \
  > /dev/null
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5" \
  "$WORK/kvlcc2_cv5_small" --folds 2 4 --set model.hidden=16 --set model.layers=1 > /dev/null
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5" \
  "$WORK/kvlcc2_cv5_wd" --folds 2 4 --set training.weight_decay=0.001 > /dev/null
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5" \
  "$WORK/kvlcc2_cv5_wd4" --folds 0 1 2 3 4 --set training.weight_decay=0.0001 > /dev/null
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5" \
  "$WORK/kvlcc2_cv5_scale" --folds 0 1 2 3 4 --set model.residual_scale=state_change \
  > /dev/null
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5" \
  "$WORK/kvlcc2_cv5_noteacher" --folds 0 1 2 3 4 \
  --set 'training.phases=[{kind: multistep, max_epochs: 60, patience: 10, lr: 0.001}]' \
  > /dev/null
#    Each variant's figures: $WORK/kvlcc2_cv5_{small,wd,wd4,scale,noteacher}/variant.json.
# 9. The five folds again, dealt by samples (the default since 2026-11-25; step 5 keeps the
#    former dealing), the two MMG hybrids with three seeds each (no LSTM), and the
#    cross-validated bands of each (docs/results/real/bands.md).
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" \
  --out "$WORK/kvlcc2_cv5_by_samples" --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 3 \
  --folds 5 > /dev/null
for physics in nominal augmented; do
  model="$WORK/kv_cv5_by_samples_$physics.safetensors"
  run python offline/set_threshold.py \
    "$WORK/kvlcc2_cv5_by_samples/runs/hybrid_on_${physics}_physics/fold0/seed0/model.safetensors" \
    none --out "$model" > /dev/null
  run python offline/set_bands.py "$model" --study "$WORK/kvlcc2_cv5_by_samples" \
    --model "hybrid on $physics physics" 2> /dev/null \
    > "$WORK/kvlcc2_cv5_by_samples/bands_$physics.md"
done
# 10. Which model the folds' own validation runs would have served (post hoc, from the
#    checkpoints of step 9): the lowest validation score among each physics alone and
#    the hybrid on each, per fold and seed.
run python docs/results/real/analysis/workflow_choice.py "$WORK/kvlcc2_cv5_by_samples" \
  "$WORK/kvlcc2_cv5_by_samples" > /dev/null
# 11. The five folds dealt by samples with five seeds, each hybrid's seeds of a fold also
#    served as one ensemble (the workflow's default since 2026-11-26), the two MMG hybrids.
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_cv5_ensemble" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 5 --folds 5 > /dev/null
# 12. Measured, not kept: a slower multistep phase (lr 0.0003 instead of 0.001) for both
#    hybrids of step 11, all five folds, seeds 0-2.
teacher='{kind: teacher, max_epochs: 15, patience: 4, lr: 0.003}'
slower='{kind: multistep, max_epochs: 60, patience: 10, lr: 0.0003}'
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5_ensemble" \
  "$WORK/kvlcc2_cv5_lr3" --folds 0 1 2 3 4 --set "training.phases=[$teacher, $slower]" \
  > /dev/null
# 13. What the multistep phase sees of each physics (step 11's folds and checkpoints): the
#    physics alone's normalized loss over 1-400 steps on the training runs, against the
#    hybrids' multistep training loss at the kept and the last epoch.
run python docs/results/real/analysis/physics_drift.py "$WORK/kvlcc2_cv5_ensemble" \
  "$WORK/kvlcc2_cv5_ensemble" > /dev/null
# 14. The hybrid on the augmented physics started from the recurrent layers of the hybrid
#    on the nominal physics of its fold and seed (training.init_from; what the workflow
#    does by default since 2026-11-27, --cold-start as before), step 11's folds, 5 seeds.
run python docs/results/real/analysis/correction_variants.py "$WORK/kvlcc2_cv5_ensemble" \
  "$WORK/kvlcc2_cv5_warm" --folds 0 1 2 3 4 --seeds 0 1 2 3 4 --ensemble \
  --models "hybrid on augmented physics" \
  --set 'training.init_from={study}/runs/hybrid_on_nominal_physics/fold{fold}/seed{seed}/model.safetensors' \
  > /dev/null
# 15. The workflow on the held-out split again, as step 4 but with the warm start (its
#    default since 2026-11-27), the two MMG hybrids with five seeds (no LSTM).
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_heldout_warm" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 5 > /dev/null
#     Its two hybrids seed by seed (paired: an order, or a tie).
mkdir -p "$OUT/heldout_warm"
run python docs/results/real/analysis/paired_seeds.py "$WORK/kvlcc2_heldout_warm" \
  "$OUT/heldout_warm" > /dev/null
# 16. Step 11 again with the diagnosis fitted on each fold's training runs alone (the fix
#     of 2026-11-27; before it, each fold's augmented physics also saw the fold's test
#     runs) and the warm start: the same folds and five seeds; the nominal hybrids do not
#     depend on the diagnosis and are step 11's trainings, copied in and kept.
noleak="$WORK/kvlcc2_cv5_noleak"
if [ ! -d "$noleak/runs" ]; then
  mkdir -p "$noleak/runs"
  cp -r "$WORK/kvlcc2_cv5_ensemble/folds" "$noleak/"
  rm -rf "$noleak"/folds/*/diagnosis "$noleak"/folds/*/view
  cp -r "$WORK/kvlcc2_cv5_ensemble/runs/hybrid_on_nominal_physics" "$noleak/runs/"
fi
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$noleak" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 5 --folds 5 > /dev/null
mkdir -p "$OUT/cv5_noleak"
run python docs/results/real/analysis/paired_seeds.py "$noleak" "$OUT/cv5_noleak" > /dev/null
#     Run by run: where each hybrid wins and loses (folds.md).
run python docs/results/real/analysis/workflow_folds.py "$noleak" "$OUT/cv5_noleak" > /dev/null
# 17. What the fallbacks to the physics alone cost (post hoc, on a copy of step 16's
#     study): each hybrid on the augmented physics that its fold's one validation run
#     served as its physics alone is served at its best candidate threshold instead,
#     and the study is pooled again (its trainings kept).
nofallback="$WORK/kvlcc2_cv5_noleak_nofallback"
rm -rf "$nofallback"
cp -r "$noleak" "$nofallback"
rm -rf "$nofallback"/runs/*/*/ensemble "$nofallback"/{report.md,table.md,results.json}
mkdir -p "$OUT/cv5_noleak/no_fallback"
run python docs/results/real/analysis/serve_best_candidate.py \
  "$nofallback/runs/hybrid_on_augmented_physics" > "$OUT/cv5_noleak/no_fallback/served.md"
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$nofallback" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 5 --folds 5 > /dev/null
run python docs/results/real/analysis/paired_seeds.py "$nofallback" \
  "$OUT/cv5_noleak/no_fallback" > /dev/null
cp "$nofallback"/{table.md,results.json} "$OUT/cv5_noleak/no_fallback/"
sed -i "s#$WORK/#\$WORK/#g" "$OUT"/cv5_noleak/no_fallback/*
# 18. Step 16 with eight seeds: seeds 5-7 of both hybrids added (a copy of its study, so
#     its five seeds are kept and only the new ones train).
noleak8="$WORK/kvlcc2_cv5_noleak8"
if [ ! -d "$noleak8/runs" ]; then
  cp -r "$noleak" "$noleak8"
  rm -rf "$noleak8"/runs/*/*/ensemble
fi
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$noleak8" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 8 --folds 5 > /dev/null
run python docs/results/real/analysis/paired_seeds.py "$noleak8" "$noleak8" > /dev/null
# 19. Step 16 with two validation runs per fold instead of one (--val-fraction 0.2: each
#     fold's view moves one training run to validation; the same test runs, five seeds;
#     every training and diagnosis anew), and its two hybrids seed by seed.
run python offline/workflow.py --dataset "$WORK/kvlcc2_ds" --out "$WORK/kvlcc2_cv5_val2" \
  --hybrid "$CONFIGS/hybrid_mmg.yaml" --seeds 5 --folds 5 --val-fraction 0.2 > /dev/null
run python docs/results/real/analysis/paired_seeds.py "$WORK/kvlcc2_cv5_val2" \
  "$WORK/kvlcc2_cv5_val2" > /dev/null
run python docs/results/real/analysis/workflow_folds.py "$WORK/kvlcc2_cv5_val2" \
  "$WORK/kvlcc2_cv5_val2" > /dev/null
# The current studies into the repository; every other study's report.md, table.md,
# results.json and figure stay in its WORK folder.
for study in heldout_warm cv5_noleak; do
  mkdir -p "$OUT/$study"
  cp "$WORK/kvlcc2_$study"/{report.md,table.md,results.json,position_error_over_horizon.png} \
    "$OUT/$study/"
  # The work folder is the user's: named, not spelled out, in the committed files.
  sed -i "s#$WORK/#\$WORK/#g" "$OUT/$study"/*.md "$OUT/$study/results.json"
done
