"""
Which state samples are forecast: one per forecast period of message time (no ROS).

Forecasts are due on a grid ``forecast_period`` apart; a state sample is taken for the
next due forecast when it lies at most half a typical state interval before the due
time. Comparing each state's stamp with the last forecast's by a strict "at least one
period later" skips, when states arrive at the forecast period itself, every state that
came a few microseconds early through jitter of its stamp -- about half of them, so a
0.2 s period became 0.2-0.4 s. A state far past the due time (after a gap) starts the
grid again at itself. Times are seconds of message time.
"""

from __future__ import annotations

from collections import deque
import math
import statistics

INTERVALS_KEPT = 16   # state intervals the typical one is the median of


class ForecastSchedule:
    """Decide per state sample whether a forecast is due (see the module docstring)."""

    def __init__(self, period: float):
        if period < 0:
            raise ValueError(f'forecast period must be >= 0 s, got {period}')
        self.period = period
        self.next_due = -math.inf
        self.last_state: float | None = None
        self.intervals: deque = deque(maxlen=INTERVALS_KEPT)

    def reset(self) -> None:
        """Forget the grid and the state intervals (a restarted source, a clock jump)."""
        self.next_due = -math.inf
        self.last_state = None
        self.intervals.clear()

    def slack(self) -> float:
        """Half the typical interval between state samples (s), 0 before there is one."""
        # statistics, not NumPy: a deque of 16 floats took NumPy 40 us a state, statistics 1 us.
        return 0.5 * statistics.median(self.intervals) if self.intervals else 0.0

    def due(self, t: float) -> bool:
        """Note a state sample stamped ``t``; return whether it is forecast."""
        if self.last_state is not None:
            if t < self.last_state:          # the stamps went back: a new time line
                self.reset()
            elif t > self.last_state:
                self.intervals.append(t - self.last_state)
        self.last_state = t
        if t < self.next_due - self.slack():
            return False
        # On the grid while the states keep up; a state a period or more past the due
        # time (after a gap, or the first one) anchors the grid at itself.
        behind = t - self.next_due >= self.period
        self.next_due = t + self.period if behind else self.next_due + self.period
        return True
