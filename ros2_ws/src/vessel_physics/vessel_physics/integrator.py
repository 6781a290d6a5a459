"""
Fixed-step RK4 and the kinematics of vessels and 6-DOF vehicles; array-agnostic.

Euler angles ZYX (Fossen 2021, eq. 2.29 and 2.41): the body velocity (u, v, w) maps to
NED as R(phi, theta, psi) (u, v, w) and the attitude follows the body rates as

    phi' = p + (q sin phi + r cos phi) tan theta
    theta' = q cos phi - r sin phi
    psi' = (q sin phi + r cos phi) / cos theta

A vessel in the plane has pitch 0 and no heave: x' = u cos psi - v cos phi sin psi,
y' = u sin psi + v cos phi cos psi, psi' = r cos phi (the MSS model's psi' = r differs by
< 0.2 % at 3 degrees of roll) and phi' = p. psi is never wrapped; pitch must stay
inside +-pi/2 (the Euler angles' singularity).
"""

from __future__ import annotations

from collections.abc import Callable

from vessel_physics.arrays import namespace


def rk4_step(f: Callable, t: float, x, dt: float):
    """Advance ``x' = f(t, x)`` by one classical Runge-Kutta step of ``dt`` seconds."""
    k1 = f(t, x)
    k2 = f(t + 0.5 * dt, x + (0.5 * dt) * k1)
    k3 = f(t + 0.5 * dt, x + (0.5 * dt) * k2)
    k4 = f(t + dt, x + dt * k3)
    return x + (dt / 6.0) * (k1 + 2.0 * (k2 + k3) + k4)


def held_period(derivative: Callable, z, c, period: float, substeps: int, repeat=None):
    """
    Advance ``z' = derivative(z, c)`` by one sample period (s) with the control c held.

    Classical RK4 with ``substeps`` equal steps (zero-order hold). ``repeat(n, body, x)``
    applies ``body`` n times; the default is a Python loop, a compiled program passes
    its own loop.
    """
    h = period / substeps

    def body(x):
        return rk4_step(lambda _t, s: derivative(s, c), 0.0, x, h)

    if repeat is not None:
        return repeat(substeps, body, z)
    for _ in range(substeps):
        z = body(z)
    return z


def free_run(derivative: Callable, z0, controls, period: float, substeps: int = 1):
    """
    Integrate ``z' = derivative(z, c)`` from ``z0`` (..., n) under ``controls`` (..., T, m).

    Each control is held for one sample ``period`` (s) of ``substeps`` RK4 steps. Returns
    the states (..., T + 1, n) at the T + 1 sample instants.
    """
    xp = namespace(z0, controls)
    z = z0
    out = [z]
    for k in range(controls.shape[-2]):
        z = held_period(derivative, z, controls[..., k, :], period, substeps)
        out.append(z)
    return xp.stack(out, axis=-2)


def kinematics(u, v, r, phi, psi):
    """Return (x', y', psi') in NED (m/s, m/s, rad/s) for FRD u, v (m/s), r (rad/s), phi, psi."""
    xp = namespace(u, v, r, phi, psi)
    cos_psi, sin_psi, cos_phi = xp.cos(psi), xp.sin(psi), xp.cos(phi)
    v_level = v * cos_phi
    return (u * cos_psi - v_level * sin_psi, u * sin_psi + v_level * cos_psi, r * cos_phi)


def attitude_rates(p, q, r, phi, theta):
    """Return (phi', theta', psi') in rad/s for FRD body rates p, q, r at roll, pitch."""
    xp = namespace(p, q, r, phi, theta)
    sin_phi, cos_phi = xp.sin(phi), xp.cos(phi)
    turn = q * sin_phi + r * cos_phi
    cos_theta = xp.cos(theta)
    return (p + turn * xp.sin(theta) / cos_theta, q * cos_phi - r * sin_phi,
            turn / cos_theta)


def body_to_ned(u, v, w, phi, theta, psi):
    """Return the NED components (m/s) of the FRD body vector (u, v, w): R(phi, theta, psi)."""
    xp = namespace(u, v, w, phi, theta, psi)
    cf, sf = xp.cos(phi), xp.sin(phi)
    ct, st = xp.cos(theta), xp.sin(theta)
    cp, sp = xp.cos(psi), xp.sin(psi)
    return (cp * ct * u + (cp * st * sf - sp * cf) * v + (cp * st * cf + sp * sf) * w,
            sp * ct * u + (sp * st * sf + cp * cf) * v + (sp * st * cf - cp * sf) * w,
            -st * u + ct * sf * v + ct * cf * w)


def ned_to_body_3d(north, east, down, phi, theta, psi):
    """Return the FRD body components of a NED vector: R(phi, theta, psi)^T (n, e, d)."""
    xp = namespace(north, east, down, phi, theta, psi)
    cf, sf = xp.cos(phi), xp.sin(phi)
    ct, st = xp.cos(theta), xp.sin(theta)
    cp, sp = xp.cos(psi), xp.sin(psi)
    return (cp * ct * north + sp * ct * east - st * down,
            (cp * st * sf - sp * cf) * north + (sp * st * sf + cp * cf) * east + ct * sf * down,
            (cp * st * cf + sp * sf) * north + (sp * st * cf - cp * sf) * east + ct * cf * down)
