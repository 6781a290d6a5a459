"""
The one spike policy: samples a vessel cannot have, found and dropped before resampling.

A spike is a sample beyond the vessel's declared ranges (``limits`` for states, the
range of an actuator) or a single-sample jump of a state far beyond its neighbours.
Every recording format goes through ``find_spikes`` on its raw samples in model units
(``quantities.model_column``), so resampling interpolates (states) or holds (actuators)
across what was dropped. Out-of-range samples are dropped only while they are rare:
more means a unit or column is wrong, and they are kept so that the map checks say which
(``map_checks.spike_check`` judges a run's counts).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from vessel_description import Vessel

MAX_SPIKE_SHARE = 0.05    # out-of-range samples are spikes only while this rare
JUMP_MADS = 10.0          # a jump beyond this many robust sigmas of its neighbours...
JUMP_SPAN = 0.1           # ...and beyond this share of the state's declared range


@dataclass
class Spikes:
    """Spike masks of one column and whether they may be dropped."""

    column: str
    samples: int
    out_of_range: np.ndarray
    jumps: np.ndarray
    bounds: tuple[float, float] | None

    @property
    def droppable(self) -> bool:
        """Whether the out-of-range samples are rare enough to be spikes."""
        return int(self.out_of_range.sum()) <= MAX_SPIKE_SHARE * max(self.samples, 1)

    @property
    def mask(self) -> np.ndarray:
        """Return the samples to drop: jumps always, out-of-range ones while rare."""
        return self.jumps | (self.out_of_range if self.droppable else False)

    def counts(self, inside: np.ndarray | None = None) -> dict[str, Any]:
        """Return counts for a report (of the samples ``inside``, default all)."""
        inside = np.ones(len(self.jumps), bool) if inside is None else inside
        return {'samples': int(inside.sum()),
                'out_of_range': int((self.out_of_range & inside).sum()),
                'jumps': int((self.jumps & inside).sum()), 'dropped': bool(self.droppable),
                'bounds': list(self.bounds) if self.bounds else None}


def bounds_of(vessel: Vessel, column: str) -> tuple[float, float] | None:
    """Return the declared range of a state (``limits``) or actuator, if any."""
    if column in vessel.limits:
        return vessel.limits[column]
    if column in vessel.actuator_names:
        a = vessel.actuator(column)
        return (a.low, a.high)
    return None


def find_spikes(column: str, values: np.ndarray, vessel: Vessel) -> Spikes:
    """
    Find the spikes of one column's finite samples (model units).

    States are tested for range and single-sample jumps, actuators for range only
    (commands may step).
    """
    values = np.asarray(values, float)
    bounds = bounds_of(vessel, column)
    out = np.zeros(len(values), bool)
    if bounds is not None:
        out = (values < bounds[0]) | (values > bounds[1])
    jumps = np.zeros(len(values), bool)
    if column in vessel.states:
        idx = np.nonzero(~out)[0]
        if len(idx) >= 5:
            x = values[idx]
            span = (bounds[1] - bounds[0]) if bounds else float(np.ptp(x))
            jumps[idx] = _jumps(x, span)
    return Spikes(column, len(values), out, jumps, bounds)


def _jumps(x: np.ndarray, span: float) -> np.ndarray:
    """Flag samples far from the median of their two neighbours either side."""
    pad = np.pad(x, 2, mode='edge')
    neighbours = np.stack([pad[:-4], pad[1:-3], pad[3:-1], pad[4:]])
    d = x - np.median(neighbours, axis=0)
    sigma = 1.4826 * np.median(np.abs(d - np.median(d)))
    return (np.abs(d) > JUMP_MADS * sigma) & (np.abs(d) > JUMP_SPAN * span)
