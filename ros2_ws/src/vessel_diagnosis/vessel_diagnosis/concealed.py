"""
Effects to conceal in simulated "real" recordings (simulator ``extra_forces`` hooks).

Each function has the hook signature of ``vessel_physics.simulation.config`` and returns
the generalized forces (n_runs, n_dof) of its vessel's family; parameters come from the
``effects`` section of config/scenarios.yaml, which also names the vessel each effect
applies to and, when not the vessel file's, the physics its simulator runs. They model
the effect their own way, not with the candidate term the diagnosis will use to name it:

- ``hull_fouling`` (patrol boat): the frictional resistance of the ITTC-1957
  correlation line, R_F = rho S C_F(Re) u|u| / 2 with C_F = 0.075 / (log10 Re - 2)^2 and
  Re = |u| L / nu, raised by ``friction_increase`` (a curve close to u^1.85 at these
  Reynolds numbers, which the library's X|u|u and Xu u terms can only approximate);
- ``actuator_offset`` (patrol boat's rudder-propellers): the named actuators stand
  ``offset`` further than their sensors report: the exact force of the vessel's ``term``
  at the true positions minus that at the reported ones (the library's candidate is the
  linearized derivative);
- ``added_resistance`` (KVLCC2, MMG): ``share`` of the published resistance as a force
  -share R_0' rho/2 L d u|u|, where the MMG model's R_0' acts with U^2 = u^2 + v^2;
- ``actuator_share`` (the Otter's port thruster): one actuator gives ``share`` of its
  contribution to the vessel's ``term`` (the loss acts where the actuator does);
- ``rotor_share`` (a rotor of the Crazyflie): one rotor gives ``share`` of its
  contribution to each of the family's force ``terms`` (its thrust and drag torque: a
  chipped propeller), evaluated with the rotor stopped and running.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from vessel_description import load_vessel
from vessel_diagnosis.scenarios import load_scenario_file
from vessel_physics.physics_file import load_physics

MIN_REYNOLDS = 1.0e5   # below this the friction line does not apply; u ~ 0 gives no force
WATER_VELOCITY = {'u': 'u_water', 'v': 'v_water'}   # the hook's through-the-water speeds


@lru_cache(maxsize=1)
def _effects() -> dict:
    return load_scenario_file()['effects']


@lru_cache(maxsize=4)
def _load(vessel_name: str, physics_name: str | None):
    vessel = load_vessel(vessel_name)
    return vessel, load_physics(physics_name or vessel.physics, vessel)


def _vessel_physics(effect: dict):
    """Return the effect's vessel and the physics it applies to (the vessel's unless named)."""
    return _load(effect['vessel'], effect.get('physics'))


def _term_force(effect: dict, state: dict, controls: dict, term: str | None = None
                ) -> np.ndarray:
    """Return ``term`` (default the effect's) of its vessel's physics at these states."""
    vessel, physics = _vessel_physics(effect)
    z = np.stack([state[WATER_VELOCITY.get(s, s)] for s in vessel.state_names], axis=-1)
    zeros = np.zeros_like(z[:, 0])
    c = np.stack([controls.get(name, zeros) for name in vessel.control_names], axis=-1)
    return physics.term_force(term or effect['term'], z, c)


def ittc_friction_coefficient(speed, length: float, viscosity: float):
    """ITTC-1957 line C_F = 0.075 / (log10 Re - 2)^2 for |speed| (m/s) over ``length`` (m)."""
    reynolds = np.maximum(np.abs(speed) * length / viscosity, MIN_REYNOLDS)
    return 0.075 / (np.log10(reynolds) - 2.0) ** 2


def hull_fouling(t, state, controls, environment) -> np.ndarray:
    """Return the added frictional resistance of a fouled hull (see module docstring)."""
    cfg = _effects()['hull_fouling']
    vessel, physics = _vessel_physics(cfg)
    u = state['u_water']
    cf = ittc_friction_coefficient(u, vessel.length_m, cfg['kinematic_viscosity_m2s'])
    out = np.zeros((len(u), len(physics.family.dofs)))
    out[:, 0] = -(cfg['friction_increase'] * 0.5 * physics.params.rho
                  * cfg['wetted_surface_m2'] * cf * u * np.abs(u))
    return out


def actuator_offset(t, state, controls, environment) -> np.ndarray:
    """Return the term's force at the true actuator positions minus at the reported ones."""
    cfg = _effects()['actuator_offset']
    shifted = {**controls, **{name: controls[name] + cfg['offset'] for name in cfg['actuators']}}
    return _term_force(cfg, state, shifted) - _term_force(cfg, state, controls)


def added_resistance(t, state, controls, environment) -> np.ndarray:
    """Return the tanker's added resistance (module docstring), [X, Y, N]."""
    cfg = _effects()['added_resistance']
    p = _vessel_physics(cfg)[1].params
    u = state['u_water']
    out = np.zeros((len(u), 3))
    out[:, 0] = -cfg['share'] * p.R_0 * 0.5 * p.rho * p.L_pp * p.d * u * np.abs(u)
    return out


def actuator_share(t, state, controls, environment) -> np.ndarray:
    """Return the share of one actuator's contribution its vessel does not get."""
    cfg = _effects()['actuator_share']
    without = {**controls, cfg['actuator']: np.zeros_like(controls[cfg['actuator']])}
    contribution = _term_force(cfg, state, controls) - _term_force(cfg, state, without)
    return -(1.0 - cfg['share']) * contribution


def rotor_share(t, state, controls, environment) -> np.ndarray:
    """Return the share of one rotor's thrust and torque its vehicle does not get."""
    cfg = _effects()['rotor_share']
    without = {**controls, cfg['actuator']: np.zeros_like(controls[cfg['actuator']])}
    contribution = sum(_term_force(cfg, state, controls, term)
                       - _term_force(cfg, state, without, term) for term in cfg['terms'])
    return -(1.0 - cfg['share']) * contribution
