"""
Assemble the model's initialization window from asynchronous inputs (no ROS).

Three streams arrive at their own rates: the vessel state (from odometry), the
actuators and the wind. Each sample is checked on arrival: non-finite values,
duplicates (same stamp as the last) and out-of-order stamps are rejected and counted,
so they never reach the model. On request the window is built on the model's grid,
``window`` samples ``dt`` apart ending at the newest state sample: states are
interpolated linearly (heading unwrapped), actuators and wind are held (zero-order
hold), as in the datasets the model was trained on. A window is only handed out when
every grid point is covered without gaps longer than ``max_gap`` and the newest state
is at most ``max_age`` old; otherwise the result says why.

Times are in seconds on the clock of the message stamps.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
import math

import numpy as np

STATE_CHANNELS = ('u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y')
ACTUATOR_CHANNELS = ('n', 'delta_port', 'delta_stbd')
WIND_CHANNELS = ('wind_speed', 'wind_dir_cos', 'wind_dir_sin')
MODEL_STATE = ('u', 'v', 'p', 'r', 'phi')
MODEL_CONTROL = ACTUATOR_CHANNELS + WIND_CHANNELS


def wrap_angle(angle: float) -> float:
    """Wrap an angle to (-pi, pi] (rad)."""
    return math.pi - (math.pi - angle) % (2.0 * math.pi)


@dataclass
class StreamCounts:
    """What happened to the samples offered to one stream."""

    accepted: int = 0
    non_finite: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    incomplete: int = 0

    @property
    def rejected(self) -> int:
        """Return the number of rejected samples."""
        return self.non_finite + self.duplicate + self.out_of_order + self.incomplete


@dataclass
class Stream:
    """Time-ordered samples of named channels, pruned to the span a window needs."""

    name: str
    channels: tuple[str, ...]
    hold: bool
    keep_s: float
    unwrap: str | None = None
    counts: StreamCounts = field(default_factory=StreamCounts)
    _times: deque = field(default_factory=deque)
    _values: deque = field(default_factory=deque)

    @property
    def latest_time(self) -> float | None:
        """Return the stamp of the newest accepted sample, or None."""
        return self._times[-1] if self._times else None

    def push(self, t: float, values: dict[str, float]) -> str | None:
        """Offer a sample at time ``t`` (s); return why it was rejected, or None."""
        if self._values:
            last = dict(zip(self.channels, self._values[-1], strict=True))
            values = {**last, **values}  # a partial sample completes from the last one
        missing = [c for c in self.channels if c not in values]
        if missing:
            self.counts.incomplete += 1
            return f'{self.name}: first sample lacks {missing}'
        row = [float(values[c]) for c in self.channels]
        if not math.isfinite(t) or not all(math.isfinite(v) for v in row):
            self.counts.non_finite += 1
            return f'{self.name}: non-finite value at t={t}'
        if self._times and t <= self._times[-1]:
            if t == self._times[-1]:
                self.counts.duplicate += 1
                return f'{self.name}: duplicate stamp t={t}'
            self.counts.out_of_order += 1
            return f'{self.name}: stamp t={t} older than the last ({self._times[-1]})'
        if self.unwrap is not None and self._values:
            i = self.channels.index(self.unwrap)
            previous = self._values[-1][i]
            row[i] = previous + wrap_angle(row[i] - previous)
        self._times.append(t)
        self._values.append(row)
        self.counts.accepted += 1
        while len(self._times) > 2 and self._times[1] < t - self.keep_s:
            self._times.popleft()
            self._values.popleft()
        return None

    def clear(self) -> None:
        """Forget every sample (counts are kept)."""
        self._times.clear()
        self._values.clear()

    def sample(self, grid: np.ndarray, max_gap: float) -> tuple[np.ndarray | None, str, int]:
        """
        Return (values on ``grid`` (len, channels), reason, covered points).

        Values are None when some grid point is not covered; ``reason`` then says why
        and ``covered`` counts the points that were.
        """
        if not self._times:
            return None, f'no {self.name} received', 0
        times = np.fromiter(self._times, float, len(self._times))
        values = np.asarray(self._values, dtype=float)
        if self.hold:
            index = np.searchsorted(times, grid, side='right') - 1
            ok = index >= 0
            age = np.where(ok, grid - times[np.maximum(index, 0)], np.inf)
            ok &= age <= max_gap
            if ok.all():
                return values[index], '', len(grid)
            worst = float(np.max(age))
            reason = (f'{self.name} silent for {worst:.1f} s (max gap {max_gap:g} s)'
                      if math.isfinite(worst) else f'{self.name} does not reach back '
                      f'{grid[-1] - grid[0]:.0f} s yet')
            return None, reason, int(ok.sum())
        before = np.searchsorted(times, grid, side='right') - 1   # last sample <= g
        after = np.searchsorted(times, grid, side='left')         # first sample >= g
        inside = (before >= 0) & (after < len(times))
        gap = np.full(len(grid), np.inf)
        gap[inside] = times[after[inside]] - times[before[inside]]
        ok = gap <= max_gap
        if not ok.all():
            if not inside[0]:
                reason = (f'{self.name} does not reach back {grid[-1] - grid[0]:.0f} s yet '
                          f'(oldest sample {grid[-1] - times[0]:.1f} s before the newest)')
            else:
                reason = (f'{self.name} gap of {float(np.max(gap[inside])):.1f} s '
                          f'(max gap {max_gap:g} s)')
            return None, reason, int(ok.sum())
        out = np.empty((len(grid), len(self.channels)))
        for j in range(len(self.channels)):
            out[:, j] = np.interp(grid, times, values[:, j])
        return out, '', len(grid)


@dataclass(frozen=True)
class Window:
    """The outcome of assembling a window; arrays only when ``ready``."""

    ready: bool
    status: str            # 'ok', 'incomplete' or 'stale'
    reason: str
    fill: float            # fraction of grid points every stream covers
    t_end: float | None    # stamp of the newest window sample (s)
    age: float | None      # now - t_end (s)
    states: np.ndarray | None = None     # (window, 5) MODEL_STATE
    controls: np.ndarray | None = None   # (window, 6) MODEL_CONTROL
    pose: tuple[float, float, float] | None = None  # x, y (m, NED), psi (rad) at t_end


class InputWindow:
    """Collects the three input streams and builds the model's window on demand."""

    def __init__(self, window: int, dt: float, max_gap: float, max_age: float):
        if window < 2 or dt <= 0 or max_gap <= 0 or max_age <= 0:
            raise ValueError(f'need window >= 2 and positive dt, max_gap, max_age; got '
                             f'{window}, {dt}, {max_gap}, {max_age}')
        self.window, self.dt, self.max_gap, self.max_age = window, dt, max_gap, max_age
        keep = (window + 1) * dt + max_gap
        self.streams = {
            'state': Stream('state', STATE_CHANNELS, hold=False, keep_s=keep, unwrap='psi'),
            'actuators': Stream('actuators', ACTUATOR_CHANNELS, hold=True, keep_s=keep),
            'wind': Stream('wind', WIND_CHANNELS, hold=True, keep_s=keep),
        }

    def push(self, stream: str, t: float, values: dict[str, float]) -> str | None:
        """Offer a sample to ``stream`` ('state', 'actuators', 'wind'); None if accepted."""
        return self.streams[stream].push(t, values)

    def clear(self) -> None:
        """Forget all samples, e.g. after the clock jumped back."""
        for stream in self.streams.values():
            stream.clear()

    def assemble(self, now: float) -> Window:
        """Build the window ending at the newest state sample, or say why it cannot."""
        t_end = self.streams['state'].latest_time
        if t_end is None:
            return Window(False, 'incomplete', 'no state received', 0.0, None, None)
        age = now - t_end
        grid = t_end - self.dt * np.arange(self.window - 1, -1, -1, dtype=float)
        parts, reasons, covered = {}, [], []
        for name, stream in self.streams.items():
            values, reason, count = stream.sample(grid, self.max_gap)
            parts[name] = values
            covered.append(count)
            if reason:
                reasons.append(reason)
        fill = min(covered) / self.window
        if reasons:
            return Window(False, 'incomplete', '; '.join(reasons), fill, t_end, age)
        if age > self.max_age:
            return Window(False, 'stale', f'newest state is {age:.1f} s old (max '
                          f'{self.max_age:g} s)', fill, t_end, age)
        state = parts['state']
        states = state[:, [STATE_CHANNELS.index(c) for c in MODEL_STATE]]
        controls = np.concatenate([parts['actuators'], parts['wind']], axis=1)
        last = state[-1]
        pose = (float(last[STATE_CHANNELS.index('x')]), float(last[STATE_CHANNELS.index('y')]),
                float(last[STATE_CHANNELS.index('psi')]))
        return Window(True, 'ok', '', fill, t_end, age, states, controls, pose)
