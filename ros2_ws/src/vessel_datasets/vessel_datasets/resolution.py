"""
Columns too coarse for the checks or the rate: find them, say so, choose a fair scale.

A logger that prints three significant digits, or holds a GNSS fix between updates,
gives a channel that repeats its value, or moves by a few steps of its resolution. Differentiated
sample by sample, such a channel is noise; compared at a longer scale, it is as good as
any. ``analyse`` measures, on a channel's raw samples, how often it repeats and its
step, and returns the time over which the step falls to ``ERROR_SHARE`` of the typical
change: the map checks smooth both sides of a comparison over at least that long, so a
right map on coarse data passes and a wrong one still fails. ``note`` says it in one
line naming the map entry, its step and how often it really changes.

The step of a number printed to a few significant digits grows with its size: a track
printed to three digits moves in 0.1 m steps near its start, 10 m steps beyond 1 km,
and its other coordinate may stay near zero, finely printed, for the whole run. So the
step is measured per magnitude band of the values (``BANDS_PER_DECADE``), each sample
takes its band's step, and the channel's step is a high percentile of those
(``COARSE_PERCENTILE``): the coarse stretches are what a check must allow for. A band's
step counts only where its changes take few distinct values (``DISTINCT_SHARE``), as
whole multiples of a printed step do: a smooth, finely sampled channel whose speed grows
with its values (a motion-capture track in float32: every change a value of its own)
has no step, and its slowest changes in a fast band are none.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

MIN_REPEAT_SHARE = 0.2   # a channel repeating its previous value this often is coarse,
COARSE_STEP = 0.1        # and so is one whose step is this share of its typical change
ERROR_SHARE = 0.05       # a step allowed per scale, as a share of the change over it
STEP_PERCENTILE = 5      # the step is this percentile of the non-zero changes (robust)
FLOAT_NOISE = 1e-9       # relative change below which two values count as equal
BANDS_PER_DECADE = 4     # magnitude bands a decade of values is cut into for their steps
MIN_BAND_CHANGES = 5     # changes a band needs for a step of its own (else the overall one)
COARSE_PERCENTILE = 90   # the channel's step: this percentile of its samples' band steps
DISTINCT_SHARE = 0.2     # a band is printed in steps when its changes take at most this
                         # share of distinct values (equal to FLOAT_NOISE of its values)
EARTH_RADIUS_M = 6371000.0  # only to express degree steps in metres in a note


@dataclass(frozen=True)
class Resolution:
    """How coarse one quantity of a recording is."""

    quantity: str       # 'position', 'heading', 'velocity', 'yaw_rate', 'time', ...
    step: float         # smallest change between samples, in ``unit``
    unit: str
    repeats: float      # share of samples equal to the previous one
    change_s: float     # mean time between changes (s)
    scale_s: float      # time over which the step is ERROR_SHARE of the change

    def to_dict(self) -> dict:
        """Return the figures for a report."""
        return {'quantity': self.quantity, 'step': self.step, 'unit': self.unit,
                'repeats': self.repeats, 'change_s': self.change_s, 'scale_s': self.scale_s}


def analyse(quantity: str, t_ns: np.ndarray, values: np.ndarray, unit: str,
            ) -> Resolution | None:
    """
    Return how coarse a channel is, or None when it is fine.

    Coarse: it repeats its previous value in at least ``MIN_REPEAT_SHARE`` of the
    samples, or its step is at least ``COARSE_STEP`` of its typical change per sample.

    ``values`` is (n,) or (n, k): the components of one quantity (x and y of a
    position) sharing a step, its change measured as the norm over components.
    """
    t = np.asarray(t_ns, np.int64)
    x = np.asarray(values, float).reshape(len(t), -1)
    ok = np.isfinite(x).all(axis=1)
    t, x = t[ok], x[ok]
    if len(t) < 10:
        return None
    d = np.diff(x, axis=0)
    # Changes below the float resolution of the values are printing noise, not steps.
    d[np.abs(d) <= FLOAT_NOISE * np.abs(x).max(axis=0)] = 0.0
    moved = np.abs(d).max(axis=1) > 0
    if moved.sum() < 3:
        return None
    repeats = 1.0 - float(moved.mean())
    step = max(float(np.percentile(np.abs(d[d != 0]), STEP_PERCENTILE)),
               _magnitude_step(x[:-1], d))
    typical = float(np.median(np.linalg.norm(d[moved], axis=1)))
    if repeats < MIN_REPEAT_SHARE and step < COARSE_STEP * typical:
        return None
    duration = (t[-1] - t[0]) / 1e9
    rate = float(np.linalg.norm(d, axis=1).sum()) / duration  # mean |change| per second
    change_s = duration / int(moved.sum())
    scale = max(step / (ERROR_SHARE * rate) if rate > 0 else math.inf, 2.0 * change_s)
    return Resolution(quantity, step, unit, repeats, change_s, scale)


def _magnitude_step(x: np.ndarray, d: np.ndarray) -> float:
    """
    Return the channel's step where its values are coarsest (module docstring).

    ``x`` (n, k) the values before each change ``d`` (n, k). Per component, the non-zero
    changes are grouped by the magnitude band of the value they start from; a sample's
    step is the largest of its components' band steps; the ``COARSE_PERCENTILE`` of
    the samples' steps is returned (0 when no band has enough changes).
    """
    per_sample = np.zeros(len(d))
    for j in range(d.shape[1]):
        magnitude = np.abs(x[:, j])
        band = np.floor(np.log10(np.maximum(magnitude, np.finfo(float).tiny))
                        * BANDS_PER_DECADE)
        changed = d[:, j] != 0
        steps = np.zeros(len(d))
        for b in np.unique(band[changed]):
            in_band = band == b
            if (in_band & changed).sum() >= MIN_BAND_CHANGES:
                changes = np.abs(d[in_band & changed, j])
                if _quantized(changes, magnitude[in_band].max()):
                    steps[in_band] = np.percentile(changes, STEP_PERCENTILE)
        per_sample = np.maximum(per_sample, steps)
    return float(np.percentile(per_sample, COARSE_PERCENTILE))


def _quantized(changes: np.ndarray, magnitude: float) -> bool:
    """Tell whether changes take few distinct values: printed in steps (module docstring)."""
    resolution = max(FLOAT_NOISE * magnitude, np.finfo(float).tiny)
    distinct = len(np.unique(np.round(changes / resolution)))
    return distinct <= DISTINCT_SHARE * len(changes)


def note(res: Resolution, label: str, column: str, period_s: float) -> str:
    """One line: which entry is coarse, its step, how often it changes, the check scale."""
    coarse = (f"; coarser than the vessel's {period_s:g} s sample period"
              if res.change_s > 1.5 * period_s else '')
    return (f'{label} ({column}) repeats its previous value in {100 * res.repeats:.0f} % of '
            f'the samples and changes in steps of {_fmt(res.step, res.unit)}, on average '
            f'every {res.change_s:.2g} s{coarse}: the map checks judge it over '
            f'{res.scale_s:.3g} s')


def _fmt(step: float, unit: str) -> str:
    if unit == 'deg':
        return f'{step:.3g} deg ({math.radians(step) * EARTH_RADIUS_M:.2g} m)'
    if unit == 'rad':
        return f'{step:.3g} rad ({math.degrees(step):.3g} deg)'
    return f'{step:.3g} {unit}'
