"""
The MMG standard manoeuvring model (Yasukawa & Yoshimura 2015), batched, Array API.

The forces of the MMG family (conventional single-screw, single-rudder ships). Frames and
vectors:

- ``z`` (..., 3): [u, v_m, r]: surge and sway velocity at midship (m/s) and yaw rate
  (rad/s), FRD body frame with its origin at midship (the MMG reference point);
- ``c`` (..., 2): [n, delta]: propeller speed (rad/s, ahead >= 0; the model's K_T(J)
  is the ahead open-water curve) and rudder angle (rad, positive turns the ship to
  starboard, the MMG convention);
- forces (..., 3): [X, Y, N] about midship (N, N, N m).

The equations follow the paper: hull forces as polynomials in v' = v_m/U and
r' = r L_pp/U, propeller thrust (1 - t_P) rho n^2 D_p^4 K_T(J_P) with the wake fraction
w_P(beta_P), and the rudder normal force F_N from the effective inflow (u_R with the
propeller race, v_R with flow straightening gamma_R) acting through t_R, a_H and x_H.
They are rewritten where the printed form divides by a quantity that can vanish
(U, n, J), so that rest and zero thrust are regular points, and every function runs on
numpy (simulation, diagnosis) and torch (hybrid models, with autograd).

``shipmmg`` (PyPI) implements the same model for scalar states with scipy's solve_ivp;
``tests/unit/test_mmg.py`` holds our forces and a zig-zag equal to it. Two documented
departures of that package from the paper are options or do not arise there: its wake
fraction w_P0 exp(-4 beta_P^2) is ``wake_model: exponential`` here (the paper's
``yasukawa2015`` form is the default), and it forms U and beta from v_m - x_G r while
v' uses v_m; the paper uses v_m for all three, as this module does.
"""

from __future__ import annotations

import math

from vessel_physics.arrays import namespace, stack_last
from vessel_physics.mmg.params import MmgParams

DOFS = ('X', 'Y', 'N')
STATE_NAMES = ('u', 'v', 'r')
# Speed (m/s) added in quadrature to U (and to the propeller-race speed): the hull
# polynomials have terms of order U^-1 (v^3 / U) and square roots have no slope at 0;
# far below any manoeuvring speed, it keeps rest a regular point with finite gradients.
MIN_SPEED = 1e-6
EXPONENTIAL_WAKE_DECAY = 4.0   # w_P = w_P0 exp(-4 beta_P^2) (the exponential wake model)


# ---------------------------------------------------------------- kinematic quantities
def _speed(xp, u, v):
    """Return U = sqrt(u^2 + v_m^2 + MIN_SPEED^2) (m/s): smooth, never zero."""
    return xp.sqrt(u * u + v * v + MIN_SPEED * MIN_SPEED)


def _drift(xp, u, v):
    """Return the drift angle beta = asin(-v_m / U) (rad; atan(-v_m/u) ahead)."""
    return xp.asin(-v / _speed(xp, u, v))


def _select(xp, condition, like, if_true: float, if_false: float):
    """Return if_true where ``condition`` holds, else if_false, as floats like ``like``."""
    return if_false + (if_true - if_false) * xp.astype(condition, like.dtype)


def wake_fraction(z, params: MmgParams):
    """Return the propeller wake fraction w_P at the states z (..., 3)."""
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    speed = _speed(xp, u, v)
    beta_p = _drift(xp, u, v) - params.x_P * (r * params.L_pp / speed)
    if params.wake_model == 'exponential':
        return params.w_P0 * xp.exp(-EXPONENTIAL_WAKE_DECAY * beta_p * beta_p)
    c_2 = _select(xp, beta_p > 0, beta_p, params.C_2_plus, params.C_2_minus)
    factor = 1.0 + (1.0 - xp.exp(-params.C_1 * xp.abs(beta_p))) * (c_2 - 1.0)
    return 1.0 - (1.0 - params.w_P0) * factor


def _thrust_coefficient_n2(xp, n_rps, u_a, params: MmgParams):
    """Return K_T(J) n^2 D_p^2 (m^2/s^2) for J = u_a / (n D_p), without dividing by n."""
    d = params.D_p
    return params.k_0 * d * d * n_rps * n_rps + params.k_1 * d * n_rps * u_a \
        + params.k_2 * u_a * u_a


