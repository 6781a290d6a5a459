"""
The multirotor's forces, term by term (rotorpy's ``Multirotor.compute_body_wrench``).

Vectors: ``z`` (..., 8) = [u, v, w, p, q, r, phi, theta]: the velocity of the CG through
the air (m/s) and the body rates (rad/s), FRD, then roll and pitch (rad, Euler ZYX);
``c`` (..., n_rotors) = the rotor speeds (rad/s, >= 0) in the order the parameter file
lists the rotors. Forces (..., 6) = [X, Y, Z, K, M, N] about the CG in FRD (N, N m).
A force F acting at a rotor's hub r = (x, y, z) adds the moment r x F. Every term is
written against the Array API (numpy, torch, jax), the rotors as arrays (..., n_rotors)
(the simulator evaluates the model at every RK4 stage: a loop over the rotors cost it
three times as much).

Rotor aerodynamics as rotorpy writes them (Forster 2015; Grafe et al. 2026): thrust
k_eta n^2 along -z, drag torque k_m n^2 about z, the H-force -n (k_d v_x, k_d v_y,
k_z v_z) and translational lift k_h (v_x^2 + v_y^2) at each hub in the hub's air
velocity v + w x r, parasitic drag -|v| diag(c_D) v at the CG. rotorpy's blade-flapping
moment is not modelled (its k_flap is 0 for the vehicles it ships).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.family import unit_force
from vessel_physics.multirotor.params import SPIN_SIGN, MultirotorParams

DOFS = ('X', 'Y', 'Z', 'K', 'M', 'N')
STATES = ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta')


def _wrench(like, fx=0.0, fy=0.0, fz=0.0, mx=0.0, my=0.0, mz=0.0):
    """Stack six components (arrays or floats) into (..., 6) shaped like ``like``."""
    xp = namespace(like)
    if xp is np:     # the simulator's path: filled in place, a third of the stack's time
        out = np.zeros(like.shape + (6,), dtype=like.dtype)
        for i, part in enumerate((fx, fy, fz, mx, my, mz)):
            if not (isinstance(part, float) and part == 0.0):
                out[..., i] = part
        return out
    zero = xp.zeros_like(like)
    return stack_last([zero + fx, zero + fy, zero + fz, zero + mx, zero + my, zero + mz], xp)


def _rotor_wrench(n, fx=None, fy=None, fz=None, mx=None, my=None, mz=None):
    """Sum per-rotor components (..., n_rotors) into a wrench (..., 6); None is zero."""
    # Each sum over the rotors is a product with ones: numpy's reduction over a short
    # last axis cost the diagnosis of 100 Hz flights ten times as much (a third of its time).
    ones = constant(np.ones(n.shape[-1]), n, namespace(n))
    return _wrench(n[..., 0], *(0.0 if part is None else part @ ones
                                for part in (fx, fy, fz, mx, my, mz)))


@lru_cache(maxsize=64)
def _rotor_table(params: MultirotorParams) -> np.ndarray:
    """Return the hubs' x, y, z (m, FRD) and spin signs of the rotors, (4, n_rotors)."""
    return np.array([[r.x for r in params.rotors], [r.y for r in params.rotors],
                     [r.z for r in params.rotors],
                     [SPIN_SIGN[r.spin] for r in params.rotors]])


def _rotors(z, c, params: MultirotorParams):
    """Return the speeds (..., n_rotors) and the hubs' x, y, z and spin signs, as ``z``."""
    xp = namespace(z, c)
    table = constant(_rotor_table(params), z, xp)
    return xp, c[..., :table.shape[1]], table[0], table[1], table[2], table[3]


@lru_cache(maxsize=64)
def _hub_velocity_map(params: MultirotorParams) -> np.ndarray:
    """
    Return A (6, 3 n_rotors): the hubs' velocities v + w x r_j = [u, v, w, p, q, r] A.

    Columns are x, then y, then z of every hub: v_x = u + q z_j - r y_j,
    v_y = v + r x_j - p z_j, v_z = w + p y_j - q x_j.
    """
    x, y, h, _ = _rotor_table(params)
    one, zero = np.ones_like(x), np.zeros_like(x)
    return np.block([[one, zero, zero], [zero, one, zero], [zero, zero, one],
                     [zero, -h, y], [h, zero, -x], [-y, x, zero]])


def _hub_air_velocity(z, params: MultirotorParams):
    """Return each hub's velocity through the air, v + w x r (m/s, FRD), (..., n_rotors)."""
    # One product with a constant matrix: elementwise, it was a fifth of a diagnosis.
    table = _hub_velocity_map(params)
    hubs = z[..., :6] @ constant(table, z, namespace(z))
    k = table.shape[1] // 3
    return hubs[..., :k], hubs[..., k:2 * k], hubs[..., 2 * k:]


def rigid_body_coriolis(z, c, params: MultirotorParams):
    """-C_RB(nu) nu at the CG: F = -m w x v, M = -w x (I w) (Newton-Euler; Fossen 2021, ch. 3)."""
    u, v, w, p, q, r = (z[..., i] for i in range(6))
    m = params.m
    h1 = params.Ixx * p + params.Ixy * q + params.Ixz * r     # I w, kg m^2/s
    h2 = params.Ixy * p + params.Iyy * q + params.Iyz * r
    h3 = params.Ixz * p + params.Iyz * q + params.Izz * r
    return _wrench(u, -m * (q * w - r * v), -m * (r * u - p * w), -m * (p * v - q * u),
                   -(q * h3 - r * h2), -(r * h1 - p * h3), -(p * h2 - q * h1))


