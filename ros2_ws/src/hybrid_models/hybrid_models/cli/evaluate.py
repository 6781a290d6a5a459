r"""
Evaluate trained checkpoints on the test runs; write table, figures and JSON.

    python offline/evaluate.py --dataset DIR --out docs/results \\
        runs/qlag runs/lstm runs/min+lin-2p ... [--sweep min+lin-2p] [--physics-only]
    ros2 run hybrid_models evaluate ...          # the same program, installed

Each positional argument is a model.safetensors file or a training output directory;
its label is the config name (or give --labels). Checkpoints that share a label are
seeds of one model: their row gives the mean ± standard deviation over the seeds (and
each seed's trajectory error in results.json). With --physics-only, every distinct
physics of the hybrids (by file and fitted values, not by kind) gets one row of its
own, and each hybrid is checked against its physics at every reported horizon step.
Writes into --out: table.md (per-state RMSE and trajectory error, Table-2 layout),
results.json (every number), states_over_time.png, trajectories.png,
trajectory_error_per_minute.png and, with --sweep LABEL, rmse_vs_threshold.png (that
hybrid constrained at inference). Cross-validation over runs (each run held out once,
several seeds, trainings included) is the crossval program.
"""

import argparse
import json
from pathlib import Path
import sys
import time

import numpy as np
import torch

from hybrid_models import report
from hybrid_models.checkpoint import CheckpointError, load_model
from hybrid_models.data import checked_vessel, dataset_hash, evaluation_protocol, load_runs
from hybrid_models.ensemble import is_hybrid
from hybrid_models.evaluation import (
    PhysicsOnly,
    evaluate_model,
    residual_share,
    seed_row,
    test_windows,
    threshold_sweep,
)
from hybrid_models.physical.identity import physics_identity, physics_label
from hybrid_models.selection import harms
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import DatasetError
from vessel_description import VesselError


def _checkpoint_path(arg: str) -> Path:
    path = Path(arg)
    return path / MODEL_FILE if path.is_dir() else path


