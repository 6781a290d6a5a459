"""
Keeping the simulation at the wall clock's pace: how many output periods a tick owes.

The node's timer fires once per output period (divided by the real-time factor), but a
timer that fires late does not fire twice: a tick that took longer than a period (a
loaded machine, a garbage collection) would leave the simulation behind for good, and a
100 Hz vehicle at real time drifts off the clock. ``Pacer.due`` says how many periods
are due at each tick, so a late tick is made up at the next one; the simulated time
then follows the wall clock on average. Behind by more than ``max_catch_up`` periods
(the machine cannot keep up at all), it starts counting afresh from now instead of
bursting, and counts the periods it let go.
"""

from __future__ import annotations

MAX_CATCH_UP = 5      # output periods simulated in one tick at most


class Pacer:
    """Output periods due at a wall-clock time (s, monotonic) for a simulated time."""

    def __init__(self, period_s: float, real_time_factor: float = 1.0,
                 max_catch_up: int = MAX_CATCH_UP):
        self.period_s = period_s
        self.real_time_factor = real_time_factor
        self.max_catch_up = max_catch_up
        self.skipped = 0           # periods let go, in all
        self._wall0 = self._sim0 = None

    def restart(self, now_s: float, sim_t: float, real_time_factor: float | None = None):
        """Count from here: the simulated time ``sim_t`` belongs to wall time ``now_s``."""
        if real_time_factor is not None:
            self.real_time_factor = real_time_factor
        self._wall0, self._sim0 = now_s, sim_t

    def due(self, now_s: float, sim_t: float) -> int:
        """Return the periods to simulate now (0 when ahead); restart when far behind."""
        if self._wall0 is None:
            self.restart(now_s - self.period_s / self.real_time_factor, sim_t)
        target = self._sim0 + (now_s - self._wall0) * self.real_time_factor
        behind = round((target - sim_t) / self.period_s)
        if behind > self.max_catch_up:
            self.skipped += behind - 1
            self.restart(now_s, sim_t + self.period_s)
            return 1
        return max(behind, 0)