def gravity(z, c, params: MultirotorParams):
    """Weight at the CG, FRD: m g (-sin theta, cos theta sin phi, cos theta cos phi)."""
    xp = namespace(z)
    phi, theta = z[..., 6], z[..., 7]
    weight = params.m * params.g
    return _wrench(phi, -weight * xp.sin(theta), weight * xp.cos(theta) * xp.sin(phi),
                   weight * xp.cos(theta) * xp.cos(phi))


def rotor_thrust(z, c, params: MultirotorParams):
    """Each rotor's thrust k_eta n^2 along -z (FRD) at its hub: Z and the moment r x F (K, M)."""
    _, n, x, y, _, _ = _rotors(z, c, params)
    thrust = params.k_eta * n * n                     # N, up: the force is -thrust along z
    return _rotor_wrench(n, fz=-thrust, mx=-y * thrust, my=x * thrust)


def rotor_torque(z, c, params: MultirotorParams):
    """Reaction of each rotor's drag torque: N = +k_m n^2 for ccw, -k_m n^2 for cw (params)."""
    _, n, _, _, _, spin = _rotors(z, c, params)
    return _wrench(z[..., 0], mz=params.k_m * ((n * n) @ spin))


def rotor_drag(z, c, params: MultirotorParams):
    """
    Rotor drag: each rotor's H-force in its hub's air velocity v_h = v + w x r, and moment.

    F = -n (k_d v_hx, k_d v_hy, k_z v_hz) at the hub (FRD; rotorpy's rotor drag and
    induced inflow, Forster 2015), M = r x F.
    """
    _, n, x, y, h, _ = _rotors(z, c, params)
    vx, vy, vz = _hub_air_velocity(z, params)
    hx, hy, hz = -params.k_d * n * vx, -params.k_d * n * vy, -params.k_z * n * vz
    return _rotor_wrench(n, hx, hy, hz, y * hz - h * hy, h * hx - x * hz, x * hy - y * hx)


def translational_lift(z, c, params: MultirotorParams):
    """
    Lift k_h (v_hx^2 + v_hy^2) of each hub's in-plane air speed along -z (translational).

    As rotorpy adds it to each rotor's thrust (independent of the rotor speed), with its
    moment r x F.
    """
    _, _, x, y, _, _ = _rotors(z, c, params)
    vx, vy, _ = _hub_air_velocity(z, params)
    lift = -params.k_h * (vx * vx + vy * vy)           # N along z at each hub
    return _rotor_wrench(lift, fz=lift, mx=y * lift, my=-x * lift)


def parasitic_drag(z, c, params: MultirotorParams):
    """Parasitic drag of the frame at the CG: -|v| (c_Dx u, c_Dy v, c_Dz w), N."""
    xp = namespace(z)
    u, v, w = z[..., 0], z[..., 1], z[..., 2]
    square = u * u + v * v + w * w
    # |v| with a zero (not NaN) gradient at rest: the inner where keeps sqrt off 0.
    moving = square > 0
    speed = xp.where(moving, xp.sqrt(xp.where(moving, square, xp.ones_like(square))),
                     xp.zeros_like(square))
    return _wrench(u, -speed * params.c_Dx * u, -speed * params.c_Dy * v,
                   -speed * params.c_Dz * w)


def rotor_share(index: int):
    """
    Return the candidate 'thrust of rotor ``index`` (from 0) off by a share'.

    The force of that rotor's thrust, its moment and its drag torque (a weak motor or a
    damaged propeller changes all three by the same share); zero where the parameters
    have fewer rotors.
    """
    def term(z, c, params: MultirotorParams):
        if index >= len(params.rotors):
            return _wrench(z[..., 0])
        rotor = params.rotors[index]
        n2 = c[..., index] * c[..., index]
        force = -params.k_eta * n2                     # N along z at the hub
        return _wrench(z[..., 0], fz=force, mx=rotor.y * force, my=-rotor.x * force,
                       mz=SPIN_SIGN[rotor.spin] * params.k_m * n2)

    term.__name__ = f'rotor{index + 1}_thrust'
    term.__doc__ = (f'Thrust, its moment and the drag torque of rotor {index + 1} in the '
                    f'file (``rotor_share``).')
    return term


def cg_offset_x(z, c, params: MultirotorParams):
    """Moment of the weight, CG 1 m forward: (0, -m g cos theta cos phi, m g cos theta sin phi)."""
    xp = namespace(z)
    phi, theta = z[..., 6], z[..., 7]
    weight = params.m * params.g
    return _wrench(phi, my=-weight * xp.cos(theta) * xp.cos(phi),
                   mz=weight * xp.cos(theta) * xp.sin(phi))


def cg_offset_y(z, c, params: MultirotorParams):
    """Moment of the weight, CG 1 m to starboard: (m g cos theta cos phi, 0, m g sin theta)."""
    xp = namespace(z)
    phi, theta = z[..., 6], z[..., 7]
    weight = params.m * params.g
    return _wrench(phi, mx=weight * xp.cos(theta) * xp.cos(phi), mz=weight * xp.sin(theta))


def _constant(z, dof: int):
    return unit_force(z, dof, len(DOFS))


def surge_bias(z, c, params: MultirotorParams):
    """Constant force X = 1 (N)."""
    return _constant(z, 0)


def sway_bias(z, c, params: MultirotorParams):
    """Constant force Y = 1 (N)."""
    return _constant(z, 1)


def heave_bias(z, c, params: MultirotorParams):
    """Constant force Z = 1 (N, down)."""
    return _constant(z, 2)


def roll_bias(z, c, params: MultirotorParams):
    """Constant moment K = 1 (N m)."""
    return _constant(z, 3)


def pitch_bias(z, c, params: MultirotorParams):
    """Constant moment M = 1 (N m)."""
    return _constant(z, 4)


def yaw_bias(z, c, params: MultirotorParams):
    """Constant moment N = 1 (N m)."""
    return _constant(z, 5)
