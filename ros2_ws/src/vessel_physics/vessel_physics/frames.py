"""
The one place converting Fossen NED/FRD <-> ROS ENU/FLU (REP-103/105).

Physics (this package): world NED (x north, y east, z down), body FRD (x forward,
y starboard, z down), heading psi from north towards east. ROS messages: world ENU
(``odom``), body FLU (``base_link``). The conversions are exact both ways and keep
unwrapped headings unwrapped (yaw_enu = pi/2 - psi_ned is affine, not wrapped). Roll is the
same angle in FRD and FLU (a rotation about the shared x axis); pitch and the y, z body
components change sign. All functions work element-wise on floats or numpy arrays.
"""

from __future__ import annotations

import math

import numpy as np

HALF_PI = 0.5 * math.pi


def position_ned_to_enu(north, east, down=0.0):
    """Return (x_enu, y_enu, z_enu) = (east, north, -down) in m."""
    return east, north, -down


def position_enu_to_ned(x_enu, y_enu, z_enu=0.0):
    """Return (north, east, down) = (y_enu, x_enu, -z_enu) in m."""
    return y_enu, x_enu, -z_enu


def heading_ned_to_enu(psi):
    """Return ENU yaw (rad, from east towards north) for NED heading ``psi``."""
    return HALF_PI - psi


def heading_enu_to_ned(yaw):
    """Return NED heading (rad, from north towards east) for ENU yaw."""
    return HALF_PI - yaw


def ned_to_body(north, east, psi):
    """
    Return a horizontal NED vector (north, east) in the levelled body frame at ``psi``.

    (forward, starboard) at heading ``psi`` (rad): the one rotation of earth-frame
    velocities (currents, tracked velocities) into the body.
    """
    cos_psi, sin_psi = np.cos(psi), np.sin(psi)
    return north * cos_psi + east * sin_psi, -north * sin_psi + east * cos_psi


def body_frd_to_flu(x, y, z=0.0):
    """Return a body vector (velocity or rate) from FRD to FLU: (x, -y, -z)."""
    return x, -y, -z


def body_flu_to_frd(x, y, z=0.0):
    """Return a body vector from FLU to FRD: (x, -y, -z) (the map is its own inverse)."""
    return x, -y, -z


def twist_frd_to_flu(u, v, p, r):
    """Return (linear.x, linear.y, angular.x, angular.z) in FLU for FRD u, v, p, r."""
    return u, -v, p, -r


def twist_flu_to_frd(vx, vy, wx, wz):
    """Return (u, v, p, r) in FRD for FLU linear x, y and angular x, z."""
    return vx, -vy, wx, -wz


def state_signs_frd_to_flu(state_names) -> np.ndarray:
    """
    Return the sign of each model state (u, v, w, p, q, r, phi, theta) from FRD to FLU.

    Velocities and rates are body vectors (``body_frd_to_flu``); roll phi is the same
    angle in both frames, pitch theta changes sign with the y axis it turns about
    (``orientation_ned_to_enu``). The map is its own inverse, so the same signs take
    FLU back to FRD.
    """
    u, v, w = body_frd_to_flu(1.0, 1.0, 1.0)
    p, q, r = body_frd_to_flu(1.0, 1.0, 1.0)
    signs = {'u': u, 'v': v, 'w': w, 'p': p, 'q': q, 'r': r, 'phi': 1.0, 'theta': -1.0}
    return np.array([signs[name] for name in state_names])


def states_frd_to_flu(z, state_names) -> np.ndarray:
    """Return model states z (..., n_state), FRD, in FLU (REP-103 ``base_link``)."""
    return np.asarray(z, dtype=float) * state_signs_frd_to_flu(state_names)


def states_flu_to_frd(z, state_names) -> np.ndarray:
    """Return states z (..., n_state) given in FLU in the model's FRD."""
    return np.asarray(z, dtype=float) * state_signs_frd_to_flu(state_names)


def interval_frd_to_flu(lower, upper, state_names) -> tuple[np.ndarray, np.ndarray]:
    """
    Return an interval of states [lower, upper] (..., n_state), FRD, in FLU.

    A state whose sign changes swaps its ends, so lower <= upper still holds.
    """
    signs = state_signs_frd_to_flu(state_names)
    a = np.asarray(lower, dtype=float) * signs
    b = np.asarray(upper, dtype=float) * signs
    return np.minimum(a, b), np.maximum(a, b)


def quaternion_from_euler(roll, pitch, yaw):
    """Return (x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll) (any consistent frame pair)."""
    cr, sr = np.cos(0.5 * np.asarray(roll)), np.sin(0.5 * np.asarray(roll))
    cp, sp = np.cos(0.5 * np.asarray(pitch)), np.sin(0.5 * np.asarray(pitch))
    cy, sy = np.cos(0.5 * np.asarray(yaw)), np.sin(0.5 * np.asarray(yaw))
    return (sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy)


def euler_from_quaternion(x, y, z, w):
    """Return (roll, pitch, yaw) in rad, yaw in (-pi, pi], for a unit quaternion."""
    x, y, z, w = (np.asarray(a, dtype=float) for a in (x, y, z, w))
    roll = np.arctan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2.0 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def orientation_ned_to_enu(phi, psi, theta=0.0):
    """Return the ENU/FLU quaternion (x, y, z, w) of the FRD body at roll, pitch, heading."""
    return quaternion_from_euler(phi, -theta, heading_ned_to_enu(psi))


def orientation_enu_to_ned(x, y, z, w):
    """Return (phi, theta, psi) in NED/FRD, psi in (-pi/2, 3pi/2], from an ENU/FLU quaternion."""
    roll, pitch, yaw = euler_from_quaternion(x, y, z, w)
    return roll, -pitch, heading_enu_to_ned(yaw)


def wind_to_flu(speed, dir_cos, dir_sin):
    """
    Return the true wind velocity (m/s, where the air moves to) in FLU.

    ``dir_cos``, ``dir_sin`` describe the angle the wind comes *from* relative to the bow,
    positive towards starboard (docs/conventions.md). The air moves the opposite way:
    -(cos, sin) in FRD, i.e. (-cos, +sin) in FLU.
    """
    return -speed * dir_cos, speed * dir_sin, 0.0 * speed


def wind_from_flu(vx, vy):
    """Return (speed, dir_cos, dir_sin) of a true wind velocity given in FLU (m/s)."""
    speed = np.hypot(vx, vy)
    safe = np.where(speed > 0, speed, 1.0)
    return speed, np.where(speed > 0, -vx / safe, 1.0), np.where(speed > 0, vy / safe, 0.0)
