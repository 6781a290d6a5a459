"""
The constant 4-DOF mass matrix with added mass and its inverse (computed once).

Rows follow Perez, Ross & Fossen (2006) for the state derivative [u', v', p', r'] (FRD,
origin CO). The matrix is not symmetric: the source's cross terms Yp' and Kv' have
opposite signs, and the rigid-body couplings m zG, m xG enter the sway, roll and yaw rows.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from vessel_physics.arrays import constant, namespace
from vessel_physics.params import VesselParams


def mass_matrix(params: VesselParams) -> np.ndarray:
    """Return M (4x4, SI) with M @ [u', v', p', r'] = [X, Y, K, N]."""
    p = params
    return np.array([
        [p.m - p.Xudot, 0.0, 0.0, 0.0],
        [0.0, p.m - p.Yvdot, -(p.m * p.zG + p.Ypdot), p.m * p.xG - p.Yrdot],
        [0.0, -(p.m * p.zG + p.Kvdot), p.Ixx - p.Kpdot, -p.Krdot],
        [0.0, p.m * p.xG - p.Nvdot, -p.Npdot, p.Izz - p.Nrdot],
    ])


@lru_cache(maxsize=32)
def inverse_mass_matrix_T(params: VesselParams) -> np.ndarray:
    """Return (M^-1)^T, cached per parameter set, so that accel = tau @ result."""
    return np.ascontiguousarray(np.linalg.inv(mass_matrix(params)).T)


def accelerations(tau, params: VesselParams):
    """Return [u', v', p', r'] = M^-1 tau for forces ``tau`` (..., 4); numpy or torch."""
    xp = namespace(tau)
    return tau @ constant(inverse_mass_matrix_T(params), tau, xp)
