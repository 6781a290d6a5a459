"""
Lags between the quantities of a recording, estimated from the data.

A tracking system that filters position and velocity but not heading (the snuboat's
motion capture: 0.9 s), a GNSS receiver that stamps on output, a gyro on another bus:
each gives a quantity whose stamp is late. Three lags are measurable on a run's dataset
columns, each by sliding one signal against another on the run's grid and taking the
shift of least squared difference (refined between grid points by a parabola):

* ``position``: d(position)/dt against the velocity, compared by speed alone, so the
  heading plays no part;
* ``heading``: the course of the velocity turned into the earth frame by a shifted
  heading against the course of d(position)/dt;
* ``yaw_rate``: the yaw rate against d(heading)/dt.

Each comparison stores its cost per shift as sums, so runs pool exactly (add the sums).
``delays`` turns the lags into the delay of each quantity behind the earliest one --
the ``delay_s`` a map entry needs.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

MAX_LAG_S = 3.0        # shifts tried: up to this far either way
MIN_CONTRAST = 0.05    # a cost curve flatter than this (relative) says nothing
# A comparison smoothed over longer than this for its columns' resolution (a track
# printed in 10 m steps: 20-30 s) blurs lags of a few seconds into its noise: not timed.
MAX_TIMED_SCALE_S = 2 * MAX_LAG_S
QUANTITIES = ('position', 'heading', 'yaw_rate')


def shifts(rate_hz: float) -> np.ndarray:
    """Return the shifts tried, in samples of the grid."""
    k = int(round(MAX_LAG_S * rate_hz))
    return np.arange(-k, k + 1)


def cost_curve(a: np.ndarray, b: np.ndarray, ks: np.ndarray, angle: bool = False
               ) -> dict[str, list[float]]:
    """
    Return sums of squared differences of a(t) and b(t + k) per shift k (samples).

    A positive best k means ``b`` lags ``a``. ``angle``: differences wrapped to
    (-pi, pi]. Non-finite pairs are left out.
    """
    sums, counts = [], []
    n = len(a)
    for k in ks:
        lo, hi = max(0, -k), min(n, n - k)
        if hi - lo < 3:
            sums.append(0.0)
            counts.append(0)
            continue
        d = b[lo + k:hi + k] - a[lo:hi]
        if angle:
            d = np.angle(np.exp(1j * d))
        d = d[np.isfinite(d)]
        sums.append(float(d @ d))
        counts.append(int(len(d)))
    return {'sum_sq': sums, 'n': counts}


def best_shift(curve: Mapping[str, list[float]], rate_hz: float) -> float | None:
    """Return the lag (s) of least mean squared difference, or None if the curve is flat."""
    n = np.asarray(curve['n'], float)
    if not (n > 0).all():
        return None
    cost = np.asarray(curve['sum_sq'], float) / n
    i = int(np.argmin(cost))
    if not cost.mean() > 0 or (cost.mean() - cost[i]) / cost.mean() < MIN_CONTRAST:
        return None
    if i in (0, len(cost) - 1):  # the minimum lies beyond the shifts tried
        return None
    c0, c1, c2 = cost[i - 1:i + 2]
    den = c0 - 2 * c1 + c2
    frac = 0.5 * (c0 - c2) / den if den > 0 else 0.0
    k0 = -(len(cost) // 2)
    return (k0 + i + frac) / rate_hz


def delays(lags: Mapping[str, float | None]) -> dict[str, float]:
    """
    Delays (s) of velocity, position, heading and yaw rate behind the earliest of them.

    ``lags``: position behind velocity, heading behind velocity, yaw rate behind
    heading (None: not measurable; the quantity then counts as on time with its
    reference).
    """
    rel = {'velocity': 0.0, 'position': lags.get('position') or 0.0,
           'heading': lags.get('heading') or 0.0}
    rel['yaw_rate'] = rel['heading'] + (lags.get('yaw_rate') or 0.0)
    first = min(rel.values())
    return {k: v - first for k, v in rel.items()}
