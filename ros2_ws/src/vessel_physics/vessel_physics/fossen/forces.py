"""
The Fossen matrix model's forces, term by term (Fossen 2021, ch. 6, 10 and 12).

Vectors: ``z`` (..., 3) = [u, v, r] through the water (surge, sway at CO in m/s, yaw rate
in rad/s, FRD); ``c`` (..., n_act [+ 3]) = the thrusters' shaft speeds (rad/s) and the
rudder angles (rad), in the order the parameter file lists them, then -- where the
vessel has a wind input -- the true wind speed (m/s) and the cos/sin of the angle it
comes from relative to the bow. Forces (..., 3) = [X, Y, N] about CO (N, N, N m).
Every term is written against the Array API (numpy, torch, jax).
"""

from __future__ import annotations

import math

import numpy as np

from vessel_physics.apparent import apparent_wind
from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.family import unit_force
from vessel_physics.fossen.params import FossenParams

DOFS = ('X', 'Y', 'N')
STATES = ('u', 'v', 'r')
CROSSFLOW_STRIPS = 20   # strip theory: midpoints of this many equal strips along the hull


def rigid_body_coriolis(z, c, params: FossenParams):
    """-C_RB(nu) nu: X = m (v r + x_G r^2), Y = -m u r, N = -m x_G u r."""
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    m = params.m
    return stack_last([m * (v * r + params.x_G * r * r), -m * u * r, -m * params.x_G * u * r], xp)


def added_mass_coriolis(z, c, params: FossenParams):
    """
    -C_A(nu_r) nu_r of the added-mass matrix (symmetrized, as Fossen's m2c does).

    With a11 = -Xudot, a22 = -Yvdot, a23 = -(Yrdot + Nvdot) / 2: X = (a22 v + a23 r) r,
    Y = -a11 u r, N = (a11 - a22) u v - a23 u r (the Munk moment (a11 - a22) u v).
    """
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    a11, a22 = -params.Xudot, -params.Yvdot
    a23 = -0.5 * (params.Yrdot + params.Nvdot)
    return stack_last([(a22 * v + a23 * r) * r, -a11 * u * r,
                       (a11 - a22) * u * v - a23 * u * r], xp)


def damping_features(z):
    """Return the damping features [u, |u|u, v, r, |v|v, |r|r] (..., 6)."""
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    return stack_last([u, xp.abs(u) * u, v, r, xp.abs(v) * v, xp.abs(r) * r], xp)


def damping_matrix(params: FossenParams) -> np.ndarray:
    """Return the (6, 3) coefficients: damping = features @ matrix."""
    p = params
    return np.array([(p.Xu, 0.0, 0.0), (p.Xuu, 0.0, 0.0), (0.0, p.Yv, p.Nv),
                     (0.0, p.Yr, p.Nr), (0.0, p.Yvv, 0.0), (0.0, 0.0, p.Nrr)])


def damping(z, c, params: FossenParams):
    """Linear and quadratic damping -D(nu_r) nu_r: Xu u + X|u|u |u|u, Yv v + Yr r + ..."""
    xp = namespace(z)
    return damping_features(z) @ constant(damping_matrix(params), z, xp)


def crossflow(z, c, params: FossenParams):
    """
    Cross-flow drag of strip theory (Fossen 2021, 6.4.1).

    The hull's sections in the local sway flow v + x r, each with the 2-D drag of a
    section of draught T:

    Y = -rho/2 T Cd int (v + x r)|v + x r| dx, N = -rho/2 T Cd int x (v + x r)|v + x r| dx
    over x in [-L/2, L/2], by the midpoint rule on ``CROSSFLOW_STRIPS`` strips.
    """
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    length = params.crossflow_length
    dx = length / CROSSFLOW_STRIPS
    # All strips at once (a trailing axis): one broadcast instead of a Python loop of
    # small-array operations, which dominated the Otter's training step.
    x = constant(-0.5 * length + (np.arange(CROSSFLOW_STRIPS) + 0.5) * dx, z, xp)
    k = -0.5 * params.rho * params.crossflow_draft * params.crossflow_Cd * dx
    flow = v[..., None] + x * r[..., None]
    drag = k * flow * xp.abs(flow)
    return stack_last([xp.zeros_like(u), xp.sum(drag, axis=-1), xp.sum(x * drag, axis=-1)], xp)


