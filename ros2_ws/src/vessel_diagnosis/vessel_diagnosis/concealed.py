"""
Effects to conceal in simulated "real" recordings (simulator ``extra_forces`` hooks).

Each function has the hook signature of ``vessel_physics.simulation.config`` and returns
the generalized forces (n_runs, n_dof) of its vessel's family; parameters come from the
``effects`` section of config/scenarios.yaml. They model the effect their own way, not
with the candidate term the diagnosis will use to name it:

- ``hull_fouling`` (patrol boat): the frictional resistance of the ITTC-1957
  correlation line, R_F = rho S C_F(Re) u|u| / 2 with C_F = 0.075 / (log10 Re - 2)^2 and
  Re = |u| Lpp / nu, raised by ``friction_increase`` (a curve close to u^1.85 at these
  Reynolds numbers, which the library's X|u|u and Xu u terms can only approximate);
- ``rudder_offset`` (patrol boat): both rudder-propellers stand ``offset_rad`` further
  than the angle the sensors report: the exact thrust vectoring at the true angle minus
  that at the reported one (the library's candidate is the linearized derivative);
- ``added_resistance`` (KVLCC2, MMG): ``share`` of the published resistance as a force
  -share R_0' rho/2 L_pp d u|u|, where the MMG model's R_0' acts with U^2 = u^2 + v^2;
- ``weak_thruster`` (Otter, Fossen): one thruster gives ``share`` of its thrust
  k n|n|, the loss acting at the thruster's position.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from vessel_diagnosis.scenarios import load_scenario_file
from vessel_physics.fossen.forces import thrust
from vessel_physics.patrol.forces import propulsion
from vessel_physics.physics_file import load_physics

MIN_REYNOLDS = 1.0e5   # below this the friction line does not apply; u ~ 0 gives no force


@lru_cache(maxsize=1)
def _effects() -> dict:
    return load_scenario_file()['effects']


@lru_cache(maxsize=4)
def _params(name: str):
    return load_physics(name).params


def ittc_friction_coefficient(speed, length: float, viscosity: float):
    """ITTC-1957 line C_F = 0.075 / (log10 Re - 2)^2 for |speed| (m/s) over ``length`` (m)."""
    reynolds = np.maximum(np.abs(speed) * length / viscosity, MIN_REYNOLDS)
    return 0.075 / (np.log10(reynolds) - 2.0) ** 2


def hull_fouling(t, state, controls, environment) -> np.ndarray:
    """Return the added frictional resistance of a fouled hull (see module docstring)."""
    cfg = _effects()['hull_fouling']
    vessel = _params('patrol_vessel.yaml')
    u = state['u_water']
    cf = ittc_friction_coefficient(u, vessel.Lpp, cfg['kinematic_viscosity_m2s'])
    out = np.zeros((len(u), 4))
    out[:, 0] = -(cfg['friction_increase'] * 0.5 * vessel.rho * cfg['wetted_surface_m2']
                  * cf * u * np.abs(u))
    return out


def rudder_offset(t, state, controls, environment) -> np.ndarray:
    """Return the thrust vectoring at the true angle minus that at the reported angle."""
    offset = _effects()['rudder_offset']['offset_rad']
    vessel = _params('patrol_vessel.yaml')
    z = np.stack([state['u_water'], state['v_water'], state['p'], state['r'], state['phi']],
                 axis=-1)
    zeros = np.zeros_like(state['u'])
    c = np.stack([controls['n'], controls['delta_port'], controls['delta_stbd'], zeros, zeros,
                  zeros], axis=-1)
    shifted = c.copy()
    shifted[:, 1:3] += offset
    return propulsion(z, shifted, vessel) - propulsion(z, c, vessel)


def added_resistance(t, state, controls, environment) -> np.ndarray:
    """Return the tanker's added resistance (module docstring), [X, Y, N]."""
    cfg = _effects()['added_resistance']
    p = _params(cfg['physics'])
    u = state['u_water']
    out = np.zeros((len(u), 3))
    out[:, 0] = -cfg['share'] * p.R_0 * 0.5 * p.rho * p.L_pp * p.d * u * np.abs(u)
    return out


def weak_thruster(t, state, controls, environment) -> np.ndarray:
    """Return the thrust one thruster of the Otter does not give (module docstring)."""
    cfg = _effects()['weak_thruster']
    p = _params(cfg['physics'])
    unit = next(t for t in p.thrusters if t.actuator == cfg['actuator'])
    loss = -(1.0 - cfg['share']) * thrust(controls[cfg['actuator']], unit)
    fx, fy = loss * np.cos(unit.angle), loss * np.sin(unit.angle)
    return np.stack([fx, fy, unit.x * fy - unit.y * fx], axis=-1)
