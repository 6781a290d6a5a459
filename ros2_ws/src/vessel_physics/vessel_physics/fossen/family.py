"""
The Fossen matrix family: small craft in the horizontal plane (``fossen.params``).

State z = [u, v, r] (FRD about CO), forces [X, Y, N]; the controls are the shaft speeds
of the thrusters and the angles of the rudders the parameter file places, each read from
the vessel actuator it names, then the wind where the vessel declares it.
M = M_RB + M_A:

    [[m - Xudot, 0,             0            ],
     [0,         m - Yvdot,     m x_G - Yrdot],
     [0,         m x_G - Nvdot, I_z - Nrdot  ]]
"""

from __future__ import annotations

import numpy as np

from vessel_physics.errors import ConfigError
from vessel_physics.family import Family, SteadySpec, Term, term_registry
from vessel_physics.fossen import forces
from vessel_physics.fossen.params import FORMAT, FossenParams, parameter_values, params_from_dict

DOFS = forces.DOFS
_UNITS = {'rho': 'kg/m^3', 'm': 'kg', 'x_G': 'm', 'I_z': 'kg m^2', 'Xudot': 'kg',
          'Yvdot': 'kg', 'Yrdot': 'kg m', 'Nvdot': 'kg m', 'Nrdot': 'kg m^2', 'Xu': 'N s/m',
          'Yv': 'N s/m', 'Yr': 'N s/rad', 'Nv': 'N s', 'Nr': 'N m s/rad', 'Xuu': 'N s^2/m^2',
          'Yvv': 'N s^2/m^2', 'Nrr': 'N m s^2/rad^2', 'crossflow_Cd': '1',
          'crossflow_draft': 'm', 'crossflow_length': 'm', 'wind_AF': 'm^2',
          'wind_AL': 'm^2', 'wind_Loa': 'm', 'wind_cx': '1', 'wind_cy': '1', 'wind_cn': '1'}
_DOFS = {'Xudot': 'X', 'Xu': 'X', 'Xuu': 'X', 'Yvdot': 'Y', 'Yv': 'Y', 'Yr': 'Y', 'Yvv': 'Y',
         'Nvdot': 'N', 'Nrdot': 'N', 'Nv': 'N', 'Nr': 'N', 'Nrr': 'N', 'I_z': 'N'}
_PROBE_Z = np.array([[1.5, 0.1, 0.05], [0.6, -0.2, -0.3]])


def _force(name, fn, dofs, category, description, velocity='water', linear=None) -> Term:
    return Term(name, fn, dofs, category, description, 'force', velocity, '1', linear)


def _candidate(name, fn, dofs, category, unit, description) -> Term:
    return Term(name, fn, dofs, category, description, 'candidate', 'water', unit)


TERMS = term_registry([
    _force('rigid_body_coriolis', forces.rigid_body_coriolis, DOFS, 'rigid_body',
           'rigid-body Coriolis and centripetal forces -C_RB(nu) nu'),
    _force('added_mass_coriolis', forces.added_mass_coriolis, DOFS, 'added_mass',
           'added-mass Coriolis and Munk moment -C_A(nu_r) nu_r'),
    _force('damping', forces.damping, DOFS, 'damping', 'linear and quadratic damping',
           linear=(forces.damping_features, forces.damping_matrix)),
    _force('crossflow', forces.crossflow, ('Y', 'N'), 'damping',
           'cross-flow drag of the hull sections (strip theory)'),
    _force('thrusters', forces.thrusters, DOFS, 'propulsion',
           'thrusters by position and direction, thrust k n|n|'),
    _force('rudders', forces.rudders, DOFS, 'rudder', 'rudder lift in the surge inflow'),
    _force('wind', forces.wind, DOFS, 'wind', 'wind load in the apparent wind',
           velocity='ground'),
    _candidate('surge_bias', forces.surge_bias, ('X',), 'static_bias', 'N',
               'constant surge force'),
    _candidate('sway_bias', forces.sway_bias, ('Y',), 'static_bias', 'N',
               'constant sway force (asymmetric hull or appendage)'),
    _candidate('yaw_bias', forces.yaw_bias, ('N',), 'static_bias', 'N m',
               'constant yaw moment (asymmetric hull or appendage)'),
    _candidate('port_thrust', forces.port_thrust, DOFS, 'actuator_bias', '1',
               'thrust of the port thrusters off by a share (a weak or fouled propeller)'),
    _candidate('starboard_thrust', forces.starboard_thrust, DOFS, 'actuator_bias', '1',
               'thrust of the starboard thrusters off by a share'),
])
MODEL_TERMS = ('rigid_body_coriolis', 'added_mass_coriolis', 'damping', 'crossflow',
               'thrusters', 'rudders', 'wind')


