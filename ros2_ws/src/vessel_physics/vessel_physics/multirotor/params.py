"""
The multirotor's parameters: rigid body, rotors by position and spin, rotor aerodynamics.

The form of rotorpy's ``Multirotor`` (Folk et al.; its rotor aerodynamics after
Forster 2015 and Grafe et al. 2026): a rigid body of mass ``m`` and inertia tensor I
about its centre of gravity, each rotor a propeller of thrust ``k_eta n^2`` and drag
torque ``k_m n^2`` (n in rad/s) along the body z axis, the H-force of rotor drag
(``k_d`` in the rotor plane, ``k_z`` the induced inflow along the axis), translational
lift ``k_h`` and the frame's parasitic drag ``c_Dx, c_Dy, c_Dz``. SI units, body FRD,
origin at the CG.

Conventions, stated once:

- ``Ixy, Ixz, Iyz`` are the off-diagonal ENTRIES of the inertia tensor in FRD,
  I = [[Ixx, Ixy, Ixz], [Ixy, Iyy, Iyz], [Ixz, Iyz, Izz]] (minus the products of inertia
  int x y dm ..., as rotorpy writes them); from a z-up body frame (FLU) Ixy and Ixz
  change sign, Iyz does not.
- A rotor's ``spin`` is its sense of rotation seen from above (from -z in FRD). A rotor
  spinning counter-clockwise (``ccw``) drives a reaction moment that yaws the body
  clockwise seen from above: +N in FRD; a ``cw`` rotor gives -N.

A parameter file (``format: multirotor-params/1``) holds exactly these keys.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

import numpy as np

from vessel_physics.errors import ConfigError, did_you_mean
from vessel_physics.files import check_ranges, numeric_fields, parameter_mapping

FORMAT = 'multirotor-params/1'
# Reaction yaw moment of a rotor's drag torque about +z FRD, per spin sense (module doc).
SPIN_SIGN = {'ccw': 1.0, 'cw': -1.0}
# The rotor-thrust candidates and the probe controls cover this many rotors (an octocopter).
MAX_ROTORS = 8


@dataclass(frozen=True)
class Rotor:
    """A rotor driven by one vessel actuator (its speed, rad/s, >= 0)."""

    actuator: str          # the vessel file's actuator name
    x: float               # hub forward of the CG, m
    y: float               # hub to starboard of the CG, m
    z: float               # hub below the CG, m (above: < 0)
    spin: str              # cw | ccw seen from above (module docstring)


@dataclass(frozen=True)
class MultirotorParams:
    """Parameters of one multirotor (module docstring); SI units, FRD about the CG."""

    name: str
    m: float               # mass, kg
    g: float               # gravitational acceleration, m/s^2
    Ixx: float             # inertia tensor about the CG, kg m^2 (entries, module docstring)
    Iyy: float
    Izz: float
    Ixy: float
    Ixz: float
    Iyz: float
    k_eta: float           # thrust coefficient, N/(rad/s)^2
    k_m: float             # yaw-moment (drag torque) coefficient, N m/(rad/s)^2
    k_d: float             # rotor drag in the rotor plane, N/(rad/s m/s) = kg/rad
    k_z: float             # induced inflow along the rotor axis, kg/rad
    k_h: float             # translational lift, N/(m/s)^2 = kg/m
    c_Dx: float            # parasitic drag of the frame, N/(m/s)^2
    c_Dy: float
    c_Dz: float
    tau_m: float           # motor time constant, s
    rotors: tuple[Rotor, ...]

    @property
    def actuators(self) -> tuple[str, ...]:
        """Return the vessel actuators the rotors read, in the file's order."""
        return tuple(r.actuator for r in self.rotors)

    @property
    def inertia(self) -> np.ndarray:
        """Return the inertia tensor about the CG in FRD (3x3, kg m^2)."""
        return np.array([[self.Ixx, self.Ixy, self.Ixz],
                         [self.Ixy, self.Iyy, self.Iyz],
                         [self.Ixz, self.Iyz, self.Izz]])


FLOAT_FIELDS = tuple(f.name for f in fields(MultirotorParams) if f.name not in ('name', 'rotors'))
_POSITIVE = ('m', 'g', 'Ixx', 'Iyy', 'Izz', 'k_eta')
_NON_NEGATIVE = ('k_m', 'k_d', 'k_z', 'k_h', 'c_Dx', 'c_Dy', 'c_Dz', 'tau_m')
_ROTOR_KEYS = tuple(f.name for f in fields(Rotor))
_ROTOR_NUMBERS = ('x', 'y', 'z')


def _rotors(items, source: str) -> tuple[Rotor, ...]:
    if not isinstance(items, list) or not items:
        raise ConfigError(f'{source}: rotors: expected a non-empty list of mappings, got '
                          f'{items!r}')
    if len(items) > MAX_ROTORS:
        raise ConfigError(f'{source}: rotors: at most {MAX_ROTORS}, got {len(items)}')
    out = []
    for i, item in enumerate(items):
        where = f'{source}: rotors[{i}]'
        values = numeric_fields(item, _ROTOR_KEYS, _ROTOR_NUMBERS, where, 'rotor keys')
        if not isinstance(item['actuator'], str) or not item['actuator']:
            raise ConfigError(f'{where}: actuator: expected the name of a vessel actuator')
        spin = item['spin']
        if spin not in SPIN_SIGN:
            raise ConfigError(f'{where}: spin: expected cw or ccw (seen from above), got '
                              f'{spin!r}{did_you_mean(str(spin), SPIN_SIGN)}')
        rotor = Rotor(actuator=item['actuator'], spin=spin, **values)
        check_ranges(rotor, _ROTOR_NUMBERS, (), (), where)
        out.append(rotor)
    return tuple(out)


def params_from_dict(data, source: str = 'multirotor parameters') -> MultirotorParams:
    """Build validated parameters from a parameter file's mapping (module docstring)."""
    data = parameter_mapping(data, FORMAT, source)
    scalars = {k: v for k, v in data.items() if k != 'rotors'}
    values = numeric_fields(scalars, FLOAT_FIELDS + ('name',), FLOAT_FIELDS, source,
                            'parameters')
    params = MultirotorParams(name=str(data['name']), **values,
                              rotors=_rotors(data.get('rotors'), source))
    check_ranges(params, FLOAT_FIELDS, _POSITIVE, (), source)
    for key in _NON_NEGATIVE:
        if getattr(params, key) < 0:
            raise ConfigError(f'{source}: {key}: must be >= 0, got {getattr(params, key)!r}')
    if np.linalg.eigvalsh(params.inertia).min() <= 0:
        raise ConfigError(f'{source}: Ixx ... Iyz: the inertia tensor must be positive '
                          f'definite, got {params.inertia.tolist()}')
    if len(set(params.actuators)) != len(params.actuators):
        raise ConfigError(f'{source}: rotors: each needs its own actuator, got '
                          f'{list(params.actuators)}')
    return params


def parameter_values(params: MultirotorParams) -> dict:
    """Return the parameters as a file's mapping (``params_from_dict`` reads it back)."""
    values = asdict(params)
    values['rotors'] = [dict(r) for r in values['rotors']]
    return {'format': FORMAT, **values}
