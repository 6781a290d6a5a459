"""
The patrol boat's generalized-force terms and the hull features they are built from.

Every term has the signature ``term(z, c, params) -> tau`` with

- ``z`` (..., 5): [u, v, p, r, phi]: surge, sway (m/s), roll, yaw rate (rad/s) in FRD and
  roll angle (rad). Hydrodynamic terms want u, v *through the water*; terms registered
  with ``velocity='ground'`` want them over ground (they differ only under a current);
- ``c`` (..., 6): [n, delta_port, delta_stbd, wind_speed, wind_dir_cos, wind_dir_sin] as
  in docs/conventions.md: shaft speed (rad/s), rudder-propeller angles (rad, positive
  turns the thrust to starboard), true wind speed (m/s) and the cos/sin of the angle it
  comes from relative to the bow;
- ``tau`` (..., 4): [X, Y, K, N] about CO in FRD (N, N, N m, N m).

They are written against the Array API standard (see ``vessel_physics.arrays``), so the
same code runs on numpy arrays in the simulator and on torch tensors, with autograd, in
the hybrid models. The family (``patrol.family``) registers them with the DOFs they act
on and their physical category. Sources: Perez, Ross & Fossen (2006); Blanke &
Christensen (1993); Fossen (2011).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
import math
import re

import numpy as np

from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.patrol.params import PatrolParams
from vessel_physics.patrol.wind_loads import wind_force

DOFS = ('X', 'Y', 'K', 'N')


def rigid_body_coriolis(z, c, params: PatrolParams):
    """Rigid-body Coriolis and centripetal forces -C_RB(nu) nu with CG at (xG, 0, zG)."""
    xp = namespace(z)
    u, v, p, r = z[..., 0], z[..., 1], z[..., 2], z[..., 3]
    m = params.m
    return stack_last([
        m * (v * r + params.xG * r * r - params.zG * p * r),
        -m * u * r,
        m * params.zG * u * r,
        -m * params.xG * u * r,
    ], xp)


def restoring(z, c, params: PatrolParams):
    """Roll restoring moment with cubic GZ term: -rho g nabla GM phi + Kphiphiphi phi^3."""
    xp = namespace(z)
    phi = z[..., 4]
    zero = xp.zeros_like(phi)
    roll = -params.restoring_roll * phi + params.Kphiphiphi * phi * phi * phi
    return stack_last([zero, zero, roll, zero], xp)


def restoring_linear(z, c, params: PatrolParams):
    """Linearized restoring -G eta: only roll, -rho g nabla GM phi (Min model)."""
    xp = namespace(z)
    phi = z[..., 4]
    zero = xp.zeros_like(phi)
    return stack_last([zero, zero, -params.restoring_roll * phi, zero], xp)


# The nonlinear hull terms of Blanke & Christensen (1993), as used for the patrol vessel
# by Perez, Ross & Fossen (2006): one spelling, shared by the hull damping below, the
# regression features (hybrid_models.physical.features) and the diagnosis library. The
# spelling follows the coefficient names: |q| is the absolute value (``a<q>`` in a
# coefficient, X|u|u -> Xauu), products are written without a sign (u r -> 'ur').
# Name -> formula on a mapping of state arrays (u, v, p, r, phi); Array API operators.
HULL_TERMS: dict[str, Callable] = {
    '|u|u': lambda s: abs(s['u']) * s['u'],
    'vr': lambda s: s['v'] * s['r'],
    'rr': lambda s: s['r'] * s['r'],
    'pr': lambda s: s['p'] * s['r'],
    '|u|v': lambda s: abs(s['u']) * s['v'],
    'ur': lambda s: s['u'] * s['r'],
    'v|v|': lambda s: s['v'] * abs(s['v']),
    'v|r|': lambda s: s['v'] * abs(s['r']),
    'r|v|': lambda s: s['r'] * abs(s['v']),
    'phi|uv|': lambda s: s['phi'] * abs(s['u'] * s['v']),
    'phi|ur|': lambda s: s['phi'] * abs(s['u'] * s['r']),
    'phiuu': lambda s: s['phi'] * s['u'] * s['u'],
    '|u|p': lambda s: abs(s['u']) * s['p'],
    'p|p|': lambda s: s['p'] * abs(s['p']),
    'p': lambda s: s['p'],
    'phi^3': lambda s: s['phi'] ** 3,
    '|u|r': lambda s: abs(s['u']) * s['r'],
    'r|r|': lambda s: s['r'] * abs(s['r']),
    'phiu|r|': lambda s: s['phi'] * s['u'] * abs(s['r']),
    'phiu|u|': lambda s: s['phi'] * s['u'] * abs(s['u']),
}
Z_COLUMNS = ('u', 'v', 'p', 'r', 'phi')   # the state vector z (module docstring)

# The hull damping terms and the coefficient of each per DOF.
HULL_DAMPING_FEATURES = ('|u|u', 'vr', '|u|v', 'ur', 'v|v|', 'v|r|', 'r|v|', 'phi|uv|',
                         'phi|ur|', 'phiuu', '|u|p', 'p|p|', 'p', '|u|r', 'r|r|', 'phiu|r|',
                         'phiu|u|')
_HULL_DAMPING_COEFFICIENTS = {   # feature -> (X, Y, K, N) parameter names
    '|u|u': ('Xauu', None, None, None),
    'vr': ('Xvr', None, None, None),
    '|u|v': (None, 'Yauv', 'Kauv', 'Nauv'),
    'ur': (None, 'Yur', 'Kur', None),
    'v|v|': (None, 'Yvav', 'Kvav', None),
    'v|r|': (None, 'Yvar', 'Kvar', None),
    'r|v|': (None, 'Yrav', 'Krav', 'Nrav'),
    'phi|uv|': (None, 'Yphiauv', 'Kphiauv', 'Nphiauv'),
    'phi|ur|': (None, 'Yphiaur', 'Kphiaur', None),
    'phiuu': (None, 'Yphiuu', 'Kphiuu', None),
    '|u|p': (None, None, 'Kaup', None),
    'p|p|': (None, None, 'Kpap', None),
    'p': (None, None, 'Kp', None),
    '|u|r': (None, None, None, 'Naur'),
    'r|r|': (None, None, None, 'Nrar'),
    'phiu|r|': (None, None, None, 'Nphiuar'),
    'phiu|u|': (None, None, None, 'Nphiuau'),
}


def hull_terms(names, states) -> list:
    """Return the named ``HULL_TERMS`` evaluated on a mapping of state arrays."""
    return [HULL_TERMS[name](states) for name in names]


def hull_damping_features(z):
    """Return the hull damping features (..., 17) in the order of HULL_DAMPING_FEATURES."""
    xp = namespace(z)
    if xp is np:
        return _hull_damping_features_numpy(z)
    states = {name: z[..., i] for i, name in enumerate(Z_COLUMNS)}
    return stack_last(hull_terms(HULL_DAMPING_FEATURES, states), xp)


# HULL_DAMPING_FEATURES as (a * b) * c over the columns [z, |z|, 1], read from their
# names: factors left to right, |xy| as |x| |y| first, 1 where a feature has fewer. A
# simulator evaluates them on a few runs per RK4 stage, where three gathers cost far less
# than 17 small products; each is the product of its HULL_TERMS formula in the same order
# (and |x y| = |x| |y| exactly), so the values are bit for bit the same.
_ABS, _ONE = len(Z_COLUMNS), 2 * len(Z_COLUMNS)


def _column(factor: str) -> int:
    """Column of a factor ('u', '|u|' or '1') in [z, |z|, 1]."""
    if factor == '1':
        return _ONE
    if factor.startswith('|'):
        return _ABS + Z_COLUMNS.index(factor.strip('|'))
    return Z_COLUMNS.index(factor)


def _factor_columns(name: str) -> tuple[int, ...]:
    """Columns (a, b, c) of a feature's factors, e.g. 'phi|uv|' -> |u|, |v|, phi."""
    factors = re.findall(r'\|[a-z]+\||phi|[a-z]', name)
    group = [f for f in factors if len(f) == 4]          # |xy|: its product comes first
    if group:
        factors = [f'|{group[0][1]}|', f'|{group[0][2]}|'] + [f for f in factors
                                                              if f not in group]
    factors += ['1'] * (3 - len(factors))
    return tuple(_column(f) for f in factors)


