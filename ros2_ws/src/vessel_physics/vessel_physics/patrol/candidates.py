"""
The patrol boat's candidate terms: effects its model lacks, named for the diagnosis.

The forces of ``patrol.forces`` are the physics the simulator and the models share;
the terms here are the further named effects that the diagnosis tries on recordings
and that an augmented physics file (``vessel_physics.physics_file``) can add. Each has the
same signature as a registered term, ``term(z, c, params) -> tau`` with ``z`` (..., 5) =
[u, v, p, r, phi], ``c`` (..., 6) = [n, delta_port, delta_stbd, wind_speed, wind_dir_cos,
wind_dir_sin] (docs/conventions.md) and ``tau`` (..., 4) = [X, Y, K, N] about CO in FRD,
and is the force of ONE unit of its coefficient: the model adds ``coefficient * term``.
They are written against the Array API, so the simulator (numpy) and the hybrid models
(torch, autograd) evaluate the same code.

Effects (Fossen 2011 unless noted):

- linear damping at low speed and laminar/frictional resistance: X = u, Y = v, N = r and
  the linear cross terms Y = r, N = v;
- constant generalized forces: a static list, an asymmetric hull or appendage;
- wind in the apparent (relative) wind with generic load shapes, q = rho_a V_r^2 / 2 and
  gamma_r where the apparent wind comes from (0 head, + starboard):
  X = -q cos gamma_r, Y = -q sin gamma_r, N = -q sin 2 gamma_r, K = -q sin gamma_r, with
  coefficients C A (m^2) or C A l (m^3); a different function from Isherwood's tables
  (``vessel_physics.wind``), so a wind effect can be named without assuming its curve;
- actuator errors: a common rudder-angle offset (the force of one radian, linearized:
  d propulsion / d delta) and a port/starboard thrust asymmetry (port thrust times
  (1 + a), starboard times (1 - a)).

A coefficient's unit is in the family's registry (``Term.unit``).
"""

from __future__ import annotations

import numpy as np

from vessel_physics.apparent import apparent_wind as relative_air
from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.family import one_dof, unit_force
from vessel_physics.patrol.forces import DOFS, propulsion, unit_thrust
from vessel_physics.patrol.params import PatrolParams

# Central-difference half step for d propulsion / d delta (rad); propulsion is smooth in
# delta (cos, sin of the angle), so the truncation error is ~1e-9 of the derivative.
RUDDER_STEP = 1.0e-4
_TWO_PI = 2.0 * np.pi


def _one_dof(value, dof: int):
    """Return (..., 4) with ``value`` in column ``dof`` and zeros elsewhere."""
    return one_dof(value, dof, len(DOFS))


def surge_linear(z, c, params: PatrolParams):
    """Linear surge resistance feature X = u (coefficient N s/m, negative = resisting)."""
    return _one_dof(z[..., 0], 0)


def sway_linear(z, c, params: PatrolParams):
    """Linear sway damping feature Y = v (N s/m)."""
    return _one_dof(z[..., 1], 1)


def sway_yaw_linear(z, c, params: PatrolParams):
    """Linear sway force from yaw rate Y = r (N s/rad)."""
    return _one_dof(z[..., 3], 1)


def yaw_linear(z, c, params: PatrolParams):
    """Linear yaw damping feature N = r (N m s/rad)."""
    return _one_dof(z[..., 3], 3)


def yaw_sway_linear(z, c, params: PatrolParams):
    """Linear yaw moment from sway N = v (N s)."""
    return _one_dof(z[..., 1], 3)


def _constant(z, dof: int):
    return unit_force(z, dof, len(DOFS))


def surge_bias(z, c, params: PatrolParams):
    """Constant surge force X = 1 (N)."""
    return _constant(z, 0)


def sway_bias(z, c, params: PatrolParams):
    """Constant sway force Y = 1 (N): an asymmetric hull or appendage."""
    return _constant(z, 1)


