"""
Actuator dynamics: rate-limited first-order rudder servo and shaft-speed response.

Both are written as state derivatives so the RK4 integrator carries the actuator states
with the vessel (numpy or torch). The rudder servo follows the MSS demo (Fossen):
delta' = clip((clip(delta_c, +-delta_max) - delta) / T_delta, +-delta'_max). The shaft
has the same shape, its set-point limited to [0, n_max] and its rate to the engine's
load acceptance.
"""

from __future__ import annotations

from vessel_physics.arrays import namespace
from vessel_physics.params import VesselParams


def rudder_rate(command, angle, params: VesselParams):
    """Return the rudder angle rate (rad/s) towards ``command`` (rad) from ``angle`` (rad)."""
    xp = namespace(command, angle)
    target = _clip(command, -params.rudder_max_angle, params.rudder_max_angle, xp)
    return _clip((target - angle) / params.rudder_time_constant,
                 -params.rudder_max_rate, params.rudder_max_rate, xp)


def shaft_accel(command, speed, params: VesselParams):
    """Return the shaft acceleration (rad/s^2) towards ``command`` (rad/s) from ``speed``."""
    xp = namespace(command, speed)
    target = _clip(command, 0.0, params.shaft_max_speed, xp)
    return _clip((target - speed) / params.shaft_time_constant,
                 -params.shaft_max_accel, params.shaft_max_accel, xp)


def _clip(x, lo: float, hi: float, xp):
    # minimum/maximum instead of clip: same result, a fraction of numpy's clip overhead.
    return xp.minimum(xp.maximum(x, lo), hi)
