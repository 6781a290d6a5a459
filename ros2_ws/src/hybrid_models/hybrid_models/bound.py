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

A threshold may also change along the forecast: a schedule [[0, T1], [s2, T2], ...]
serves T1 for the steps that end at or before s2 seconds, T2 from there to the next
start, and the last one to the end of any horizon (``step_bounds``). The do-no-harm
selection (``hybrid_models.selection``) writes one when, say, the physics alone is the
better forecast over the first seconds and the correction helps after them.
"""

from __future__ import annotations

from contextlib import contextmanager
import math

import numpy as np

from vessel_physics.arrays import namespace

BOUND_MODES = ('tanh', 'clamp')
PERCENTILES = (2.5, 97.5)


class ServedThreshold:
    """For a model served at a threshold: ``relative_threshold`` and ``set_threshold(T)``."""

    @contextmanager
    def served_at(self, relative_threshold):
        """Serve at another threshold inside the ``with`` block; the own one after it."""
        own = self.relative_threshold
        self.set_threshold(relative_threshold)
        try:
            yield self
        finally:
            self.set_threshold(own)


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


def schedule_of(threshold) -> list[tuple[float, float | None]]:
    """
    Return a served threshold as a schedule [(start_s, T), ...], checked.

    A number or None is one threshold from 0 s on; a schedule must start at 0 s and
    have increasing starts.
    """
    if threshold is None or isinstance(threshold, (int, float)):
        return [(0.0, None if threshold is None else float(threshold))]
    schedule = [(float(start), None if t is None else float(t)) for start, t in threshold]
    starts = [start for start, _ in schedule]
    if not schedule or starts[0] != 0.0 or any(np.diff(starts) <= 0):
        raise ValueError(f'a threshold schedule is [[0, T1], [start_s, T2], ...] with '
                         f'increasing starts, got {threshold}')
    return schedule


def is_constant(threshold) -> bool:
    """Tell whether a served threshold is one value for the whole forecast."""
    return len(schedule_of(threshold)) == 1


def loosest(threshold) -> float:
    """
    Return a served threshold as one number: the largest of a schedule, NaN if unbounded.

    What a message that carries one figure reports (the predictor's Forecast): the bound
    that holds at every step of the forecast.
    """
    values = [t for _, t in schedule_of(threshold)]
    return math.nan if any(t is None for t in values) else float(max(values))


def step_bounds(threshold, out_range: np.ndarray, dt: float, horizon: int) -> np.ndarray:
    """
    Return the half-widths (horizon, n_state) of forecast steps 1..horizon.

    Step k ends k * dt seconds after the forecast starts; it takes the schedule's entry
    with the last start before that time.
    """
    schedule = schedule_of(threshold)
    ends = dt * (np.arange(1, horizon + 1) - 1e-9)   # a step ending at a start is before it
    which = np.searchsorted([start for start, _ in schedule], ends, side='left') - 1
    rows = np.stack([half_width(t, out_range) for _, t in schedule])
    return rows[np.maximum(which, 0)]


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
