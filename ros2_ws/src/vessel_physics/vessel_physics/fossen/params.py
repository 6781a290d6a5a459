"""
The Fossen matrix model's parameters: rigid body, added mass, damping, thrusters, rudders.

The form in which small craft are usually written (Fossen 2021, ch. 6 and 10; the
Otter of PythonVehicleSimulator, Gazebo/VRX's USV plugins): horizontal-plane motion
(surge, sway, yaw) about CO, the origin of the body frame (FRD), with

    (M_RB + M_A) nu_r' + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D(nu_r) nu_r = tau

M_RB from the mass m, the centre of gravity at (x_G, 0) and the yaw inertia I_z about CO;
M_A from the added-mass derivatives (Xudot, ..., negative as Fossen writes them); the
Coriolis matrices follow from M_RB and M_A; D is linear (Xu, Yv, Yr, Nv, Nr) plus
quadratic (X|u|u, Y|v|v, N|r|r) plus the cross-flow drag of strip theory. tau comes from
thrusters and rudders placed by position and direction, and optionally from the wind.
A parameter file (``format: fossen-params/1``) holds exactly these keys, SI units.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

from vessel_physics.errors import ConfigError
from vessel_physics.files import check_ranges, numeric_fields, parameter_mapping

FORMAT = 'fossen-params/1'


@dataclass(frozen=True)
class Thruster:
    """A propeller driven by one vessel actuator (its shaft speed, rad/s)."""

    actuator: str          # the vessel file's actuator name
    x: float               # position forward of CO, m
    y: float               # position to starboard of CO, m
    angle: float           # direction of the thrust from the x axis towards starboard, rad
    k_forward: float       # thrust k n|n| for n > 0, N s^2 / rad^2 (bollard pull data)
    k_reverse: float       # the same for n <= 0 (astern)
    time_constant_s: float  # shaft speed response to its set-point, s


@dataclass(frozen=True)
class Rudder:
    """A rudder driven by one vessel actuator (its angle, rad; + turns the craft to starboard)."""

    actuator: str
    x: float               # position forward of CO, m (aft < 0)
    y: float               # position to starboard of CO, m
    area: float            # lateral area, m^2
    lift_slope: float      # lift coefficient per radian of angle of attack
    max_rate: float        # servo rate limit, rad/s
    time_constant_s: float  # servo response, s


@dataclass(frozen=True)
class FossenParams:
    """Parameters of one Fossen matrix model (module docstring); SI units, FRD about CO."""

    name: str
    rho: float             # water density, kg/m^3
    m: float               # mass, kg
    x_G: float             # centre of gravity forward of CO, m
    I_z: float             # yaw moment of inertia about CO, kg m^2
    Xudot: float           # added mass, kg (negative)
    Yvdot: float
    Yrdot: float           # kg m
    Nvdot: float           # kg m
    Nrdot: float           # kg m^2
    Xu: float              # linear damping, N s/m (negative)
    Yv: float
    Yr: float              # N s/rad
    Nv: float              # N s
    Nr: float              # N m s/rad
    Xuu: float             # quadratic damping X|u|u, N s^2/m^2
    Yvv: float             # Y|v|v
    Nrr: float             # N|r|r, N m s^2/rad^2
    crossflow_Cd: float    # 2-D cross-flow drag coefficient of the hull sections (Hoerner)
    crossflow_draft: float  # m, draught of the sections
    crossflow_length: float  # m, length of the hull the strips cover (0: no cross-flow drag)
    wind_AF: float         # frontal projected area above water, m^2 (0: no wind load)
    wind_AL: float         # lateral projected area above water, m^2
    wind_Loa: float        # length over all, m
    wind_cx: float         # wind load coefficients: C_X = c_x cos, C_Y = c_y sin,
    wind_cy: float         # C_N = c_n sin 2 of the apparent wind angle
    wind_cn: float
    thrusters: tuple[Thruster, ...]
    rudders: tuple[Rudder, ...]

    @property
    def actuators(self) -> tuple[str, ...]:
        """Return the vessel actuators the thrusters and rudders read, in that order."""
        return tuple(t.actuator for t in self.thrusters) + tuple(r.actuator
                                                                for r in self.rudders)


FLOAT_FIELDS = tuple(f.name for f in fields(FossenParams)
                     if f.name not in ('name', 'thrusters', 'rudders'))
_POSITIVE = ('rho', 'm', 'I_z')
_NON_NEGATIVE = ('crossflow_Cd', 'crossflow_draft', 'crossflow_length', 'wind_AF', 'wind_AL',
                 'wind_Loa')


def _devices(cls, items, key: str, source: str) -> tuple:
    if not isinstance(items, list):
        raise ConfigError(f'{source}: {key}: expected a list of mappings, got {items!r}')
    names = [f.name for f in fields(cls)]
    out = []
    for i, item in enumerate(items):
        where = f'{source}: {key}[{i}]'
        values = numeric_fields(item, names, [n for n in names if n != 'actuator'], where,
                                f'{key[:-1]} keys')
        if not isinstance(item['actuator'], str) or not item['actuator']:
            raise ConfigError(f'{where}: actuator: expected the name of a vessel actuator')
        device = cls(actuator=item['actuator'], **values)
        check_ranges(device, [n for n in names if n != 'actuator'],
                     [n for n in ('area', 'max_rate') if n in names], (), where)
        if device.time_constant_s < 0:
            raise ConfigError(f'{where}: time_constant_s: must be >= 0')
        out.append(device)
    return tuple(out)


def params_from_dict(data, source: str = 'fossen parameters') -> FossenParams:
    """Build validated parameters from a parameter file's mapping (module docstring)."""
    data = parameter_mapping(data, FORMAT, source)
    scalars = {k: v for k, v in data.items() if k not in ('thrusters', 'rudders')}
    values = numeric_fields(scalars, FLOAT_FIELDS + ('name',), FLOAT_FIELDS, source,
                            'parameters')
    params = FossenParams(name=str(data['name']), **values,
                          thrusters=_devices(Thruster, data.get('thrusters', []), 'thrusters',
                                             source),
                          rudders=_devices(Rudder, data.get('rudders', []), 'rudders', source))
    check_ranges(params, FLOAT_FIELDS, _POSITIVE, (), source)
    for key in _NON_NEGATIVE:
        if getattr(params, key) < 0:
            raise ConfigError(f'{source}: {key}: must be >= 0, got {getattr(params, key)!r}')
    if not params.thrusters:
        raise ConfigError(f'{source}: thrusters: a craft needs at least one thruster')
    if len(set(params.actuators)) != len(params.actuators):
        raise ConfigError(f'{source}: thrusters and rudders: each needs its own actuator, got '
                          f'{list(params.actuators)}')
    return params


def parameter_values(params: FossenParams) -> dict:
    """Return the parameters as a file's mapping (``params_from_dict`` reads it back)."""
    values = asdict(params)
    values['thrusters'] = [dict(t) for t in values['thrusters']]
    values['rudders'] = [dict(r) for r in values['rudders']]
    return {'format': FORMAT, **values}
