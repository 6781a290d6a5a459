"""
The MMG standard manoeuvring model (Yasukawa & Yoshimura 2015), batched, Array API.

A physics family for conventional single-screw, single-rudder ships, beside the patrol
boat's 4-DOF terms (``vessel_physics.terms``). Frames and vectors:

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

from collections.abc import Iterable
import dataclasses
from dataclasses import dataclass, fields
import math
from pathlib import Path

from vessel_physics.arrays import namespace
from vessel_physics.errors import ConfigError
from vessel_physics.files import check_ranges, numeric_fields, read_yaml
from vessel_physics.integrator import held_period
from vessel_physics.params import config_dir

FORMAT = 'mmg-params/1'
DOFS = ('X', 'Y', 'N')
STATE_NAMES = ('u', 'v', 'r')
WAKE_MODELS = ('yasukawa2015', 'exponential')
# Speed (m/s) added in quadrature to U (and to the propeller-race speed): the hull
# polynomials have terms of order U^-1 (v^3 / U) and square roots have no slope at 0;
# far below any manoeuvring speed, it keeps rest a regular point with finite gradients.
MIN_SPEED = 1e-6
EXPONENTIAL_WAKE_DECAY = 4.0   # w_P = w_P0 exp(-4 beta_P^2) (the exponential wake model)

# Non-dimensional hull derivatives: forces / (rho/2 L d U^2), moments / (rho/2 L^2 d U^2).
HULL_X = ('R_0', 'X_vv', 'X_vr', 'X_rr', 'X_vvvv')
HULL_Y = ('Y_v', 'Y_r', 'Y_vvv', 'Y_vvr', 'Y_vrr', 'Y_rrr')
HULL_N = ('N_v', 'N_r', 'N_vvv', 'N_vvr', 'N_vrr', 'N_rrr')


@dataclass(frozen=True)
class MmgParams:
    """
    Parameters of one MMG model; dimensional particulars SI, the rest as published.

    Primed quantities (``*_dash`` in the paper) are non-dimensional: masses by
    rho/2 L_pp^2 d, inertias by rho/2 L_pp^4 d, lengths by L_pp.
    """

    name: str
    rho: float          # water density, kg/m^3
    L_pp: float         # length between perpendiculars, m
    B: float            # breadth, m
    d: float            # draught, m
    displacement: float  # displaced volume, m^3 (mass m = rho * displacement)
    x_G: float          # centre of gravity forward of midship, m
    k_zz: float         # yaw radius of gyration about G, as a fraction of L_pp
    m_x: float          # added mass in surge, non-dimensional
    m_y: float          # added mass in sway, non-dimensional
    J_z: float          # added yaw moment of inertia, non-dimensional
    # Hull derivatives (non-dimensional)
    R_0: float
    X_vv: float
    X_vr: float
    X_rr: float
    X_vvvv: float
    Y_v: float
    Y_r: float
    Y_vvv: float
    Y_vvr: float
    Y_vrr: float
    Y_rrr: float
    N_v: float
    N_r: float
    N_vvv: float
    N_vvr: float
    N_vrr: float
    N_rrr: float
    # Propeller
    D_p: float          # propeller diameter, m
    x_P: float          # longitudinal propeller position, non-dimensional (aft < 0)
    t_P: float          # thrust deduction factor
    w_P0: float         # wake fraction in straight motion
    k_0: float          # K_T(J) = k_0 + k_1 J + k_2 J^2
    k_1: float
    k_2: float
    wake_model: str     # 'yasukawa2015' or 'exponential'
    C_1: float          # yasukawa2015: 1 - w_P = (1 - w_P0)(1 + (1 - exp(-C_1 |b|))(C_2 - 1))
    C_2_plus: float     # C_2 for beta_P > 0
    C_2_minus: float    # C_2 for beta_P < 0
    # Rudder
    A_R: float          # rudder area, m^2
    H_R: float          # rudder span, m (eta = D_p / H_R)
    f_alpha: float      # rudder lift gradient coefficient
    epsilon: float      # wake ratio between rudder and propeller (1 - w_R) / (1 - w_P)
    kappa: float        # propeller-race factor of u_R
    t_R: float          # steering resistance deduction factor
    a_H: float          # rudder force increase factor (hull interaction)
    x_H: float          # acting point of the hull's interaction force, non-dimensional
    x_R: float          # rudder position, non-dimensional (aft < 0)
    l_R: float          # effective rudder position for beta_R, non-dimensional
    gamma_R_plus: float   # flow straightening for beta_R > 0
    gamma_R_minus: float  # flow straightening for beta_R < 0
    # Effects outside the standard method, as the diagnosis finds them (0 when absent)
    delta_0: float      # rudder angle offset, rad: the rudder acts at delta + delta_0
    X_0: float          # constant surge force, N
    Y_0: float          # constant sway force, N
    N_0: float          # constant yaw moment about midship, N m

    # ------------------------------------------------------------ dimensional values
    @property
    def half_rho_l2d(self) -> float:
        """Return rho/2 L_pp^2 d (kg): the unit of the non-dimensional masses."""
        return 0.5 * self.rho * self.L_pp ** 2 * self.d

    @property
    def mass(self) -> float:
        """Return the ship's mass rho * displacement (kg)."""
        return self.rho * self.displacement

    @property
    def mass_matrix(self) -> tuple[tuple[float, ...], ...]:
        """
        Return M (3x3) about midship with added mass (kg, kg m, kg m^2).

        Yasukawa & Yoshimura (2015) eq. 4: (m + m_x) u', (m + m_y) v_m' + x_G m r',
        (I_zG + x_G^2 m + J_z) r' + x_G m v_m'.
        """
        m, unit = self.mass, self.half_rho_l2d
        izz = m * (self.k_zz * self.L_pp) ** 2 + self.x_G ** 2 * m + self.J_z * unit * \
            self.L_pp ** 2
        return ((m + self.m_x * unit, 0.0, 0.0),
                (0.0, m + self.m_y * unit, self.x_G * m),
                (0.0, self.x_G * m, izz))

    def replace(self, **changes) -> MmgParams:
        """Return a copy with some parameters changed (validated like a loaded file)."""
        return _validated(dataclasses.replace(self, **changes))


