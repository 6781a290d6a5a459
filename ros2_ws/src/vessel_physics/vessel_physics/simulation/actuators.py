"""
Actuator dynamics: a rate-limited first-order servo for every actuator.

Written as a state derivative so the RK4 integrator carries the actuator states with the
vessel (numpy or torch). The rudder servo of the MSS demo (Fossen) and an engine's shaft
have this shape: x' = clip((clip(x_c, low, high) - x) / T, -rate, rate), with the limits
of each actuator (``SimConfig.actuators``).
"""

from __future__ import annotations

from vessel_physics.arrays import namespace


def servo_rate(command, state, low: float, high: float, time_constant: float,
               max_rate: float):
    """Return the rate of an actuator at ``state`` towards ``command`` (units per second)."""
    xp = namespace(command, state)
    target = _clip(command, low, high, xp)
    return _clip((target - state) / time_constant, -max_rate, max_rate, xp)


def _clip(x, lo: float, hi: float, xp):
    # minimum/maximum instead of clip: same result, a fraction of numpy's clip overhead.
    return xp.minimum(xp.maximum(x, lo), hi)
