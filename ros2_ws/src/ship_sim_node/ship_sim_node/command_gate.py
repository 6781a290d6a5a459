"""
Decide which external actuator command is in force (no ROS).

External commands override the simulated operator while they keep arriving: each
accepted command holds for ``timeout_s`` of simulated time, after which the operator
resumes. A command with NaN/Inf or out-of-range values is rejected as a whole, and the
last good command keeps holding until its own timeout.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
import math


@dataclass(frozen=True)
class CommandLimits:
    """Accepted set-point range [low, high] of each actuator, by name (its vessel file's)."""

    ranges: Mapping[str, tuple[float, float]]

    def violation(self, key: str, value: float) -> str | None:
        """Return why ``value`` is not an acceptable set-point for ``key``, or None."""
        if key not in self.ranges:
            return f'unknown actuator {key!r}'
        if not math.isfinite(value):
            return f'{key}={value} is not finite'
        low, high = self.ranges[key]
        if not low <= value <= high:
            return f'{key}={value:.4g} outside [{low:.4g}, {high:.4g}]'
        return None


class CommandGate:
    """Hold the latest valid external command for a limited simulated time."""

    def __init__(self, limits: CommandLimits, timeout_s: float):
        if timeout_s <= 0:
            raise ValueError(f'timeout_s must be > 0, got {timeout_s}')
        self.limits = limits
        self.timeout_s = timeout_s
        self._command: dict[str, float] | None = None
        self._received_at = -math.inf
        self.accepted = 0
        self.rejected = 0

    def offer(self, command: dict[str, float], t: float) -> str | None:
        """Offer a command received at simulated time ``t``; return a rejection reason or None."""
        reasons = [r for r in (self.limits.violation(k, v) for k, v in command.items()) if r]
        if reasons:
            self.rejected += 1
            return '; '.join(reasons)
        self._command = dict(command)
        self._received_at = t
        self.accepted += 1
        return None

    def active(self, t: float) -> dict[str, float] | None:
        """Return the command in force at simulated time ``t``, or None (operator drives)."""
        if self._command is None or t - self._received_at > self.timeout_s:
            return None
        return dict(self._command)

    def clear(self) -> None:
        """Forget any command (after a reset)."""
        self._command = None
        self._received_at = -math.inf
