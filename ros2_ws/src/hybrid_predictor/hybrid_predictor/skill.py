"""
Live skill of the published forecasts, and whether the vessel departs from its model (no ROS).

Each kept forecast (one per ``Settings.forecast_period`` of message time) waits until
its scored steps mature: the measured sample stamped nearest a step's time (the
forecast's stamp plus ``step`` step periods, within half a period; a missing sample
leaves that step unscored) gives the step's error per state and its position error,
the distance (m) between the forecast track and the measured position. Forecasts and
measurements are given in one convention (the published one: states FLU, track ENU);
errors and coverage do not depend on which.

The calibrated bands promise their coverage only for forecasts whose assumed controls
the vessel then applied (``hybrid_models.bands``): the node gives this tracker forecasts
re-made with the inputs measured over their horizon (``hindsight``), not the ones it
published, which assumed a plan or held the latest inputs.

Scored steps enter a rolling window of ``window`` seconds per step. Per scored step and
quantity (each state, and ``position``) the summary gives the count, the RMSE and the
fraction of measurements inside each band level. The departure detector watches the
judged level (``level``, 0.9): a (quantity, step) whose coverage, over at least
``min_samples`` measurements, stays below ``warn_coverage`` for ``sustain`` seconds is
raised; it clears once its coverage reaches ``clear_coverage`` again (or its window
empties). Forecasts without bands (``band_levels`` empty) are scored but never judged.

Memory is bounded: at most one pending forecast per ``forecast_period`` over the longest
scored step, and one entry per kept forecast and scored step in the window. Times in s
of message time.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
import math

import numpy as np

POSITION = 'position'


@dataclass(frozen=True)
class Settings:
    """The skill tracker's parameters (the node's ``skill_*`` parameters)."""

    forecast_period: float    # s of message time between forecasts kept for scoring
    window: float             # s of message time the rolling summary covers
    min_samples: int          # scored measurements a (quantity, step) needs to be judged
    warn_coverage: float      # judged band coverage below which a (quantity, step) is low
    clear_coverage: float     # coverage at which a raised (quantity, step) clears
    sustain: float            # s a (quantity, step) must stay low before it is raised
    level: float = 0.9        # band level judged

    def __post_init__(self):
        if self.forecast_period <= 0 or self.window <= 0 or self.sustain < 0:
            raise ValueError('skill: forecast_period and window must be positive and '
                             f'sustain non-negative, got {self.forecast_period}, '
                             f'{self.window}, {self.sustain}')
        if not 0.0 <= self.warn_coverage <= self.clear_coverage <= 1.0:
            raise ValueError(f'skill: need 0 <= warn_coverage ({self.warn_coverage}) <= '
                             f'clear_coverage ({self.clear_coverage}) <= 1')


def period_passed(last: float | None, stamp: float, period: float) -> bool:
    """Tell whether ``stamp`` (s) is a ``period`` after ``last`` (or the time line went back)."""
    return last is None or not 0.0 <= stamp - last < period


@dataclass
class _Pending:
    """A kept forecast at its scored steps, waiting for them to mature."""

    t0: float                 # its stamp (s)
    times: np.ndarray         # (S,) when each scored step matures (s)
    states: np.ndarray        # (S, n) forecast states at the scored steps
    xy: np.ndarray            # (S, 2) forecast position (m)
    lower: np.ndarray | None  # (L, S, n) band edges, None without bands
    upper: np.ndarray | None
    radius: np.ndarray | None  # (L, S) position radius (m)
    scored: np.ndarray        # (S,) bool


@dataclass
class _Scores:
    """Rolling scores of one scored step: one row per matured forecast."""

    times: deque = field(default_factory=deque)     # s
    errors: deque = field(default_factory=deque)    # (n + 1,) state errors, position (m)
    inside: deque = field(default_factory=deque)    # (L, n + 1) 1 in, 0 out, NaN unknown;
    #                                                 None without bands

    def coverage(self, level_index: int) -> tuple[np.ndarray, np.ndarray]:
        """Return (count, fraction inside) per quantity at a band level (NaN if none)."""
        banded = [b[level_index] for b in self.inside if b is not None]
        if not banded:
            return np.zeros(0), np.zeros(0)
        inside = np.array(banded)
        count = np.isfinite(inside).sum(axis=0)
        with np.errstate(invalid='ignore'):
            return count, np.nansum(inside, axis=0) / count

    def drop_until(self, t: float) -> None:
        """Forget scores at or before ``t`` (s)."""
        while self.times and self.times[0] <= t:
            self.times.popleft()
            self.errors.popleft()
            self.inside.popleft()


@dataclass(frozen=True)
class Departure:
    """The detector's verdict: which (quantity, step) stay outside the band, since when."""

    affected: tuple[tuple[str, int, float], ...]   # (quantity, step, coverage)
    since: float | None                            # s, when the first was raised
    judged: bool                                   # False: no bands, nothing judged
    note: str = ''

    @property
    def active(self) -> bool:
        """Tell whether the vessel is judged to depart from its model."""
        return bool(self.affected)


