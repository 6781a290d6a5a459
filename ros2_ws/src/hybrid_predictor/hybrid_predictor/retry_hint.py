"""
When a refused what-if request should come back: the ``retry_after`` of a "busy" answer.

Admitted requests are computed one after the other (the node's batch lock), so a slot
frees once per service time. A refused client told "retry later" comes back at a time of
its own choosing, and a crowd of them comes back together: most are refused again, and
each refusal costs both sides a request's conversion. This spreads them out instead: the
first refused client is given the time the running request is expected to finish, the
next one a service time later, and so on, as if they stood in a queue the node does not
hold. Times are seconds on a monotonic wall clock (what-if work is wall-clock work in
every clock mode). ROS-free; the node holds one under its count lock.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class RetryHint:
    """
    Expected service time of admitted requests and the retry times handed out.

    ``longest`` caps a hint (s): a client is never told to stay away longer, however
    many were refused before it. ``smoothing`` weighs the newest service time in the
    running mean (0-1].
    """

    longest: float
    smoothing: float = 0.2
    service_time: float | None = None   # s, running mean; None until one has finished
    _admitted: list[float] = field(default_factory=list)   # admission times, in order
    _last_finish: float = float('-inf')
    _booked: float = float('-inf')      # the latest retry time handed out

    def __post_init__(self):
        if not self.longest > 0:
            raise ValueError(f'longest must be > 0 s, got {self.longest}')
        if not 0 < self.smoothing <= 1:
            raise ValueError(f'smoothing must be in (0, 1], got {self.smoothing}')

    def admitted(self, now: float) -> None:
        """Note a request admitted at ``now``."""
        self._admitted.append(now)

    def finished(self, admitted_at: float, now: float) -> None:
        """Note the answer, at ``now``, of the request admitted at ``admitted_at``."""
        self._admitted.remove(admitted_at)
        # Its service began when it was admitted or when the one before it finished.
        took = now - max(admitted_at, self._last_finish)
        self._last_finish = now
        self.service_time = took if self.service_time is None else (
            self.service_time + self.smoothing * (took - self.service_time))

    def refused(self, now: float) -> float:
        """Return the seconds from ``now`` after which a refused client should retry."""
        if not self._admitted:
            return 0.0
        if self.service_time is None:
            # No answer yet to learn from: assume the running request is half done.
            step = now - self._admitted[0]
            next_free = now + step
        else:
            step = self.service_time
            next_free = max(self._admitted[0], self._last_finish) + step
        self._booked = min(max(self._booked + step, next_free, now), now + self.longest)
        return self._booked - now
