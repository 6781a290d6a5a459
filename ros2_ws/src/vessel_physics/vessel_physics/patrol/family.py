"""
The patrol family: the 4-DOF vessel of Perez, Ross & Fossen (2006), its registry and mass.

State z = [u, v, p, r, phi] (FRD, about CO: centre line, midships, waterline), generalized
forces [X, Y, K, N]; controls c = [n, delta_port, delta_stbd, wind_speed, wind_dir_cos,
wind_dir_sin] (one shaft speed for twin rudder-propellers, the true wind). Its vessel
file names one propeller, two azimuth (rudder-propeller) actuators and the wind.

The mass matrix rows follow Perez, Ross & Fossen (2006) for [u', v', p', r']. It is not
symmetric: the source's cross terms Yp' and Kv' have opposite signs, and the rigid-body
couplings m zG, m xG enter the sway, roll and yaw rows.
"""

from __future__ import annotations

from dataclasses import asdict, fields
import re

import numpy as np

from vessel_physics.errors import ConfigError
from vessel_physics.family import Family, SteadySpec, Term, term_registry
from vessel_physics.patrol import candidates as cand
from vessel_physics.patrol import forces
from vessel_physics.patrol.params import FORMAT, PatrolParams, params_from_dict

FEATURE_DOFS: dict[str, tuple[str, ...]] = {
    # Which generalized forces each hull feature enters (X holds the hull drag and the
    # Coriolis/centripetal products m(v r + xG r^2 - zG p r)); the regression physics
    # fits them per state.
    '|u|u': ('X',), 'vr': ('X',), 'rr': ('X',), 'pr': ('X',),
    '|u|v': ('Y', 'K', 'N'), 'ur': ('Y', 'K', 'N'), 'v|v|': ('Y', 'K'), 'v|r|': ('Y', 'K'),
    'r|v|': ('Y', 'K', 'N'), 'phi|uv|': ('Y', 'K', 'N'), 'phi|ur|': ('Y', 'K'),
    'phiuu': ('Y', 'K'), '|u|p': ('K',), 'p|p|': ('K',), 'phi^3': ('K',), '|u|r': ('N',),
    'r|r|': ('N',), 'phiu|r|': ('N',), 'phiu|u|': ('N',),
}
# The hull features in the order of a regression's columns (a checkpoint's weights
# follow it): Blanke & Christensen (1993) as used for the patrol vessel.
FEATURE_ORDER = ('|u|u', 'vr', 'rr', 'pr', '|u|v', 'ur', 'v|v|', 'v|r|', 'r|v|', 'phi|uv|',
                 'phi|ur|', 'phiuu', '|u|p', 'p|p|', 'phi^3', '|u|r', 'r|r|', 'phiu|r|',
                 'phiu|u|')
DOFS = forces.DOFS
ALL = DOFS

_MASS_UNITS = {'Xudot': 'kg', 'Yvdot': 'kg', 'Ypdot': 'kg m', 'Yrdot': 'kg m', 'Kvdot': 'kg m',
               'Kpdot': 'kg m^2', 'Krdot': 'kg m^2', 'Nvdot': 'kg m', 'Npdot': 'kg m^2',
               'Nrdot': 'kg m^2'}
_OTHER_UNITS = {'GM': 'm', 'wake_fraction': '1', 'Ixx': 'kg m^2', 'Izz': 'kg m^2'}
_OTHER_DOFS = {'GM': 'K', 'wake_fraction': 'XYKN', 'Ixx': 'K', 'Izz': 'N'}
_PROBE_Z = np.array([[6.0, 0.2, 0.01, 0.02, 0.01], [3.0, -0.3, -0.02, -0.01, -0.02]])
_PROBE_C = np.array([[80.0, 0.05, 0.04, 5.0, 0.6, 0.8], [50.0, -0.1, -0.12, 9.0, -0.8, -0.6]])
ROLL_RATE = 2   # column of p in z: phi' = p


def _force(name, fn, dofs, category, description, velocity='water', linear=None) -> Term:
    return Term(name, fn, dofs, category, description, 'force', velocity, '1', linear)


def _candidate(name, fn, dofs, category, unit, description, velocity='water') -> Term:
    return Term(name, fn, dofs, category, description, 'candidate', velocity, unit)


