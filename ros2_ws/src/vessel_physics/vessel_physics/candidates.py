"""
Candidate force terms for model discovery: physics the nominal models may lack.

The terms of ``vessel_physics.terms`` are the physics the simulator and the models share;
the terms here are the further named effects that the diagnosis tool tries on recordings
and that an augmented physics file (``vessel_physics.augmented``) can add. Each has the
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

A coefficient's unit is in ``CANDIDATES[name].unit``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vessel_physics.arrays import constant, namespace
from vessel_physics.params import VesselParams
from vessel_physics.terms import DOFS, propulsion, unit_thrust
from vessel_physics.wind import RHO_AIR

# Central-difference half step for d propulsion / d delta (rad); propulsion is smooth in
# delta (cos, sin of the angle), so the truncation error is ~1e-9 of the derivative.
RUDDER_STEP = 1.0e-4
_TWO_PI = 2.0 * np.pi


def _one_dof(value, dof: int):
    """Return (..., 4) with ``value`` in column ``dof`` and zeros elsewhere."""
    xp = namespace(value)
    zero = xp.zeros_like(value)
    return xp.stack([value if j == dof else zero for j in range(4)], axis=-1)


def surge_linear(z, c, params: VesselParams):
    """Linear surge resistance feature X = u (coefficient N s/m, negative = resisting)."""
    return _one_dof(z[..., 0], 0)


def sway_linear(z, c, params: VesselParams):
    """Linear sway damping feature Y = v (N s/m)."""
    return _one_dof(z[..., 1], 1)


def sway_yaw_linear(z, c, params: VesselParams):
    """Linear sway force from yaw rate Y = r (N s/rad)."""
    return _one_dof(z[..., 3], 1)


def yaw_linear(z, c, params: VesselParams):
    """Linear yaw damping feature N = r (N m s/rad)."""
    return _one_dof(z[..., 3], 3)


def yaw_sway_linear(z, c, params: VesselParams):
    """Linear yaw moment from sway N = v (N s)."""
    return _one_dof(z[..., 1], 3)


def _constant(z, dof: int):
    xp = namespace(z)
    return _one_dof(xp.ones_like(z[..., 0]), dof)


def surge_bias(z, c, params: VesselParams):
    """Constant surge force X = 1 (N)."""
    return _constant(z, 0)


def sway_bias(z, c, params: VesselParams):
    """Constant sway force Y = 1 (N): an asymmetric hull or appendage."""
    return _constant(z, 1)


def roll_bias(z, c, params: VesselParams):
    """Constant roll moment K = 1 (N m): a static list (off-centre load)."""
    return _constant(z, 2)


def yaw_bias(z, c, params: VesselParams):
    """Constant yaw moment N = 1 (N m): an asymmetric hull or appendage."""
    return _constant(z, 3)


def apparent_wind(z, c):
    """
    Return (q, cos gamma_r, sin gamma_r) of the apparent wind; numpy or torch.

    q = rho_a V_r^2 / 2 (Pa) and gamma_r the angle the apparent wind comes from relative
    to the bow (+ starboard), from the true wind in ``c`` and the ground velocity u, v in
    ``z``. In a calm (V_r = 0) the angle is taken as head wind; q is 0 there anyway.
    """
    xp = namespace(z, c)
    from_x = c[..., 3] * c[..., 4] + z[..., 0]
    from_y = c[..., 3] * c[..., 5] + z[..., 1]
    v2 = from_x * from_x + from_y * from_y
    calm = v2 < 1e-12
    norm = xp.sqrt(xp.where(calm, 1.0, v2))
    cos_g = xp.where(calm, 1.0, from_x / norm)
    sin_g = xp.where(calm, 0.0, from_y / norm)
    return 0.5 * RHO_AIR * v2, cos_g, sin_g


def relative_wind_surge(z, c, params: VesselParams):
    """Wind surge load X = -q cos gamma_r (coefficient C_X A_F, m^2; > 0 is drag)."""
    q, cos_g, _ = apparent_wind(z, c)
    return _one_dof(-q * cos_g, 0)


def relative_wind_sway(z, c, params: VesselParams):
    """Wind side load Y = -q sin gamma_r (coefficient C_Y A_L, m^2; > 0 pushes to leeward)."""
    q, _, sin_g = apparent_wind(z, c)
    return _one_dof(-q * sin_g, 1)


def relative_wind_roll(z, c, params: VesselParams):
    """Wind heeling moment K = -q sin gamma_r (coefficient C_Y A_L h, m^3; > 0 to leeward)."""
    q, _, sin_g = apparent_wind(z, c)
    return _one_dof(-q * sin_g, 2)


def relative_wind_yaw(z, c, params: VesselParams):
    """Wind yaw moment N = -q sin 2 gamma_r (coefficient C_N A_L L, m^3)."""
    q, cos_g, sin_g = apparent_wind(z, c)
    return _one_dof(-2.0 * q * sin_g * cos_g, 3)


def rudder_offset(z, c, params: VesselParams):
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


def propeller_asymmetry(z, c, params: VesselParams):
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
    return xp.stack([dx, dy, -params.prop_lz * dy,
                     params.prop_lx * dy + params.prop_ly * (fx[..., 0] + fx[..., 1])],
                    axis=-1)


@dataclass(frozen=True)
class CandidateTerm:
    """A candidate force term: function, DOFs, physical category and coefficient unit."""

    name: str
    fn: Callable
    dofs: tuple[str, ...]
    category: str
    velocity: str      # 'water' (through the water) or 'ground' (over ground)
    unit: str          # unit of the coefficient that multiplies the term
    description: str


CANDIDATES: dict[str, CandidateTerm] = {t.name: t for t in (
    CandidateTerm('surge_linear', surge_linear, ('X',), 'resistance', 'water', 'N s/m',
                  'linear surge resistance X = Xu u'),
    CandidateTerm('sway_linear', sway_linear, ('Y',), 'hull_damping', 'water', 'N s/m',
                  'linear sway damping Y = Yv v'),
    CandidateTerm('sway_yaw_linear', sway_yaw_linear, ('Y',), 'hull_damping', 'water',
                  'N s/rad', 'linear sway force from yaw rate Y = Yr r'),
    CandidateTerm('yaw_linear', yaw_linear, ('N',), 'hull_damping', 'water', 'N m s/rad',
                  'linear yaw damping N = Nr r'),
    CandidateTerm('yaw_sway_linear', yaw_sway_linear, ('N',), 'hull_damping', 'water', 'N s',
                  'linear yaw moment from sway N = Nv v'),
    CandidateTerm('surge_bias', surge_bias, ('X',), 'static_bias', 'water', 'N',
                  'constant surge force'),
    CandidateTerm('sway_bias', sway_bias, ('Y',), 'static_bias', 'water', 'N',
                  'constant sway force (asymmetric hull or appendage)'),
    CandidateTerm('roll_bias', roll_bias, ('K',), 'static_bias', 'water', 'N m',
                  'constant roll moment (static list)'),
    CandidateTerm('yaw_bias', yaw_bias, ('N',), 'static_bias', 'water', 'N m',
                  'constant yaw moment (asymmetric hull or appendage)'),
    CandidateTerm('relative_wind_surge', relative_wind_surge, ('X',), 'wind', 'ground', 'm^2',
                  'wind surge load -q cos(gamma_r) C_X A_F in the apparent wind'),
    CandidateTerm('relative_wind_sway', relative_wind_sway, ('Y',), 'wind', 'ground', 'm^2',
                  'wind side load -q sin(gamma_r) C_Y A_L in the apparent wind'),
    CandidateTerm('relative_wind_roll', relative_wind_roll, ('K',), 'wind', 'ground', 'm^3',
                  'wind heeling moment -q sin(gamma_r) C_Y A_L h in the apparent wind'),
    CandidateTerm('relative_wind_yaw', relative_wind_yaw, ('N',), 'wind', 'ground', 'm^3',
                  'wind yaw moment -q sin(2 gamma_r) C_N A_L L in the apparent wind'),
    CandidateTerm('rudder_offset', rudder_offset, DOFS, 'actuator_bias', 'water', 'rad',
                  'common offset of the rudder-propeller angles'),
    CandidateTerm('propeller_asymmetry', propeller_asymmetry, DOFS, 'actuator_bias', 'water',
                  '1', 'port/starboard thrust asymmetry (port 1 + a, starboard 1 - a)'),
)}

__all__ = ['CANDIDATES', 'CandidateTerm', 'apparent_wind', 'propeller_asymmetry',
           'relative_wind_roll', 'relative_wind_surge', 'relative_wind_sway',
           'relative_wind_yaw', 'roll_bias', 'rudder_offset', 'surge_bias', 'surge_linear',
           'sway_bias', 'sway_linear', 'sway_yaw_linear', 'yaw_bias', 'yaw_linear',
           'yaw_sway_linear']
