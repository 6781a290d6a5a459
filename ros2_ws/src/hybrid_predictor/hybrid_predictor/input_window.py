"""
Assemble the model's initialization window from asynchronous inputs (no ROS).

Every topic of the vessel's topic map (vessel_description, ``recordings.topics``) is a
stream of named channels read from its messages, in the messages' own frames and
units after the map's scale. Each sample is checked on arrival: non-finite values,
duplicates (same stamp as the last) and out-of-order stamps are rejected and counted,
so they never reach the model. On request the window is built on the model's grid,
``window`` samples ``dt`` apart ending at the newest sample of the state topic (the
one giving surge): the streams go through the same preprocessing as offline
conversion -- ``vessel_datasets.quantities.derive`` (orientation to heading and roll,
heading unwrapped), ``vessel_datasets.resample.sample`` (states linear, actuators and
wind held) and ``to_columns`` (frames, units, the vessel's vector order) -- so the
model sees what it was trained on. A window is only handed out when every grid point
is covered without gaps longer than ``max_gap`` and the newest state is at most
``max_age`` old; otherwise the result says why.

Times are in seconds on the clock of the message stamps.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
import math

import numpy as np

from vessel_datasets.extract import TopicSamples
from vessel_datasets.fields import compile_getter
from vessel_datasets.quantities import channel_methods, derive, to_columns
from vessel_datasets.resample import sample
from vessel_datasets.topic_map import TopicMap

POSE = ('x', 'y', 'psi')
STATE_ENTRY = 'surge'  # its topic's newest sample ends the window


def channel_reader(topic_map: TopicMap, topic: str):
    """
    Return a function reading a topic's channel values from one of its messages.

    It takes any message object with the mapped fields (rclpy or rosbags) and returns
    ``{channel: scale * field + offset}``. An element a message does not carry (a joint
    it does not name) is left out, so the stream completes it from its last sample; a
    message carrying none of the topic's channels raises ValueError.
    """
    leaves = [leaf for leaf in topic_map.leaves() if leaf.topic == topic]
    reads = [(leaf.channel, compile_getter(leaf.path, absent=None), leaf.scale, leaf.offset)
             for leaf in leaves]
    fields = ', '.join(leaf.path for leaf in leaves)

    def read(msg) -> dict[str, float]:
        out = {}
        for channel, get, scale, offset in reads:
            value = get(msg)
            if value is not None:
                out[channel] = scale * float(value) + offset
        if not out:
            raise ValueError(f'carries none of the mapped fields ({fields})')
        return out

    return read


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
    """Time-ordered samples of one topic's channels, pruned to the span a window needs."""

    name: str
    channels: tuple[str, ...]
    hold: bool            # every channel is held (actuators, wind): no interpolation
    keep_s: float
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

    def arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Return the buffered times (s) and values (n, channels)."""
        times = np.fromiter(self._times, float, len(self._times))
        return times, np.asarray(self._values, dtype=float).reshape(len(times), -1)

    def coverage(self, grid: np.ndarray, max_gap: float) -> tuple[str, int]:
        """
        Return (why ``grid`` is not covered or '', covered points).

        A held stream covers a grid point with a sample at most ``max_gap`` before it;
        an interpolated one with samples on both sides at most ``max_gap`` apart.
        """
        if not self._times:
            return f'no {self.name} received', 0
        times, _ = self.arrays()
        if self.hold:
            index = np.searchsorted(times, grid, side='right') - 1
            ok = index >= 0
            age = np.where(ok, grid - times[np.maximum(index, 0)], np.inf)
            ok &= age <= max_gap
            if ok.all():
                return '', len(grid)
            worst = float(np.max(age))
            reason = (f'{self.name} silent for {worst:.1f} s (max gap {max_gap:g} s)'
                      if math.isfinite(worst) else f'{self.name} does not reach back '
                      f'{grid[-1] - grid[0]:.0f} s yet')
            return reason, int(ok.sum())
        before = np.searchsorted(times, grid, side='right') - 1   # last sample <= g
        after = np.searchsorted(times, grid, side='left')         # first sample >= g
        inside = (before >= 0) & (after < len(times))
        gap = np.full(len(grid), np.inf)
        gap[inside] = times[after[inside]] - times[before[inside]]
        ok = gap <= max_gap
        if ok.all():
            return '', len(grid)
        if not inside[0]:
            return (f'{self.name} does not reach back {grid[-1] - grid[0]:.0f} s yet '
                    f'(oldest sample {grid[-1] - times[0]:.1f} s before the newest)',
                    int(ok.sum()))
        return (f'{self.name} gap of {float(np.max(gap[inside])):.1f} s (max gap '
                f'{max_gap:g} s)', int(ok.sum()))


@dataclass(frozen=True)
class Window:
    """The outcome of assembling a window; arrays only when ``ready``."""

    ready: bool
    status: str            # 'ok', 'incomplete' or 'stale'
    reason: str
    fill: float            # fraction of grid points every stream covers
    t_end: float | None    # stamp of the newest window sample (s)
    age: float | None      # now - t_end (s)
    states: np.ndarray | None = None     # (window, n_state) in the vessel's state order
    controls: np.ndarray | None = None   # (window, n_control) in its control order
    pose: tuple[float, float, float] | None = None  # x, y (m, NED), psi (rad) at t_end


class InputWindow:
    """Collects one stream per topic of a vessel's topic map; builds windows on demand."""

    def __init__(self, topic_map: TopicMap, window: int, dt: float, max_gap: float,
                 max_age: float):
        if window < 2 or dt <= 0 or max_gap <= 0 or max_age <= 0:
            raise ValueError(f'need window >= 2 and positive dt, max_gap, max_age; got '
                             f'{window}, {dt}, {max_gap}, {max_age}')
        self.topic_map, self.vessel = topic_map, topic_map.vessel
        self.window, self.dt, self.max_gap, self.max_age = window, dt, max_gap, max_age
        keep = (window + 1) * dt + max_gap
        self.methods = channel_methods(topic_map)
        leaves: dict[str, list[str]] = {}
        for leaf in topic_map.leaves():
            leaves.setdefault(leaf.topic, []).append(leaf.channel)
        self.streams = {
            topic: Stream(topic, tuple(channels),
                          all(self.methods[c] == 'hold' for c in channels), keep)
            for topic, channels in leaves.items()}
        self.state_topic = next(e.topic for e in topic_map.entries if e.name == STATE_ENTRY)

    def push(self, stream: str, t: float, values: dict[str, float]) -> str | None:
        """Offer a sample of channel values to a topic's stream; None if accepted."""
        return self.streams[stream].push(t, values)

    def clear(self) -> None:
        """Forget all samples, e.g. after the clock jumped back."""
        for stream in self.streams.values():
            stream.clear()

    def assemble(self, now: float) -> Window:
        """Build the window ending at the newest state sample, or say why it cannot."""
        t_end = self.streams[self.state_topic].latest_time
        if t_end is None:
            return Window(False, 'incomplete', f'no {self.state_topic} received', 0.0, None,
                          None)
        age = now - t_end
        grid = t_end - self.dt * np.arange(self.window - 1, -1, -1, dtype=float)
        reasons, covered = [], []
        for stream in self.streams.values():
            reason, count = stream.coverage(grid, self.max_gap)
            covered.append(count)
            if reason:
                reasons.append(reason)
        fill = min(covered) / self.window
        if reasons:
            return Window(False, 'incomplete', '; '.join(reasons), fill, t_end, age)
        if age > self.max_age:
            return Window(False, 'stale', f'newest state is {age:.1f} s old (max '
                          f'{self.max_age:g} s)', fill, t_end, age)
        columns = self._columns(grid)
        states = np.column_stack([columns[c] for c in self.vessel.state_names])
        controls = np.column_stack([columns[c] for c in self.vessel.control_names])
        pose = tuple(float(columns[c][-1]) for c in POSE)
        return Window(True, 'ok', '', fill, t_end, age, states, controls, pose)

    def _columns(self, grid: np.ndarray) -> dict[str, np.ndarray]:
        """Return the vessel's columns on ``grid``, through the offline preprocessing."""
        grid_ns = np.round(grid * 1e9).astype(np.int64)
        channels: dict[str, np.ndarray] = {}
        for topic, stream in self.streams.items():
            times, values = stream.arrays()
            raw = TopicSamples(topic, '', stream.channels, np.round(times * 1e9).astype(
                np.int64), values)
            s = derive(raw, self.topic_map)
            on_grid = sample(s.t_ns, s.values, grid_ns, [self.methods[c] for c in s.channels])
            channels.update({c: on_grid[:, i] for i, c in enumerate(s.channels)})
        return to_columns(channels, self.topic_map, relative=False)
