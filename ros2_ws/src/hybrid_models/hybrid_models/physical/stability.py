"""
A regression physics that damps its own motion: least squares with bounded self-gains.

A Lin/Hyd regression fitted on one-step pairs, z_{t+1,i} = W_i f(z_t, c_t) + b_i, has a
self-gain g_i(z) = d z_{t+1,i} / d z_{t,i} = W_i df/dz_i(z) that depends on the state
through the hull terms (u r, |u| r, r|r|, ...). Nothing in the recordings keeps it below
1 where they never went: fitted on a model boat's straight runs, the yaw row's gain
exceeded 1 in turns faster than 0.24 m/s and its forecasts of turns diverged (issue
#23). A hull damps its own motion, so here each row is fitted under the linear
constraints g_i(z) <= MAX_GAIN at points spread over the vessel's envelope: the box of
the vessel file's state limits (the training rows' range where a state has none) and
the training rows themselves. scipy's SLSQP solves each row's small quadratic
programme, starting from the unconstrained solution.

The constraint is on each state's own gain, not on the coupled system's spectrum; the
fit-time envelope check (``hybrid_models.physical.envelope``) still judges the result.
Numpy and scipy only.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize

MAX_GAIN = 1.0           # a state's own one-step gain: 1 lets it hold, never grow
ENVELOPE_POINTS = 2000   # points of the limits' box the constraints are checked at
ROW_POINTS = 1000        # training rows the constraints are checked at as well
STEP = 1e-4              # central differences, as a fraction of each state's span


def envelope_points(z: np.ndarray, limits: dict, names: tuple[str, ...],
                    seed: int = 0) -> np.ndarray:
    """
    Return states (P, n_state) spread over the envelope: the limits' box and the rows.

    The box is each state's limits (its range over the rows ``z`` when the vessel file
    gives none), sampled uniformly (seeded, so a fit is reproducible).
    """
    z = np.asarray(z, np.float64)
    lo = np.array([limits[n][0] if n in limits else z[:, i].min() for i, n in enumerate(names)])
    hi = np.array([limits[n][1] if n in limits else z[:, i].max() for i, n in enumerate(names)])
    rng = np.random.default_rng(seed)
    box = lo + (hi - lo) * rng.random((ENVELOPE_POINTS, len(names)))
    rows = z[np.unique(np.linspace(0, len(z) - 1, min(ROW_POINTS, len(z))).astype(int))]
    return np.vstack([box, rows])


def feature_slopes(features: Callable, points: np.ndarray, c: np.ndarray,
                   state: int) -> np.ndarray:
    """
    Return df/dz_state (P, F) at ``points`` (controls ``c``), by central differences.

    The difference step is STEP times the state's span over ``points``.
    """
    h = STEP * (float(np.ptp(points[:, state])) or 1.0)
    up, down = points.copy(), points.copy()
    up[:, state] += h
    down[:, state] -= h
    return (features(up, c) - features(down, c)) / (2.0 * h)


def constrained_ridge(xs: np.ndarray, y: np.ndarray, ridge: float, slopes: np.ndarray,
                      w0: np.ndarray) -> np.ndarray:
    """
    Return w minimising |xs w - y|^2 + ridge N |w|^2 subject to slopes w <= MAX_GAIN.

    xs (N, k) standardized columns, y (N,) centred, slopes (P, k) in the same columns;
    w0 the unconstrained solution (returned unchanged when it already holds).
    """
    if (slopes @ w0 <= MAX_GAIN).all():
        return w0
    n, k = xs.shape
    hessian = xs.T @ xs + ridge * n * np.eye(k)
    linear = xs.T @ y
    scale = float(np.abs(linear).max()) or 1.0   # a well-scaled objective for SLSQP
    result = minimize(lambda w: (0.5 * w @ hessian @ w - linear @ w) / scale, w0,
                      jac=lambda w: (hessian @ w - linear) / scale, method='SLSQP',
                      constraints=[{'type': 'ineq', 'fun': lambda w: MAX_GAIN - slopes @ w,
                                    'jac': lambda w: -slopes}],
                      options={'maxiter': 500, 'ftol': 1e-12})
    worst = float((slopes @ result.x).max())
    if worst > MAX_GAIN + 1e-6:
        raise RuntimeError(f'the damped fit found no weights with self-gain <= {MAX_GAIN:g} '
                           f'(best {worst:.4g}; {result.message})')
    return result.x
