"""
The MMG parameters (Yasukawa & Yoshimura 2015): particulars in SI, coefficients as published.

A parameter file (``format: mmg-params/1``) holds exactly these fields; its ``L_pp`` is
the length it was made for, so a file for another scale is refused where a vessel file
of another length uses it (``scale_physics`` writes the Froude-scaled file).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, fields

from vessel_physics.errors import ConfigError
from vessel_physics.files import check_ranges, numeric_fields, parameter_mapping

FORMAT = 'mmg-params/1'
WAKE_MODELS = ('yasukawa2015', 'exponential')

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
        return validated(dataclasses.replace(self, **changes))


_FLOAT_FIELDS = tuple(f.name for f in fields(MmgParams) if f.name not in ('name', 'wake_model'))
_POSITIVE = ('rho', 'L_pp', 'B', 'd', 'displacement', 'k_zz', 'D_p', 'A_R', 'H_R',
             'f_alpha', 'epsilon')
_FRACTIONS = ('t_P', 'w_P0', 't_R')   # in [0, 1)
LENGTH_TOL = 0.01   # a file within 1 % of the vessel's length is made for it


def validated(params: MmgParams, source: str = 'mmg') -> MmgParams:
    """Return the parameters after checking every range (ConfigError, one line)."""
    check_ranges(params, _FLOAT_FIELDS, _POSITIVE, _FRACTIONS, source)
    if params.wake_model not in WAKE_MODELS:
        raise ConfigError(f'{source}: wake_model: must be one of {WAKE_MODELS}, got '
                          f'{params.wake_model!r}')
    return params


def params_from_dict(data, source: str = 'mmg') -> MmgParams:
    """Build validated parameters from a mapping with the dataclass's keys (+ format)."""
    data = parameter_mapping(data, FORMAT, source, 'MMG parameters')
    values = numeric_fields(data, (f.name for f in fields(MmgParams)), _FLOAT_FIELDS, source,
                            'MMG parameters')
    return validated(MmgParams(name=str(data['name']), wake_model=str(data['wake_model']),
                                **values), source)


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
    return validated(dataclasses.replace(params, rho=rho, **changes))
