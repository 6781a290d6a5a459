"""
The model judged in hindsight: forecasts re-made with the inputs the vessel then applied (no ROS).

A published forecast assumes future controls and wind: a plan, or the latest ones held.
Its error then mixes two things, the model's and the assumption's, and the calibrated
bands (``hybrid_models.bands``) promise their coverage only for the first: through the
nodes, held-input forecasts on a passage left their band often enough to raise the
departure WARN on a vessel that matched its model exactly (32 reports in 1.5 h,
``offline/bench.py departure``). Whether the vessel departs from its model is a question
about the model alone, so it is asked of forecasts made, once the horizon has passed,
from the same window and the inputs that were measured meanwhile.

``Hindsight`` keeps one window per the tracker's ``forecast_period`` of message time and
the measured samples since; it hands the skill tracker (``skill.LiveSkill``) the measurements
``delay`` seconds late (the longest scored step), and at each kept window's stamp in
that late stream the forecast re-made from it by ``remake(window, applied)``, before
the measurements it is scored against. The tracker thus sees one time line, in order,
and its verdicts come ``delay`` seconds after the measurements that decide them. The
applied inputs are known up to the first forecast step without a measurement (the
node's windows bridge gaps up to its ``max_gap`` only): a window is scored at the steps
before it, the later ones are missing (and the window is counted ``windows_gapped``),
since a held value in the gap would be an assumption again.

Memory is bounded by the delay: the measurements of ``delay`` seconds and one window
per ``forecast_period`` within it. Times in s of message time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
import math
from typing import Any

import numpy as np

from hybrid_predictor.skill import LiveSkill, period_passed


@dataclass(frozen=True)
class Row:
    """One measured sample, as the skill tracker takes it."""

    t: float
    states: np.ndarray
    x: float
    y: float
    controls: np.ndarray


@dataclass(frozen=True)
class Remade:
    """A forecast re-made with the applied inputs, as ``LiveSkill.add_forecast`` takes it."""

    states: np.ndarray              # (H, n)
    x: np.ndarray                   # (H,)
    y: np.ndarray
    band_levels: tuple = ()
    band_lower: np.ndarray | None = None    # (L, H, n)
    band_upper: np.ndarray | None = None
    band_radius: np.ndarray | None = None   # (L, H)
    band_note: str = ''


def applied_future(applied: np.ndarray, horizon: int) -> np.ndarray:
    """Return the future controls (1, horizon, m): ``applied`` (K, m), then its last row held."""
    pad = np.repeat(applied[-1:], horizon - len(applied), axis=0)
    return np.concatenate([applied, pad])[None]


class Hindsight:
    """Feed a skill tracker late, with each kept window's forecast re-made in hindsight."""

    def __init__(self, skill: LiveSkill, remake: Callable[[Any, np.ndarray], Remade]):
        """
        Feed ``skill``; keep a window per its ``forecast_period`` (s) for ``remake``.

        ``remake(window, applied)`` returns the forecast from ``window`` (whatever the
        caller keeps) under ``applied`` (K, m), the measured controls at steps 1..K (K is
        the longest scored step S, or less before a gap), at least K steps of it.
        """
        self.skill = skill
        self.remake = remake
        self.dt = skill.dt
        self.steps = int(skill.steps.max())
        self.delay = self.steps * self.dt
        self.rows: deque[Row] = deque()
        self.windows: deque[tuple[float, Any]] = deque()
        self.last_kept: float | None = None
        self.counts = {'windows_kept': 0, 'windows_remade': 0, 'windows_gapped': 0}

    def reset(self) -> None:
        """Forget every window and measurement, and the tracker's state (a restart)."""
        self.rows.clear()
        self.windows.clear()
        self.last_kept = None
        self.skill.reset()

    def wants(self, stamp: float) -> bool:
        """Tell whether a window ending at ``stamp`` (s) would be kept."""
        return period_passed(self.last_kept, stamp, self.skill.settings.forecast_period)

    def keep(self, stamp: float, window: Any) -> bool:
        """Keep ``window`` (its newest sample at ``stamp``) if one period passed; say if kept."""
        if not self.wants(stamp):
            return False
        if self.last_kept is not None and stamp < self.last_kept:
            self.reset()   # the time line went back
        self.windows.append((stamp, window))
        self.last_kept = stamp
        self.counts['windows_kept'] += 1
        return True

    @property
    def newest(self) -> float | None:
        """Return the newest measurement's time (s), or None."""
        return self.rows[-1].t if self.rows else None

    def add_measurement(self, t: float, states, x: float, y: float, controls) -> None:
        """Take one measured sample at ``t`` (s); feed the tracker what is now ``delay`` old."""
        if self.rows and t < self.rows[-1].t - 0.5 * self.dt:
            self.reset()   # the source restarted
        self.rows.append(Row(float(t), np.asarray(states, np.float64), float(x), float(y),
                             np.asarray(controls, np.float64)))
        self._release(t - self.delay - 0.5 * self.dt)

    def _release(self, until: float) -> None:
        while True:
            row_t = self.rows[0].t if self.rows else math.inf
            window_t = self.windows[0][0] if self.windows else math.inf
            if min(row_t, window_t) > until:
                return
            if row_t <= window_t:
                row = self.rows.popleft()
                self.skill.add_measurement(row.t, row.states, row.x, row.y)
            else:
                self._remake(*self.windows.popleft())

    def _remake(self, stamp: float, window: Any) -> None:
        applied = self._applied(stamp)
        known = len(applied)
        if known < self.steps:
            self.counts['windows_gapped'] += 1
        if known < self.skill.steps.min():
            return
        f = self.remake(window, applied)
        cut = slice(0, known)   # the steps whose inputs were all measured
        levels = len(f.band_levels)
        self.skill.add_forecast(
            stamp, f.states[cut], f.x[cut], f.y[cut], f.band_levels,
            f.band_lower[:, cut] if levels else None, f.band_upper[:, cut] if levels else None,
            f.band_radius[:, cut] if levels else None, f.band_note)
        self.counts['windows_remade'] += 1

    def _applied(self, stamp: float) -> np.ndarray:
        """Return the measured controls at steps 1, 2, ... after ``stamp``, up to a gap."""
        times = np.fromiter((r.t for r in self.rows), float, len(self.rows))
        wanted = stamp + self.dt * np.arange(1, self.steps + 1)
        half = 0.5 * self.dt
        index = np.searchsorted(times, wanted - half)   # the first sample not too early
        found = index < len(times)
        found[found] = times[index[found]] <= wanted[found] + half
        known = int(np.argmin(found)) if not found.all() else len(found)
        return np.stack([self.rows[int(i)].controls for i in index[:known]]) if known \
            else np.zeros((0, 0))
