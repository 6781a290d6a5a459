"""
Which model a cross-validated workflow's own validation runs would have served.

Usage:  tools/with_env.sh python docs/results/real/analysis/workflow_choice.py STUDY OUT
STUDY is the --out folder of ``offline/workflow.py --folds K`` (results.json, folds/,
runs/); OUT receives choice.md and choice.json.

The workflow trains the hybrid on the nominal and on the augmented physics and compares
them on held-out runs, but a user must pick one model before seeing those. Here, per
fold and seed, the candidates are the two physics files alone and the two hybrids, each
judged by the score that chose its served threshold on the fold's validation runs (the
checkpoint's selection record; the physics alone is epoch -1 of the hybrid's training
log on the same runs and scale). The one with the lowest score is "chosen on
validation"; its position error at the horizon's end on the fold's test runs is pooled
over folds, per seed, as in the study's table.
"""

from __future__ import annotations

import json
from pathlib import Path
import sys

import numpy as np
from workflow_folds import at_horizon, over_folds, write_result

from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.models import predict
from hybrid_models.studies.crossval import run_dir
from hybrid_models.training.train import MODEL_FILE

ALONE = ' (its physics alone)'


def reference_score(directory: Path) -> float:
    """Return the physics alone's validation score: epoch -1 of a training's log."""
    for line in (directory / 'log.jsonl').read_text().splitlines():
        entry = json.loads(line)
        if entry.get('phase_kind') == 'reference':
            return float(entry['val_score'])
    raise ValueError(f'{directory}: no reference epoch in log.jsonl')


def fold_choices(study: Path, fold, hybrids: list[str], protocol: dict, spec) -> dict:
    """Return per seed: each candidate's validation score and test error, and the choice."""
    window, horizon, stride = (protocol[k] for k in ('window', 'horizon', 'stride'))
    runs = [r for r in load_runs(fold.path, 'test', spec) if r.length >= window + horizon]
    windows = forecast_windows(runs, window, horizon, stride, 'true')
    seeds = {}
    for seed in protocol['seeds']:
        candidates = {}
        for label in hybrids:
            directory = run_dir(study, label, fold, seed)
            model, meta = load_model(directory / MODEL_FILE)[:2]
            candidates[label] = (float(meta['selection']['score']),
                                 at_horizon(predict(model, windows), windows, spec))
            candidates[label + ALONE] = (reference_score(directory), at_horizon(
                predict(PhysicsOnly(model.physical), windows), windows, spec))
        chosen = min(candidates, key=lambda k: candidates[k][0])
        seeds[seed] = {'candidates': {k: {'val_score': v[0], 'test_error_m': v[1]}
                                      for k, v in candidates.items()},
                       'chosen': chosen}
    return {'fold': fold.index, 'forecasts': len(windows.run_index), 'seeds': seeds}


def pooled(rows: list[dict], seed: int, pick) -> float:
    """Return the test error pooled over folds (weighted by forecasts) of ``pick(seed)``."""
    weights = np.array([r['forecasts'] for r in rows], float)
    values = np.array([pick(r['seeds'][seed]) for r in rows])
    return float((values * weights).sum() / weights.sum())


def markdown(rows: list[dict], seeds: list[int], horizon_s: float) -> str:
    """Return the pooled table and how often each candidate was chosen."""
    labels = list(rows[0]['seeds'][seeds[0]]['candidates'])
    lines = [f'Position error at {horizon_s:.0f} s [m] on the test runs, pooled over '
             f'{len(rows)} folds; mean ± sd over {len(seeds)} seeds.', '',
             '| model | error | chosen on validation (fold x seed) |', '|---|---|---|']

    def row(name, pick, count=''):
        values = [pooled(rows, s, pick) for s in seeds]
        sd = np.std(values, ddof=1) if len(values) > 1 else 0.0
        lines.append(f'| {name} | {np.mean(values):.2f} ± {sd:.2f} | {count} |')

    for label in labels:
        count = sum(r['seeds'][s]['chosen'] == label for r in rows for s in seeds)
        row(label, lambda x, k=label: x['candidates'][k]['test_error_m'], str(count))
    row('**chosen on validation**',
        lambda x: x['candidates'][x['chosen']]['test_error_m'])
    return '\n'.join(lines) + '\n'


def main(argv: list[str]) -> int:
    """Choose per fold and seed on validation; write choice.md and choice.json."""
    done = over_folds(argv, __doc__, fold_choices)
    if done is None:
        return 2
    rows, protocol, spec, _, out = done
    write_result(out / 'choice', rows,
                 markdown(rows, list(protocol['seeds']), protocol['horizon'] * spec.dt))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
