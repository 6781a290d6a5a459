"""
Fixed-step RK4 and the 4-DOF kinematics; array-agnostic so models can reuse them.

Kinematics for roll phi, pitch 0 (Fossen 2011, Euler angles, zyx): the body velocity
(u, v, 0) maps to NED as x' = u cos psi - v cos phi sin psi, y' = u sin psi +
v cos phi cos psi, and psi' = (q sin phi + r cos phi) / cos theta = r cos phi, phi' = p.
The exact psi' = r cos phi is used (the MSS model's psi' = r differs by < 0.2 % at
3 degrees of roll). psi is never wrapped.
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