def mass_matrix(params: FossenParams) -> np.ndarray:
    """Return M = M_RB + M_A (3x3) about CO (module docstring)."""
    p = params
    return np.array([[p.m - p.Xudot, 0.0, 0.0],
                     [0.0, p.m - p.Yvdot, p.m * p.x_G - p.Yrdot],
                     [0.0, p.m * p.x_G - p.Nvdot, p.I_z - p.Nrdot]])


class Fossen(Family):
    """The Fossen matrix model's family (module docstring)."""

    name = 'fossen'
    title = 'Fossen matrix model of small craft'
    parameters_format = FORMAT
    params_type = FossenParams
    states = forces.STATES
    dofs = DOFS
    terms = TERMS
    model_terms = MODEL_TERMS
    environment = frozenset({'wind', 'current'})
    steady = SteadySpec(('u', 'v', 'r'), (1e-5, 1e-5, 1e-6), (15.0, 5.0, 2.0), 15.0, 1e-4)

    def read_parameters(self, data, source):
        """Return validated parameters (``fossen.params``)."""
        return params_from_dict(data, source)

    def parameter_values(self, params):
        """Return the parameters as a file's mapping."""
        return parameter_values(params)

    def parameter_names(self):
        """Return the scalar parameters (thrusters and rudders are lists)."""
        return tuple(_UNITS)

    def parameter_unit(self, name):
        """Return the SI unit of a parameter."""
        return _UNITS[name]

    def parameter_dofs(self, name):
        """Return the DOFs a parameter acts on."""
        return _DOFS.get(name, 'XYN')

    def mass_matrix(self, params):
        """Return M_RB + M_A."""
        return mass_matrix(params)

    def controls_of(self, vessel, params):
        """Return the vessel's columns of the thrusters' and rudders' actuators, then wind."""
        by_name = {a.name: a for a in vessel.actuators}
        expected = {**{t.actuator: 'propeller' for t in params.thrusters},
                    **{r.actuator: 'rudder' for r in params.rudders}}
        for name, kind in expected.items():
            if name not in by_name or by_name[name].kind != kind:
                raise ConfigError(
                    f'vessel {vessel.name!r}: the parameters {params.name!r} drive a {kind} '
                    f'{name!r}, but the vessel file has actuators '
                    f'{ {a.name: a.kind for a in vessel.actuators} }')
        if set(vessel.actuator_names) - set(expected):
            raise ConfigError(f'vessel {vessel.name!r}: actuators '
                              f'{sorted(set(vessel.actuator_names) - set(expected))} drive no '
                              f'thruster or rudder of the parameters {params.name!r}')
        order = [vessel.control_index(n) for n in params.actuators]
        if 'wind' in vessel.environment:
            order += [vessel.control_index(c) for c in vessel.environment_columns]
        return None if order == list(range(vessel.n_control)) else tuple(order)

    def actuator_dynamics(self, params, vessel):
        """Return each thruster's and rudder's servo (the vessel file's range)."""
        out = {}
        for t in params.thrusters:
            a = vessel.actuator(t.actuator)
            out[t.actuator] = (a.low, a.high, t.time_constant_s, float('inf'))
        for r in params.rudders:
            a = vessel.actuator(r.actuator)
            out[r.actuator] = (a.low, a.high, r.time_constant_s, r.max_rate)
        return out

    def probe(self):
        """Return two probe states; controls for up to eight actuators and a wind."""
        return _PROBE_Z, np.array([[60.0] * 8 + [3.0, 0.6, 0.8], [-30.0] * 8 + [5.0, -0.8, 0.6]])


FAMILY = Fossen()
