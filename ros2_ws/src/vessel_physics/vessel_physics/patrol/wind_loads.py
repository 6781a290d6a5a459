"""
The patrol boat's wind loads: Isherwood (1972), from tabulated coefficients.

Angles. The true wind blows *from* the NED direction ``from_ned`` (rad, from north towards
east). Relative to the bow it comes from ``gamma = from_ned - psi``, positive towards
starboard (docs/conventions.md): 0 head wind, +pi/2 from starboard, -pi/2 from port.
The apparent (relative) wind is the air velocity seen from the moving hull, and its
from-angle ``gamma_r`` uses the same convention.

Loads (Isherwood 1972; Fossen 2011, ch. 8). With q = rho_a V_r^2 / 2:
X = q CX(|gamma_r|) AF, Y = -q CY(|gamma_r|) AL sign(gamma_r),
N = -q CN(|gamma_r|) AL Loa sign(gamma_r), K = h Y.
Isherwood's tables are for the angle magnitude; the minus signs make a wind from
starboard push the hull to port (Y < 0), as it must. CX, CY, CN are linear in |gamma_r|
between the 10-degree nodes of ``data/isherwood1972.csv``. Isherwood has no roll moment:
the side force acts at the lateral-area centroid, ``wind_height`` above CO, and in FRD
(z down) a force Y at z = -h gives K = -z Y = h Y. A wind from port (Y > 0) therefore
heels the vessel to starboard (K > 0, starboard down): the ship leans to leeward, as the
wind pushes the superstructure while the water holds the hull below.
"""

from __future__ import annotations

from functools import lru_cache
import math
from pathlib import Path

import numpy as np

from vessel_physics.apparent import RHO_AIR
from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.patrol.params import PatrolParams

ISHERWOOD_CSV = Path(__file__).resolve().parent / 'data' / 'isherwood1972.csv'
ANGLE_STEP_DEG = 10.0
N_NODES = 19  # 0, 10, ..., 180 degrees
NODES_DEG = np.arange(N_NODES) * ANGLE_STEP_DEG


@lru_cache(maxsize=1)
def _isherwood_rows() -> dict[str, np.ndarray]:
    """Read the published table: {'CX': (19, 7), 'CY': (19, 7), 'CN': (19, 6)}."""
    rows: dict[str, list] = {'CX': [], 'CY': [], 'CN': []}
    for line in ISHERWOOD_CSV.read_text().splitlines():
        if not line or line.startswith('#') or line.startswith('table'):
            continue
        fields = line.split(',')
        values = [float(x) for x in fields[1:] if x.strip()]
        rows[fields[0]].append(values)
    out = {}
    for name, values in rows.items():
        table = np.array(values)
        if table.shape[0] != N_NODES or not np.allclose(
                table[:, 0], np.arange(N_NODES) * ANGLE_STEP_DEG):
            raise ValueError(f'{ISHERWOOD_CSV}: table {name} must have rows at 0..180 deg')
        out[name] = table[:, 1:]
    return out


@lru_cache(maxsize=32)
def isherwood_coefficients(params: PatrolParams) -> np.ndarray:
    """Return CX, CY, CN at 0, 10, ..., 180 deg for this hull, shape (19, 3)."""
    p = params
    ratios = [2 * p.AL / p.Loa ** 2, 2 * p.AF / p.B ** 2, p.Loa / p.B, p.wind_S / p.Loa,
              p.wind_C / p.Loa]
    rows = _isherwood_rows()
    cx = -(rows['CX'] @ np.array([1.0, *ratios, p.wind_M]))
    cy = rows['CY'] @ np.array([1.0, *ratios, p.ASS / p.AL])
    cn = rows['CN'] @ np.array([1.0, *ratios])
    return np.stack([cx, cy, cn], axis=1)


def interpolate_coefficients(abs_gamma, params: PatrolParams):
    """Return (..., 3) CX, CY, CN linear in ``abs_gamma`` (rad, 0..pi); numpy or torch."""
    xp = namespace(abs_gamma)
    if xp is np:
        # Same piecewise-linear interpolation, one call per coefficient (the hot loop).
        table = isherwood_coefficients(params)
        deg = abs_gamma * (180.0 / math.pi)
        return stack_last([np.interp(deg, NODES_DEG, table[:, j]) for j in range(3)], np)
    table = constant(isherwood_coefficients(params), abs_gamma, xp)
    pos = xp.clip(abs_gamma * (180.0 / math.pi / ANGLE_STEP_DEG), 0.0, N_NODES - 1.0)
    index = xp.clip(xp.floor(pos), 0.0, N_NODES - 2.0)
    frac = pos - index
    flat = xp.reshape(xp.astype(index, xp.int64), (-1,))
    lower = xp.reshape(xp.take(table, flat, axis=0), (*abs_gamma.shape, 3))
    upper = xp.reshape(xp.take(table, flat + 1, axis=0), (*abs_gamma.shape, 3))
    return lower + frac[..., None] * (upper - lower)


def wind_force(z, c, params: PatrolParams):
    """
    Isherwood wind load [X, Y, K, N] (..., 4), FRD, N and N m; numpy or torch.

    ``z`` (..., 5) = [u, v, p, r, phi] with u, v over ground (m/s); ``c`` (..., 6) =
    [n, delta_port, delta_stbd, wind_speed, wind_dir_cos, wind_dir_sin]: the true wind
    speed (m/s) and the cos/sin of the angle it comes from relative to the bow.
    """
    xp = namespace(z, c)
    u, v = z[..., 0], z[..., 1]
    speed, dir_cos, dir_sin = c[..., 3], c[..., 4], c[..., 5]
    # Apparent wind: minus the air velocity relative to the hull, i.e. where it comes from.
    from_x = speed * dir_cos + u
    from_y = speed * dir_sin + v
    v2 = from_x * from_x + from_y * from_y
    # atan2(0, 0) has no gradient; where there is no apparent wind q = 0 anyway.
    calm = v2 < 1e-12
    gamma = xp.atan2(xp.where(calm, 0.0, from_y), xp.where(calm, 1.0, from_x))
    coef = interpolate_coefficients(xp.abs(gamma), params)
    q = 0.5 * RHO_AIR * v2
    side = xp.sign(gamma)
    x_force = q * coef[..., 0] * params.AF
    y_force = -q * coef[..., 1] * params.AL * side
    n_moment = -q * coef[..., 2] * params.AL * params.Loa * side
    return stack_last([x_force, y_force, params.wind_height * y_force, n_moment], xp)


