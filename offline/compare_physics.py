#!/usr/bin/env python3
r"""
Train the same hybrid on different physics; compare the relative threshold each needs.

    python offline/compare_physics.py --dataset DIR --out RESULTS \\
        --physics nominal=DIR/nominal_physics.yaml augmented=DIAG/augmented_physics.yaml

The question it answers: does better physics (e.g. the augmented physics that
``offline/diagnose.py`` writes) let the LSTM's share shrink? For each physics file it
trains the hybrid of ``--config`` (default the 2P hybrid) with that physics as its
physical part (``model.physical.kind=physics``), resumable, ``--jobs`` at a time. Then on
the test runs it sweeps the relative threshold at inference (0 = physics alone) and
reports, per physics, the smallest threshold whose per-state RMSE is within
``--tolerance`` (5 %) of (a) the FIRST physics' unconstrained hybrid, i.e. the same
accuracy for every physics, and (b) its own unconstrained hybrid.

Writes into --out: report.md, results.json (every number), table.md and
threshold_comparison.png. Progress on stderr. Exit codes: 0 done, 1 a training or an
input failed, 2 bad arguments.
"""

import argparse
from concurrent.futures import ThreadPoolExecutor, as_completed
import json
from pathlib import Path
import sys
import time

import numpy as np
import torch

from hybrid_models import report
from hybrid_models.checkpoint import CheckpointError, load_model
from hybrid_models.data import dataset_hash, load_runs
from hybrid_models.evaluation import (
    PhysicsOnly,
    evaluate_model,
    smallest_threshold,
    test_windows,
    threshold_sweep,
    trajectory_of,
)
from hybrid_models.training.config import evaluation_protocol
from hybrid_models.training.jobs import train_job
from hybrid_models.training.train import MODEL_FILE
from hybrid_models.vehicle import VehicleSpec
from vessel_physics.augmented import load_physics
from vessel_physics.errors import ConfigError

ROOT = Path(__file__).resolve().parents[1]

DEFAULT_CONFIG = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'hybrid_2p.yaml'
DEFAULT_THRESHOLDS = [0.005, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.5]


def labelled_physics(text: str) -> tuple[str, Path]:
    """Parse LABEL=FILE for argparse."""
    label, sep, path = text.partition('=')
    if not sep or not label or not path:
        raise argparse.ArgumentTypeError(f'expected LABEL=FILE, got {text!r}')
    return label, Path(path).resolve()


def parse_args(argv):
    """Return the parsed command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, type=Path, help='dataset directory')
    parser.add_argument('--physics', nargs='+', required=True, type=labelled_physics,
                        metavar='LABEL=FILE',
                        help='physics files to compare; the first is the reference')
    parser.add_argument('--out', required=True, type=Path, help='results directory')
    parser.add_argument('--config', type=Path, default=DEFAULT_CONFIG,
                        help='training config (default: the 2P hybrid)')
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='config override for every training (repeatable)')
    parser.add_argument('--thresholds', type=float, nargs='+', default=DEFAULT_THRESHOLDS,
                        help='relative thresholds to sweep (0 = physics only is always added)')
    parser.add_argument('--tolerance', type=float, default=0.05,
                        help='"same accuracy": every state RMSE within this share (0.05)')
    parser.add_argument('--jobs', type=int, default=2, help='trainings at a time')
    parser.add_argument('--threads', type=int, default=2, help='cores to use in total')
    parser.add_argument('--time-limit-minutes', type=float,
                        help="cap each training (default: the config's)")
    parser.add_argument('--window', type=int,
                        help="initialization window (samples; default: the vessel's)")
    parser.add_argument('--horizon', type=int,
                        help="forecast length (samples; default: the vessel's horizon)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecast starts (default: horizon/7.5)')
    args = parser.parse_args(argv)
    labels = [label for label, _ in args.physics]
    if len(set(labels)) != len(labels) or len(labels) < 2:
        parser.error(f'give at least two physics with distinct labels, got {labels}')
    if any(not 0 < t for t in args.thresholds) or args.tolerance < 0:
        parser.error('thresholds must be > 0 and the tolerance >= 0')
    return args


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


def _fmt_threshold(t) -> str:
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
                     f'{_fmt_threshold(need["for_reference_accuracy"])} | '
                     f'{_fmt_threshold(need["for_own_unconstrained_accuracy"])} |')
    names = list(spec.state_names)
    lines += ['', f'Per state and for the trajectory error: the smallest threshold within {tol} '
              f'of the {reference} hybrid (unconstrained):', '',
              '| physics | ' + ' | '.join(names) + ' | trajectory |',
              '|---|' + '---|' * (len(names) + 1)]
    for label, _ in args.physics:
        need = result['needed_thresholds'][label]
        cells = [_fmt_threshold(need['for_reference_per_state'][s]) for s in names]
        cells.append(_fmt_threshold(need['for_reference_trajectory']))
        lines.append(f'| {label} | ' + ' | '.join(cells) + ' |')
    lines += ['', 'Every threshold, per-state RMSE and trajectory error (mean ± 95 % CI):', '',
              table, '', 'Figure: threshold_comparison.png. Every number: results.json.',
              '', 'Reproduce:', '', '```', ' '.join(['python offline/compare_physics.py']
                                                     + result['argv']), '```', '']
    (args.out / 'report.md').write_text('\n'.join(lines))


def main(argv=None) -> int:
    """Train, evaluate, report; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse_args(argv)
    for label, path in args.physics:
        try:
            load_physics(path)
        except ConfigError as exc:
            print(f'compare_physics: error: {label}: {exc}', file=sys.stderr)
            return 1
    args.out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.threads)
    start = time.monotonic()
    trainings = train_all(args)
    failed = [t for t in trainings if t['status'] not in ('ok', 'kept')]
    if failed:
        print(f"compare_physics: error: {failed[0]['label']}: {failed[0]['status']}",
              file=sys.stderr)
        return 1
    try:
        _, cfg = load_model(args.out / 'runs' / args.physics[0][0] / MODEL_FILE)
    except CheckpointError as exc:
        print(f'compare_physics: error: {exc}', file=sys.stderr)
        return 1
    spec = VehicleSpec.from_dict(cfg['vehicle'])
    args.window, args.horizon, args.stride = evaluation_protocol(spec, args.window,
                                                                 args.horizon, args.stride)
    evaluated = evaluate_all(args, spec)
    result = {'dataset': {'path': str(args.dataset), 'sha256': dataset_hash(args.dataset)},
              'physics': {label: str(path) for label, path in args.physics},
              'reference': args.physics[0][0], 'tolerance': args.tolerance,
              'protocol': {'window': args.window, 'horizon': args.horizon,
                           'stride': args.stride, 'target': 'true'},
              'trainings': trainings, 'evaluation': evaluated,
              'needed_thresholds': needed_thresholds(evaluated, args.physics[0][0],
                                                     args.tolerance),
              'argv': argv, 'minutes': round((time.monotonic() - start) / 60, 1)}
    (args.out / 'results.json').write_text(json.dumps(result, indent=2))
    write_report(args, spec, result)
    for label, need in result['needed_thresholds'].items():
        print(f'{label}: threshold for the {args.physics[0][0]} accuracy '
              f'{_fmt_threshold(need["for_reference_accuracy"])}, within '
              f'{100 * args.tolerance:g} % of its own '
              f'{_fmt_threshold(need["for_own_unconstrained_accuracy"])}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
