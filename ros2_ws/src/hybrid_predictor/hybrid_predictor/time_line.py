"""
Which time line a source's stamps are on, relative to the node's clock (no ROS).

A live source's stamps trail the node's clock by a steady lag: transport latency, near
zero. The lag can change for good: a simulator stopped and continued keeps stamping
where it stopped (its stamps now trail the wall clock by the pause), a source restarts
with another start time, a sensor's clock is set wrong. Judged by a fixed clock, such a
source stays "stale" for ever although its samples arrive live. So the window keeps
an ``offset``, the lag its state samples are expected at (0 at start), and a state
sample whose lag differs from it by more than ``tolerance`` (the window's ``max_age``)
is off the line. Off-line samples that keep arriving with a steady lag (within
``tolerance`` of the first one) form a candidate line; once the candidate has lasted
``span`` seconds, of the node's clock and of the wall clock both (under a fast
simulated clock a late /clock message makes samples look off-line for a moment), with
at least ``MIN_SAMPLES`` states while the current line stayed silent, the window
re-anchors on it. A candidate that stops (one
burst of old data, a replay) expires after ``span`` without a sample and changes
nothing. A candidate while the current line also stays live means two sources publish
the same topic on time lines that far apart: reported, never followed.

Times in seconds; lags are node clock minus stamp (positive: the source is behind).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

MIN_SAMPLES = 3   # state samples a candidate line needs before it can take over


@dataclass
class Candidate:
    """A line of off-line state samples that may take over."""

    lag: float          # lag of its first sample (s)
    since: float        # node clock at its first sample (s)
    since_wall: float   # wall clock at its first sample (s)
    last_seen: float    # node clock at its latest sample (s)
    last_stamp: float   # stamp of its latest sample (s)
    samples: int = 1
    contested: bool = False   # the current line delivered too while it ran


@dataclass(frozen=True)
class ReAnchor:
    """One change of line: when (node clock), from which offset to which."""

    at: float
    old_offset: float
    new_offset: float


class TimeLines:
    """The current line of a source's state stamps and a candidate for the next one."""

    def __init__(self, tolerance: float, span: float):
        self.configure(tolerance, span)
        self.offset = 0.0
        self.candidate: Candidate | None = None
        self.last_on_line: float | None = None   # node clock of the latest on-line state
        self.re_anchors: list[ReAnchor] = []
        self.contested_lag: float | None = None  # lag of a second live line, if any

    def configure(self, tolerance: float, span: float) -> None:
        """Set the tolerance (s) of a line and the span (s) a candidate must last."""
        if tolerance <= 0 or span < 0:
            raise ValueError(f'need tolerance > 0 and span >= 0; got {tolerance}, {span}')
        self.tolerance, self.span = tolerance, span

    def reset(self) -> None:
        """Back to the node's own clock (offset 0), no candidate (e.g. /clock reset)."""
        self.offset = 0.0
        self.candidate = None
        self.last_on_line = None
        self.contested_lag = None

    def on_line(self, t: float, now: float) -> bool:
        """Whether a sample stamped ``t`` at node time ``now`` is on the current line."""
        return abs((now - t) - self.offset) <= self.tolerance

    def fits_candidate(self, t: float, now: float) -> bool:
        """Whether a sample (of any stream) belongs to the candidate line."""
        c = self.candidate
        return c is not None and abs((now - t) - c.lag) <= self.tolerance

    def expire(self, now: float) -> None:
        """Drop a candidate that stopped delivering."""
        c = self.candidate
        if c is not None and now - c.last_seen > max(self.span, self.tolerance):
            self.candidate = None
            self.contested_lag = None

    def state(self, t: float, now: float, wall: float | None = None) -> bool:
        """
        Note a state sample; return True when the window must re-anchor on its line.

        ``wall`` is the wall (steady) clock in s (None: the node's clock is the wall
        clock). The caller then moves the window onto the candidate line (``take_over``).
        """
        wall = now if wall is None else wall
        self.expire(now)
        if self.on_line(t, now):
            self.last_on_line = now
            if self.candidate is not None:
                self.candidate.contested = True
            return False
        lag = now - t
        c = self.candidate
        if c is None or abs(lag - c.lag) > self.tolerance or t <= c.last_stamp:
            self.candidate = Candidate(lag, now, wall, now, t)
            return False
        c.samples += 1
        c.last_seen, c.last_stamp = now, t
        lasted = min(now - c.since, wall - c.since_wall)
        if c.samples < MIN_SAMPLES or lasted < self.span:
            return False
        if c.contested:   # both lines stayed live for the whole span: two sources
            self.contested_lag = c.lag
            return False
        return self.last_on_line is None or now - self.last_on_line >= self.span

    def take_over(self, now: float) -> ReAnchor:
        """Make the candidate the current line; return the change."""
        c = self.candidate
        event = ReAnchor(now, self.offset, c.lag)
        self.re_anchors.append(event)
        self.offset = c.lag
        self.candidate = None
        self.contested_lag = None
        self.last_on_line = now
        return event

    def describe(self, topic: str) -> str:
        """Say, in one phrase, where the stamps of ``topic`` stand against the clock."""
        lag = self.offset
        side = 'behind' if lag > 0 else 'ahead of'
        return f"stamps of {topic} {abs(lag):.1f} s {side} the node's clock"

    @property
    def latest(self) -> ReAnchor | None:
        """Return the latest re-anchoring, or None."""
        return self.re_anchors[-1] if self.re_anchors else None

    def shifted(self) -> bool:
        """Whether the current line is off the node's clock by more than the tolerance."""
        return math.fabs(self.offset) > self.tolerance
