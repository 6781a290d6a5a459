"""
The zig-zag manoeuvre (IMO MSC.137(76)) of an MMG ship, batched.

Each of B ships approaches at its own speed and propeller speed, puts the rudder over to
its rudder angle at the rudder rate, and reverses it whenever the heading passes the
check angle the other way (a "10/5" zig-zag: rudder 10 deg, check 5 deg). Rudder angles
follow the MMG sign (positive turns to starboard); the first rudder is positive.
The overshoot angles are the heading's excursion beyond the check angle after each
reversal; ``overshoots`` computes them from a heading alone, so measured runs get the
same figures.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from vessel_physics.family import Physics
from vessel_physics.integrator import free_run


@dataclass
class ZigZag:
    """Time series of a batch of zig-zags (B ships, T samples)."""

    t: np.ndarray          # (T,) s
    z: np.ndarray          # (B, T, 3) u, v (m/s), r (rad/s)
    heading: np.ndarray    # (B, T) rad, from the approach course
    delta: np.ndarray      # (B, T) rad
    check: np.ndarray      # (B,) rad, the check angles

    def overshoots(self) -> np.ndarray:
        """Return the first and second overshoot angles (B, 2), degrees."""
        return np.array([overshoots(psi, check) for psi, check in
                         zip(self.heading, self.check, strict=True)])


def overshoots(heading: np.ndarray, check: float) -> tuple[float, float]:
    """
    Return the first two overshoot angles (deg) of one zig-zag's heading (rad).

    A reversal happens when the heading passes the check angle on the side it is turning
    to; the overshoot is how far it then goes beyond it. The first turn may go either way.
    NaN when the run is too short.
    """
    beyond = np.flatnonzero(np.abs(heading) > check)
    if not len(beyond):
        return math.nan, math.nan
    heading = np.sign(heading[beyond[0]]) * heading   # first turn to starboard from here
    side = 0.0
    reversals = []
    for k, psi in enumerate(heading):
        if side >= 0 and psi > check:
            reversals.append(k)
            side = -1.0
        elif side <= 0 and psi < -check and reversals:
            reversals.append(k)
            side = 1.0
    out = [math.nan, math.nan]
    for i in range(min(2, len(reversals) - 1)):
        leg = heading[reversals[i]:reversals[i + 1]]
        out[i] = math.degrees(np.max(np.abs(leg)) - check)
    return out[0], out[1]


def zigzag(physics: Physics, speed: np.ndarray, shaft_speed: np.ndarray,
           rudder: np.ndarray, check: np.ndarray, rudder_rate: float, seconds: float,
           dt: float, substeps: int = 1) -> ZigZag:
    """
    Simulate B zig-zags, one per entry of the (B,) arrays.

    ``speed`` (m/s), ``shaft_speed`` (rad/s), the ``rudder`` and ``check`` angles (rad);
    ``rudder_rate`` (rad/s) limits the rudder's motion; RK4 with ``substeps`` steps per
    sample period ``dt`` (s), the rudder held over each period.
    """
    speed, shaft_speed, angle, check = (np.asarray(a, dtype=float) for a in (
        speed, shaft_speed, rudder, check))
    batch, steps = len(speed), int(round(seconds / dt))
    z = np.zeros((batch, steps + 1, 3))
    heading = np.zeros((batch, steps + 1))
    delta = np.zeros((batch, steps + 1))
    z[:, 0, 0] = speed
    target = angle.copy()
    for k in range(steps):
        passed = np.where(target > 0, heading[:, k] > check, heading[:, k] < -check)
        target = np.where(passed, -target, target)
        delta[:, k + 1] = delta[:, k] + np.clip(target - delta[:, k], -rudder_rate * dt,
                                                rudder_rate * dt)
        controls = np.stack([shaft_speed, delta[:, k + 1]], axis=-1)[:, None, :]
        z[:, k + 1] = free_run(physics.derivative, z[:, k], controls, dt, substeps)[:, -1]
        heading[:, k + 1] = heading[:, k] + 0.5 * dt * (z[:, k, 2] + z[:, k + 1, 2])
    return ZigZag(np.arange(steps + 1) * dt, z, heading, delta, check)
