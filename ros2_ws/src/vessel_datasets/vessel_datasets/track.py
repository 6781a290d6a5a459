"""
Velocity from the track: earth-frame velocities of a vessel that logs only its position.

Many small craft log a GNSS position (about once a second, often held between fixes),
a heading and their actuators, but no velocity. The earth-frame velocity is then the
derivative of the track: the fixes (a sample repeating the previous position is a held
fix, not a new one) are fitted with a smoothing spline per axis, whose smoothing
``scipy.interpolate.make_smoothing_spline`` chooses by generalised cross-validation,
and its derivative is taken at the fixes. ``quantities.to_columns`` turns it into body
velocities with the heading, so the drift angle comes out of the data; a speed over
ground column is never surge, and only ever a cross-check of this.
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import make_smoothing_spline

MIN_FIXES = 5  # fewer distinct fixes give no derivative


def fixes(t_ns: np.ndarray, north: np.ndarray, east: np.ndarray
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return the samples that are new fixes: the first, and each that moved."""
    moved = np.ones(len(t_ns), bool)
    moved[1:] = (np.diff(north) != 0) | (np.diff(east) != 0)
    return t_ns[moved], north[moved], east[moved]


def velocity(t_ns: np.ndarray, north: np.ndarray, east: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return (times, v_north, v_east) (ns, m/s) at the fixes of a track (m, NED).

    Raises ValueError when fewer than ``MIN_FIXES`` distinct fixes remain.
    """
    t, n, e = fixes(np.asarray(t_ns, np.int64), np.asarray(north, float),
                    np.asarray(east, float))
    if len(t) < MIN_FIXES:
        raise ValueError(f'the track has {len(t)} distinct fixes; velocities from the track '
                         f'need at least {MIN_FIXES}')
    s = (t - t[0]) / 1e9
    rates = [make_smoothing_spline(s, axis).derivative()(s) for axis in (n, e)]
    return t, rates[0], rates[1]
