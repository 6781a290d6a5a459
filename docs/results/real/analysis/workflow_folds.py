"""
Per fold and per held-out run: where a cross-validated workflow's hybrids win and lose.

Usage:  tools/with_env.sh python docs/results/real/analysis/workflow_folds.py STUDY OUT
STUDY is the --out folder of ``offline/workflow.py --folds K`` (its results.json, folds/
and runs/); OUT receives folds.md and folds.json.

The workflow's table pools every fold. This breaks it down: for each test run of each
fold, the position error at the horizon's end (mean over that run's forecasts) of the
nominal and of the augmented physics alone, and of each hybrid as the mean over its
seeds, their spread, and the forecast of the seeds' mean (an ensemble, which the
predictor does not serve: it measures how much of a hybrid's error is seed variance).
Next to each run, the largest rudder angle of that run against the largest of the
fold's training runs, so that extrapolation shows.
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
from hybrid_models.studies.crossval import Fold, read_study, run_dir
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import read_dataset


def at_horizon(pred: np.ndarray, windows, spec) -> float:
    """Mean position error (m) at the last forecast step."""
    return float(forecast_metrics(pred, windows.z_target, spec)['trajectory']['final_mean'])


def open_study(study: Path) -> tuple[list[Fold], dict, object, list[str]]:
    """Return a workflow study's folds, protocol, vessel and the labels of its trained hybrids."""
    folds, result = read_study(study)
    # trained per seed (an ensemble row packs them and has no trainings of its own)
    hybrids = [row['label'] for row in result['rows']
               if 'physics' in row and 'per_seed_metrics' in row]
    return folds, result['protocol'], read_dataset(folds[0].path).vessel, hybrids


def over_folds(argv: list[str], usage: str, per_fold):
    """
    Run ``per_fold(study, fold, hybrids, protocol, spec)`` on every fold of STUDY.

    ``argv`` is [STUDY, OUT]; otherwise ``usage`` is printed and None returned. Return
    (per fold results, protocol, vessel, hybrid labels, OUT made); a line on stderr as
    each fold is done.
    """
    if len(argv) != 2:
        print(usage, file=sys.stderr)
        return None
    study, out = Path(argv[0]), Path(argv[1])
    folds, protocol, spec, hybrids = open_study(study)
    results = []
    for fold in folds:
        results.append(per_fold(study, fold, hybrids, protocol, spec))
        print(f'fold {fold.index} of {len(folds)} done', file=sys.stderr, flush=True)
    out.mkdir(parents=True, exist_ok=True)
    return results, protocol, spec, hybrids, out


def write_result(stem: Path, data, text: str) -> None:
    """Write ``data`` to STEM.json and ``text`` to STEM.md, and print the text."""
    stem.with_suffix('.json').write_text(json.dumps(data, indent=2))
    stem.with_suffix('.md').write_text(text)
    print(text)


def pooled_over_runs(per_run_seed, forecasts) -> tuple[float, float]:
    """
    Return the mean and sd over seeds of an error pooled over runs.

    ``per_run_seed`` (runs, seeds): each run's error per seed; pooled over the runs it is
    their mean weighted by ``forecasts`` (runs,), the pooled figure of a study's table.
    """
    per_run_seed = np.asarray(per_run_seed, np.float64)
    weights = np.asarray(forecasts, np.float64)
    values = (per_run_seed * weights[:, None]).sum(axis=0) / weights.sum()
    return float(values.mean()), float(values.std(ddof=1)) if len(values) > 1 else 0.0


def rudder_range(runs, spec) -> float:
    """Largest |rudder| (deg) of the vessel's rudders over ``runs``; NaN without one."""
    rudders = [spec.control_index(a.name) for a in spec.actuators if a.kind == 'rudder']
    if not rudders:
        return float('nan')
    return float(np.degrees(max(np.abs(r.c[:, rudders]).max() for r in runs)))


def fold_rows(study: Path, fold: Fold, hybrids: list[str], protocol: dict, spec
              ) -> list[dict]:
    """One row per test run of ``fold`` long enough for one forecast of the study's."""
    window, horizon, stride = (protocol[k] for k in ('window', 'horizon', 'stride'))
    models = {label: [load_model(run_dir(study, label, fold, s) / MODEL_FILE)[0]
                      for s in protocol['seeds']] for label in hybrids}
    for label, members in models.items():
        assert all(isinstance(m, HybridModel) for m in members), f'{label} is not a hybrid'
    trained = rudder_range(load_runs(fold.path, 'train', spec), spec)
    runs = [r for r in load_runs(fold.path, 'test', spec) if r.length >= window + horizon]
    # One forecast call per model for the whole fold: each new batch shape compiles anew.
    windows = forecast_windows(runs, window, horizon, stride, 'true')
    preds = {label: [predict(m, windows) for m in members] for label, members in models.items()}
    alone = {label: predict(PhysicsOnly(members[0].physical), windows)
             for label, members in models.items()}
    rows = []
    for k, run in enumerate(runs):
        mine = windows.run_index == k
        own = windows.subset(mine)
        row = {'fold': fold.index, 'run': run.run_id, 'forecasts': len(own),
               'rudder_deg': rudder_range([run], spec), 'trained_rudder_deg': trained}
        for label in models:
            per_seed = [at_horizon(p[mine], own, spec) for p in preds[label]]
            row[label] = {'mean': float(np.mean(per_seed)),
                          'sd': float(np.std(per_seed, ddof=1)) if len(per_seed) > 1 else 0.0,
                          'ensemble': at_horizon(np.mean(preds[label], axis=0)[mine], own,
                                                 spec),
                          'physics_alone': at_horizon(alone[label][mine], own, spec)}
        rows.append(row)
    return rows


def markdown(rows: list[dict], hybrids: list[str], horizon_s: float) -> str:
    """Return the rows as a Markdown table."""
    head = ['fold', 'held-out run', 'rudder (trained up to)']
    for label in hybrids:
        head += [f'{label}: physics alone', f'{label}: mean ± sd of seeds', 'ensemble']
    lines = [f"Position error at {horizon_s:.0f} s [m], mean over each run's forecasts.",
             '', '| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for r in rows:
        cells = [str(r['fold']), f"{r['run']} ({r['forecasts']})",
                 f"{r['rudder_deg']:.0f}° ({r['trained_rudder_deg']:.0f}°)"]
        for label in hybrids:
            h = r[label]
            cells += [f"{h['physics_alone']:.2f}", f"{h['mean']:.2f} ± {h['sd']:.2f}",
                      f"{h['ensemble']:.2f}"]
        lines.append('| ' + ' | '.join(cells) + ' |')
    # Each run's mean weighted by its forecasts is the pooled figure of the study's table.
    weights = np.array([r['forecasts'] for r in rows], dtype=float)
    cells = ['all', f'pooled ({int(weights.sum())})', '']
    for label in hybrids:
        cells += [f'**{np.average([r[label][k] for r in rows], weights=weights):.2f}**'
                  for k in ('physics_alone', 'mean', 'ensemble')]
    lines.append('| ' + ' | '.join(cells) + ' |')
    return '\n'.join(lines) + '\n'


def main(argv: list[str]) -> int:
    """Break a workflow study down by fold and run; write folds.md and folds.json."""
    done = over_folds(argv, __doc__, fold_rows)
    if done is None:
        return 2
    per_fold, protocol, spec, hybrids, out = done
    rows = [row for rows in per_fold for row in rows]
    write_result(out / 'folds', rows, markdown(rows, hybrids, protocol['horizon'] * spec.dt))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
