"""
The multirotor family: rotorcraft in six degrees of freedom (``multirotor.params``).

State z = [u, v, w, p, q, r, phi, theta] (FRD about the CG; roll and pitch, Euler ZYX),
forces [X, Y, Z, K, M, N]; the controls are the rotor speeds (rad/s) in the order the
parameter file lists the rotors, each read from the vessel actuator (kind ``rotor``) it
names. M = diag(m, m, m, I) with the full inertia tensor I about the CG, and roll and
pitch follow the body rates (``integrator.attitude_rates``).

``minq`` is Baier et al.'s MinQ: rigid body and gravity, with the rotors' thrust and
drag torque from their speeds. The model adds rotor drag, translational lift and
parasitic drag (rotorpy with ``aero=True``).

The family has no steady state to search for (``steady`` is None): the simulator
starts a multirotor at rest.
"""

from __future__ import annotations

import numpy as np

from vessel_physics.arrays import namespace, stack_last
from vessel_physics.errors import ConfigError
from vessel_physics.family import Family, Term, term_registry
from vessel_physics.integrator import attitude_rates
from vessel_physics.multirotor import forces
from vessel_physics.multirotor.params import (
    FORMAT,
    MAX_ROTORS,
    MultirotorParams,
    parameter_values,
    params_from_dict,
)

DOFS = forces.DOFS
_UNITS = {'m': 'kg', 'Ixx': 'kg m^2', 'Iyy': 'kg m^2', 'Izz': 'kg m^2', 'Ixy': 'kg m^2',
          'Ixz': 'kg m^2', 'Iyz': 'kg m^2', 'k_eta': 'N s^2/rad^2', 'k_m': 'N m s^2/rad^2',
          'k_d': 'kg/rad', 'k_z': 'kg/rad', 'k_h': 'kg/m', 'c_Dx': 'N s^2/m^2',
          'c_Dy': 'N s^2/m^2', 'c_Dz': 'N s^2/m^2'}
# Not candidates of the diagnosis: a constant of nature, and a lag no force reads.
_OTHER_UNITS = {'g': 'm/s^2', 'tau_m': 's'}
_DOFS = {'m': 'XYZ', 'k_eta': 'ZKM', 'k_m': 'N', 'k_d': 'XYKMN', 'k_z': 'ZKM',
         'k_h': 'ZKM', 'c_Dx': 'X', 'c_Dy': 'Y', 'c_Dz': 'Z',
         **{name: 'KMN' for name in ('Ixx', 'Iyy', 'Izz', 'Ixy', 'Ixz', 'Iyz')}}
# Two states of flight with every velocity, rate and angle non-zero, and distinct rotor
# speeds for as many rotors as a file may list.
_PROBE_Z = np.array([[1.2, -0.4, 0.3, 0.5, -0.7, 0.9, 0.2, -0.15],
                     [-0.6, 0.8, -0.5, -1.1, 0.4, -0.3, -0.35, 0.25]])
_PROBE_C = np.array([np.linspace(1500.0, 2200.0, MAX_ROTORS),
                     np.linspace(2400.0, 900.0, MAX_ROTORS)])


def _force(name, fn, dofs, category, description) -> Term:
    return Term(name, fn, dofs, category, description, 'force')


def _candidate(name, fn, dofs, category, unit, description) -> Term:
    return Term(name, fn, dofs, category, description, 'candidate', 'water', unit)


TERMS = term_registry([
    _force('rigid_body_coriolis', forces.rigid_body_coriolis, DOFS, 'rigid_body',
           'rigid-body Coriolis and gyroscopic forces -m w x v, -w x I w'),
    _force('gravity', forces.gravity, ('X', 'Y', 'Z'), 'gravity', 'weight at the CG'),
    _force('rotor_thrust', forces.rotor_thrust, ('Z', 'K', 'M'), 'propulsion',
           'rotor thrust k_eta n^2 along -z at each hub'),
    _force('rotor_torque', forces.rotor_torque, ('N',), 'propulsion',
           "reaction of the rotors' drag torque k_m n^2 by spin"),
    _force('rotor_drag', forces.rotor_drag, DOFS, 'aerodynamics',
           'H-force of rotor drag and induced inflow at each hub'),
    _force('translational_lift', forces.translational_lift, ('Z', 'K', 'M'), 'aerodynamics',
           'translational lift k_h (v_x^2 + v_y^2) at each hub'),
    _force('parasitic_drag', forces.parasitic_drag, ('X', 'Y', 'Z'), 'aerodynamics',
           'parasitic drag of the frame -|v| diag(c_D) v'),
    *(_candidate(f'rotor{i + 1}_thrust', forces.rotor_share(i), ('Z', 'K', 'M', 'N'),
                 'actuator_bias', '1',
                 f"thrust of rotor {i + 1} (in the file's order) off by a share (a weak "
                 f'motor or damaged propeller: its thrust, moment and drag torque)')
      for i in range(MAX_ROTORS)),
    _candidate('cg_offset_x', forces.cg_offset_x, ('M', 'N'), 'static_bias', 'm',
               "centre of gravity forward of the rotors' reference (moment of the weight)"),
    _candidate('cg_offset_y', forces.cg_offset_y, ('K', 'N'), 'static_bias', 'm',
               "centre of gravity to starboard of the rotors' reference"),
    _candidate('surge_bias', forces.surge_bias, ('X',), 'static_bias', 'N',
               'constant force along x'),
    _candidate('sway_bias', forces.sway_bias, ('Y',), 'static_bias', 'N',
               'constant force along y'),
    _candidate('heave_bias', forces.heave_bias, ('Z',), 'static_bias', 'N',
               'constant force along z (a payload, a thrust offset)'),
    _candidate('roll_bias', forces.roll_bias, ('K',), 'static_bias', 'N m',
               'constant roll moment'),
    _candidate('pitch_bias', forces.pitch_bias, ('M',), 'static_bias', 'N m',
               'constant pitch moment'),
    _candidate('yaw_bias', forces.yaw_bias, ('N',), 'static_bias', 'N m',
               'constant yaw moment (a tilted motor, unequal propellers)'),
])
MINQ_TERMS = ('rigid_body_coriolis', 'gravity', 'rotor_thrust', 'rotor_torque')
MODEL_TERMS = MINQ_TERMS + ('rotor_drag', 'translational_lift', 'parasitic_drag')


