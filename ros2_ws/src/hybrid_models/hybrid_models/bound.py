"""
The interpretability constraint: a bound on the LSTM's residual output.

Baier et al. define the relative threshold T as the ratio between the SIZE of the
LSTM's output interval and the size of the physical model's expected output range:
a physical range [-5, 5] with the LSTM limited to [-1, 1] is T = 20 %. So the LSTM
output of state i lies in [-b_i, b_i] with

    b_i = T * R_i / 2,   R_i = q97.5(z_phy_i) - q2.5(z_phy_i),

where R_i, "the 95 % range", is the spread between the 2.5th and 97.5th percentiles
of the physical model's ONE-STEP outputs (teacher-forced from measured states) over
the training and validation runs, in the state's own unit.

One meaning of T everywhere (training configs, checkpoints, ``set_threshold``, the
forecaster, the predictor node): T > 0 bounds the correction to T R / 2; 0 keeps the
physics alone (b = 0, the correction is zero); inf leaves it unbounded. None means no
threshold is given: a training config or a checkpoint without one is unbounded, and a
forecaster given none serves its checkpoint's own. The bound itself is written against
the Array API, so training (torch) and serving (jax) run this one code.
"""

from __future__ import annotations

import math

import numpy as np

from vessel_physics.arrays import namespace

BOUND_MODES = ('tanh', 'clamp')
PERCENTILES = (2.5, 97.5)


def output_range(z_phy: np.ndarray) -> np.ndarray:
    """Per-state 95 % range R_i = q97.5 - q2.5 of one-step outputs z_phy (N, n_state)."""
    lo, hi = np.percentile(np.asarray(z_phy, dtype=np.float64), PERCENTILES, axis=0)
    return hi - lo


def half_width(relative_threshold: float | None, out_range: np.ndarray) -> np.ndarray:
    """Bound b_i = T R_i / 2 (inf everywhere when T is None: unconstrained; 0 when T = 0)."""
    if relative_threshold is None:
        return np.full(np.shape(out_range), math.inf)
    if not relative_threshold >= 0:
        raise ValueError(f'relative threshold must be >= 0 or None, got {relative_threshold}')
    if not np.isfinite(out_range).all():
        raise ValueError('the output range is not set (a model trained before bounds were '
                         'computed); a threshold needs it')
    return relative_threshold * np.asarray(out_range, dtype=np.float64) / 2.0


def apply_bound(x, bound, mode: str = 'tanh'):
    """
    Limit x to [-bound, bound] per last-axis channel, on any Array API arrays.

    Infinite bounds pass x through; zero bounds give zero. 'tanh' is smooth,
    b tanh(x / b): slope 1 near zero, so small corrections pass almost unchanged and
    gradients never vanish abruptly; |output| <= b holds exactly in floating point
    because |tanh| <= 1. 'clamp' is the hard limit (zero gradient outside).
    """
    if mode not in BOUND_MODES:
        raise ValueError(f'unknown bound mode {mode!r}; use {BOUND_MODES}')
    xp = namespace(x, bound)
    finite = xp.isfinite(bound)
    positive = finite & (bound > 0)
    # Stand-in 1 where the bound is inf or 0, so that no division makes a nan.
    safe = xp.where(positive, bound, xp.ones_like(bound))
    if mode == 'tanh':
        limited = safe * xp.tanh(x / safe)
    else:
        limited = xp.clip(x, -safe, safe)
    return xp.where(positive, limited, xp.where(finite, xp.zeros_like(x), x))