_FLOAT_FIELDS = tuple(f.name for f in fields(MmgParams) if f.name not in ('name', 'wake_model'))
_POSITIVE = ('rho', 'L_pp', 'B', 'd', 'displacement', 'k_zz', 'D_p', 'A_R', 'H_R',
             'f_alpha', 'epsilon')
_FRACTIONS = ('t_P', 'w_P0', 't_R')   # in [0, 1)
_INFORMATION_KEYS = ('description', 'sources')
LENGTH_TOL = 0.01   # a file within 1 % of the vessel's length is made for it


def _validated(params: MmgParams, source: str = 'mmg') -> MmgParams:
    check_ranges(params, _FLOAT_FIELDS, _POSITIVE, _FRACTIONS, source)
    if params.wake_model not in WAKE_MODELS:
        raise ConfigError(f'{source}: wake_model: must be one of {WAKE_MODELS}, got '
                          f'{params.wake_model!r}')
    return params


def params_from_dict(data, source: str = 'mmg') -> MmgParams:
    """Build validated parameters from a mapping with the dataclass's keys (+ format)."""
    if isinstance(data, dict):
        data = {k: v for k, v in data.items() if k not in _INFORMATION_KEYS}
        fmt = data.pop('format', FORMAT)
        if fmt != FORMAT:
            raise ConfigError(f'{source}: format: expected {FORMAT!r}, got {fmt!r}')
    values = numeric_fields(data, (f.name for f in fields(MmgParams)), _FLOAT_FIELDS, source,
                            'MMG parameters')
    return _validated(MmgParams(name=str(data['name']), wake_model=str(data['wake_model']),
                                **values), source)


def is_mmg_file(path: str | Path) -> bool:
    """Tell whether a YAML file is an MMG parameter file (its ``format`` key)."""
    try:
        data = read_yaml(path, 'MMG parameter file')
    except ConfigError:
        return False
    return isinstance(data, dict) and data.get('format') == FORMAT


