r"""
Reproduce Baier et al.'s Table 3 (the quadrotor) on a dataset: train, evaluate, report.

    python offline/reproduce_table3.py --dataset DIR --out DIR [--seeds 5]
    python offline/reproduce_table3.py --dataset DIR --out DIR --horizon 50 \\
        --peers PEERS.npz          # the nanodrone benchmark's protocol and its own models

Trains QLag, the LSTM baseline and the two-phase hybrids on MinQ (the multirotor
family's rigid body, gravity, rotor thrust and drag torque), Lin, Qua, MinQ+Lin and
MinQ+Qua, each with --seeds seeds (configs table3_*.yaml of hybrid_models), --jobs at a
time, resumably: a finished training is kept, a killed one continues. Then on the test
runs: every model's per-state RMSE and trajectory error (mean ± sd over seeds), the
paper's columns (RMSE of the velocities over ground x', y', z' and of the body rates p,
q, r), the nanodrone benchmark's mean errors per horizon step (position, velocity,
attitude angle, body rates), each hybrid's physics alone, the threshold sweep of the
best hybrid by validation (never chosen by test error) and of MinQ+Qua-2P (the paper's
bounded model), and the paper's findings checked.
--peers adds rows of other tools' forecasts on the same windows (the benchmark's own
models: offline/peers/nanodrone_benchmark.py writes them).

Writes into --out: REPORT.md, table.md, results.json (every number), per_step.png and
threshold.png. Exit codes: 0 done, 1 a training or an input failed, 2 bad arguments.
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
from hybrid_models.data import checked_vessel, dataset_hash, evaluation_protocol, load_runs
from hybrid_models.ensemble import is_hybrid
from hybrid_models.evaluation import (
    PhysicsOnly,
    evaluate_model,
    seed_row,
    test_windows,
)
from hybrid_models.metrics import forecast_metrics
from hybrid_models.physical.identity import physics_identity
from hybrid_models.studies import table3
from hybrid_models.studies.table2 import val_score
from hybrid_models.training.jobs import train_job
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import DatasetError
from vessel_description import VesselError


def parse_args(argv):
    """Return the parsed command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, type=Path, help='dataset directory')
    parser.add_argument('--out', required=True, type=Path, help='results directory')
    parser.add_argument('--work', type=Path, help='training directory (default OUT/runs)')
    parser.add_argument('--seeds', type=int, default=5, help='seeds per model (default 5)')
    parser.add_argument('--jobs', type=int, default=2, help='trainings at a time')
    parser.add_argument('--threads', type=int, default=2, help='cores to use in total')
    parser.add_argument('--horizon', type=int,
                        help="forecast length (samples; default: the vehicle's, 1 s)")
    parser.add_argument('--stride', type=int, default=10,
                        help='samples between forecast starts (default 10)')
    parser.add_argument('--peers', type=Path,
                        help='forecasts of other tools on the same windows (.npz)')
    parser.add_argument('--smoke', action='store_true', help='tiny configs (a dry run)')
    args = parser.parse_args(argv)
    if args.seeds < 1 or args.jobs < 1 or args.threads < 1 or args.stride < 1:
        parser.error('--seeds, --jobs, --threads and --stride must be at least 1')
    if not (args.dataset / 'manifest.json').is_file():
        parser.error(f'{args.dataset} is no dataset (no manifest.json)')
    return args


