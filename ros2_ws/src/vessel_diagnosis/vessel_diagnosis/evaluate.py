"""
Show the gain: one-step and 900-step errors of nominal and augmented physics, held out.

Held-out runs were not used to name or fit anything. Per-run terms (a current) cannot
be carried over from other runs, so on each held-out run they are estimated from its
first ``calibration_s`` only, with the global terms fixed, the way an online predictor
would estimate them from the past; every error is measured after that span, for both
models alike.

- one step: predictions of z_k+1 from the measured z_k, every sample;
- forecasts: the convention of ``hybrid_models.data`` (a window of measured samples,
  then the horizon from the last of them under the recorded controls; both the vessel
  file's unless the settings give them), one every ``stride_s``; per-state RMSE and the
  trajectory error of Baier et al. from ``hybrid_models.metrics.forecast_metrics`` (one
  definition for the whole project).

Targets are the noise-free ``*_true`` states where the recordings have them (simulated
data), else the measured states.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace

import numpy as np

from hybrid_models.metrics import forecast_metrics
from vessel_description import Vessel
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.recordings import Run
from vessel_physics.family import Physics

# Forecast steps at which RMSE per state is kept, as shares of the horizon (the first
# step, then 1/15, 1/3, 2/3 and all of it: 1, 60, 300, 600, 900 of the patrol boat's).
HORIZON_MARKS = (1 / 15, 1 / 3, 2 / 3, 1.0)


def _targets(run: Run) -> np.ndarray:
    return run.z_true if run.z_true is not None else run.z


def one_step_errors(runs: Sequence[Run], physics: Physics, currents: Mapping[str, np.ndarray],
                    start: int, substeps: int) -> np.ndarray:
    """Return the one-step errors (n, n_state) on every run from sample ``start`` on."""
    out = []
    for run in runs:
        if run.length - 1 <= start:
            continue
        sl = slice(start, run.length - 1)
        cur = currents.get(run.run_id)
        rows = run.length - 1 - start
        cur = None if cur is None else np.broadcast_to(cur, (rows, 2))
        pred = Predictor(physics, run.dt, substeps).one_step(
            run.z[sl], run.psi[sl], run.c[sl], run.c[start + 1:], cur)
        out.append(_targets(run)[start + 1:] - pred)
    return np.concatenate(out) if out else np.zeros((0, len(physics.family.states)))


def forecast_spans(vessel: Vessel, settings, dt: float) -> tuple[int, int, int]:
    """Return the window, horizon and stride of the held-out forecasts in samples."""
    ev = settings.evaluation
    window = ev.window_s if ev.window_s is not None else vessel.window_s
    horizon = ev.horizon_s if ev.horizon_s is not None else vessel.horizon_s
    return (settings.samples(window, dt), settings.samples(horizon, dt),
            settings.samples(ev.stride_s, dt))


def forecasts(runs: Sequence[Run], physics: Physics, currents: Mapping[str, np.ndarray],
              start: int, settings, spans: tuple[int, int, int]
              ) -> tuple[np.ndarray, np.ndarray]:
    """Return (predictions, targets), each (B, horizon, n_state), of forecasts after ``start``."""
    window, horizon, stride = spans
    n_state = len(physics.family.states)
    preds, trues = [], []
    for run in runs:
        t0s = np.arange(start + window, run.length - horizon + 1, stride)
        if not len(t0s):
            continue
        idx = (t0s - 1)[:, None] + np.arange(horizon + 1)[None, :]
        cur = currents.get(run.run_id)
        cur = None if cur is None else np.broadcast_to(cur, (len(t0s), 2))
        pred = Predictor(physics, run.dt, settings.prediction.substeps).simulate(
            run.z[t0s - 1], run.psi[t0s - 1], run.c[idx], cur)
        preds.append(pred)
        trues.append(_targets(run)[idx[:, 1:]])
    if not preds:
        return np.zeros((0, horizon, n_state)), np.zeros((0, horizon, n_state))
    return np.concatenate(preds), np.concatenate(trues)


def _rmse(err: np.ndarray, states) -> dict[str, float]:
    return {s: float(np.sqrt(np.mean(err[..., i] ** 2))) for i, s in enumerate(states)}


def _gain(before: float | None, after: float | None) -> float | None:
    if before is None or after is None or not before > 0:
        return None
    return float((before - after) / before)


def evaluate(runs: Sequence[Run], models: Mapping[str, tuple[Physics, Mapping]], settings,
             vessel: Vessel) -> dict:
    """
    Return the errors of each model on the held-out ``runs`` of ``vessel``.

    ``models`` maps a name to (physics, per-run currents); the first model is the
    reference for the gains.
    """
    ev = settings.evaluation
    dt = runs[0].dt if runs else vessel.dt
    start = int(round(ev.calibration_s / dt)) if runs else 0
    spans = forecast_spans(vessel, settings, dt)
    states = vessel.state_names
    out: dict = {'runs': [r.run_id for r in runs], 'start_sample': start,
                 'target': 'true' if all(r.z_true is not None for r in runs) else 'measured',
                 'window': spans[0], 'horizon': spans[1], 'stride': spans[2],
                 'one_step_rmse': {}, 'forecast': {}, 'rmse_by_step': {}}
    vessel = replace(vessel, rate_hz=1.0 / dt)
    marks = sorted({1, *(max(1, int(round(share * spans[1]))) for share in HORIZON_MARKS)})
    for name, (physics, currents) in models.items():
        err = one_step_errors(runs, physics, currents, start, settings.prediction.substeps)
        out['one_step_rmse'][name] = _rmse(err, states) if len(err) else None
        pred, true = forecasts(runs, physics, currents, start, settings, spans)
        if len(pred):
            metrics = forecast_metrics(pred, true, vessel)
            out['forecast'][name] = metrics
            out['rmse_by_step'][name] = {
                str(k): _rmse(pred[:, k - 1] - true[:, k - 1], states) for k in marks
                if k <= pred.shape[1]}
        else:
            out['forecast'][name] = None
    names = list(models)
    if len(names) >= 2:
        ref, new = names[0], names[1]
        one_ref, one_new = out['one_step_rmse'][ref], out['one_step_rmse'][new]
        f_ref, f_new = out['forecast'][ref], out['forecast'][new]
        out['improvement'] = {
            'one_step_rmse': ({s: _gain(one_ref[s], one_new[s]) for s in states}
                              if one_ref and one_new else None),
            'forecast_rmse': ({s: _gain(f_ref['rmse'][s], f_new['rmse'][s]) for s in states}
                              if f_ref and f_new else None),
            'trajectory': (_gain(f_ref['trajectory']['mean'], f_new['trajectory']['mean'])
                           if f_ref and f_new else None),
        }
    out['n_forecasts'] = (out['forecast'][names[0]] or {}).get('n_forecasts', 0) if names else 0
    return out