def find_params_file(name: str | Path, base: Path | None = None) -> Path:
    """Return an MMG parameter file given by path, beside ``base``, or packaged name."""
    path = Path(name)
    if not path.suffix:
        path = path.with_suffix('.yaml')
    candidates = [path] if path.is_absolute() else (
        ([base / path] if base else []) + [path, config_dir() / path])
    for candidate in candidates:
        if candidate.is_file():
            return candidate
    raise ConfigError(f'mmg: no MMG parameter file {str(name)!r} (looked in '
                      f'{", ".join(str(c.parent) for c in candidates)})')


def display_name(path: str | Path) -> str:
    """Name a parameter file for a report: packaged ones by package, others as given."""
    path = Path(path)
    try:
        return f'vessel_physics/config/{path.resolve().relative_to(config_dir().resolve())}'
    except ValueError:
        return str(path)


def load_mmg(path: str | Path, length_m: float | None = None,
             vessel: str = 'the vessel') -> MmgParams:
    """
    Load and validate an MMG parameter file; with ``length_m``, for a vessel that long.

    A file states the length it was made for (``L_pp``): one for another length is
    another scale, refused in one line naming both (``scale_physics`` writes the
    Froude-scaled file).
    """
    params = params_from_dict(read_yaml(path, 'MMG parameter file'), source=str(path))
    if length_m is not None and abs(params.L_pp / length_m - 1) > LENGTH_TOL:
        raise ConfigError(f'{path}: made for L_pp {params.L_pp:g} m, but {vessel} is '
                          f'{length_m:g} m long (particulars.length_m): another scale; write '
                          f'the Froude-scaled file with `ros2 run vessel_physics '
                          f'scale_physics {Path(path).name} --length {length_m:g}`')
    return params


# Froude scaling by lambda = L_new / L_old at the same Froude number: per field, the
# power of lambda it scales with (fields not named are non-dimensional: unchanged).
FROUDE_POWERS = {'L_pp': 1, 'B': 1, 'd': 1, 'x_G': 1, 'D_p': 1, 'H_R': 1, 'A_R': 2,
                 'displacement': 3, 'X_0': 3, 'Y_0': 3, 'N_0': 4}


def froude_scaled(params: MmgParams, length_m: float, rho: float | None = None
                  ) -> MmgParams:
    """
    Return the parameters of the same hull at ``length_m`` by Froude's law.

    Lengths scale by lambda, areas by lambda^2, volume, mass and forces by lambda^3,
    moments by lambda^4 (forces and moments also by the density ratio when ``rho``
    changes); non-dimensional coefficients are unchanged, so inertias follow k_zz L_pp.
    Speeds then scale by sqrt(lambda), propeller and yaw rates by 1/sqrt(lambda).
    """
    lam = length_m / params.L_pp
    rho = params.rho if rho is None else rho
    changes = {k: getattr(params, k) * lam ** p for k, p in FROUDE_POWERS.items()}
    for k in ('X_0', 'Y_0', 'N_0'):
        changes[k] *= rho / params.rho
    return _validated(dataclasses.replace(params, rho=rho, **changes))


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
    return xp.stack([q * x, q * y, q * params.L_pp * n], axis=-1)


def propeller(z, c, params: MmgParams):
    """Propeller force [X_P, 0, 0] (..., 3): (1 - t_P) rho n^2 D_p^4 K_T(J_P)."""
    xp = namespace(z, c)
    u = z[..., 0]
    n_rps = c[..., 0] / (2.0 * math.pi)
    u_a = (1.0 - wake_fraction(z, params)) * u
    thrust = params.rho * params.D_p ** 2 * _thrust_coefficient_n2(xp, n_rps, u_a, params)
    zero = xp.zeros_like(u)
    return xp.stack([(1.0 - params.t_P) * thrust, zero, zero], axis=-1)


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
    return xp.stack([-(1.0 - params.t_R) * f_n * xp.sin(delta),
                     -(1.0 + params.a_H) * f_n * xp.cos(delta),
                     -lever * f_n * xp.cos(delta)], axis=-1)


