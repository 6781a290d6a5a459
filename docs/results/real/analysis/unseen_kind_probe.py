"""
Measure whether a held-out manoeuvre kind is new to the correction and its bound matters.

Usage:  tools/with_env.sh python docs/results/real/analysis/unseen_kind_probe.py STUDY LABEL [OUT]
STUDY is the --out folder of ``offline/crossval.py --fold-by ...``, LABEL one of its
hybrids; the table goes to stdout and, with OUT, to OUT/unseen_kind_probe.md.

Issue #47 asked for a bound that fades towards the physics where the correction's inputs
leave what training covered. This measures whether that would act where the hybrid
harms, and what the fade as built does (``hybrid_models.novelty``). Per fold and seed:

- **new inputs:** the share of the held-out runs' correction inputs (normalised
  controls and one-step physics outputs from the measured states, as the LSTM reads
  them) farther from the training runs than the validation runs' 99th percentile, in
  the RMS Mahalanobis distance d(x) = sqrt((x - m)^T S^-1 (x - m) / n) (m, S from the
  training runs; S + 1e-3 I), and farther than twice that radius: what a bound scaled
  by the distance would cut;
- **the bound's effect:** the per-state RMSE over the held-out forecasts at the served
  threshold, at a tenth of it, and at it served with the novelty fade (the model's own
  calibration, ``set_novelty on``), with the share of the bound the fade left, mean and
  least over the held-out forecast steps; beside the physics alone's;
- **the seeds' disagreement:** served as one ensemble (the mean of their corrections at
  every step), the share of held-out steps whose spread of the members' corrections
  (per state, in units of the residual scale) exceeds the validation forecasts' 99th
  percentile: what a bound scaled by the disagreement would cut; and the ensemble's
  per-state RMSE.
"""

from __future__ import annotations

from pathlib import Path
import sys

import numpy as np
import torch

from hybrid_models import novelty
from hybrid_models.checkpoint import load_model
from hybrid_models.data import forecast_windows, load_runs
from hybrid_models.engine import Forecaster
from hybrid_models.evaluation import PhysicsOnly
from hybrid_models.hybrid_step import correction, correction_input
from hybrid_models.metrics import forecast_metrics
from hybrid_models.models import predict
from hybrid_models.studies.crossval import read_study, run_dir
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import read_dataset

QUANTILE = 0.99   # of the validation inputs' distance: "inside what training covered"


@torch.no_grad()
def correction_inputs(model, runs) -> np.ndarray:
    """Return the LSTM's inputs (N, n_control + n_state) along runs, from measured states."""
    weights = {k: getattr(model, k) for k in ('state_mean', 'state_std', 'control_mean',
                                              'control_std')}
    rows = []
    for run in runs:
        z, c = torch.as_tensor(run.z[:-1].copy()), torch.as_tensor(run.c[:-1].copy())
        rows.append(correction_input(weights, model.physical(z, c), c).numpy())
    return np.concatenate(rows).astype(np.float64)


def distance(x: np.ndarray, train: np.ndarray) -> np.ndarray:
    """Return the RMS Mahalanobis distance of rows x from the rows of ``train``."""
    return novelty.distance(x, novelty.calibrate(train, train).weights())[:, 0]


@torch.no_grad()
def faded(model, windows) -> tuple[np.ndarray, np.ndarray]:
    """Return the model's forecasts served with the novelty fade, and each step's share."""
    model.novelty_fade = True
    try:
        share = Forecaster.from_model(model).forecast_each(
            windows.z_window, windows.c_window, windows.c_future).available
        return predict(model, windows), share
    finally:
        model.novelty_fade = False


@torch.no_grad()
def ensemble_forecast(members: list, windows) -> tuple[np.ndarray, np.ndarray]:
    """Return the seeds' ensemble forecasts (B, H, n) and their corrections' spread."""
    z_window, c_window, c_future = (torch.as_tensor(a) for a in (
        windows.z_window, windows.c_window, windows.c_future))
    recurrent = [m.start(z_window, c_window) for m in members]
    weights = [m.step_weights() for m in members]
    z, states, spreads = z_window[:, -1], [], []
    for k in range(c_future.shape[1]):
        z_phy = members[0].physical(z, c_future[:, k])
        corrections = []
        for i, m in enumerate(members):
            res, recurrent[i] = correction(m.cell, weights[i], z_phy, c_future[:, k],
                                           recurrent[i], m.bound_mode)
            corrections.append(res)
        corrections = torch.stack(corrections)
        spreads.append((corrections.std(0, unbiased=False) / members[0].residual_std).numpy())
        z = z_phy + corrections.mean(0)
        states.append(z)
    return torch.stack(states, 1).numpy(), np.stack(spreads, 1).reshape(-1, z.shape[-1])