_FACTOR_COLUMNS = tuple(np.array(k) for k in zip(*map(_factor_columns,
                                                      HULL_DAMPING_FEATURES), strict=True))


def _hull_damping_features_numpy(z: np.ndarray) -> np.ndarray:
    columns = np.empty((*z.shape[:-1], _ONE + 1), dtype=z.dtype)
    columns[..., :_ABS] = z
    np.abs(z, out=columns[..., _ABS:_ONE])
    columns[..., _ONE] = 1.0
    first, second, third = (columns[..., k] for k in _FACTOR_COLUMNS)
    # Row-major like np.stack's: the gathers come out column-major, and the product with
    # hull_damping_matrix would then take another BLAS path, rounding otherwise.
    out = np.empty((*z.shape[:-1], len(HULL_DAMPING_FEATURES)), dtype=z.dtype)
    np.multiply(first, second, out=out)
    return np.multiply(out, third, out=out)


@lru_cache(maxsize=32)
def hull_damping_matrix(params: PatrolParams) -> np.ndarray:
    """Coefficient matrix (17, 4): hull_damping = features @ matrix."""
    matrix = np.zeros((len(HULL_DAMPING_FEATURES), 4))
    for i, feature in enumerate(HULL_DAMPING_FEATURES):
        for j, name in enumerate(_HULL_DAMPING_COEFFICIENTS[feature]):
            if name is not None:
                matrix[i, j] = getattr(params, name)
    return matrix