def inertial(z, c, params: MmgParams):
    """
    Return the velocity-dependent inertial forces (..., 3) moved to the right-hand side.

    (m + m_y) v_m r + x_G m r^2, -(m + m_x) u r and -x_G m u r (Yasukawa & Yoshimura
    2015, eq. 4).
    """
    xp = namespace(z)
    u, v, r = z[..., 0], z[..., 1], z[..., 2]
    m, unit = params.mass, params.half_rho_l2d
    return xp.stack([(m + params.m_y * unit) * v * r + params.x_G * m * r * r,
                     -(m + params.m_x * unit) * u * r,
                     -params.x_G * m * u * r], axis=-1)


def bias(z, c, params: MmgParams):
    """Return the constant forces [X_0, Y_0, N_0] (..., 3), e.g. a diagnosed asymmetry."""
    xp = namespace(z)
    ones = xp.ones_like(z[..., 0])
    return xp.stack([params.X_0 * ones, params.Y_0 * ones, params.N_0 * ones], axis=-1)


TERMS = {'inertial': inertial, 'hull': hull, 'propeller': propeller, 'rudder': rudder,
         'bias': bias}
FULL_TERMS = tuple(TERMS)


def force(z, c, params: MmgParams, terms: Iterable[str] = FULL_TERMS):
    """Sum of the named force groups (..., 3) about midship, [X, Y, N]."""
    total = None
    for name in terms:
        try:
            fn = TERMS[name]
        except KeyError:
            raise KeyError(f'unknown MMG term {name!r}; known: {sorted(TERMS)}') from None
        tau = fn(z, c, params)
        total = tau if total is None else total + tau
    if total is None:
        return namespace(z).zeros_like(z)
    return total


def inverse_mass_matrix_t(params: MmgParams):
    """Return (M^-1)^T as nested tuples, so ``tau @ minv_t`` gives the accelerations."""
    (a, _, _), (_, b, c), (_, _, d) = params.mass_matrix
    det = b * d - c * c
    return ((1.0 / a, 0.0, 0.0), (0.0, d / det, -c / det), (0.0, -c / det, b / det))


def derivative(z, c, params: MmgParams, terms: Iterable[str] = FULL_TERMS, extra=None):
    """
    Return z' = M^-1 (tau(z, c) + extra) (..., 3): [u', v_m', r'] (m/s^2, rad/s^2).

    ``extra`` (..., 3) is an optional additional force, e.g. discovered terms.
    """
    xp = namespace(z, c)
    tau = force(z, c, params, terms)
    if extra is not None:
        tau = tau + extra
    minv_t = xp.asarray(inverse_mass_matrix_t(params), dtype=z.dtype)
    return tau @ minv_t


def simulate(params: MmgParams, z0, controls, dt: float, substeps: int = 1,
             terms: Iterable[str] = FULL_TERMS):
    """
    Integrate from ``z0`` (..., 3) under ``controls`` (..., T, 2) held per sample.

    Returns the states (..., T + 1, 3) at the T + 1 sample instants, classical RK4 with
    ``substeps`` steps per sample period ``dt`` (s); the batch dimensions run together.
    """
    xp = namespace(z0, controls)
    terms = tuple(terms)

    def rates(z, c):
        return derivative(z, c, params, terms)

    z = z0
    out = [z]
    for k in range(controls.shape[-2]):
        z = held_period(rates, z, controls[..., k, :], dt, substeps)
        out.append(z)
    return xp.stack(out, axis=-2)


__all__ = ['DOFS', 'FORMAT', 'FULL_TERMS', 'MmgParams', 'STATE_NAMES', 'TERMS', 'WAKE_MODELS',
           'bias', 'derivative', 'find_params_file', 'force', 'hull', 'inertial',
           'inverse_mass_matrix_t', 'is_mmg_file', 'load_mmg', 'params_from_dict', 'propeller',
           'rudder', 'rudder_normal_force', 'simulate', 'wake_fraction']
