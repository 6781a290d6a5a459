"""
The multirotor's forces, term by term (rotorpy's ``Multirotor.compute_body_wrench``).

Vectors: ``z`` (..., 8) = [u, v, w, p, q, r, phi, theta]: the velocity of the CG through
the air (m/s) and the body rates (rad/s), FRD, then roll and pitch (rad, Euler ZYX);
``c`` (..., n_rotors) = the rotor speeds (rad/s, >= 0) in the order the parameter file
lists the rotors. Forces (..., 6) = [X, Y, Z, K, M, N] about the CG in FRD (N, N m).
A force F acting at a rotor's hub r = (x, y, z) adds the moment r x F. Every term is
written against the Array API (numpy, torch, jax).

Rotor aerodynamics as rotorpy writes them (Forster 2015; Grafe et al. 2026): thrust
k_eta n^2 along -z, drag torque k_m n^2 about z, the H-force -n (k_d v_x, k_d v_y,
k_z v_z) and translational lift k_h (v_x^2 + v_y^2) at each hub in the hub's air
velocity v + w x r, parasitic drag -|v| diag(c_D) v at the CG. rotorpy's blade-flapping
moment is not modelled (its k_flap is 0 for the vehicles it ships).
"""

from __future__ import annotations

from vessel_physics.arrays import namespace
from vessel_physics.family import unit_force
from vessel_physics.multirotor.params import SPIN_SIGN, MultirotorParams, Rotor

DOFS = ('X', 'Y', 'Z', 'K', 'M', 'N')
STATES = ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta')


def _wrench(like, fx=0.0, fy=0.0, fz=0.0, mx=0.0, my=0.0, mz=0.0):
    """Stack six components (arrays or floats) into (..., 6) shaped like ``like``."""
    xp = namespace(like)
    zero = xp.zeros_like(like)
    return xp.stack([zero + fx, zero + fy, zero + fz, zero + mx, zero + my, zero + mz],
                    axis=-1)


def _at_hub(rotor: Rotor, fx, fy, fz):
    """Return the moment r x F (K, M, N) of a force at the rotor's hub."""
    return (rotor.y * fz - rotor.z * fy, rotor.z * fx - rotor.x * fz,
            rotor.x * fy - rotor.y * fx)


def _hub_air_velocity(z, rotor: Rotor):
    """Return the hub's velocity through the air, v + w x r (m/s, FRD)."""
    u, v, w, p, q, r = (z[..., i] for i in range(6))
    return (u + q * rotor.z - r * rotor.y, v + r * rotor.x - p * rotor.z,
            w + p * rotor.y - q * rotor.x)


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


def _thrust_and_torque(z, c, params: MultirotorParams, weights, thrust=True, torque=True):
    """Thrust k_eta n^2 along -z at each hub (with r x F) and drag torque, rotor i weighted."""
    fz = mx = my = mz = 0.0
    for i, rotor in enumerate(params.rotors):
        if not weights[i]:
            continue
        n2 = c[..., i] * c[..., i]
        if thrust:
            force = -weights[i] * params.k_eta * n2
            k, m, _ = _at_hub(rotor, 0.0, 0.0, force)
            fz, mx, my = fz + force, mx + k, my + m
        if torque:
            mz = mz + weights[i] * SPIN_SIGN[rotor.spin] * params.k_m * n2
    return _wrench(z[..., 0], 0.0, 0.0, fz, mx, my, mz)


def rotor_thrust(z, c, params: MultirotorParams):
    """Each rotor's thrust k_eta n^2 along -z (FRD) at its hub: Z and the moment r x F (K, M)."""
    return _thrust_and_torque(z, c, params, [1.0] * len(params.rotors), torque=False)


def rotor_torque(z, c, params: MultirotorParams):
    """Reaction of each rotor's drag torque: N = +k_m n^2 for ccw, -k_m n^2 for cw (params)."""
    return _thrust_and_torque(z, c, params, [1.0] * len(params.rotors), thrust=False)


def rotor_drag(z, c, params: MultirotorParams):
    """
    Rotor drag: each rotor's H-force in its hub's air velocity v_h = v + w x r, and moment.

    F = -n (k_d v_hx, k_d v_hy, k_z v_hz) at the hub (FRD; rotorpy's rotor drag and
    induced inflow, Forster 2015), M = r x F.
    """
    fx = fy = fz = mx = my = mz = 0.0
    for i, rotor in enumerate(params.rotors):
        n = c[..., i]
        vx, vy, vz = _hub_air_velocity(z, rotor)
        hx, hy, hz = -n * params.k_d * vx, -n * params.k_d * vy, -n * params.k_z * vz
        k, m, nn = _at_hub(rotor, hx, hy, hz)
        fx, fy, fz, mx, my, mz = fx + hx, fy + hy, fz + hz, mx + k, my + m, mz + nn
    return _wrench(z[..., 0], fx, fy, fz, mx, my, mz)


def translational_lift(z, c, params: MultirotorParams):
    """
    Lift k_h (v_hx^2 + v_hy^2) of each hub's in-plane air speed along -z (translational).

    As rotorpy adds it to each rotor's thrust (independent of the rotor speed), with its
    moment r x F.
    """
    fz = mx = my = 0.0
    for rotor in params.rotors:
        vx, vy, _ = _hub_air_velocity(z, rotor)
        lift = -params.k_h * (vx * vx + vy * vy)
        k, m, _ = _at_hub(rotor, 0.0, 0.0, lift)
        fz, mx, my = fz + lift, mx + k, my + m
    return _wrench(z[..., 0], 0.0, 0.0, fz, mx, my, 0.0)


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
        weights = [1.0 if i == index else 0.0 for i in range(len(params.rotors))]
        return _thrust_and_torque(z, c, params, weights)

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