TERMS = term_registry([
    _force('rigid_body_coriolis', forces.rigid_body_coriolis, ALL, 'rigid_body',
           'rigid-body Coriolis/centripetal -C_RB(nu) nu'),
    _force('restoring', forces.restoring, ('K',), 'restoring',
           'hydrostatic roll moment with cubic GZ term'),
    _force('restoring_linear', forces.restoring_linear, ('K',), 'restoring',
           'linearized hydrostatic roll moment -G eta'),
    _force('hull_damping', forces.hull_damping, ALL, 'damping',
           'nonlinear hull damping and cross-flow (Blanke & Christensen 1993)',
           linear=(forces.hull_damping_features, forces.hull_damping_matrix)),
    _force('propulsion', forces.propulsion, ALL, 'propulsion',
           'twin rudder-propellers (thrust vectoring)'),
    _force('wind', forces.wind, ALL, 'wind', 'Isherwood (1972) wind load, K = h Y',
           velocity='ground'),
    _candidate('surge_linear', cand.surge_linear, ('X',), 'resistance', 'N s/m',
               'linear surge resistance X = Xu u'),
    _candidate('sway_linear', cand.sway_linear, ('Y',), 'hull_damping', 'N s/m',
               'linear sway damping Y = Yv v'),
    _candidate('sway_yaw_linear', cand.sway_yaw_linear, ('Y',), 'hull_damping', 'N s/rad',
               'linear sway force from yaw rate Y = Yr r'),
    _candidate('yaw_linear', cand.yaw_linear, ('N',), 'hull_damping', 'N m s/rad',
               'linear yaw damping N = Nr r'),
    _candidate('yaw_sway_linear', cand.yaw_sway_linear, ('N',), 'hull_damping', 'N s',
               'linear yaw moment from sway N = Nv v'),
    _candidate('surge_bias', cand.surge_bias, ('X',), 'static_bias', 'N',
               'constant surge force'),
    _candidate('sway_bias', cand.sway_bias, ('Y',), 'static_bias', 'N',
               'constant sway force (asymmetric hull or appendage)'),
    _candidate('roll_bias', cand.roll_bias, ('K',), 'static_bias', 'N m',
               'constant roll moment (static list)'),
    _candidate('yaw_bias', cand.yaw_bias, ('N',), 'static_bias', 'N m',
               'constant yaw moment (asymmetric hull or appendage)'),
    _candidate('relative_wind_surge', cand.relative_wind_surge, ('X',), 'wind', 'm^2',
               'wind surge load -q cos(gamma_r) C_X A_F in the apparent wind', 'ground'),
    _candidate('relative_wind_sway', cand.relative_wind_sway, ('Y',), 'wind', 'm^2',
               'wind side load -q sin(gamma_r) C_Y A_L in the apparent wind', 'ground'),
    _candidate('relative_wind_roll', cand.relative_wind_roll, ('K',), 'wind', 'm^3',
               'wind heeling moment -q sin(gamma_r) C_Y A_L h in the apparent wind',
               'ground'),
    _candidate('relative_wind_yaw', cand.relative_wind_yaw, ('N',), 'wind', 'm^3',
               'wind yaw moment -q sin(2 gamma_r) C_N A_L L in the apparent wind', 'ground'),
    _candidate('rudder_offset', cand.rudder_offset, ALL, 'actuator_bias', 'rad',
               'common offset of the rudder-propeller angles'),
    _candidate('propeller_asymmetry', cand.propeller_asymmetry, ALL, 'actuator_bias', '1',
               'port/starboard thrust asymmetry (port 1 + a, starboard 1 - a)'),
    *(Term(name, forces.HULL_TERMS[name], FEATURE_DOFS[name], 'hull_damping',
           f'hull feature {name} (Blanke & Christensen 1993)', 'feature')
      for name in FEATURE_ORDER),
])

SIMULATOR_TERMS = ('rigid_body_coriolis', 'restoring', 'hull_damping', 'propulsion', 'wind')
MIN_TERMS = ('rigid_body_coriolis', 'restoring_linear')
PRO_TERMS = MIN_TERMS + ('propulsion',)


def mass_matrix(params: PatrolParams) -> np.ndarray:
    """Return M (4x4, SI) with M @ [u', v', p', r'] = [X, Y, K, N]."""
    p = params
    return np.array([
        [p.m - p.Xudot, 0.0, 0.0, 0.0],
        [0.0, p.m - p.Yvdot, -(p.m * p.zG + p.Ypdot), p.m * p.xG - p.Yrdot],
        [0.0, -(p.m * p.zG + p.Kvdot), p.Ixx - p.Kpdot, -p.Krdot],
        [0.0, p.m * p.xG - p.Nvdot, -p.Npdot, p.Izz - p.Nrdot],
    ])