def mass_matrix(params: MultirotorParams) -> np.ndarray:
    """Return M = diag(m, m, m, I) (6x6) about the CG."""
    out = np.zeros((6, 6))
    out[:3, :3] = params.m * np.eye(3)
    out[3:, 3:] = params.inertia
    return out


class Multirotor(Family):
    """The multirotor's family (module docstring)."""

    name = 'multirotor'
    title = 'multirotor rigid-body model'
    parameters_format = FORMAT
    params_type = MultirotorParams
    states = forces.STATES
    dofs = DOFS
    terms = TERMS
    model_terms = MODEL_TERMS
    term_sets = {'minq': MINQ_TERMS}
    environment = frozenset()
    steady = None        # no steady state searched: the simulator starts it at rest

    def read_parameters(self, data, source):
        """Return validated parameters (``multirotor.params``)."""
        return params_from_dict(data, source)

    def parameter_values(self, params):
        """Return the parameters as a file's mapping."""
        return parameter_values(params)

    def parameter_names(self):
        """Return the scalar parameters the forces read (the rotors are a list)."""
        return tuple(_UNITS)

    def parameter_unit(self, name):
        """Return the SI unit of a parameter."""
        return {**_UNITS, **_OTHER_UNITS}[name]

    def parameter_dofs(self, name):
        """Return the DOFs a parameter acts on."""
        return _DOFS.get(name, ''.join(DOFS))

    def mass_matrix(self, params):
        """Return diag(m, m, m, I)."""
        return mass_matrix(params)

    def kinematic_rates(self, z):
        """Return (phi', theta') (..., 2) from the body rates (Euler ZYX)."""
        phi_rate, theta_rate, _ = attitude_rates(z[..., 3], z[..., 4], z[..., 5], z[..., 6],
                                                 z[..., 7])
        xp = namespace(z)
        return stack_last([phi_rate, theta_rate], xp)

    def controls_of(self, vessel, params):
        """Return the vessel's columns of the rotors' actuators, in the file's order."""
        kinds = {a.name: a.kind for a in vessel.actuators}
        for name in params.actuators:
            if kinds.get(name) != 'rotor':
                raise ConfigError(f'vessel {vessel.name!r}: the parameters {params.name!r} drive '
                                  f'a rotor {name!r}, but the vessel file has actuators '
                                  f'{kinds}')
        if set(kinds) - set(params.actuators):
            raise ConfigError(f'vessel {vessel.name!r}: actuators '
                              f'{sorted(set(kinds) - set(params.actuators))} drive no rotor '
                              f'of the parameters {params.name!r}')
        if vessel.environment:
            raise ConfigError(f'vessel {vessel.name!r}: environment {list(vessel.environment)}:'
                              f' the {self.title} feels none')
        order = [vessel.control_index(n) for n in params.actuators]
        return None if order == list(range(vessel.n_control)) else tuple(order)

    def actuator_dynamics(self, params, vessel):
        """Return each rotor's first-order motor lag tau_m (the vessel file's range)."""
        out = {}
        for rotor in params.rotors:
            a = vessel.actuator(rotor.actuator)
            out[rotor.actuator] = (a.low, a.high, params.tau_m, float('inf'))
        return out

    def probe(self):
        """Return two probe states and rotor speeds for up to ``MAX_ROTORS`` rotors."""
        return _PROBE_Z, _PROBE_C


FAMILY = Multirotor()