def probe(study: Path, label: str) -> list[dict]:
    """Return one row per fold and seed (and one per fold for the physics alone)."""
    folds, result = read_study(study)
    protocol = result['protocol']
    spec = read_dataset(folds[0].path).vessel
    rows = []
    for fold in folds:
        train, val, test = (load_runs(fold.path, split, spec) for split in
                            ('train', 'val', 'test'))
        windows = forecast_windows(test, protocol['window'], protocol['horizon'],
                                   protocol['stride'], protocol['target'])

        def rmse(pred, windows=windows):
            return forecast_metrics(pred, windows.z_target, spec)['rmse']

        members = [load_model(run_dir(study, label, fold, seed) / MODEL_FILE)[0].eval()
                   for seed in protocol['seeds']]
        for seed, model in zip(protocol['seeds'], members, strict=True):
            fitted = correction_inputs(model, train)
            radius = np.quantile(distance(correction_inputs(model, val), fitted), QUANTILE)
            d = distance(correction_inputs(model, test), fitted)
            served = model.relative_threshold
            with model.served_at(served / 10):
                tenth = rmse(predict(model, windows))
            pred, share = faded(model, windows)
            rows.append({'fold': fold.index, 'forecasts': len(windows), 'seed': seed,
                         'beyond': float(np.mean(d > radius)),
                         'beyond_twice': float(np.mean(d > 2 * radius)),
                         'threshold': served, 'served': rmse(predict(model, windows)),
                         'tenth': tenth, 'faded': rmse(pred),
                         'share': [float(share.mean()), float(share.min())]})
        validation = forecast_windows(val, protocol['window'], protocol['horizon'],
                                      max(1, protocol['horizon'] // 3), protocol['target'])
        radius = np.quantile(ensemble_forecast(members, validation)[1], QUANTILE, axis=0)
        pred, spread = ensemble_forecast(members, windows)
        beyond = np.mean(spread > radius, axis=0).tolist()
        rows.append({'fold': fold.index, 'forecasts': len(windows), 'seed': 'ensemble',
                     'spread_beyond': dict(zip(spec.state_names, beyond, strict=True)),
                     'served': rmse(pred)})
        rows.append({'fold': fold.index, 'forecasts': len(windows), 'seed': 'physics alone',
                     'served': rmse(predict(PhysicsOnly(members[-1].physical), windows))})
        print(f'fold {fold.index} done', file=sys.stderr, flush=True)
    return rows


def markdown(rows: list[dict]) -> str:
    """Return the rows as a Markdown table (RMSE per state: served / a tenth of it)."""
    states = list(rows[0]['served'])
    lines = ['| fold (forecasts) | seed | inputs beyond the radius | beyond twice it | '
             'served T | ' + ' | '.join(f'{s} RMSE at T / at T/10 / faded' for s in states)
             + ' | share of the bound faded, mean / least |',
             '|---|---|---|---|---|' + '---|' * (len(states) + 1)]
    for r in rows:
        if 'spread_beyond' in r:
            shares = ', '.join(f'{s} {v:.0%}' for s, v in r['spread_beyond'].items())
            cells = ' | '.join(f"{r['served'][s]:.4f}" for s in states)
            lines.append(f"| {r['fold']} ({r['forecasts']}) | ensemble of the seeds "
                         f"(steps whose spread is beyond the radius: {shares}) | | | | "
                         f"{cells} | |")
            continue
        if 'beyond' not in r:
            cells = ' | '.join(f"{r['served'][s]:.4f}" for s in states)
            lines.append(f"| {r['fold']} ({r['forecasts']}) | physics alone | | | | {cells} | "
                         f"|")
            continue
        cells = ' | '.join(f"{r['served'][s]:.4f} / {r['tenth'][s]:.4f} / "
                           f"{r['faded'][s]:.4f}" for s in states)
        lines.append(f"| {r['fold']} ({r['forecasts']}) | {r['seed']} | {r['beyond']:.0%} | "
                     f"{r['beyond_twice']:.0%} | {r['threshold']:g} | {cells} | "
                     f"{r['share'][0]:.2f} / {r['share'][1]:.2f} |")
    return '\n'.join(lines) + '\n'


def main(argv: list[str]) -> int:
    """Print (and with OUT write) the probe's table for one hybrid of a by-kind study."""
    if len(argv) not in (2, 3):
        print(__doc__, file=sys.stderr)
        return 2
    table = markdown(probe(Path(argv[0]), argv[1]))
    print(table)
    if len(argv) == 3:
        out = Path(argv[2])
        out.mkdir(parents=True, exist_ok=True)
        (out / 'unseen_kind_probe.md').write_text(table)
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
