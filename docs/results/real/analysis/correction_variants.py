"""
Retrain a cross-validated workflow's hybrids with a changed config; compare on held-out runs.

Usage:  tools/with_env.sh python docs/results/real/analysis/correction_variants.py
            STUDY OUT --folds 2 4 --seeds 0 1 2 --set model.hidden=16 --set model.layers=1

STUDY is the --out folder of ``offline/workflow.py --folds K``. For each given fold,
seed and hybrid of the study (one per physics; ``--models`` to choose), the study's own
training config of that run is trained again with the ``--set`` overrides (in which
``{study}``, ``{fold}`` and ``{seed}`` stand for the study folder and the run's fold
and seed, e.g. ``training.init_from={study}/runs/hybrid_on_nominal_physics/fold{fold}/
seed{seed}/model.safetensors``) (``offline/train.py``, two trainings
at a time, one thread each; a finished training in OUT is kept). Then the study's
models and the variants forecast the fold's held-out runs with the study's protocol,
and the position error at the horizon's end is printed and written to OUT/variant.json:
per run and pooled over the runs (weighted by their forecasts), mean ± sd over seeds.
"""

from __future__ import annotations

import argparse
from concurrent.futures import ThreadPoolExecutor
import json
from pathlib import Path
import subprocess
import sys

import numpy as np
from workflow_folds import at_horizon, open_study, pooled_over_runs

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.metrics import forecast_metrics
from hybrid_models.models import predict
from hybrid_models.selection import harms
from hybrid_models.studies.crossval import ensemble_path, run_dir
from hybrid_models.training.ensemble import serve_ensemble
from hybrid_models.training.train import MODEL_FILE

TRAIN = Path(__file__).resolve().parents[4] / 'offline' / 'train.py'


def train(config: Path, out: Path, seed: int, overrides: list[str]) -> Path:
    """Train ``config`` with ``overrides`` (placeholders filled) into ``out``; return out."""
    if (out / MODEL_FILE).is_file():
        return out
    out.mkdir(parents=True, exist_ok=True)
    command = [sys.executable, str(TRAIN), str(config), '--out', str(out), '--quiet',
               '--set', f'training.seed={seed}', '--set', 'training.threads=1']
    for item in overrides:
        command += ['--set', item]
    with open(out / 'stderr.txt', 'w') as log:
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL, stderr=log)
    print(f'trained {out}', file=sys.stderr, flush=True)
    return out


def pooled(rows: list[dict], key: str) -> tuple[float, float]:
    """Mean and sd over seeds of ``key`` pooled over the runs of ``rows``."""
    return pooled_over_runs([r[key] for r in rows], [r['forecasts'] for r in rows])


def per_run(fold_rows: list[dict], windows, key: str, members: list, spec) -> None:
    """Write each run's position error at the horizon's end of ``members`` into its row."""
    for k, row in enumerate(fold_rows):
        mine = windows.run_index == k
        row[key] = [at_horizon(p[mine], windows.subset(mine), spec) for p in members]


def variant_dir(out: Path, label: str, fold, seed: int) -> Path:
    """Return where the variant of ``label``'s model of ``fold`` and ``seed`` is trained."""
    return out / label.replace(' ', '_') / f'fold{fold.index}' / f'seed{seed}'


