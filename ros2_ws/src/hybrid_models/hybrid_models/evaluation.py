"""
Test-set evaluation of trained checkpoints (the numbers behind Table 2).

Protocol: on every test run, a 900-step forecast starts every ``stride`` samples
(default 120 s: 23 forecasts per one-hour run, covering the run evenly), each after a
60-sample initialization window of MEASURED states and controls; predictions are
compared with the noise-free ``<state>_true`` columns where the dataset has them
(Baier et al. train on noisy and test on noise-free data).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import nn

from hybrid_models.data import RunArrays, Windows, forecast_windows
from hybrid_models.metrics import forecast_metrics, normalized_rmse_sum
from hybrid_models.models import predict
from hybrid_models.nets import HybridModel, as_tensor
from hybrid_models.physical import PhysicalModel
from vessel_description import Vessel


@dataclass
class Evaluated:
    """One model's forecasts and figures."""

    label: str
    pred: np.ndarray
    metrics: dict


class PhysicsOnly(nn.Module):
    """A hybrid's physical model run alone, multistep (for the physics-only rows)."""

    kind = 'physics'

    def __init__(self, physical: PhysicalModel):
        super().__init__()
        self.physical = physical

    def forecast(self, z_window, c_window, c_future):
        """Feed the physical model its own output."""
        z, out = z_window[:, -1], []
        for k in range(c_future.shape[1]):
            z = self.physical(z, c_future[:, k])
            out.append(z)
        return torch.stack(out, dim=1)


def test_windows(runs: list[RunArrays], window: int, horizon: int, stride: int,
                 target: str = 'true') -> Windows:
    """The evaluation forecasts (see module docstring)."""
    return forecast_windows(runs, window, horizon, stride, target)


def evaluate_model(label: str, model: nn.Module, windows: Windows, spec: Vessel,
                   state_std: np.ndarray) -> Evaluated:
    """Forecast every window and compute the metrics."""
    pred = predict(model, windows)
    metrics = forecast_metrics(pred, windows.z_target, spec, state_std=state_std)
    metrics['rmse_normalized_sum'] = normalized_rmse_sum(pred, windows.z_target, state_std)
    return Evaluated(label, pred, metrics)


def threshold_sweep(model: HybridModel, windows: Windows, spec: Vessel,
                    state_std: np.ndarray, thresholds) -> list[dict]:
    """
    Metrics of a hybrid constrained at each relative threshold (None = unconstrained).

    The threshold is applied at inference only; the model's own setting is restored.
    """
    rows = []
    for t in [None] + list(thresholds):
        with model.served_at(t):
            ev = evaluate_model(str(t), model, windows, spec, state_std)
            rows.append({'relative_threshold': t, **ev.metrics,
                         'bound': model.bound.tolist()})
    return rows


def rmse_of(row: dict) -> dict:
    """Return a sweep row's per-state RMSE (what ``smallest_threshold`` compares by default)."""
    return row['rmse']


def trajectory_of(row: dict) -> dict:
    """Return a sweep row's mean trajectory error, as {'trajectory': metres}."""
    return {'trajectory': row['trajectory'].get('mean')}


def smallest_threshold(sweep: list[dict], reference: dict, tolerance: float,
                       figures=rmse_of) -> float | None:
    """
    Return the smallest relative threshold whose accuracy matches a reference.

    "Matches": every figure named in ``reference`` (by default per-state RMSEs; e.g. the
    unconstrained model's) is at most (1 + ``tolerance``) times the reference's, with
    ``figures(row)`` giving a row's figures. Rows at threshold None (unconstrained) never
    count; a diverged row never matches. None when no row does.
    """
    if tolerance < 0:
        raise ValueError(f'tolerance must be >= 0, got {tolerance}')
    matching = []
    for row in sweep:
        if row['relative_threshold'] is None or row.get('diverged'):
            continue
        got = figures(row)
        if all(got[k] is not None and got[k] <= (1 + tolerance) * ref
               for k, ref in reference.items()):
            matching.append(row['relative_threshold'])
    return min(matching) if matching else None


@torch.no_grad()
def residual_share(model: HybridModel, windows: Windows) -> dict:
    """How much the LSTM contributes: mean |residual| / bound and the fraction near it."""
    model.eval()
    w = windows.subset(slice(0, min(len(windows), 256)))
    _, _, res = model.forecast(as_tensor(w.z_window), as_tensor(w.c_window),
                               as_tensor(w.c_future), return_parts=True)
    res = res.abs().reshape(-1, res.shape[-1])
    out = {'mean_abs_residual': res.mean(0).tolist()}
    if torch.isfinite(model.bound).all():
        out['fraction_above_90pct_of_bound'] = (res > 0.9 * model.bound).float().mean(0).tolist()
    return out


def over_seeds(values: list):
    """
    Mean and standard deviation over seeds of equally shaped figures (nested dicts/lists).

    Return (mean, sd) of the same shape; a figure that is None in any seed (a diverged
    run) is None in both, and sd is None for a single seed.
    """
    first = values[0]
    if isinstance(first, dict):
        pairs = {k: over_seeds([v[k] for v in values]) for k in first}
        return {k: m for k, (m, _) in pairs.items()}, {k: s for k, (_, s) in pairs.items()}
    if isinstance(first, list):
        pairs = [over_seeds([v[i] for v in values]) for i in range(len(first))]
        return [m for m, _ in pairs], [s for _, s in pairs]
    if isinstance(first, bool) or not isinstance(first, (int, float)) or first is None:
        return first, None
    if any(v is None for v in values):
        return None, None
    x = np.asarray(values, np.float64)
    return float(x.mean()), (float(x.std(ddof=1)) if len(x) > 1 else None)


SEED_FIGURES = ('rmse', 'trajectory', 'profile')


def seed_row(label: str, metrics: list[dict], **extra) -> dict:
    """
    One table row of a model trained with several seeds: mean figures, their spread.

    ``metrics``: one ``forecast_metrics`` result per seed. The row's ``metrics`` are the
    means (so tables and checks read it like a single model's), ``spread`` the standard
    deviations over seeds, ``per_seed`` each seed's trajectory error.
    """
    mean, sd = over_seeds([{k: m[k] for k in SEED_FIGURES} for m in metrics])
    merged = {**metrics[0], **mean,
              'diverged': any(m['diverged'] for m in metrics)}
    return {'label': label, 'seeds': len(metrics), 'metrics': merged, 'spread': sd,
            'per_seed': [m['trajectory']['mean'] for m in metrics], **extra}