def train_all(jobs: list[table3.Job], args, work: Path) -> list[dict]:
    """Train every job (resumable), --jobs at a time; return the trainings' summaries."""
    threads = max(1, args.threads // args.jobs)
    start, results = time.monotonic(), []
    with ThreadPoolExecutor(args.jobs) as pool:
        futures = [pool.submit(train_job, job.name, job.config, [
            *job.overrides, f'dataset={args.dataset.resolve()}', f'training.threads={threads}',
            f'name={job.label}'], work / job.name) for job in jobs]
        for fut in as_completed(futures):
            res = fut.result()
            results.append(res)
            print(f"[{(time.monotonic() - start) / 60:6.1f} min] {res['label']}: "
                  f"{res['status']}", file=sys.stderr)
    return sorted(results, key=lambda r: r['label'])


def main(argv=None) -> int:
    """Train, evaluate, report; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse_args(argv)
    torch.set_num_threads(args.threads)
    work = args.work or args.out / 'runs'
    work.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    jobs = table3.plan(args.seeds, args.smoke)
    print(f'{len(jobs)} trainings, {args.jobs} at a time', file=sys.stderr)
    trainings = train_all(jobs, args, work)
    failed = [t for t in trainings if t['status'] not in ('ok', 'kept')]
    if failed:
        print(f"reproduce_table3: error: {failed[0]['label']}: {failed[0]['status']}",
              file=sys.stderr)
        return 1
    try:
        members = {}
        for job in jobs:
            members.setdefault(job.label, []).append(load_model(work / job.name / MODEL_FILE))
        spec = checked_vessel(args.dataset, [m for ms in members.values() for m in ms])
        window, horizon, stride = evaluation_protocol(spec, None, args.horizon, args.stride)
    except (CheckpointError, DatasetError, VesselError, ValueError) as exc:
        print(f'reproduce_table3: error: {exc}', file=sys.stderr)
        return 1
    if not spec.is_spatial:
        print(f'reproduce_table3: error: vehicle {spec.name!r} is not a 6-DOF vehicle; '
              f"Table 2 is the vessels' (reproduce_table2)", file=sys.stderr)
        return 2
    runs = load_runs(args.dataset, 'test', spec)
    windows = test_windows(runs, window, horizon, stride, table3.TARGET)
    truth = table3.test_truth(args.dataset, windows)
    print(f'{len(windows)} forecasts of {horizon} steps on {len(runs)} test runs',
          file=sys.stderr)
    rows, physics = [], {}
    for label, ms in members.items():
        rows.append(_model_row(label, ms, windows, spec, truth))
        print(f"{label:>14s}: trajectory "
              f"{report.trajectory_cell(rows[-1]['metrics']['trajectory'])} m", file=sys.stderr)
        if is_hybrid(ms[0][0]):
            _physics_rows(ms, label, windows, spec, truth, physics)
    rows += list(physics.values())
    hybrids = [label for label in members if label.endswith('-2P')]
    best = min(hybrids, key=lambda label: np.mean([val_score(work / job.name) for job in jobs
                                                   if job.label == label]))
    # The best hybrid by validation, and the one the paper's finding names if another.
    swept = list(dict.fromkeys([best, table3.PAPER_BOUNDED]))
    print(f'best hybrid by validation: {best}; sweeping the relative threshold of '
          f'{", ".join(swept)}', file=sys.stderr)
    sweeps = {label: _sweep(members[label], windows, spec, truth) for label in swept}
    if args.peers:
        try:
            rows += _peer_rows(args.peers, args.dataset, windows, spec, truth)
        except (KeyError, OSError, ValueError) as exc:
            print(f'reproduce_table3: error: --peers: {exc}', file=sys.stderr)
            return 1
    result = {'dataset': {'path': str(args.dataset), 'sha256': dataset_hash(args.dataset),
                          'runs': [r.run_id for r in runs]},
              'protocol': {'window': window, 'horizon': horizon, 'stride': stride,
                           'target': 'true where simulated, else measured',
                           'n_forecasts': len(windows),
                           'seeds': args.seeds},
              'rows': rows, 'best_hybrid_by_validation': best,
              'threshold_sweep': {'label': best, 'rows': sweeps[best]},
              'threshold_sweeps': sweeps,
              'trainings': trainings, 'argv': argv}
    result['claims'] = table3.check_claims(rows, best, sweeps)
    result['minutes'] = round((time.monotonic() - started) / 60, 1)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'results.json').write_text(json.dumps(result, indent=2))
    steps = sorted({1, max(1, horizon // 5), max(1, horizon // 2), horizon})
    tables = (table3.paper_table(rows) + '\n' + table3.step_table(rows, steps) + '\n'
              + report.markdown_table(rows, spec))
    (args.out / 'table.md').write_text(tables)
    table3.plot_per_step(args.out / 'per_step.png', rows, spec,
                         ['LSTM', best, *[r['label'] for r in rows if r['kind'] == 'peer']])
    table3.plot_sweep(args.out / 'threshold.png', sweeps)
    (args.out / 'REPORT.md').write_text(table3.report(result, tables))
    print((args.out / 'REPORT.md').read_text())
    return 0


def _figures(z_pred, windows, spec, truth) -> dict:
    return table3.figures_of(np.asarray(z_pred, np.float64),
                             np.asarray(windows.z_target, np.float64), spec, truth)


def _model_row(label, members, windows, spec, truth) -> dict:
    """One model's row over its seeds: the usual figures and the quadrotor's."""
    metrics, figures = [], []
    for model, cfg in members:
        state_std = np.asarray(cfg['normalization']['state']['std'])
        ev = evaluate_model(label, model, windows, spec, state_std)
        metrics.append(ev.metrics)
        figures.append(_figures(ev.pred, windows, spec, truth))
    row = seed_row(label, metrics, kind='model',
                   val=[cfg.get('val') for _, cfg in members],
                   train_seconds=[cfg.get('train_seconds') for _, cfg in members])
    mean, spread = table3.mean_figures(figures)
    row.update(paper_rmse=mean['paper_rmse'], paper_spread=spread['paper_rmse'],
               per_step=mean['per_step'], per_step_spread=spread['per_step'])
    return row


def _physics_rows(members, owner, windows, spec, truth, physics: dict) -> None:
    """Add each distinct physics of a hybrid's seeds as a row of its own, run alone."""
    for model, cfg in members:
        fingerprint, name = physics_identity(model.physical)
        if fingerprint in physics:
            continue
        label = f'{name} alone'
        if any(r['label'] == label for r in physics.values()):
            label = f'{name} alone (of {owner})'
        state_std = np.asarray(cfg['normalization']['state']['std'])
        ev = evaluate_model(label, PhysicsOnly(model.physical), windows, spec, state_std)
        fig = _figures(ev.pred, windows, spec, truth)
        physics[fingerprint] = {'label': label, 'kind': 'physics', 'metrics': ev.metrics,
                                'paper_rmse': fig['paper_rmse'], 'per_step': fig['per_step'],
                                'fingerprint': fingerprint}


def _sweep(members, windows, spec, truth) -> list[dict]:
    """Serve the best hybrid's seeds at each relative threshold; figures over seeds."""
    rows = []
    for t in [None, 0.0, *table3.THRESHOLDS]:
        per_seed = []
        for model, cfg in members:
            state_std = np.asarray(cfg['normalization']['state']['std'])
            with model.served_at(t):
                ev = evaluate_model(str(t), model, windows, spec, state_std)
            per_seed.append({'metrics': ev.metrics,
                             **_figures(ev.pred, windows, spec, truth)})
        row = seed_row(str(t), [p['metrics'] for p in per_seed])
        mean, spread = table3.mean_figures([{k: p[k] for k in ('paper_rmse', 'per_step')}
                                            for p in per_seed])
        rows.append({'relative_threshold': t, 'metrics': row['metrics'],
                     'spread': row['spread'], 'paper_rmse': mean['paper_rmse'],
                     'paper_spread': spread['paper_rmse'], 'per_step': mean['per_step']})
    return rows


def _peer_rows(path: Path, dataset, windows, spec, truth) -> list[dict]:
    """Rows of other tools' forecasts of the same windows, against the same truth."""
    true = table3.quantities(np.asarray(windows.z_target, np.float64), spec, truth,
                             measured_heading=True)
    rows = []
    for label, pred in table3.read_peers(path, dataset, windows, spec).items():
        metrics = forecast_metrics(pred['z'], windows.z_target, spec)
        rows.append({'label': f'benchmark {label}', 'kind': 'peer', 'metrics': metrics,
                     'paper_rmse': table3.paper_figures(pred, true),
                     'per_step': table3.benchmark_figures(pred, true)})
    return rows


if __name__ == '__main__':
    sys.exit(main())