# ---------------------------------------------------------------- the three force groups
def hull(z, c, params: MmgParams):
    """Hull forces [X_H, Y_H, N_H] (..., 3) from the polynomials in v' and r'."""
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    speed = _speed(xp, u, v)
    v_d, r_d = v / speed, r * params.L_pp / speed
    q = 0.5 * params.rho * params.L_pp * params.d * (u * u + v * v)
    p = params
    x = -p.R_0 + p.X_vv * v_d * v_d + p.X_vr * v_d * r_d + p.X_rr * r_d * r_d \
        + p.X_vvvv * v_d ** 4
    y = p.Y_v * v_d + p.Y_r * r_d + p.Y_vvv * v_d ** 3 + p.Y_vvr * v_d * v_d * r_d \
        + p.Y_vrr * v_d * r_d * r_d + p.Y_rrr * r_d ** 3
    n = p.N_v * v_d + p.N_r * r_d + p.N_vvv * v_d ** 3 + p.N_vvr * v_d * v_d * r_d \
        + p.N_vrr * v_d * r_d * r_d + p.N_rrr * r_d ** 3
    return stack_last([q * x, q * y, q * params.L_pp * n], xp)


def propeller(z, c, params: MmgParams):
    """Propeller force [X_P, 0, 0] (..., 3): (1 - t_P) rho n^2 D_p^4 K_T(J_P)."""
    xp = namespace(z, c)
    u = z[..., 0]
    n_rps = c[..., 0] / (2.0 * math.pi)
    u_a = (1.0 - wake_fraction(z, params)) * u
    thrust = params.rho * params.D_p ** 2 * _thrust_coefficient_n2(xp, n_rps, u_a, params)
    zero = xp.zeros_like(u)
    return stack_last([(1.0 - params.t_P) * thrust, zero, zero], xp)


def rudder_normal_force(z, c, params: MmgParams):
    """
    Return the rudder normal force F_N (N) from the effective inflow (u_R, v_R).

    u_R = epsilon sqrt(eta (u_a (1 - kappa) + kappa sqrt(u_a^2 + 8 K_T n^2 D_p^2 / pi))^2
    + (1 - eta) u_a^2) with u_a = (1 - w_P) u: the paper's form with J eliminated, so the
    propeller race of a ship at rest is regular. v_R = U gamma_R beta_R,
    beta_R = beta - l_R' r'.
    """
    xp = namespace(z, c)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    delta = c[..., 1] + params.delta_0
    n_rps = c[..., 0] / (2.0 * math.pi)
    speed = _speed(xp, u, v)
    u_a = (1.0 - wake_fraction(z, params)) * u
    race = 8.0 / math.pi * xp.maximum(_thrust_coefficient_n2(xp, n_rps, u_a, params), 0.0)
    eta = params.D_p / params.H_R
    ahead = u_a * (1.0 - params.kappa) + params.kappa * xp.sqrt(u_a * u_a + race
                                                                 + MIN_SPEED * MIN_SPEED)
    u_r = params.epsilon * xp.sqrt(eta * ahead * ahead + (1.0 - eta) * u_a * u_a)
    beta_r = _drift(xp, u, v) - params.l_R * (r * params.L_pp / speed)
    gamma = _select(xp, beta_r < 0, beta_r, params.gamma_R_minus, params.gamma_R_plus)
    v_r = speed * gamma * beta_r
    alpha = delta - xp.atan2(v_r, u_r)
    return 0.5 * params.rho * params.A_R * params.f_alpha * (u_r * u_r + v_r * v_r) \
        * xp.sin(alpha)


def rudder(z, c, params: MmgParams):
    """Rudder forces with hull interaction [X_R, Y_R, N_R] (..., 3)."""
    xp = namespace(z, c)
    delta = c[..., 1] + params.delta_0
    f_n = rudder_normal_force(z, c, params)
    lever = (params.x_R + params.a_H * params.x_H) * params.L_pp
    return stack_last([-(1.0 - params.t_R) * f_n * xp.sin(delta),
                       -(1.0 + params.a_H) * f_n * xp.cos(delta),
                       -lever * f_n * xp.cos(delta)], xp)


def inertial(z, c, params: MmgParams):
    """
    Return the velocity-dependent inertial forces (..., 3) moved to the right-hand side.

    (m + m_y) v_m r + x_G m r^2, -(m + m_x) u r and -x_G m u r (Yasukawa & Yoshimura
    2015, eq. 4).
    """
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    m, unit = params.mass, params.half_rho_l2d
    return stack_last([(m + params.m_y * unit) * v * r + params.x_G * m * r * r,
                       -(m + params.m_x * unit) * u * r,
                       -params.x_G * m * u * r], xp)


def bias(z, c, params: MmgParams):
    """Return the constant forces [X_0, Y_0, N_0] (..., 3), e.g. a diagnosed asymmetry."""
    xp = namespace(z)
    ones = xp.ones_like(z[..., 0])
    return stack_last([params.X_0 * ones, params.Y_0 * ones, params.N_0 * ones], xp)
