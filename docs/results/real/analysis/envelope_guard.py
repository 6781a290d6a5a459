"""
Would serving the physics alone on unfamiliar input windows help? A post-hoc test.

Usage:  tools/with_env.sh python docs/results/real/analysis/envelope_guard.py STUDY OUT
STUDY is the --out folder of ``offline/workflow.py --folds K``; OUT receives guard.json.

A guard of this kind would switch the learned correction off where the input window is
unlike any the correction was trained on. Each window is summarised by the mean and
standard deviation of every state and control over it (standardised by the training
windows' spread); its novelty is the distance to the nearest training window of the
fold. The thresholds are calibrated on the training windows themselves, leave one run
out (each window's distance to the windows of the other training runs): novel means
beyond their 90th, 95th or 99th percentile or their largest. For every fold's held-out
runs and every seed of each hybrid, the position error at the horizon's end is printed
with the guard off and at each threshold, a guarded forecast being the physics alone.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

import numpy as np
from workflow_folds import at_horizon, open_study, pooled_over_runs

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.models import predict
from hybrid_models.studies.crossval import run_dir
from hybrid_models.training.train import MODEL_FILE

LEVELS = {'off': None, 'q99': 0.99, 'q95': 0.95, 'q90': 0.90, 'max': 1.0}


def features(windows) -> np.ndarray:
    """Return (B, 2 n): per state and control, its mean and std over each input window."""
    x = np.concatenate([windows.z_window, windows.c_window], axis=-1).astype(np.float64)
    return np.concatenate([x.mean(axis=1), x.std(axis=1)], axis=-1)


def nearest(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Return the distance of each row of ``a`` to its nearest row of ``b``."""
    return np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1).min(axis=1))


def novelty(train_windows, test_windows) -> tuple[np.ndarray, dict]:
    """Return the test windows' novelty and the thresholds of LEVELS (see module doc)."""
    train = features(train_windows)
    scale = train.std(axis=0) + 1e-12
    train = train / scale
    own = np.empty(len(train))
    for run in np.unique(train_windows.run_index):
        mine = train_windows.run_index == run
        own[mine] = nearest(train[mine], train[~mine])
    thresholds = {name: np.inf if q is None else float(np.quantile(own, q))
                  for name, q in LEVELS.items()}
    return nearest(features(test_windows) / scale, train), thresholds


def main(argv: list[str]) -> int:
    """Forecast each fold's held-out runs with and without the guard; print, write JSON."""
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('study', type=Path, help='the --out folder of workflow.py --folds K')
    parser.add_argument('out', type=Path, help='receives guard.json')
    args = parser.parse_args(argv)
    folds, protocol, spec, hybrids = open_study(args.study)
    window, horizon, stride = (protocol[k] for k in ('window', 'horizon', 'stride'))
    rows = []
    for fold in folds:
        trained = forecast_windows(load_runs(fold.path, 'train', spec), window, horizon,
                                   stride, 'true')
        runs = [r for r in load_runs(fold.path, 'test', spec) if r.length >= window + horizon]
        windows = forecast_windows(runs, window, horizon, stride, 'true')
        distance, thresholds = novelty(trained, windows)
        for label in hybrids:
            members = [load_model(run_dir(args.study, label, fold, s) / MODEL_FILE)[0]
                       for s in protocol['seeds']]
            preds = [predict(m, windows) for m in members]
            alone = predict(PhysicsOnly(members[0].physical), windows)
            for k, run in enumerate(runs):
                mine = windows.run_index == k
                own = windows.subset(mine)
                novel = {n: distance[mine] > t for n, t in thresholds.items()}
                row = {'fold': fold.index, 'run': run.run_id, 'hybrid': label,
                       'forecasts': int(mine.sum()),
                       'novel': {n: float(flags.mean()) for n, flags in novel.items()}}
                for name, flags in novel.items():
                    guarded = flags[:, None, None]
                    row[name] = [at_horizon(np.where(guarded, alone[mine], p[mine]), own, spec)
                                 for p in preds]
                rows.append(row)
        print(f'fold {fold.index}: {len(rows)} rows', file=sys.stderr, flush=True)
    summary = {}
    for label in hybrids:
        mine = [r for r in rows if r['hybrid'] == label]
        weights = [r['forecasts'] for r in mine]
        for name in LEVELS:
            mean, sd = pooled_over_runs([r[name] for r in mine], weights)
            novel = float(np.average([r['novel'][name] for r in mine], weights=weights))
            summary[f'{label}, guard {name}'] = (mean, sd, novel)
            print(f'{label}, guard {name}: {mean:.2f} ± {sd:.2f} m at '
                  f'{horizon * spec.dt:.0f} s; physics alone on {100 * novel:.0f} % of '
                  f'the forecasts')
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'guard.json').write_text(json.dumps({'summary': summary, 'runs': rows}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
