"""The apparent wind seen from a moving hull: one definition for every family's wind loads."""

from __future__ import annotations

from vessel_physics.arrays import namespace

RHO_AIR = 1.224  # kg/m^3, air density of Isherwood (1972) and Fossen (2011)


def apparent_wind(u, v, speed, dir_cos, dir_sin):
    """
    Return (q, cos gamma_r, sin gamma_r) of the apparent wind; numpy, torch or jax.

    q = rho_a V_r^2 / 2 (Pa) and gamma_r the angle the apparent wind comes from relative
    to the bow (+ starboard), from the ground velocity u, v (m/s, FRD) and the true wind:
    its speed (m/s) and the cos/sin of the angle it comes from relative to the bow. In a
    calm (V_r = 0) the angle is taken as head wind; q is 0 there anyway.
    """
    xp = namespace(u, speed)
    from_x = speed * dir_cos + u
    from_y = speed * dir_sin + v
    v2 = from_x * from_x + from_y * from_y
    calm = v2 < 1e-12
    norm = xp.sqrt(xp.where(calm, 1.0, v2))
    cos_g = xp.where(calm, 1.0, from_x / norm)
    sin_g = xp.where(calm, 0.0, from_y / norm)
    return 0.5 * RHO_AIR * v2, cos_g, sin_g