def parameter_unit(name: str) -> str:
    """Return the SI unit of a textbook coefficient name (e.g. Xauu -> 'N s^2 m^-2')."""
    if name in _MASS_UNITS:
        return _MASS_UNITS[name]
    if name in _OTHER_UNITS:
        return _OTHER_UNITS[name]
    dof, rest = name[0], name[1:]
    metres, seconds, radians = (1 if dof in 'KN' else 0), 0, 0
    for token in re.findall(r'phi|a?[uvpr]', rest):
        q = token[-1]
        if token == 'phi':
            radians -= 1
        elif q in 'uv':
            metres, seconds = metres - 1, seconds + 1
        else:
            radians, seconds = radians - 1, seconds + 1
    parts = ['N'] + [f'{u}^{e}' if e != 1 else u for u, e in
                     (('m', metres), ('s', seconds), ('rad', radians)) if e]
    return ' '.join(parts)


class Patrol(Family):
    """The patrol boat's family (module docstring)."""

    name = 'patrol'
    title = '4-DOF patrol-boat model (Perez, Ross & Fossen 2006)'
    parameters_format = FORMAT
    params_type = PatrolParams
    states = forces.Z_COLUMNS
    dofs = DOFS
    terms = TERMS
    model_terms = SIMULATOR_TERMS
    term_sets = {'min': MIN_TERMS, 'pro': PRO_TERMS}
    environment = frozenset({'wind', 'waves', 'current'})
    steady = SteadySpec(('u', 'v', 'r', 'phi'), (1e-4, 1e-4, 1e-6, 1e-6),
                        (30.0, 5.0, 0.3, 0.5), 30.0, 1.0)
    control_names = ('n', 'delta_port', 'delta_stbd', 'wind_speed', 'wind_dir_cos', 'wind_dir_sin')

    def read_parameters(self, data, source):
        """Return validated patrol parameters (``patrol.params``)."""
        return params_from_dict(data, source)

    def parameter_values(self, params):
        """Return the parameters as a plain mapping."""
        return asdict(params)

    def parameter_names(self):
        """Return the numeric parameters."""
        return tuple(f.name for f in fields(PatrolParams) if f.name != 'name')

    def parameter_unit(self, name):
        """Return the SI unit of a coefficient from its textbook name."""
        return parameter_unit(name)

    def parameter_dofs(self, name):
        """Return the DOFs a parameter acts on: its name's first letter, or listed."""
        return _OTHER_DOFS.get(name, name[0] if name[0] in 'XYKN' else 'XYKN')

    def mass_matrix(self, params):
        """Return the 4x4 mass matrix with added mass (module docstring)."""
        return mass_matrix(params)

    def kinematic_rates(self, z):
        """Return phi' = p."""
        return z[..., ROLL_RATE:ROLL_RATE + 1]

    def controls_of(self, vessel, params):
        """
        Return the columns of n, both rudder-propeller angles and the wind in the vessel's c.

        The vessel needs one propeller, two azimuth actuators (port first) and a wind input.
        """
        kinds = [a.kind for a in vessel.actuators]
        if sorted(kinds) != ['azimuth', 'azimuth', 'propeller'] or 'wind' not in \
                vessel.environment:
            raise ConfigError(
                f'vessel {vessel.name!r}: the {self.title} needs one propeller, two azimuth '
                f'(rudder-propeller) actuators and a wind input; it has actuators '
                f'{dict(zip(vessel.actuator_names, kinds, strict=True))} and environment '
                f'{list(vessel.environment)}')
        azimuths = [i for i, k in enumerate(kinds) if k == 'azimuth']
        order = [kinds.index('propeller'), *azimuths,
                 *(vessel.control_index(c) for c in self.control_names[3:])]
        return None if order == list(range(len(order))) and \
            len(order) == vessel.n_control else tuple(order)

    def actuator_dynamics(self, params, vessel):
        """Return the shaft's and the rudder servos' limits from the parameters."""
        out = {}
        for a in vessel.actuators:
            if a.kind == 'propeller':
                out[a.name] = (0.0, params.shaft_max_speed, params.shaft_time_constant,
                               params.shaft_max_accel)
            else:
                out[a.name] = (-params.rudder_max_angle, params.rudder_max_angle,
                               params.rudder_time_constant, params.rudder_max_rate)
        return out

    def wave_hull(self, params):
        """Return the box hull of the wave forces: Lpp, B, T, displacement, GM."""
        from vessel_physics.simulation.waves import BoxHull
        return BoxHull(params.rho, params.Lpp, params.B, params.T, params.displacement,
                       params.GM)

    def probe(self):
        """Return two probe states and controls."""
        return _PROBE_Z, _PROBE_C


FAMILY = Patrol()
