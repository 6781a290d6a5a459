"""
Per fold: every model of a cross-validated study, mean ± sd over its seeds.

Usage:  tools/with_env.sh python docs/results/real/analysis/study_by_fold.py STUDY [OUT]
STUDY is the --out folder of ``offline/crossval.py`` (results.json, folds/, runs/); the
table goes to stdout and, with OUT, to OUT/by_fold.md and OUT/by_fold.json.

A study's table pools its folds. With ``--fold-by`` each fold is one kind of manoeuvre
held out, and the pooled figure hides which kind a model fails on. Per fold and model:
the trajectory error over the horizon and the position error at its end (each the mean
over the fold's forecasts; mean ± sd over seeds), for each hybrid also its physics
alone, and the forecasts that diverged (non-finite, or outside the vessel file's state
limits at some step), which the means leave out.
"""

from __future__ import annotations

import json
from pathlib import Path
import sys

import numpy as np

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.metrics import forecast_metrics
from hybrid_models.models import predict
from hybrid_models.nets import HybridModel
from hybrid_models.physical.envelope import beyond_limits
from hybrid_models.studies.crossval import read_study, run_dir, study_models
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import read_dataset


def errors(pred: np.ndarray, windows, spec) -> dict:
    """Trajectory and end-of-horizon position error over the forecasts that stay sane."""
    bad = beyond_limits(pred, spec).any(axis=1)
    if bad.all():
        return {'trajectory': float('nan'), 'final': float('nan'), 'diverged': int(bad.sum())}
    kept = windows.subset(~bad)
    traj = forecast_metrics(pred[~bad], kept.z_target, spec)['trajectory']
    return {'trajectory': float(traj['mean']), 'final': float(traj['final_mean']),
            'diverged': int(bad.sum())}


def by_fold(study: Path) -> tuple[list[dict], float]:
    """Return one row per fold and model (and per hybrid's physics alone), and the horizon (s)."""
    folds, result = read_study(study)
    protocol = result['protocol']
    spec = read_dataset(folds[0].path).vessel
    window, horizon, stride = (protocol[k] for k in ('window', 'horizon', 'stride'))
    rows = []
    for fold in folds:
        runs = [r for r in load_runs(fold.path, 'test', spec) if r.length >= window + horizon]
        windows = forecast_windows(runs, window, horizon, stride, protocol['target'])
        for label in study_models(result):
            members = [load_model(run_dir(study, label, fold, s) / MODEL_FILE)[0]
                       for s in protocol['seeds']]
            per_seed = [errors(predict(m, windows), windows, spec) for m in members]
            rows.append(summary(fold.index, fold.test, label, per_seed, len(windows)))
            if isinstance(members[0], HybridModel):
                alone = errors(predict(PhysicsOnly(members[0].physical), windows), windows,
                               spec)
                rows.append(summary(fold.index, fold.test, f'{label}: physics alone',
                                    [alone], len(windows)))
        print(f'fold {fold.index} done', file=sys.stderr, flush=True)
    return rows, horizon * spec.dt


def summary(fold: int, test, label: str, per_seed: list[dict], forecasts: int) -> dict:
    """Mean and sd over seeds of a fold's figures."""
    row = {'fold': fold, 'test_runs': len(test), 'forecasts': forecasts, 'model': label,
           'seeds': len(per_seed), 'diverged': [s['diverged'] for s in per_seed]}
    for key in ('trajectory', 'final'):
        values = np.array([s[key] for s in per_seed])
        row[key] = float(np.mean(values))
        row[f'{key}_sd'] = float(np.std(values, ddof=1)) if len(values) > 1 else 0.0
    return row


def _cell(row: dict, key: str) -> str:
    if row['seeds'] == 1:
        return f'{row[key]:.2f}'
    return f'{row[key]:.2f} ± {row[f"{key}_sd"]:.2f}'


def markdown(rows: list[dict], horizon_s: float) -> str:
    """Return the rows as a Markdown table."""
    lines = ['| fold (forecasts) | model | trajectory error [m] | error at '
             f'{horizon_s:g} s [m] | forecasts diverged (per seed) |', '|---|---|---|---|---|']
    for r in rows:
        lines.append(f"| {r['fold']} ({r['forecasts']}) | {r['model']} | "
                     f"{_cell(r, 'trajectory')} | {_cell(r, 'final')} | "
                     f"{', '.join(map(str, r['diverged']))} |")
    return '\n'.join(lines) + '\n'


def main(argv: list[str]) -> int:
    """Print (and with OUT write) the per-fold table of a study."""
    if len(argv) not in (1, 2):
        print(__doc__, file=sys.stderr)
        return 2
    study = Path(argv[0])
    rows, horizon_s = by_fold(study)
    table = markdown(rows, horizon_s)
    print(table)
    if len(argv) == 2:
        out = Path(argv[1])
        out.mkdir(parents=True, exist_ok=True)
        (out / 'by_fold.md').write_text(table)
        (out / 'by_fold.json').write_text(json.dumps(rows, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
