"""
The same hybrid on different physics: train one per physics file, sweep, report.

``train_all`` trains the hybrid of a config once per physics file (resumable, a few at a
time); ``evaluate_all`` sweeps each one's relative threshold on the test runs (0 = its
physics alone); ``needed_thresholds`` finds the smallest threshold that keeps the
accuracy; ``write_report`` writes report.md, table.md and threshold_comparison.png. The
``compare_physics`` program (hybrid_models.cli.compare_physics) runs them in order.
"""

from concurrent.futures import ThreadPoolExecutor, as_completed
import sys
import time

import numpy as np

from hybrid_models import report
from hybrid_models.checkpoint import load_model
from hybrid_models.data import load_runs
from hybrid_models.evaluation import (
    PhysicsOnly,
    evaluate_model,
    smallest_threshold,
    test_windows,
    threshold_sweep,
    trajectory_of,
)
from hybrid_models.training.jobs import train_job
from hybrid_models.training.train import MODEL_FILE


def train_all(args) -> list[dict]:
    """Train one hybrid per physics file (resumable); return the trainings' summaries."""
    threads = max(1, args.threads // args.jobs)
    common = list(args.set) + [f'dataset={args.dataset.resolve()}',
                               f'training.threads={threads}', 'model.physical.kind=physics']
    if args.time_limit_minutes:
        common.append(f'training.time_limit_minutes={args.time_limit_minutes}')
    jobs = [(label, args.config, common + [f'model.physical.physics={path}', f'name={label}'],
             args.out / 'runs' / label) for label, path in args.physics]
    start, results = time.monotonic(), []
    with ThreadPoolExecutor(args.jobs) as pool:
        for fut in as_completed([pool.submit(train_job, *job) for job in jobs]):
            res = fut.result()
            results.append(res)
            print(f"[{(time.monotonic() - start) / 60:6.1f} min] {res['label']}: "
                  f"{res['status']}", file=sys.stderr)
    return results


def evaluate_all(args, spec) -> dict:
    """Sweep every trained hybrid's threshold on the test runs (0 = its physics alone)."""
    runs = load_runs(args.dataset, 'test', spec)
    windows = test_windows(runs, args.window, args.horizon, args.stride, 'true')
    print(f'{len(windows)} forecasts of {args.horizon} steps on {len(runs)} test runs',
          file=sys.stderr)
    out = {'runs': [r.run_id for r in runs], 'n_forecasts': len(windows), 'models': {}}
    for label, _ in args.physics:
        model, cfg = load_model(args.out / 'runs' / label / MODEL_FILE)
        state_std = np.asarray(cfg['normalization']['state']['std'])
        physics_only = evaluate_model('physics', PhysicsOnly(model.physical), windows, spec,
                                      state_std).metrics
        sweep = [{'relative_threshold': 0.0, **physics_only, 'bound': [0.0] * spec.n_state}]
        sweep += threshold_sweep(model, windows, spec, state_std, args.thresholds)
        out['models'][label] = {
            'sweep': sweep, 'output_range': model.output_range.tolist(),
            'training': {k: cfg.get(k) for k in ('train_seconds', 'epochs', 'best_epoch',
                                                 'stop_reason', 'val')}}
        free = next(r for r in sweep if r['relative_threshold'] is None)
        print(f'{label:>12s}: physics only {report.trajectory_cell(physics_only["trajectory"])}'
              f' m, unconstrained hybrid {report.trajectory_cell(free["trajectory"])} m',
              file=sys.stderr)
    return out


def needed_thresholds(evaluated: dict, reference: str, tolerance: float) -> dict:
    """
    Per physics: the smallest threshold for the reference's accuracy and for its own.

    Besides every state at once (the criterion), each state alone and the trajectory
    error, against the reference's unconstrained hybrid: where the criterion is not met,
    they say which state holds it back.
    """
    def unconstrained(label):
        return next(r for r in evaluated['models'][label]['sweep']
                    if r['relative_threshold'] is None)
    target = unconstrained(reference)
    out = {}
    for label, m in evaluated['models'].items():
        sweep = m['sweep']
        out[label] = {
            'for_reference_accuracy': smallest_threshold(sweep, target['rmse'], tolerance),
            'for_own_unconstrained_accuracy': smallest_threshold(
                sweep, unconstrained(label)['rmse'], tolerance),
            'for_reference_per_state': {
                s: smallest_threshold(sweep, {s: ref}, tolerance)
                for s, ref in target['rmse'].items()},
            'for_reference_trajectory': smallest_threshold(
                sweep, trajectory_of(target), tolerance, trajectory_of)}
    return out


def format_threshold(t) -> str:
    """Say a threshold in words: a percentage, physics alone (0) or none (None)."""
    if t is None:
        return 'none of the swept'
    return 'physics alone (0 %)' if t == 0 else f'{100 * t:g} %'


def write_report(args, spec, result: dict) -> None:
    """report.md, table.md and the figure."""
    reference = args.physics[0][0]
    rows = []
    for label, m in result['evaluation']['models'].items():
        for r in m['sweep']:
            t = r['relative_threshold']
            name = ('unconstrained' if t is None else 'physics only' if t == 0
                    else f'T = {100 * t:g} %')
            rows.append({'label': f'{label}, {name}', 'metrics': r})
    table = report.markdown_table(rows, spec)
    (args.out / 'table.md').write_text(table)
    report.plot_threshold(args.out / 'threshold_comparison.png', spec,
                          {label: m['sweep'] for label, m in
                           result['evaluation']['models'].items()},
                          'the same hybrid on different physics (test runs)')
    tol = f'{100 * args.tolerance:g} %'
    lines = ['# The relative threshold each physics needs', '',
             f'Dataset `{args.dataset}` (sha256 `{result["dataset"]["sha256"][:12]}`), '
             f'{len(result["evaluation"]["runs"])} test runs, '
             f'{result["evaluation"]["n_forecasts"]} forecasts of {args.horizon} steps; '
             f'hybrid config `{args.config.name}`; every training on the same data and seed.',
             '', '| physics | file | threshold for the accuracy of the '
             f'{reference} hybrid (all states within {tol}) | threshold within {tol} of '
             'its own unconstrained hybrid |', '|---|---|---|---|']
    for label, path in args.physics:
        need = result['needed_thresholds'][label]
        lines.append(f'| {label} | `{path.name}` | '
                     f'{format_threshold(need["for_reference_accuracy"])} | '
                     f'{format_threshold(need["for_own_unconstrained_accuracy"])} |')
    names = list(spec.state_names)
    lines += ['', f'Per state and for the trajectory error: the smallest threshold within {tol} '
              f'of the {reference} hybrid (unconstrained):', '',
              '| physics | ' + ' | '.join(names) + ' | trajectory |',
              '|---|' + '---|' * (len(names) + 1)]
    for label, _ in args.physics:
        need = result['needed_thresholds'][label]
        cells = [format_threshold(need['for_reference_per_state'][s]) for s in names]
        cells.append(format_threshold(need['for_reference_trajectory']))
        lines.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    lines += ['', 'Every threshold, per-state RMSE and trajectory error (mean ± 95 % CI):', '',
              table, '', 'Figure: threshold_comparison.png. Every number: results.json.',
              '', 'Reproduce:', '', '```', ' '.join(['python offline/compare_physics.py']
                                                     + result['argv']), '```', '']
    (args.out / 'report.md').write_text('\n'.join(lines))
