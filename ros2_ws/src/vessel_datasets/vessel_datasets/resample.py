"""
Put irregular topic samples on one fixed-rate grid, split into runs at gaps.

Each topic covers the time between its first and last sample except where two
consecutive samples are more than ``max_gap`` apart (a gap). A run is a stretch that
every topic covers; its grid points are the multiples of the sample period inside it,
so runs from different bags share one clock grid. States are interpolated linearly,
commands held from their last sample at or before the grid point (zero-order hold).
All times are integer nanoseconds; floats are used only relative to a run's start.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

METHODS = ('linear', 'hold')


@dataclass(frozen=True)
class Gap:
    """Two consecutive samples of a topic too far apart to interpolate between."""

    topic: str
    start_ns: int
    end_ns: int

    @property
    def duration_s(self) -> float:
        """Length of the gap (s)."""
        return (self.end_ns - self.start_ns) / 1e9


@dataclass(frozen=True)
class RunSpan:
    """A stretch covered by every topic and the grid points inside it."""

    start_ns: int
    end_ns: int
    grid_ns: np.ndarray

    @property
    def duration_s(self) -> float:
        """Time from the first to the last grid point (s)."""
        return (int(self.grid_ns[-1]) - int(self.grid_ns[0])) / 1e9 if len(self.grid_ns) else 0.0


def period_ns(rate_hz: float) -> int:
    """Sample period in integer nanoseconds for a rate in Hz."""
    if not rate_hz > 0:
        raise ValueError(f'rate must be positive, got {rate_hz} Hz')
    return int(round(1e9 / rate_hz))


def find_gaps(topic: str, t_ns: np.ndarray, max_gap_ns: int) -> list[Gap]:
    """Gaps of one topic's strictly increasing sample times."""
    idx = np.nonzero(np.diff(t_ns) > max_gap_ns)[0]
    return [Gap(topic, int(t_ns[i]), int(t_ns[i + 1])) for i in idx]


def coverage(t_ns: np.ndarray, max_gap_ns: int) -> list[tuple[int, int]]:
    """Intervals [start, end] (ns) a topic covers without gaps."""
    if not len(t_ns):
        return []
    idx = np.nonzero(np.diff(t_ns) > max_gap_ns)[0]
    starts = [int(t_ns[0])] + [int(t_ns[i + 1]) for i in idx]
    ends = [int(t_ns[i]) for i in idx] + [int(t_ns[-1])]
    return list(zip(starts, ends, strict=True))


def intersect(a: Sequence[tuple[int, int]], b: Sequence[tuple[int, int]]
              ) -> list[tuple[int, int]]:
    """Intersection of two sorted lists of disjoint closed intervals."""
    out = []
    i = j = 0
    while i < len(a) and j < len(b):
        lo, hi = max(a[i][0], b[j][0]), min(a[i][1], b[j][1])
        if lo <= hi:
            out.append((lo, hi))
        if a[i][1] < b[j][1]:
            i += 1
        else:
            j += 1
    return out


def aligned_grid(start_ns: int, end_ns: int, dt_ns: int) -> np.ndarray:
    """Multiples of ``dt_ns`` inside [start, end] (ns)."""
    first = -(-start_ns // dt_ns) * dt_ns
    if first > end_ns:
        return np.empty(0, dtype=np.int64)
    return np.arange(first, end_ns + 1, dt_ns, dtype=np.int64)


def plan_runs(times: Mapping[str, np.ndarray], max_gap_ns: Mapping[str, int], dt_ns: int,
              min_samples: int) -> tuple[list[RunSpan], list[RunSpan], list[Gap]]:
    """
    Find the runs every topic covers, the runs too short to keep and every gap.

    ``times`` maps each topic to its sample times; ``min_samples`` is the fewest grid
    points a run needs (at least 2).
    """
    gaps = [g for topic, t in times.items() for g in find_gaps(topic, t, max_gap_ns[topic])]
    spans: list[tuple[int, int]] | None = None
    for topic, t in times.items():
        cov = coverage(t, max_gap_ns[topic])
        spans = cov if spans is None else intersect(spans, cov)
    kept, short = [], []
    for start, end in spans or []:
        run = RunSpan(start, end, aligned_grid(start, end, dt_ns))
        (kept if len(run.grid_ns) >= max(2, min_samples) else short).append(run)
    return kept, short, sorted(gaps, key=lambda g: (g.start_ns, g.topic))


def sample(t_ns: np.ndarray, values: np.ndarray, grid_ns: np.ndarray,
           methods: Sequence[str]) -> np.ndarray:
    """
    Values of each column at the grid points, by 'linear' or 'hold' per column.

    The grid must lie inside the covered span of ``t_ns`` (as ``plan_runs`` makes it).
    """
    lo = max(int(np.searchsorted(t_ns, grid_ns[0], side='right')) - 1, 0)
    hi = int(np.searchsorted(t_ns, grid_ns[-1], side='left')) + 1
    t, v = t_ns[lo:hi], values[lo:hi]
    ref = grid_ns[0]
    tf = (t - ref).astype(np.float64)
    gf = (grid_ns - ref).astype(np.float64)
    held = np.clip(np.searchsorted(t, grid_ns, side='right') - 1, 0, len(t) - 1)
    out = np.empty((len(grid_ns), values.shape[1]))
    for k, method in enumerate(methods):
        if method == 'linear':
            out[:, k] = np.interp(gf, tf, v[:, k])
        elif method == 'hold':
            out[:, k] = v[held, k]
        else:
            raise ValueError(f'unknown resampling method {method!r}; use one of {METHODS}')
    return out