def main(argv=None) -> int:
    """Parse arguments, evaluate, write the results folder; return the exit code."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('checkpoints', nargs='+', help='model files or training dirs')
    parser.add_argument('--dataset', required=True, help='dataset directory')
    parser.add_argument('--out', type=Path, required=True, help='results directory')
    parser.add_argument('--labels', nargs='*', help='row labels (default: config names)')
    parser.add_argument('--split', default='test', help='split to evaluate (default test)')
    parser.add_argument('--horizon', type=int,
                        help="forecast length (samples; default: the vessel's horizon)")
    parser.add_argument('--window', type=int,
                        help="initialization window (samples; default: the vessel's)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecast starts within a run (default: '
                             'horizon/7.5, 120 for 900)')
    parser.add_argument('--target', choices=('true', 'measured'), default='true',
                        help="compare with noise-free '<state>_true' columns (default)")
    parser.add_argument('--sweep', help='label of a hybrid to sweep relative thresholds')
    parser.add_argument('--thresholds', type=float, nargs='*',
                        default=[0.025, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5],
                        help='relative thresholds for --sweep')
    parser.add_argument('--physics-only', action='store_true',
                        help="also evaluate each hybrid's physical model alone")
    parser.add_argument('--plot', nargs='*', help='labels to draw (default: all, max 6)')
    parser.add_argument('--threads', type=int, default=2)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    try:
        loaded = [load_model(_checkpoint_path(p)) for p in args.checkpoints]
    except (CheckpointError, FileNotFoundError) as exc:
        print(f'evaluate.py: error: {exc}', file=sys.stderr)
        return 2
    labels = args.labels or [cfg.get('name', Path(p).stem)
                             for (_, cfg), p in zip(loaded, args.checkpoints, strict=True)]
    if len(labels) != len(loaded):
        print('evaluate.py: error: give one label per checkpoint', file=sys.stderr)
        return 2
    try:
        spec = checked_vessel(args.dataset, loaded, args.checkpoints)
        args.window, args.horizon, args.stride = evaluation_protocol(
            spec, args.window, args.horizon, args.stride)
    except (DatasetError, VesselError, ValueError) as exc:
        print(f'evaluate.py: error: {exc}', file=sys.stderr)
        return 2
    runs = load_runs(args.dataset, args.split, spec)
    windows = test_windows(runs, args.window, args.horizon, args.stride, args.target)
    print(f'{len(windows)} forecasts of {args.horizon} steps on {len(runs)} '
          f'{args.split} runs', file=sys.stderr)
    args.out.mkdir(parents=True, exist_ok=True)
    rows, preds, models = [], {}, {}
    physics_rows: dict[str, dict] = {}
    for label, members in _by_label(labels, loaded).items():
        row, ev = _model_row(label, members, windows, spec, args.horizon)
        rows.append(row)
        preds[label], models[label] = ev.pred, members[0]
        print(f'{label:>16s}: trajectory {report.trajectory_cell(row["metrics"]["trajectory"])}'
              f' m' + (f' (mean of {row["seeds"]} seeds)' if row.get('seeds', 1) > 1 else ''),
              file=sys.stderr)
        if args.physics_only and is_hybrid(members[0][0]):
            # Each seed against its own physics (seeds on other data fit other physics).
            known = len(physics_rows)
            own = [physics_rows[_physics_row(m, label, windows, spec, physics_rows)]
                   for m in members]
            rows += list(physics_rows.values())[known:]
            row['physics'] = sorted({p['label'] for p in own})
            row['harms_vs_physics'] = [
                harms(m['profile'], p['metrics']['profile']) for m, p in zip(
                    row.get('per_seed_metrics', [row['metrics']]), own, strict=True)]
            worse = sum(bool(h) for h in row['harms_vs_physics'])
            print(f'{label:>16s}: worse than {", ".join(row["physics"])} at a reported step '
                  f'in {worse} of {len(own)} seed(s)', file=sys.stderr)
    result = {'dataset': {'path': str(args.dataset), 'sha256': dataset_hash(args.dataset),
                          'split': args.split, 'runs': [r.run_id for r in runs]},
              'protocol': {'window': args.window, 'horizon': args.horizon,
                           'stride': args.stride, 'target': args.target,
                           'n_forecasts': len(windows)},
              'rows': rows}
    if args.sweep:
        if args.sweep not in models or not is_hybrid(models[args.sweep][0]):
            print(f'evaluate.py: error: --sweep {args.sweep!r} is not a hybrid label',
                  file=sys.stderr)
            return 2
        model, cfg = models[args.sweep]
        state_std = np.asarray(cfg['normalization']['state']['std'])
        sweep = threshold_sweep(model, windows, spec, state_std, args.thresholds)
        result['threshold_sweep'] = {'label': args.sweep, 'rows': sweep}
        report.plot_threshold(args.out / 'rmse_vs_threshold.png', spec,
                              {args.sweep: sweep}, args.sweep)
    (args.out / 'results.json').write_text(json.dumps(result, indent=2))
    (args.out / 'table.md').write_text(report.markdown_table(rows, spec))
    drawn = {k: v for k, v in preds.items() if not args.plot or k in args.plot}
    drawn = dict(list(drawn.items())[:6])
    example = int(np.argmin(np.abs(windows.t0 - np.median(windows.t0))))
    title = f'{runs[windows.run_index[example]].run_id}, t0 = {windows.t0[example]} s'
    report.plot_states(args.out / 'states_over_time.png', spec, windows.z_target[example],
                       {k: v[example] for k, v in drawn.items()}, title)
    report.plot_trajectories(args.out / 'trajectories.png', spec, windows.z_target[example],
                             {k: v[example] for k, v in drawn.items()}, title)
    report.plot_error_per_minute(args.out / 'trajectory_error_per_minute.png', spec,
                                 windows.z_target, drawn)
    print(report.markdown_table(rows, spec))
    return 0


def _by_label(labels: list[str], loaded: list) -> dict[str, list]:
    """Group (model, config) pairs by label, in order: seeds of one model share one."""
    groups: dict[str, list] = {}
    for label, member in zip(labels, loaded, strict=True):
        groups.setdefault(label, []).append(member)
    return groups


def _model_row(label: str, members: list, windows, spec, horizon: int):
    """Evaluate every seed of one model; return its table row and the first seed's run."""
    evaluated, started = [], time.monotonic()
    for model, cfg in members:
        state_std = np.asarray(cfg['normalization']['state']['std'])
        evaluated.append(evaluate_model(label, model, windows, spec, state_std))
    seconds = (time.monotonic() - started) / len(members)
    model, cfg = members[0]
    extra = {'seconds': round(seconds, 2),
             'ms_per_forecast_step_batched': round(1e3 * seconds / horizon, 3),
             'train_seconds': cfg.get('train_seconds'), 'epochs': cfg.get('epochs'),
             'best_epoch': cfg.get('best_epoch'), 'stop_reason': cfg.get('stop_reason'),
             'val': cfg.get('val'), 'model': cfg.get('model'),
             'parameters': cfg.get('parameters')}
    if is_hybrid(model):
        extra['bound'] = cfg.get('bound')
        extra['residual'] = residual_share(model, windows)
        extra['served_thresholds'] = [c['model'].get('relative_threshold') for _, c in members]
    if len(members) == 1:
        return {'label': label, 'metrics': evaluated[0].metrics, **extra}, evaluated[0]
    row = seed_row(label, [e.metrics for e in evaluated], **extra)
    row['per_seed_metrics'] = [e.metrics for e in evaluated]
    return row, evaluated[0]


def _physics_row(member, owner: str, windows, spec, physics_rows: dict) -> str:
    """Add the row of a hybrid's physics alone unless it has one; return its fingerprint."""
    model, cfg = member
    fingerprint, name = physics_identity(model.physical)
    if fingerprint not in physics_rows:
        label = physics_label(name, fingerprint, owner,
                              {row['label'] for row in physics_rows.values()})
        ev = evaluate_model(label, PhysicsOnly(model.physical), windows, spec,
                            np.asarray(cfg['normalization']['state']['std']))
        physics_rows[fingerprint] = {'label': label, 'metrics': ev.metrics,
                                     'fingerprint': fingerprint}
    return fingerprint


if __name__ == '__main__':
    sys.exit(main())