def hull_damping(z, c, params: PatrolParams):
    """
    Nonlinear hull damping and cross-flow forces (Blanke & Christensen 1993 set).

    X: X|u|u |u|u + Xvr v r; Y: Y|u|v |u|v + Yur u r + Yv|v| v|v| + Yv|r| v|r| + Yr|v| r|v|
    + phi (Yphi|uv| |uv| + Yphi|ur| |ur| + Yphiuu u^2); K: the same kinds with K plus
    K|u|p |u|p + Kp|p| p|p| + Kp p; N: N|u|v |u|v + N|u|r |u|r + Nr|r| r|r| + Nr|v| r|v|
    + phi (Nphi|uv| |uv| + Nphiu|r| u|r| + Nphiu|u| u|u|).
    """
    xp = namespace(z)
    return hull_damping_features(z) @ constant(hull_damping_matrix(params), z, xp)


def unit_thrust(u, v, n_rps, delta, params: PatrolParams):
    """
    Thrust (N) of rudder-propellers at angles ``delta`` and ``n_rps`` (rev/s, signed).

    Va = max(0, (1 - w)(u cos delta + v sin delta)), J = Va / (|n| D),
    |T| = max(0, rho D^4 n^2 KT(J)) with KT = KT0 + KT1 J + KT2 J^2, written as
    rho (KT0 D^4 n^2 + KT1 D^3 |n| Va + KT2 D^2 Va^2) so that n = 0 needs no division.
    The thrust keeps the sign of the shaft speed: a propeller turning astern pulls
    astern (the open-water curve is the ahead one, a first approximation astern).
    Arguments broadcast against each other.
    """
    xp = namespace(delta)
    return _thrust(u, v, n_rps, xp.cos(delta), xp.sin(delta), params, xp)


def _thrust(u, v, n_rps, cos_delta, sin_delta, params: PatrolParams, xp):
    """``unit_thrust`` from the cosine and sine of the angles (propulsion has them)."""
    d = params.prop_diameter
    va = xp.maximum((1.0 - params.wake_fraction) * (u * cos_delta + v * sin_delta), 0.0)
    n_abs = xp.abs(n_rps)
    magnitude = params.rho * d * d * (params.KT0 * d * d * n_abs * n_abs
                                      + params.KT1 * d * n_abs * va + params.KT2 * va * va)
    return xp.sign(n_rps) * xp.maximum(magnitude, 0.0)


def propulsion(z, c, params: PatrolParams):
    """
    Twin rudder-propellers on one shaft speed: thrust vectors and their moments about CO.

    Unit i at (lx, +-ly, lz) with force (T cos d, T sin d, 0): X = sum Fx, Y = sum Fy,
    K = -lz Y (a side force below CO heels away from it), N = lx Y + ly (Fx_port - Fx_stbd).
    """
    xp = namespace(z, c)
    u, v = z[..., 0:1], z[..., 1:2]
    n_rps = c[..., 0:1] * (1.0 / (2.0 * math.pi))
    delta = c[..., 1:3]                          # (..., 2): port, starboard
    cos_delta, sin_delta = xp.cos(delta), xp.sin(delta)
    thrust = _thrust(u, v, n_rps, cos_delta, sin_delta, params, xp)
    fx = thrust * cos_delta
    fy = thrust * sin_delta
    side = fy[..., 0] + fy[..., 1]
    return stack_last([fx[..., 0] + fx[..., 1], side, -params.prop_lz * side,
                       params.prop_lx * side + params.prop_ly * (fx[..., 0] - fx[..., 1])], xp)


def wind(z, c, params: PatrolParams):
    """Isherwood (1972) wind load from the true wind in ``c`` and ground velocity in ``z``."""
    return wind_force(z, c, params)


def roll_natural_frequency(params: PatrolParams) -> float:
    """Uncoupled roll natural frequency sqrt(rho g nabla GM / (Ixx - Kp')) (rad/s)."""
    return math.sqrt(params.restoring_roll / (params.Ixx - params.Kpdot))


__all__ = ['DOFS', 'HULL_DAMPING_FEATURES', 'HULL_TERMS', 'Z_COLUMNS', 'hull_damping',
           'hull_damping_features', 'hull_damping_matrix', 'hull_terms', 'propulsion',
           'restoring', 'restoring_linear', 'rigid_body_coriolis', 'roll_natural_frequency',
           'unit_thrust', 'wind']