def main(argv: list[str]) -> int:
    """Train the variants, forecast the held-out runs, print and write the comparison."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('study', type=Path)
    parser.add_argument('out', type=Path)
    parser.add_argument('--folds', type=int, nargs='+', required=True)
    parser.add_argument('--seeds', type=int, nargs='+', default=[0, 1, 2])
    parser.add_argument('--set', dest='overrides', action='append', default=[],
                        metavar='KEY=VALUE', help='config override, as for train.py; '
                        '{study}, {fold} and {seed} are filled in per run')
    parser.add_argument('--models', nargs='+', metavar='LABEL',
                        help="the study's hybrids to vary (default: all)")
    parser.add_argument('--ensemble', action='store_true',
                        help="also the variant's seeds of a fold served as one ensemble, "
                             "against the study's ensemble of the same fold")
    args = parser.parse_args(argv)
    if not args.overrides:
        parser.error('give at least one --set: the variant to compare')
    folds, protocol, spec, hybrids = open_study(args.study)
    chosen = [f for f in folds if f.index in args.folds]
    if len(chosen) != len(set(args.folds)):
        parser.error(f'the study has folds {[f.index for f in folds]}')
    others = []   # the study's hybrids not varied: their ensembles are compared (--ensemble)
    if args.models:
        unknown = sorted(set(args.models) - set(hybrids))
        if unknown:
            parser.error(f"{unknown} not among the study's hybrids {hybrids}")
        others = [label for label in hybrids if label not in args.models]
        hybrids = [label for label in hybrids if label in args.models]

    def filled(fold, seed) -> list[str]:
        return [item.format(study=args.study, fold=fold.index, seed=seed)
                for item in args.overrides]

    tasks = [(run_dir(args.study, label, fold, 0) / 'config.yaml',
              variant_dir(args.out, label, fold, seed), seed, filled(fold, seed))
             for fold in chosen for label in hybrids for seed in args.seeds]
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(lambda t: train(*t), tasks))
    window, horizon, stride = (protocol[k] for k in ('window', 'horizon', 'stride'))
    rows, pooled_preds, targets = [], {}, []
    for fold in chosen:
        runs = [r for r in load_runs(fold.path, 'test', spec) if r.length >= window + horizon]
        windows = forecast_windows(runs, window, horizon, stride, 'true')
        targets.append(windows.z_target)
        fold_rows = [{'fold': fold.index, 'run': r.run_id,
                      'forecasts': int((windows.run_index == k).sum())}
                     for k, r in enumerate(runs)]
        for label in hybrids:
            study_models = [load_model(run_dir(args.study, label, fold, s) / MODEL_FILE)[0]
                            for s in args.seeds]
            variants = [load_model(variant_dir(args.out, label, fold, s) / MODEL_FILE)[0]
                        for s in args.seeds]
            alone = predict(PhysicsOnly(study_models[0].physical), windows)
            preds = {'physics alone': [alone],
                     'study': [predict(m, windows) for m in study_models],
                     'variant': [predict(m, windows) for m in variants]}
            if args.ensemble:
                packed = variant_dir(args.out, label, fold, 0).parent / 'ensemble.safetensors'
                if not packed.is_file():
                    serve_ensemble([variant_dir(args.out, label, fold, s) / MODEL_FILE
                                    for s in args.seeds], fold.path, packed)
                preds['study ensemble'] = [predict(load_model(
                    ensemble_path(args.study, label, fold))[0], windows)]
                preds['variant ensemble'] = [predict(load_model(packed)[0], windows)]
            for name, members in preds.items():
                pooled_preds.setdefault(f'{label}: {name}', []).append(members)
            for name, members in preds.items():
                per_run(fold_rows, windows, f'{label}: {name}', members, spec)
        for label in others if args.ensemble else ():
            pred = predict(load_model(ensemble_path(args.study, label, fold))[0], windows)
            per_run(fold_rows, windows, f'{label}: study ensemble', [pred], spec)
        rows += fold_rows
    keys = [k for k in rows[0] if ':' in k]
    for key in keys:
        mean, sd = pooled(rows, key)
        print(f'{key}: {mean:.2f} ± {sd:.2f} m at {horizon * spec.dt:.0f} s')
    # Do no harm over all folds: a seed (or ensemble) worse than its physics alone at a
    # reported step of the pooled forecasts.
    true = np.concatenate(targets)
    profile = {key: [forecast_metrics(np.concatenate(per_fold), true, spec)['profile']
                     for per_fold in zip(*folds_preds, strict=True)]
               for key, folds_preds in pooled_preds.items()}
    harm = {}
    for key, profiles in profile.items():
        label = key.split(': ')[0]
        if not key.endswith('physics alone'):
            alone = profile[f'{label}: physics alone'][0]
            harm[key] = [harms(p, alone) for p in profiles]
            print(f'{key}: worse than its physics alone at a reported step in '
                  f'{sum(map(bool, harm[key]))} of {len(profiles)}')
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'variant.json').write_text(json.dumps(
        {'overrides': args.overrides, 'folds': args.folds, 'seeds': args.seeds,
         'pooled': {k: pooled(rows, k) for k in keys},
         'per_fold': {f.index: {k: pooled([r for r in rows if r['fold'] == f.index], k)[0]
                                for k in keys} for f in chosen},
         'harms_vs_physics': harm,
         'runs': rows}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