class LiveSkill:
    """Score kept forecasts as they mature; keep a rolling summary; detect departure."""

    def __init__(self, state_names, steps, settings: Settings, step_period: float):
        """Track forecasts of ``state_names`` at ``steps`` (1: the first), step_period s apart."""
        self.names = (*state_names, POSITION)
        self.steps = np.array(sorted(set(int(s) for s in steps)), dtype=np.int64)
        if len(self.steps) == 0 or self.steps[0] < 1:
            raise ValueError(f'skill: scored steps must be >= 1, got {list(steps)}')
        self.settings = settings
        self.dt = float(step_period)
        self.pending: deque[_Pending] = deque()
        self.scores = {int(s): _Scores() for s in self.steps}
        self.levels: tuple[float, ...] = ()
        self.band_note = 'no forecast yet'
        self.last_kept: float | None = None
        self.newest: float | None = None
        self.low_since: dict[tuple[str, int], float] = {}
        self.raised: dict[tuple[str, int], float] = {}
        self.counts = {'forecasts_kept': 0, 'steps_scored': 0, 'steps_missing': 0}

    def reset(self) -> None:
        """Forget every forecast, score and verdict (a clock or source restart)."""
        self.pending.clear()
        for s in self.scores.values():
            s.drop_until(math.inf)
        self.last_kept = self.newest = None
        self.low_since.clear()
        self.raised.clear()

    # ------------------------------------------------------------------ input
    def add_forecast(self, stamp: float, states: np.ndarray, x, y, band_levels=(),
                     band_lower=None, band_upper=None, band_radius=None,
                     band_note: str = '', step: int | None = None) -> bool:
        """
        Keep a forecast for scoring if one ``forecast_period`` passed since the last one.

        ``states`` (H, n), ``x``, ``y`` (H,) at steps 1..H after ``stamp`` (s); bands as
        the Forecast carries them, reshaped: ``band_lower``/``band_upper`` (L, H, n),
        ``band_radius`` (L, H).
        ``step``: score this one scored step of the forecast only, just before it matures
        (``hindsight`` gives each step of a kept window when its inputs are known); no
        period is then required, the window was kept already.
        Returns True if kept.
        """
        if step is None:
            if not self.wants(stamp):
                return False
            if self.last_kept is not None and stamp < self.last_kept:
                self.reset()   # the time line went back: nothing pending belongs to it
        states = np.asarray(states, np.float64)
        horizon = len(states)
        steps = self.steps[self.steps <= horizon]
        if step is not None:
            steps = steps[steps == step]
        if len(steps) == 0:
            return False
        k = steps - 1
        self.levels = tuple(float(v) for v in band_levels)
        self.band_note = band_note
        banded = bool(self.levels)
        self.pending.append(_Pending(
            t0=stamp, times=stamp + steps * self.dt, states=states[k],
            xy=np.column_stack([np.asarray(x, np.float64)[k], np.asarray(y, np.float64)[k]]),
            lower=np.asarray(band_lower, np.float64)[:, k] if banded else None,
            upper=np.asarray(band_upper, np.float64)[:, k] if banded else None,
            radius=np.asarray(band_radius, np.float64)[:, k] if banded else None,
            scored=np.zeros(len(steps), bool)))
        if step is None:
            self.last_kept = stamp
        if step is None or step == self.steps[0]:
            self.counts['forecasts_kept'] += 1
        return True

    def wants(self, stamp: float) -> bool:
        """Tell whether a forecast stamped ``stamp`` (s) would be kept."""
        return period_passed(self.last_kept, stamp, self.settings.forecast_period)

    def add_measurement(self, t: float, states: np.ndarray, x: float, y: float) -> None:
        """Score the pending forecasts' steps maturing at ``t`` (s) against a measurement."""
        states = np.asarray(states, np.float64)
        half = 0.5 * self.dt
        for f in self.pending:
            if t <= f.t0:
                continue
            hit = np.flatnonzero(~f.scored & (np.abs(f.times - t) <= half))
            for i in hit:
                self._score(f, int(i), t, states, x, y)
        self.newest = t if self.newest is None else max(self.newest, t)
        while self.pending and self.pending[0].times[-1] + half < t:
            done = self.pending.popleft()
            self.counts['steps_missing'] += int((~done.scored).sum())
        self._judge(t)

    def _score(self, f: _Pending, i: int, t: float, states: np.ndarray, x: float,
               y: float) -> None:
        f.scored[i] = True
        step = int(round((f.times[i] - f.t0) / self.dt))
        position_error = math.hypot(x - f.xy[i, 0], y - f.xy[i, 1])   # NaN: no position
        errors = np.append(states - f.states[i], position_error)
        inside = None
        if f.lower is not None:
            low = np.column_stack([f.lower[:, i], np.full(len(f.radius), -np.inf)])
            high = np.column_stack([f.upper[:, i], f.radius[:, i]])
            value = np.broadcast_to(np.append(states, position_error), low.shape)
            # unknown (NaN) where the measurement or the band (beyond the calibrated
            # horizon) is missing
            known = np.isfinite(value) & ~np.isnan(low) & ~np.isnan(high)
            inside = np.where(known, (value >= low) & (value <= high), np.nan)
        scores = self.scores[step]
        scores.times.append(t)
        scores.errors.append(errors)
        scores.inside.append(inside)
        self.counts['steps_scored'] += 1

    # ------------------------------------------------------------------ output
    def _window(self, step: int, now: float) -> _Scores:
        scores = self.scores[step]
        scores.drop_until(now - self.settings.window)
        return scores

    def summary(self, now: float | None = None) -> dict:
        """
        Return the rolling summary at ``now`` (s; default: the newest measurement).

        ``{step: {quantity: {'n', 'rmse', 'coverage': {level: fraction}}}}``; ``n`` counts
        the scored measurements in the window, ``coverage`` those with bands.
        """
        now = self.newest if now is None else now
        out = {}
        for step in self.scores:
            scores = self._window(step, -math.inf if now is None else now)
            errors = np.array(scores.errors) if scores.errors else np.empty((0, len(
                self.names)))
            covers = [scores.coverage(li) for li in range(len(self.levels))]
            per = {}
            for q, name in enumerate(self.names):
                e = errors[:, q][np.isfinite(errors[:, q])]
                cover = {level: float(fraction[q]) for level, (count, fraction)
                         in zip(self.levels, covers, strict=True) if len(count) and count[q]}
                per[name] = {'n': len(e), 'rmse': float(np.sqrt(np.mean(e ** 2))) if len(e)
                             else math.nan, 'coverage': cover}
            out[int(step)] = per
        return out

    def _judge(self, now: float) -> None:
        if self.settings.level not in self.levels:
            self.low_since.clear()
            self.raised.clear()
            return
        li = self.levels.index(self.settings.level)
        s = self.settings
        for step in self.scores:
            count, cover = self._window(step, now).coverage(li)
            for q, name in enumerate(self.names):
                key = (name, step)
                c = float(cover[q]) if len(count) and count[q] >= s.min_samples else None
                if key in self.raised:
                    if c is None or c >= s.clear_coverage:
                        del self.raised[key]
                        self.low_since.pop(key, None)
                    continue
                if c is None or c >= s.warn_coverage:
                    self.low_since.pop(key, None)
                    continue
                since = self.low_since.setdefault(key, now)
                if now - since >= s.sustain:
                    self.raised[key] = since

    def departure(self) -> Departure:
        """Return the detector's current verdict."""
        if not self.levels:
            return Departure((), None, False, f'not judged: the forecasts carry no bands '
                             f'({self.band_note})')
        if self.settings.level not in self.levels:
            return Departure((), None, False, f'not judged: no {self.settings.level:g} '
                             f'band among {list(self.levels)}')
        li = self.levels.index(self.settings.level)
        affected = []
        for name, step in sorted(self.raised, key=lambda k: (self.names.index(k[0]), k[1])):
            count, cover = self.scores[step].coverage(li)
            affected.append((name, step, float(cover[self.names.index(name)])
                             if len(count) else math.nan))
        since = min(self.raised.values()) if self.raised else None
        return Departure(tuple(affected), since, True)

    def describe(self, departure: Departure) -> str:
        """Return the WARN line naming the quantities and steps affected ('' if none)."""
        if not departure.active:
            return ''
        by_name: dict[str, list[str]] = {}
        for name, step, cover in departure.affected:
            by_name.setdefault(name, []).append(f'{step * self.dt:g} s ({100 * cover:.0f} %)')
        parts = '; '.join(f'{name} at {", ".join(at)}' for name, at in by_name.items())
        return (f'the vessel departs from its model: its {100 * self.settings.level:g} % '
                f'band covers too few measurements of {parts} ahead, for '
                f'{self.newest - departure.since:.0f} s; record and run the offline '
                f'diagnosis')
