"""
The MMG family: single-screw, single-rudder ships (Yasukawa & Yoshimura 2015).

State z = [u, v_m, r] (FRD at midship), forces [X, Y, N] about midship, controls
c = [n, delta]: the propeller speed (rad/s) and the rudder angle (rad, + turns the ship
to starboard). A vessel file gives one propeller and one rudder (any names, any order).
The mass matrix is eq. 4 of the paper, inverted in closed form.
"""

from __future__ import annotations

from dataclasses import asdict, fields
from pathlib import Path

import numpy as np

from vessel_physics.errors import ConfigError
from vessel_physics.family import Family, SteadySpec, Term, term_registry
from vessel_physics.mmg import forces
from vessel_physics.mmg.params import FORMAT, LENGTH_TOL, MmgParams, params_from_dict

DOFS = forces.DOFS
_DIMENSIONAL = {'rho': 'kg/m^3', 'L_pp': 'm', 'B': 'm', 'd': 'm', 'displacement': 'm^3',
                'x_G': 'm', 'D_p': 'm', 'A_R': 'm^2', 'H_R': 'm', 'delta_0': 'rad',
                'X_0': 'N', 'Y_0': 'N', 'N_0': 'N m'}
_PROBE_Z = np.array([[1.1, 0.05, 0.01], [0.7, -0.08, -0.03]])
_PROBE_C = np.array([[64.0, 0.1], [40.0, -0.2]])

TERMS = term_registry([
    Term('inertial', forces.inertial, DOFS, 'rigid_body',
         'velocity-dependent inertial forces moved to the right-hand side (eq. 4)'),
    Term('hull', forces.hull, DOFS, 'damping', "hull forces, polynomials in v' and r'"),
    Term('propeller', forces.propeller, ('X',), 'propulsion',
         '(1 - t_P) rho n^2 D_p^4 K_T(J_P) with the wake w_P(beta_P)'),
    Term('rudder', forces.rudder, DOFS, 'rudder',
         'rudder normal force with hull interaction (t_R, a_H, x_H)'),
    Term('bias', forces.bias, DOFS, 'static_bias', 'constant forces X_0, Y_0, N_0'),
])
FULL_TERMS = tuple(TERMS)


def inverse_mass_matrix_t(params: MmgParams) -> np.ndarray:
    """Return (M^-1)^T in closed form, so ``tau @ minv_t`` gives the accelerations."""
    (a, _, _), (_, b, c), (_, _, d) = params.mass_matrix
    det = b * d - c * c
    return np.array(((1.0 / a, 0.0, 0.0), (0.0, d / det, -c / det), (0.0, -c / det, b / det)))


class Mmg(Family):
    """The MMG standard model's family (module docstring)."""

    name = 'mmg'
    title = 'MMG standard model (Yasukawa & Yoshimura 2015)'
    parameters_format = FORMAT
    params_type = MmgParams
    states = forces.STATE_NAMES
    dofs = DOFS
    terms = TERMS
    model_terms = FULL_TERMS
    environment = frozenset({'current'})
    steady = SteadySpec(('u', 'v', 'r'), (1e-5, 1e-5, 1e-6), (20.0, 5.0, 0.5), 20.0, 1e-4)

    def read_parameters(self, data, source):
        """Return validated MMG parameters (``mmg.params``)."""
        return params_from_dict(data, source)

    def parameter_values(self, params):
        """Return the parameters as a mapping (with the format tag, as files have it)."""
        return {'format': FORMAT, **asdict(params)}

    def parameter_names(self):
        """Return the numeric parameters."""
        return tuple(f.name for f in fields(MmgParams) if f.name not in ('name', 'wake_model'))

    def replace(self, params, **changes):
        """Return validated parameters with some values changed."""
        return params.replace(**changes)

    def parameter_unit(self, name):
        """Return the unit: SI for particulars and the effects, else non-dimensional."""
        return _DIMENSIONAL.get(name, '1')

    def parameter_dofs(self, name):
        """Return the DOFs a parameter acts on (constant forces: their own)."""
        return {'X_0': 'X', 'Y_0': 'Y', 'N_0': 'N', 'R_0': 'X'}.get(
            name, 'X' if name.startswith('X_') else 'XYN')

    def mass_matrix(self, params):
        """Return M (3x3) about midship with added mass (eq. 4)."""
        return np.array(params.mass_matrix)

    def inverse_mass_matrix_t(self, params):
        """Return (M^-1)^T in closed form."""
        return inverse_mass_matrix_t(params)

    def check_scale(self, params, vessel, source):
        """Refuse a parameter file made for another length than the vessel's."""
        if abs(params.L_pp / vessel.length_m - 1) > LENGTH_TOL:
            name = Path(source).name
            raise ConfigError(
                f'{name}: made for L_pp {params.L_pp:g} m, but vessel {vessel.name!r} is '
                f'{vessel.length_m:g} m long (particulars.length_m): another scale; write the '
                f'Froude-scaled file with `ros2 run vessel_physics scale_physics {name} '
                f'--length {vessel.length_m:g}`')

    def controls_of(self, vessel, params):
        """Return the columns of the propeller and the rudder in the vessel's c."""
        kinds = [a.kind for a in vessel.actuators]
        if sorted(kinds) != ['propeller', 'rudder']:
            raise ConfigError(f'vessel {vessel.name!r}: the {self.title} is for one propeller '
                              f'and one rudder; it has actuators '
                              f'{dict(zip(vessel.actuator_names, kinds, strict=True))}')
        order = (vessel.control_index(vessel.actuators[kinds.index('propeller')].name),
                 vessel.control_index(vessel.actuators[kinds.index('rudder')].name))
        return None if order == (0, 1) and vessel.n_control == 2 else order

    def probe(self):
        """Return two probe states and controls."""
        return _PROBE_Z, _PROBE_C


FAMILY = Mmg()