def thrust(n, thruster):
    """Thrust (N) of one thruster at shaft speed ``n`` (rad/s): k n|n|, k by direction."""
    xp = namespace(n)
    ahead = xp.astype(n > 0, n.dtype)     # keeps the dtype (a where of floats would not)
    k = thruster.k_reverse + (thruster.k_forward - thruster.k_reverse) * ahead
    return k * n * xp.abs(n)


def _thruster_force(c, params: FossenParams, weights):
    """Sum of thrust vectors and their moments about CO, thruster i weighted weights[i]."""
    xp = namespace(c)
    x_force = y_force = n_moment = 0.0
    for i, t in enumerate(params.thrusters):
        if not weights[i]:
            continue
        force = weights[i] * thrust(c[..., i], t)
        fx, fy = force * math.cos(t.angle), force * math.sin(t.angle)
        x_force = x_force + fx
        y_force = y_force + fy
        n_moment = n_moment + t.x * fy - t.y * fx
    zero = xp.zeros_like(c[..., 0])
    return stack_last([zero + x_force, zero + y_force, zero + n_moment], xp)


def thrusters(z, c, params: FossenParams):
    """Every thruster's force (T cos a, T sin a) at (x, y): X, Y and N = x Fy - y Fx."""
    return _thruster_force(c, params, [1.0] * len(params.thrusters))


def port_thrust(z, c, params: FossenParams):
    """Force of the thrusters on the port side (y < 0): a coefficient is their share lost."""
    return _thruster_force(c, params, [1.0 if t.y < 0 else 0.0 for t in params.thrusters])


def starboard_thrust(z, c, params: FossenParams):
    """Force of the thrusters on the starboard side (y > 0)."""
    return _thruster_force(c, params, [1.0 if t.y > 0 else 0.0 for t in params.thrusters])


def rudders(z, c, params: FossenParams):
    """
    Lift of each rudder in the surge inflow: F = rho/2 A C_L' delta u|u|.

    A lifting surface without stall or propeller race (a first approximation for small
    craft).

    It acts at (x, y) as X = -F sin delta, Y = -F cos delta (a positive angle pushes the
    stern to port and turns the craft to starboard), N = x Y - y X.
    """
    xp = namespace(z, c)
    u = z[..., 0]
    first = len(params.thrusters)
    x_force = y_force = n_moment = xp.zeros_like(u)
    for j, rudder in enumerate(params.rudders):
        delta = c[..., first + j]
        lift = 0.5 * params.rho * rudder.area * rudder.lift_slope * delta * u * xp.abs(u)
        fx, fy = -lift * xp.sin(delta), -lift * xp.cos(delta)
        x_force = x_force + fx
        y_force = y_force + fy
        n_moment = n_moment + rudder.x * fy - rudder.y * fx
    return stack_last([x_force, y_force, n_moment], xp)


def wind(z, c, params: FossenParams):
    """
    Return the load of the apparent wind, Fossen 2021 10.1; ``z`` over ground.

    X = -q c_x A_F cos g, Y = -q c_y A_L sin g, N = -q c_n A_L L_oa sin 2g with
    q = rho_a V_r^2 / 2 and g the angle the apparent wind comes from.

    Zero where the vessel has no wind input (``c`` holds its actuators only).
    """
    xp = namespace(z, c)
    first = len(params.actuators)
    if c.shape[-1] < first + 3:
        return xp.zeros_like(z)
    q, cos_g, sin_g = apparent_wind(z[..., 0], z[..., 1], c[..., first], c[..., first + 1],
                                    c[..., first + 2])
    return stack_last([-q * params.wind_cx * params.wind_AF * cos_g,
                       -q * params.wind_cy * params.wind_AL * sin_g,
                       -2.0 * q * params.wind_cn * params.wind_AL * params.wind_Loa * sin_g
                       * cos_g], xp)


def _constant(z, dof: int):
    return unit_force(z, dof, len(DOFS))


def surge_bias(z, c, params: FossenParams):
    """Constant surge force X = 1 (N)."""
    return _constant(z, 0)


def sway_bias(z, c, params: FossenParams):
    """Constant sway force Y = 1 (N)."""
    return _constant(z, 1)


def yaw_bias(z, c, params: FossenParams):
    """Constant yaw moment N = 1 (N m)."""
    return _constant(z, 2)