def roll_bias(z, c, params: PatrolParams):
    """Constant roll moment K = 1 (N m): a static list (off-centre load)."""
    return _constant(z, 2)


def yaw_bias(z, c, params: PatrolParams):
    """Constant yaw moment N = 1 (N m): an asymmetric hull or appendage."""
    return _constant(z, 3)


def apparent_wind(z, c):
    """Return (q, cos gamma_r, sin gamma_r) of the apparent wind from ``z`` and ``c``."""
    return relative_air(z[..., 0], z[..., 1], c[..., 3], c[..., 4], c[..., 5])


def relative_wind_surge(z, c, params: PatrolParams):
    """Wind surge load X = -q cos gamma_r (coefficient C_X A_F, m^2; > 0 is drag)."""
    q, cos_g, _ = apparent_wind(z, c)
    return _one_dof(-q * cos_g, 0)


def relative_wind_sway(z, c, params: PatrolParams):
    """Wind side load Y = -q sin gamma_r (coefficient C_Y A_L, m^2; > 0 pushes to leeward)."""
    q, _, sin_g = apparent_wind(z, c)
    return _one_dof(-q * sin_g, 1)


def relative_wind_roll(z, c, params: PatrolParams):
    """Wind heeling moment K = -q sin gamma_r (coefficient C_Y A_L h, m^3; > 0 to leeward)."""
    q, _, sin_g = apparent_wind(z, c)
    return _one_dof(-q * sin_g, 2)


def relative_wind_yaw(z, c, params: PatrolParams):
    """Wind yaw moment N = -q sin 2 gamma_r (coefficient C_N A_L L, m^3)."""
    q, cos_g, sin_g = apparent_wind(z, c)
    return _one_dof(-2.0 * q * sin_g * cos_g, 3)


def rudder_offset(z, c, params: PatrolParams):
    """
    Force of a one-radian offset of both rudder-propeller angles, d propulsion / d delta.

    A measured angle that reads low by b (a zero offset of the angle sensors or of the
    rudder servo) gives the thrust vector an extra b; the model adds b times this term
    (linear in b: offsets are small). Central difference of ``propulsion``.
    """
    xp = namespace(z, c)
    step = constant(np.array([0.0, RUDDER_STEP, RUDDER_STEP, 0.0, 0.0, 0.0]), c, xp)
    return (propulsion(z, c + step, params) - propulsion(z, c - step, params)) * (
        0.5 / RUDDER_STEP)


def propeller_asymmetry(z, c, params: PatrolParams):
    """
    Force of a port/starboard thrust asymmetry a = 1: port T (1 + a), starboard T (1 - a).

    With unit forces F_i = T_i (cos d_i, sin d_i) at (lx, -+ly, lz), the change is
    dX = Fx_p - Fx_s, dY = Fy_p - Fy_s, dK = -lz dY, dN = lx dY + ly (Fx_p + Fx_s).
    """
    xp = namespace(z, c)
    u, v = z[..., 0:1], z[..., 1:2]
    n_rps = c[..., 0:1] * (1.0 / _TWO_PI)
    delta = c[..., 1:3]
    thrust = unit_thrust(u, v, n_rps, delta, params)
    fx, fy = thrust * xp.cos(delta), thrust * xp.sin(delta)
    dx = fx[..., 0] - fx[..., 1]
    dy = fy[..., 0] - fy[..., 1]
    return stack_last([dx, dy, -params.prop_lz * dy,
                       params.prop_lx * dy + params.prop_ly * (fx[..., 0] + fx[..., 1])], xp)


__all__ = ['apparent_wind', 'propeller_asymmetry', 'relative_wind_roll',
           'relative_wind_surge', 'relative_wind_sway', 'relative_wind_yaw', 'roll_bias',
           'rudder_offset', 'surge_bias', 'surge_linear', 'sway_bias', 'sway_linear',
           'sway_yaw_linear', 'yaw_bias', 'yaw_linear', 'yaw_sway_linear']
