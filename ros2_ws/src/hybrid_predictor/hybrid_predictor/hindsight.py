"""
The model judged in hindsight: forecasts re-made with the inputs the vessel then applied (no ROS).

A published forecast assumes future controls and wind: a plan, or the latest ones held.
Its error then mixes two things, the model's and the assumption's, and the calibrated
bands (``hybrid_models.bands``) promise their coverage only for the first: through the
nodes, held-input forecasts on a passage left their band often enough to raise the
departure WARN on a vessel that matched its model exactly (32 reports in 1.5 h,
``offline/bench.py departure``). Whether the vessel departs from its model is a question
about the model alone, so it is asked of forecasts made from the same window and the
inputs that were measured meanwhile.

A forecast's step k depends on the inputs of steps 1..k only, so each scored step is
judged as soon as it matures: ``Hindsight`` keeps one window per the tracker's
``forecast_period`` of message time and the measured samples since; when the measurement
at a kept window's scored step k arrives, it re-makes the forecast from the window by
``remake(window, applied)`` with the inputs measured at steps 1..k, gives the tracker
(``skill.LiveSkill``) that step, and then the measurement that scores it. The tracker
sees one time line, in order, as the measurements come: a step 225 s ahead is judged
225 s after its window, not one horizon after. The applied inputs are known up to the
first forecast step without a measurement (the node's windows bridge gaps up to its
``max_gap`` only): a window is scored at the steps before it, the later ones are
missing (and the window is counted ``windows_gapped``), since a held value in the gap
would be an assumption again.

Memory is bounded by the longest scored step (``delay``): the measurements of ``delay``
seconds and one window per ``forecast_period`` within it. Times in s of message time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
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
    """Feed a skill tracker each kept window's scored steps, re-made as they mature."""

    def __init__(self, skill: LiveSkill, remake: Callable[[Any, np.ndarray], Remade]):
        """
        Feed ``skill``; keep a window per its ``forecast_period`` (s) for ``remake``.

        ``remake(window, applied)`` returns the forecast from ``window`` (whatever the
        caller keeps) under ``applied`` (K, m), the measured controls at steps 1..K (K is
        the scored step that matures now), at least K steps of it.
        """
        self.skill = skill
        self.remake = remake
        self.dt = skill.dt
        self.scored = [int(k) for k in skill.steps]
        self.delay = self.scored[-1] * self.dt    # how far back the inputs of a window reach
        self.rows: deque[Row] = deque()
        self.windows: deque[list] = deque()   # [stamp, window, index of its next step]
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
        self.windows.append([stamp, window, 0])
        self.last_kept = stamp
        self.counts['windows_kept'] += 1
        return True

    @property
    def newest(self) -> float | None:
        """Return the newest measurement's time (s), or None."""
        return self.rows[-1].t if self.rows else None

    def add_measurement(self, t: float, states, x: float, y: float, controls) -> None:
        """Take one measured sample at ``t`` (s): score the steps it matures, then it."""
        if self.rows and t < self.rows[-1].t - 0.5 * self.dt:
            self.reset()   # the source restarted
        self.rows.append(Row(float(t), np.asarray(states, np.float64), float(x), float(y),
                             np.asarray(controls, np.float64)))
        half = 0.5 * self.dt
        while self.rows[0].t < t - self.delay - half:
            self.rows.popleft()   # no kept window's steps reach back that far
        for entry in self.windows:
            stamp, window, i = entry
            if i < len(self.scored) and stamp + self.scored[i] * self.dt <= t + half:
                entry[2] = self._remake(stamp, window, i)
        while self.windows and self.windows[0][2] >= len(self.scored):
            self.windows.popleft()
        self.skill.add_measurement(t, self.rows[-1].states, x, y)

    def _remake(self, stamp: float, window: Any, i: int) -> int:
        """Give the tracker scored step ``i`` of the window; return the next step's index."""
        step = self.scored[i]
        applied = self._applied(stamp, step)
        if len(applied) < step:   # a gap in the inputs: no later step can be scored
            self.counts['windows_gapped'] += 1
            return len(self.scored)
        f = self.remake(window, applied)
        levels = len(f.band_levels)
        self.skill.add_forecast(
            stamp, f.states[:step], f.x[:step], f.y[:step], f.band_levels,
            f.band_lower[:, :step] if levels else None,
            f.band_upper[:, :step] if levels else None,
            f.band_radius[:, :step] if levels else None, f.band_note, step=step)
        if i == 0:
            self.counts['windows_remade'] += 1
        return i + 1

    def _applied(self, stamp: float, steps: int) -> np.ndarray:
        """Return the measured controls at steps 1 .. ``steps`` after ``stamp``, up to a gap."""
        times = np.fromiter((r.t for r in self.rows), float, len(self.rows))
        wanted = stamp + self.dt * np.arange(1, steps + 1)
        half = 0.5 * self.dt
        index = np.searchsorted(times, wanted - half)   # the first sample not too early
        found = index < len(times)
        found[found] = times[index[found]] <= wanted[found] + half
        known = int(np.argmin(found)) if not found.all() else len(found)
        return np.stack([self.rows[int(i)].controls for i in index[:known]]) if known \
            else np.zeros((0, 0))
