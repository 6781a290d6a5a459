"""
Forecast metrics: per-state RMSE and the trajectory error of Baier et al.

Trajectory (any vessel; roll enters only where it is modelled): heading and position
are integrated from the origin with heading 0 for predicted and true states alike,
forward Euler at the sample period dt; state k is held over step k, which ends at
sample k:

    psi_k = dt * sum_{j<=k} r_j                       (heading at the end of step k)
    x_k = dt * sum_{j<=k} (u_j cos psi_{j-1} - v_j cos phi_j sin psi_{j-1})
    y_k = dt * sum_{j<=k} (u_j sin psi_{j-1} + v_j cos phi_j cos psi_{j-1})

with psi_{-1} = 0. A 6-DOF vehicle (``Vessel.is_spatial``) moves in space the same way:
its heading takes psi' = (q sin phi + r cos phi) / cos theta and its position
R(phi_j, theta_j, psi_{j-1}) (u_j, v_j, w_j) per step (``vessel_physics.integrator``),
so its track has a third column, down. This is the one dead reckoning of the project:
the predictor's published track (``hybrid_predictor.plans.track``) is this one, rotated
and shifted. The error at step k is the Euclidean distance between predicted and true
positions.
The reported mean runs over all steps and forecasts; its 95 % confidence interval is
1.96 * std / sqrt(n) with std and n over the per-forecast mean errors (forecasts, not
steps, are the sampling units; overlapping forecasts are still correlated, so read the
interval as a lower bound on the uncertainty).

Errors are also reported along the horizon, at every quarter of it (``reported_steps``):
the mean position error and each state's RMSE over forecasts at those steps. Model
cards show this profile, and the do-no-harm selection (``hybrid_models.selection``)
compares a hybrid with its physics alone at the same steps.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vessel_description import Vessel
from vessel_physics.integrator import attitude_rates, body_to_ned

Z95 = 1.959963984540054
REPORTED_POINTS = 4   # the horizon profile reports errors at every quarter of the horizon


def dead_reckoning(z: np.ndarray, spec: Vessel) -> tuple[np.ndarray, np.ndarray]:
    """
    Integrate states (..., H, n_state) into a track from the origin, heading 0 (module doc).

    Return positions (..., H, 2) in m (north, east; (..., H, 3) with down for a 6-DOF
    vehicle) and headings (..., H) in rad, both at the end of each step. A vessel without
    roll moves as if phi = 0.
    """
    if spec.is_spatial:
        return _dead_reckoning_3d(z, spec)
    dt = spec.dt
    u, v = (z[..., spec.state_index(n)] for n in ('u', 'v'))
    turn = heading_rate(z, spec)
    heading = dt * np.cumsum(turn, axis=-1)
    held = heading - dt * turn           # the heading a step starts from
    sway = v * np.cos(z[..., spec.state_index('phi')]) if spec.has_roll else v
    x_dot = u * np.cos(held) - sway * np.sin(held)
    y_dot = u * np.sin(held) + sway * np.cos(held)
    xy = dt * np.stack([np.cumsum(x_dot, axis=-1), np.cumsum(y_dot, axis=-1)], axis=-1)
    return xy, heading


def heading_rate(z, spec: Vessel):
    """
    Return psi' (rad/s) of states z (..., n_state) as the dead reckoning integrates it.

    r for a vessel on the water, (q sin phi + r cos phi) / cos theta in space; any
    Array API arrays (the compiled forecaster turns a held wind by it, step by step).
    """
    if not spec.is_spatial:
        return z[..., spec.state_index('r')]
    p, q, r, phi, theta = (z[..., spec.state_index(n)] for n in ('p', 'q', 'r', 'phi',
                                                                  'theta'))
    return attitude_rates(p, q, r, phi, theta)[2]


def _dead_reckoning_3d(z: np.ndarray, spec: Vessel) -> tuple[np.ndarray, np.ndarray]:
    """``dead_reckoning`` of a 6-DOF vehicle: positions (..., H, 3) NED, headings (..., H)."""
    velocity, heading = earth_velocities(z, spec)
    return spec.dt * np.cumsum(velocity, axis=-2), heading


def earth_velocities(z: np.ndarray, spec: Vessel, heading0=0.0
                     ) -> tuple[np.ndarray, np.ndarray]:
    """
    Return a 6-DOF vehicle's velocities over ground (..., H, 3), NED, and its headings.

    The heading is integrated from ``heading0`` (rad; scalar or (...,)) as in
    ``dead_reckoning``; step k's velocity is its body velocity turned by its roll and
    pitch and the heading it starts from. These are the inertial-frame velocities
    (x', y', z') of Baier et al.'s quadrotor, in NED.
    """
    u, v, w, phi, theta = (z[..., spec.state_index(n)] for n in ('u', 'v', 'w', 'phi', 'theta'))
    start = np.asarray(heading0, np.float64)[..., None]
    heading = start + spec.dt * np.cumsum(heading_rate(z, spec), axis=-1)
    held = np.concatenate([np.broadcast_to(start, heading[..., :1].shape),
                           heading[..., :-1]], axis=-1)
    return np.stack(body_to_ned(u, v, w, phi, theta, held), axis=-1), heading


def positions(z: np.ndarray, spec: Vessel) -> np.ndarray:
    """Return only the track (..., H, 2 or 3) in m of ``dead_reckoning``."""
    return dead_reckoning(z, spec)[0]


def trajectory_errors(pred: np.ndarray, true: np.ndarray, spec: Vessel) -> np.ndarray:
    """Distance (B, H) in m between predicted and true positions at every step."""
    with np.errstate(invalid='ignore', over='ignore'):
        return np.linalg.norm(positions(pred, spec) - positions(true, spec), axis=-1)


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def forecast_metrics(pred: np.ndarray, true: np.ndarray, spec: Vessel,
                     minute: int | None = None, state_std: np.ndarray | None = None) -> dict:
    """
    Every number of one model's forecasts (B, H, n_state) against the truth.

    Non-finite forecasts (a diverged model) give ``diverged: true`` and None values;
    ``state_std`` adds the state error (sum of RMSE / std) to the horizon profile.
    """
    pred = np.asarray(pred, dtype=np.float64)
    true = np.asarray(true, dtype=np.float64)
    with np.errstate(invalid='ignore', over='ignore'):
        sq = (pred - true) ** 2
        rmse = np.sqrt(sq.reshape(-1, spec.n_state).mean(axis=0))
    diverged = not np.isfinite(pred).all()
    err = trajectory_errors(pred, true, spec)
    per_forecast = err.mean(axis=1)
    n = len(per_forecast)
    std = float(per_forecast.std(ddof=1)) if n > 1 else float('nan')
    minute = minute or max(1, int(round(60.0 * spec.rate_hz)))  # samples per minute
    steps = err.shape[1] // minute * minute
    per_minute = err[:, :steps].reshape(n, -1, minute).mean(axis=2) if steps else None
    return {
        'diverged': bool(diverged),
        'rmse': {s: _finite(rmse[i]) for i, s in enumerate(spec.state_names)},
        'trajectory': {
            'mean': _finite(err.mean()),
            'std': _finite(std),
            'n': n,
            'ci95': _finite(Z95 * std / np.sqrt(n)) if n > 1 else None,
            'final_mean': _finite(err[:, -1].mean()),
            'per_minute_mean': None if per_minute is None else [
                _finite(x) for x in per_minute.mean(axis=0)],
        },
        'profile': StepErrors.of(pred, true, spec).profile(spec, state_std=state_std),
        'n_forecasts': n,
        'horizon': int(pred.shape[1]),
    }


def reported_steps(horizon: int, points: int = REPORTED_POINTS) -> list[int]:
    """Horizon steps (1 = the first predicted sample) at which errors are reported."""
    return sorted({max(1, round(horizon * j / points)) for j in range(1, points + 1)})


@dataclass
class StepErrors:
    """
    Error sums per horizon step over a set of forecasts; sums of parts add up.

    Forecasts split over chunks or processes give parts whose ``+`` is the whole, so
    every profile and score below is exact whatever the split.
    """

    sse: np.ndarray        # (H, n_state) sums of squared state errors
    position: np.ndarray   # (H,) sums of position errors (m)
    count: int             # forecasts

    @classmethod
    def of(cls, pred: np.ndarray, true: np.ndarray, spec: Vessel) -> StepErrors:
        """Sum the errors of forecasts (B, H, n_state) against the truth."""
        with np.errstate(invalid='ignore', over='ignore'):
            sse = ((np.asarray(pred, np.float64) - true) ** 2).sum(axis=0)
            position = trajectory_errors(np.asarray(pred, np.float64),
                                         np.asarray(true, np.float64), spec).sum(axis=0)
        return cls(sse, position, len(pred))

    def __add__(self, other: StepErrors) -> StepErrors:
        return StepErrors(self.sse + other.sse, self.position + other.position,
                          self.count + other.count)

    def flat(self) -> list[float]:
        """Every sum as one list (to add parts over processes), then ``from_flat``."""
        return [*self.sse.ravel().tolist(), *self.position.tolist(), float(self.count)]

    @classmethod
    def from_flat(cls, values, horizon: int, n_state: int) -> StepErrors:
        """Rebuild from ``flat()`` output (of the same horizon and state count)."""
        values = np.asarray(values, np.float64)
        cut = horizon * n_state
        return cls(values[:cut].reshape(horizon, n_state), values[cut:cut + horizon],
                   int(round(values[-1])))

    def score(self, state_std: np.ndarray) -> float:
        """Sum over states of RMSE / std over every step (the model-selection score)."""
        return normalized_rmse_sum_of(self.sse.sum(axis=0), self.count * len(self.sse),
                                      state_std)

    def profile(self, spec: Vessel, steps: list[int] | None = None,
                state_std: np.ndarray | None = None) -> dict:
        """
        Return the errors at ``steps`` (default ``reported_steps``).

        The mean position error (m) and each state's RMSE over the forecasts, and with
        ``state_std`` their sum over states of RMSE / std (``normalized``, the selection
        score at one step); None where a forecast diverged.
        """
        steps = steps or reported_steps(len(self.sse))
        at = np.asarray(steps) - 1
        with np.errstate(invalid='ignore', over='ignore'):
            rmse = np.sqrt(self.sse[at] / self.count)
            position = self.position[at] / self.count
        out = {'steps': list(steps), 'seconds': [k * spec.dt for k in steps],
               'position_m': [_finite(x) for x in position],
               'rmse': {s: [_finite(x) for x in rmse[:, i]]
                        for i, s in enumerate(spec.state_names)}}
        if state_std is not None:
            out['normalized'] = [_finite(x) for x in (rmse / state_std).sum(axis=1)]
        return out


def squared_error_sums(pred: np.ndarray, true: np.ndarray) -> tuple[np.ndarray, int]:
    """Per-state sums of squared errors (float64) and the number of terms in each."""
    with np.errstate(invalid='ignore', over='ignore'):
        err = (np.asarray(pred, np.float64) - true).reshape(-1, pred.shape[-1])
        return (err ** 2).sum(axis=0), len(err)


def normalized_rmse_sum_of(sse: np.ndarray, count: int, state_std: np.ndarray) -> float:
    """Sum over states of RMSE / std from error sums (parts of a split add up)."""
    with np.errstate(invalid='ignore', over='ignore'):
        total = float((np.sqrt(np.asarray(sse) / count) / state_std).sum())
    return total if np.isfinite(total) else float('inf')


def normalized_rmse_sum(pred: np.ndarray, true: np.ndarray, state_std: np.ndarray) -> float:
    """Sum over states of RMSE / std (the model-selection score; inf if diverged)."""
    return normalized_rmse_sum_of(*squared_error_sums(pred, true), state_std)
