"""
Simulation configuration: schema, defaults, validation and loading.

``load_simulation(path or mapping)`` returns a frozen ``SimConfig``. Every key has a type,
a default and an allowed range in ``SCHEMA``; a mapping only needs the keys it changes.
The shipped scenario of each vessel is ``config/simulation/<vessel>.yaml``; the default,
the patrol boat's, spells out every key. Any invalid
key or value raises ``ConfigError`` whose message is one line naming the key and the
allowed values (unknown keys get a did-you-mean).

A scenario names the vessel file (``vessel``: its vectors, rate, actuator ranges and
recording map) and the physics the simulated vessel truly has (``physics``: any family's
physics or parameter file; default the one the vessel file names). Operator keys left
at null are derived from the vessel file's actuator ranges (``derived_operator``); a
craft without rudders is steered by differential thrust. A vehicle with rotors is flown
by the flight controller instead: its scenario has a ``flight`` section
(``FLIGHT_SCHEMA``: gains, trajectory kinds and their settings), which no other vessel
may have.

Unmodelled-effect hook. ``extra_forces: "package.module:function"`` names a callable
(module importable from PYTHONPATH) that the simulator calls at every RK4 stage::

    function(t, state, controls, environment) -> array of shape (n_runs, 4)

- ``t``: float, simulation time in s (0 at the first sample; negative in warm-up);
- ``state``: dict of float64 arrays of shape (n_runs,): the vessel's states (``u``, ``v``
  body velocity over ground, m/s, FRD; ``p``, ``r`` rad/s; ``phi`` rad; a 6-DOF
  vehicle's ``w``, ``q``, ``theta`` too), ``u_water``, ``v_water`` (through the water,
  m/s), ``psi`` (rad, NED, unwrapped), ``x``, ``y`` (and a 6-DOF vehicle's ``z``, down)
  (m, NED, from the first sample; during warm-up, from where the warm-up began);
- ``controls``: dict of arrays (n_runs,): the actual state of each vessel actuator, by
  its name (units of the vessel file);
- ``environment``: dict of arrays (n_runs,): ``wind_speed`` (m/s, true),
  ``wind_dir`` (rad, where the true wind comes from relative to the bow, + starboard),
  ``current_north``, ``current_east`` (m/s, NED), ``wave_elevation`` (m, at CO);
- returns the extra generalized forces (n_runs, n_dof) of the vessel's family (the
  patrol boat: [X, Y, K, N] about CO in FRD, N and N m; the multirotor [X, Y, Z, K, M,
  N] about the CG), added before the mass matrix.
  It must be a smooth function of its arguments (RK4 evaluates it four times per step)
  and must not modify its inputs.

``extra_forces_from_s`` switches the hook on mid-run (a vessel that departs from its
model: fouling that sets in, a rudder knocked off its sensor): its forces are scaled by
a smoothstep from 0 at that time to 1 ``extra_forces_ramp_s`` later. null: on from the
start, warm-up included.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
import importlib
import math
from pathlib import Path
from typing import Any

from vessel_description import Vessel, VesselError, load_vessel
from vessel_physics.errors import ConfigError, did_you_mean
from vessel_physics.family import Physics
from vessel_physics.files import config_dir, find_file, read_document
from vessel_physics.physics_file import load_physics
from vessel_physics.simulation.trajectories import KINDS

__all__ = ['ConfigError', 'SimConfig', 'load_simulation', 'load_hook', 'default_config_path',
           'vessel_config_path']

MAX_DT = 0.1  # s; REFERENCES: never integrate at the output rate, RK4 at <= 0.1 s


# ---------------------------------------------------------------- value specifications
@dataclass(frozen=True)
class Number:
    """A real number in [lo, hi] (or (lo, hi] with lo_open)."""

    default: float
    lo: float
    hi: float
    unit: str = ''
    lo_open: bool = False
    integer: bool = False
    optional: bool = False

    def allowed(self) -> str:
        kind = 'an integer' if self.integer else 'a number'
        left = '<' if self.lo_open else '<='
        unit = f' ({self.unit})' if self.unit else ''
        null = ' or null' if self.optional else ''
        return f'{kind} {self.lo:g} {left} value <= {self.hi:g}{unit}{null}'

    def check(self, value: Any) -> float | int | None:
        if value is None and self.optional:
            return None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError
        if self.integer and (not float(value).is_integer()):
            raise ValueError
        v = float(value)
        if not math.isfinite(v) or v > self.hi or v < self.lo or (self.lo_open and v == self.lo):
            raise ValueError
        return int(v) if self.integer else v


@dataclass(frozen=True)
class Interval:
    """A pair [lo, hi] with bound_lo <= lo <= hi <= bound_hi."""

    default: tuple[float, float]
    lo: float
    hi: float
    unit: str = ''
    lo_open: bool = False
    optional: bool = False

    def allowed(self) -> str:
        left = '<' if self.lo_open else '<='
        unit = f' ({self.unit})' if self.unit else ''
        null = ' or null' if self.optional else ''
        return f'[lo, hi] with {self.lo:g} {left} lo <= hi <= {self.hi:g}{unit}{null}'

    def check(self, value: Any) -> tuple[float, float] | None:
        if value is None and self.optional:
            return None
        if not isinstance(value, (list, tuple)) or len(value) != 2:
            raise ValueError
        pair = tuple(Number(0.0, self.lo, self.hi, lo_open=self.lo_open).check(v)
                     for v in value)
        if pair[0] > pair[1]:
            raise ValueError
        return pair


@dataclass(frozen=True)
class Flag:
    """true or false."""

    default: bool

    def allowed(self) -> str:
        return 'true or false'

    def check(self, value: Any) -> bool:
        if not isinstance(value, bool):
            raise ValueError
        return value


@dataclass(frozen=True)
class Text:
    """A string (optionally None)."""

    default: str | None
    description: str
    optional: bool = False

    def allowed(self) -> str:
        return self.description + (' or null' if self.optional else '')

    def check(self, value: Any) -> str | None:
        if value is None and self.optional:
            return None
        if not isinstance(value, str) or not value.strip():
            raise ValueError
        return value


# ---------------------------------------------------------------- the configuration
@dataclass(frozen=True)
class OperatorConfig:
    """Open-loop operator (see simulation.operator); nulls are derived from the vessel."""

    enabled: bool
    mode: str
    shaft_speed_rpm: tuple[float, float] | None
    shaft_hold_s: tuple[float, float]
    rudder_hold_s: tuple[float, float]
    rudder_routine_rad: float | None
    turn_probability: float
    rudder_turn_rad: tuple[float, float] | None
    turn_hold_s: tuple[float, float]
    rudder_difference_rad: float | None
    differential_per_rad: float
    zigzag_rudder_rad: tuple[float, float] | None
    zigzag_check_share: tuple[float, float]


@dataclass(frozen=True)
class WindConfig:
    """Wind field and Isherwood loads (see vessel_physics.wind)."""

    enabled: bool
    force_scale: float
    mean_speed_mps: tuple[float, float]
    veer_std_deg: float
    veer_period_s: tuple[float, float]
    veer_components: int
    gusts: bool
    gust_drag_coefficient: float
    gust_length_scale_m: float
    gust_components: int
    gust_frequency_hz: tuple[float, float]


@dataclass(frozen=True)
class WavesConfig:
    """JONSWAP sea state and wave forces (see vessel_physics.waves)."""

    enabled: bool
    force_scale: float
    hs_m: tuple[float, float]
    tp_scatter: float
    gamma: float
    components: int
    frequency_range: tuple[float, float]
    spreading_deg: float
    gain_surge: float
    gain_sway: float
    gain_roll: float
    gain_yaw: float


@dataclass(frozen=True)
class CurrentConfig:
    """Ocean current (see vessel_physics.current)."""

    enabled: bool
    speed_mps: tuple[float, float]
    variation: float
    variation_period_s: float


@dataclass(frozen=True)
class ControllerConfig:
    """Gains of the flight controller (see simulation.flight), per axis."""

    position_gain: tuple[float, float, float]
    velocity_gain: tuple[float, float, float]
    attitude_gain: tuple[float, float, float]
    rate_gain: tuple[float, float, float]
    max_tilt_rad: float
    min_thrust_share: float


@dataclass(frozen=True)
class FlightConfig:
    """
    A multirotor's flights (see simulation.flight and simulation.trajectories).

    ``kinds`` is the cycle of trajectory kinds that runs take in turn (a kind listed
    twice flies twice as often); each kind's own settings are a mapping of the keys of
    ``FLIGHT_SCHEMA``.
    """

    enabled: bool
    controller: ControllerConfig
    kinds: tuple[str, ...]
    ramp_s: float
    square: Mapping[str, Any]
    random: Mapping[str, Any]
    multisine: Mapping[str, Any]
    melon: Mapping[str, Any]
    aggressive: Mapping[str, Any]


@dataclass(frozen=True)
class NoiseConfig:
    """Gaussian sensor noise standard deviations (SI units of each channel)."""

    enabled: bool
    std: Mapping[str, float]


@dataclass(frozen=True)
class SimConfig:
    """
    A validated simulation configuration: the vessel file, its true physics, the rest.

    ``actuators`` maps each vessel actuator to its servo (low, high, time constant s,
    max rate per s); ``noise.std`` holds one standard deviation per measured channel.
    ``flight`` is the flight controller's section of a vehicle with rotors (None for
    the others, which the ``operator`` drives).
    """

    vessel: Vessel
    physics: Physics
    vessel_file: str
    physics_file: str
    dt: float
    output_rate_hz: float
    warmup_s: float
    operator: OperatorConfig
    wind: WindConfig
    waves: WavesConfig
    current: CurrentConfig
    noise: NoiseConfig
    actuators: Mapping[str, tuple[float, float, float, float]]
    extra_forces: str | None
    extra_forces_from_s: float | None = None
    extra_forces_ramp_s: float = 60.0
    flight: FlightConfig | None = None
    source: str = field(default='<defaults>', compare=False)

    @property
    def params(self):
        """Return the true physics' parameters."""
        return self.physics.params

    @property
    def steps_per_sample(self) -> int:
        """RK4 steps per output period."""
        return int(round(1.0 / (self.output_rate_hz * self.dt)))

    def to_dict(self) -> dict:
        """Return a plain, YAML/JSON-able dict (the physics with its parameter values)."""
        from vessel_physics.physics_file import physics_to_dict
        out = {'vessel_file': self.vessel_file, 'vessel': self.vessel.name,
               'physics_file': self.physics_file,
               'physics': physics_to_dict(self.physics, inline=True)}
        skip = ('vessel', 'physics', 'vessel_file', 'physics_file', 'source') + (
            ('flight',) if self.flight is None else ('operator',))
        for f in fields(self):
            if f.name in skip:
                continue
            value = getattr(self, f.name)
            out[f.name] = _plain(asdict(value) if hasattr(value, '__dataclass_fields__')
                                 else value)
        return out


def _plain(value):
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: _plain(v) for k, v in value.items()}
    return value


NOISE_CHANNELS = {   # default standard deviation of each channel a vessel may measure
    'u': (0.02, 'm/s'), 'v': (0.02, 'm/s'), 'p': (0.001, 'rad/s'), 'r': (0.0005, 'rad/s'),
    'phi': (0.002, 'rad'), 'psi': (0.002, 'rad'), 'x': (1.0, 'm'), 'y': (1.0, 'm'),
    'wind_speed': (0.2, 'm/s'), 'wind_dir': (0.05, 'rad'),
    # a 6-DOF vehicle's third components, as their planar twins by default
    'w': (0.02, 'm/s'), 'q': (0.001, 'rad/s'), 'theta': (0.002, 'rad'), 'z': (1.0, 'm'),
}
NOISE_BY_KIND = {   # actuators by kind, in their model unit
    'propeller': 0.5, 'rudder': 0.002, 'azimuth': 0.002, 'thruster': 0.0, 'other': 0.0,
    'rotor': 5.0,
}
OPERATOR_MODES = ('routine', 'zigzag')
# Operator orders derived from the vessel file where a scenario leaves them null, as
# shares of the actuators' ranges: the patrol boat's own orders are these shares of its
# ranges (366-980 of 1000 rpm; rudders 0.05, 0.1-0.3, 0.003 of 0.785 rad).
SHAFT_SHARE = (0.366, 0.98)
ROUTINE_SHARE, TURN_SHARE, DIFFERENCE_SHARE = 0.0637, (0.127, 0.382), 0.0038
ZIGZAG_SHARE = (0.25, 0.5)
# A craft steered by differential thrust has no rudder range: its steering orders are
# in radians of a virtual helm whose range is this.
VIRTUAL_HELM_RAD = 1.0


@dataclass(frozen=True)
class Choice:
    """One of a few words."""

    default: str
    options: tuple[str, ...]

    def allowed(self) -> str:
        return 'one of ' + ', '.join(self.options)

    def check(self, value: Any) -> str:
        if value not in self.options:
            raise ValueError
        return value


@dataclass(frozen=True)
class Servos:
    """Servo of some actuators: name -> {time_constant_s: s >= 0, max_rate: > 0 or null}."""

    default: Mapping = field(default_factory=dict)

    def allowed(self) -> str:
        return ('a mapping of actuator names to {time_constant_s: seconds >= 0, max_rate: '
                'units per second > 0 or null}')

    def check(self, value: Any) -> dict:
        if not isinstance(value, Mapping):
            raise ValueError
        out = {}
        for name, servo in value.items():
            if not isinstance(servo, Mapping) or set(servo) - {'time_constant_s', 'max_rate'}:
                raise ValueError
            rate = servo.get('max_rate')
            out[str(name)] = (Number(0.0, 0.0, 1e4).check(servo.get('time_constant_s', 0.0)),
                              math.inf if rate is None else
                              Number(1.0, 0.0, 1e9, lo_open=True).check(rate))
        return out


@dataclass(frozen=True)
class Deviations:
    """Standard deviations by channel name (numbers >= 0), merged over NOISE_CHANNELS."""

    default: Mapping[str, float]

    def allowed(self) -> str:
        return 'a mapping of channel names to standard deviations >= 0'

    def check(self, value: Any) -> dict[str, float]:
        if not isinstance(value, Mapping):
            raise ValueError
        out = {}
        for key, number in value.items():
            out[str(key)] = Number(0.0, 0.0, 1e3).check(number)
        return out

@dataclass(frozen=True)
class Vector:
    """A list of ``len(default)`` numbers, each in [lo, hi]."""

    default: tuple[float, ...]
    lo: float
    hi: float
    unit: str = ''

    def allowed(self) -> str:
        unit = f' ({self.unit})' if self.unit else ''
        return f'a list of {len(self.default)} numbers {self.lo:g} <= value <= {self.hi:g}{unit}'

    def check(self, value: Any) -> tuple[float, ...]:
        if not isinstance(value, (list, tuple)) or len(value) != len(self.default):
            raise ValueError
        return tuple(Number(0.0, self.lo, self.hi).check(v) for v in value)


@dataclass(frozen=True)
class Names:
    """A non-empty list of names, each one of ``options`` (repeats allowed)."""

    default: tuple[str, ...]
    options: tuple[str, ...]

    def allowed(self) -> str:
        return f'a non-empty list of {", ".join(self.options)} (repeats allowed)'

    def check(self, value: Any) -> tuple[str, ...]:
        if not isinstance(value, (list, tuple)) or not value or \
                any(v not in self.options for v in value):
            raise ValueError
        return tuple(value)


SCHEMA: dict[str, Any] = {
    'vessel': Text('patrol_boat', 'a vessel file name or path (vessel_description)'),
    'physics': Text(None, 'a physics or parameter file name or path', optional=True),
    'dt': Number(0.1, 0.0, MAX_DT, 's', lo_open=True),
    'output_rate_hz': Number(None, 0.0, 100.0, 'Hz', lo_open=True, optional=True),
    'warmup_s': Number(60.0, 0.0, 3600.0, 's'),
    'operator': {
        'enabled': Flag(True),
        'mode': Choice('routine', OPERATOR_MODES),
        'shaft_speed_rpm': Interval(None, -1e5, 1e5, 'rpm', optional=True),
        'shaft_hold_s': Interval((60.0, 900.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_hold_s': Interval((10.0, 120.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_routine_rad': Number(None, 0.0, 1.6, 'rad', optional=True),
        'turn_probability': Number(0.1, 0.0, 1.0),
        'rudder_turn_rad': Interval(None, 0.0, 1.6, 'rad', optional=True),
        'turn_hold_s': Interval((20.0, 90.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_difference_rad': Number(None, 0.0, 0.2, 'rad', optional=True),
        'differential_per_rad': Number(1.0, 0.0, 100.0, '1/rad'),
        'zigzag_rudder_rad': Interval(None, 0.0, 1.6, 'rad', optional=True),
        'zigzag_check_share': Interval((0.5, 1.0), 0.0, 2.0, lo_open=True),
    },
    'wind': {
        'enabled': Flag(True),
        'force_scale': Number(1.0, 0.0, 100.0),
        'mean_speed_mps': Interval((0.5, 4.0), 0.0, 40.0, 'm/s'),
        'veer_std_deg': Number(10.0, 0.0, 90.0, 'deg'),
        'veer_period_s': Interval((600.0, 3600.0), 1.0, 1e6, 's'),
        'veer_components': Number(3, 1, 20, integer=True),
        'gusts': Flag(True),
        'gust_drag_coefficient': Number(0.0026, 0.0, 0.05),
        'gust_length_scale_m': Number(1800.0, 1.0, 1e5, 'm'),
        'gust_components': Number(24, 1, 200, integer=True),
        'gust_frequency_hz': Interval((0.0005, 0.5), 0.0, 10.0, 'Hz', lo_open=True),
    },
    'waves': {
        'enabled': Flag(True),
        'force_scale': Number(1.0, 0.0, 100.0),
        'hs_m': Interval((0.5, 2.5), 0.0, 15.0, 'm'),
        'tp_scatter': Number(0.1, 0.0, 1.0),
        'gamma': Number(3.3, 1.0, 10.0),
        'components': Number(40, 1, 500, integer=True),
        'frequency_range': Interval((0.5, 3.5), 0.0, 20.0, 'multiples of the peak frequency',
                                    lo_open=True),
        'spreading_deg': Number(15.0, 0.0, 90.0, 'deg'),
        'gain_surge': Number(0.2, 0.0, 100.0),
        'gain_sway': Number(0.25, 0.0, 100.0),
        'gain_roll': Number(0.3, 0.0, 100.0),
        'gain_yaw': Number(0.15, 0.0, 100.0),
    },
    'current': {
        'enabled': Flag(False),
        'speed_mps': Interval((0.0, 0.5), 0.0, 5.0, 'm/s'),
        'variation': Number(0.1, 0.0, 1.0),
        'variation_period_s': Number(3600.0, 1.0, 1e7, 's'),
    },
    'noise': {
        'enabled': Flag(True),
        'std': Deviations({name: default for name, (default, _) in NOISE_CHANNELS.items()}),
    },
    'actuators': Servos(),
    'extra_forces': Text(None, "a hook 'module:function'", optional=True),
    'extra_forces_from_s': Number(None, -3600.0, 1e9, 's', optional=True),
    'extra_forces_ramp_s': Number(60.0, 0.0, 1e6, 's', lo_open=True),
}


def _yaw(amplitude: tuple[float, float], period: tuple[float, float]) -> dict:
    """Return the keys of the heading swing every trajectory kind has (trajectories.YawSwing)."""
    return {'yaw_amplitude_rad': Interval(amplitude, 0.0, 3.2, 'rad'),
            'yaw_period_s': Interval(period, 0.0, 1e5, 's', lo_open=True)}


# The flight controller's section: only vehicles with rotors have one (simulation.flight,
# simulation.trajectories; docs/simulator.md).
FLIGHT_SCHEMA: dict[str, Any] = {
    'enabled': Flag(True),
    'kinds': Names(('random', 'square', 'multisine', 'random', 'melon', 'aggressive'), KINDS),
    'ramp_s': Number(2.0, 0.0, 600.0, 's'),
    'controller': {
        'position_gain': Vector((6.5, 6.5, 15.0), 0.0, 1e4, '1/s^2: north, east, down'),
        'velocity_gain': Vector((4.0, 4.0, 9.0), 0.0, 1e4, '1/s: north, east, down'),
        'attitude_gain': Vector((310.0, 310.0, 310.0), 0.0, 1e6, '1/s^2: roll, pitch, yaw'),
        'rate_gain': Vector((57.0, 57.0, 57.0), 0.0, 1e4, '1/s: roll, pitch, yaw'),
        'max_tilt_rad': Number(1.1, 0.0, 1.5, 'rad', lo_open=True),
        'min_thrust_share': Number(0.2, 0.0, 1.0),
    },
    'square': {
        'side_m': Interval((0.8, 1.2), 0.0, 100.0, 'm', lo_open=True),
        'move_s': Interval((0.65, 0.95), 0.0, 600.0, 's', lo_open=True),
        'hold_s': Interval((0.5, 1.5), 0.0, 600.0, 's', lo_open=True),
        'climb_m': Interval((0.5, 1.0), 0.0, 100.0, 'm'),
        **_yaw((0.0, 0.2), (6.0, 15.0)),
    },
    'random': {
        'box_m': Vector((1.1, 1.1, 0.45), 0.0, 100.0, 'm: half-extents north, east, down'),
        'speed_mps': Interval((0.6, 1.4), 0.0, 50.0, 'm/s', lo_open=True),
        'min_segment_s': Number(0.6, 0.0, 600.0, 's', lo_open=True),
        **_yaw((0.0, 0.2), (6.0, 15.0)),
    },
    'multisine': {
        'horizontal_amplitude_m': Interval((0.35, 0.6), 0.0, 100.0, 'm'),
        'vertical_amplitude_m': Interval((0.25, 0.5), 0.0, 100.0, 'm'),
        'components': Number(2, 1, 20, integer=True),
        'frequency_hz': Interval((0.1, 0.5), 0.0, 10.0, 'Hz', lo_open=True),
        'sweep_s': Interval((40.0, 70.0), 0.0, 1e5, 's', lo_open=True),
        **_yaw((0.0, 0.2), (6.0, 15.0)),
    },
    'melon': {
        'radius_m': Interval((0.6, 0.8), 0.0, 100.0, 'm'),
        'lap_hz': Interval((0.25, 0.4), 0.0, 10.0, 'Hz', lo_open=True),
        'sweep_s': Interval((30.0, 60.0), 0.0, 1e5, 's', lo_open=True),
        'turn_period_s': Interval((20.0, 40.0), 0.0, 1e5, 's', lo_open=True),
        **_yaw((0.0, 0.2), (6.0, 15.0)),
    },
    'aggressive': {
        'box_m': Vector((1.1, 1.1, 0.45), 0.0, 100.0, 'm: half-extents north, east, down'),
        'speed_mps': Interval((1.0, 2.0), 0.0, 50.0, 'm/s', lo_open=True),
        'min_segment_s': Number(0.5, 0.0, 600.0, 's', lo_open=True),
        'hop_share': Number(0.4, 0.0, 1.0),
        'hop_speed_mps': Interval((0.8, 1.2), 0.0, 50.0, 'm/s', lo_open=True),
        **_yaw((0.3, 0.8), (3.0, 8.0)),
    },
}

_SECTIONS = {'operator': OperatorConfig, 'wind': WindConfig, 'waves': WavesConfig,
             'current': CurrentConfig, 'noise': NoiseConfig}


def defaults(schema: Mapping = SCHEMA) -> dict:
    """Return the default configuration as a plain nested dict."""
    return {key: defaults(spec) if isinstance(spec, Mapping) else _plain(spec.default)
            for key, spec in schema.items()}


def _validate(data: Any, schema: Mapping, prefix: str, source: str) -> dict:
    if not isinstance(data, Mapping):
        where = prefix.rstrip('.') or 'top level'
        raise ConfigError(f'{source}: {where}: expected a mapping of keys to values, got '
                          f'{type(data).__name__}')
    for key in data:
        if key not in schema:
            raise ConfigError(f'{source}: {prefix}{key}: unknown key'
                              f'{did_you_mean(str(key), schema)}; allowed keys: '
                              f'{", ".join(schema)}')
    out = {}
    for key, spec in schema.items():
        name = prefix + key
        if isinstance(spec, Mapping):
            out[key] = _validate(data.get(key, {}), spec, name + '.', source)
            continue
        value = data.get(key, spec.default)
        try:
            out[key] = spec.check(value)
        except ValueError:
            raise ConfigError(f'{source}: {name}: expected {spec.allowed()}, got '
                              f'{value!r}') from None
    return out


def _merge(base: dict, over: Mapping) -> dict:
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def load_hook(spec: str, source: str = 'config') -> Callable:
    """Import the ``'module:function'`` hook; raise ConfigError (one line) if it fails."""
    module_name, sep, attr = spec.partition(':')
    usage = "expected 'module:function' with the module importable from PYTHONPATH"
    if not sep or not module_name or not attr:
        raise ConfigError(f'{source}: extra_forces: {usage}, got {spec!r}')
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # noqa: BLE001 - any import failure is the user's hook's
        reason = ' '.join(str(exc).split()) or type(exc).__name__
        raise ConfigError(f'{source}: extra_forces: cannot import module {module_name!r} '
                          f'({reason}); {usage}') from None
    fn = getattr(module, attr, None)
    if not callable(fn):
        raise ConfigError(f'{source}: extra_forces: module {module_name!r} has no callable '
                          f'{attr!r}; {usage}')
    return fn


DEFAULT_VESSEL = 'patrol_boat'   # the simulator's own vessel, the node's default


def vessel_config_path(vessel: str) -> Path:
    """Path of the shipped scenario of a vessel, config/simulation/<name>.yaml."""
    return config_dir() / 'simulation' / f'{vessel}.yaml'


def default_config_path() -> Path:
    """Path of the default scenario: the patrol boat's (config/simulation/patrol_boat.yaml)."""
    return vessel_config_path(DEFAULT_VESSEL)


def _vessel(name: str, base: Path | None, label: str) -> Vessel:
    """
    Load the scenario's vessel file: a path (beside the scenario, or as given).

    Else the name of a shipped vessel; a physics file named there gets a pointer to
    ``physics``.
    """
    path = Path(name)
    if path.suffix and not path.is_absolute() and base is not None and (base / path).is_file():
        path = base / path
    if path.suffix and not path.is_file():
        try:    # a packaged physics file, as scenarios named it before vessel files
            path = find_file(name, (), 'physics file')
        except ConfigError:
            pass
    if path.suffix and path.is_file():
        document = read_document(path, 'vessel file')
        if isinstance(document, Mapping) and 'states' not in document:
            raise ConfigError(f'{label}: vessel: {name!r} is a physics or parameter file, not '
                              f'a vessel file: write physics: {name} and name the vessel file '
                              f'(e.g. vessel: {DEFAULT_VESSEL})')
    try:
        return load_vessel(path if path.suffix else name)
    except VesselError as exc:
        raise ConfigError(f'{label}: vessel: {exc}') from None


def derived_operator(values: dict, vessel: Vessel, label: str = 'config') -> OperatorConfig:
    """
    Fill the operator orders a scenario leaves null from the vessel's actuator ranges.

    Shaft speeds: ``SHAFT_SHARE`` of the propellers' highest speed; rudder orders:
    ``ROUTINE_SHARE`` etc. of the steering actuators' range (the virtual helm's for a
    craft steered by differential thrust).
    """
    out = dict(values)
    propellers = [a for a in vessel.actuators if a.kind == 'propeller']
    steering = [a for a in vessel.actuators if a.kind in ('rudder', 'azimuth')]
    rpm = 60.0 / (2 * math.pi)
    if out['shaft_speed_rpm'] is None:
        top = min(a.high for a in propellers) if propellers else 0.0
        out['shaft_speed_rpm'] = tuple(share * top * rpm for share in SHAFT_SHARE)
    for a in propellers:
        low, high = a.low * rpm, a.high * rpm
        if not low - 1e-6 <= out['shaft_speed_rpm'][0] <= out['shaft_speed_rpm'][1] \
                <= high + 1e-6:
            raise ConfigError(f'{label}: operator.shaft_speed_rpm: '
                              f'{list(out["shaft_speed_rpm"])} leaves the range of {a.name}, '
                              f'[{low:.4g}, {high:.4g}] rpm, of vessel {vessel.name!r}')
    helm = min(min(abs(a.low), abs(a.high)) for a in steering) if steering else \
        VIRTUAL_HELM_RAD
    defaults_ = {'rudder_routine_rad': ROUTINE_SHARE * helm,
                 'rudder_turn_rad': tuple(x * helm for x in TURN_SHARE),
                 'rudder_difference_rad': DIFFERENCE_SHARE * helm,
                 'zigzag_rudder_rad': tuple(x * helm for x in ZIGZAG_SHARE)}
    for key, value in defaults_.items():
        if out[key] is None:
            out[key] = value
    return OperatorConfig(**out)


def _servos(values: dict, physics: Physics, vessel: Vessel, dt: float, label: str) -> dict:
    """Each actuator's servo: the physics' own, else the scenario's, else an ideal one."""
    given = physics.family.actuator_dynamics(physics.params, vessel) or {}
    out = {}
    for a in vessel.actuators:
        if a.name in values:
            time_constant, rate = values[a.name]
            out[a.name] = (a.low, a.high, max(time_constant, dt), rate)
        elif a.name in given:
            out[a.name] = given[a.name]
        else:   # ideal: it follows a new order within about one integration step
            out[a.name] = (a.low, a.high, dt, math.inf)
    unknown = sorted(set(values) - set(vessel.actuator_names))
    if unknown:
        raise ConfigError(f'{label}: actuators: {unknown} are not actuators of vessel '
                          f'{vessel.name!r} ({", ".join(vessel.actuator_names)})')
    return out


def _noise(values: dict, vessel: Vessel, label: str) -> NoiseConfig:
    """One standard deviation per measured channel of the vessel (``NOISE_CHANNELS``)."""
    channels = measured_channels(vessel)
    std = values['std']
    for key in std:
        if key not in channels and key not in NOISE_CHANNELS:
            raise ConfigError(f'{label}: noise.std.{key}: not a measured channel of vessel '
                              f'{vessel.name!r}{did_you_mean(key, channels)}; channels: '
                              f'{", ".join(channels)}')
    kinds = {a.name: a.kind for a in vessel.actuators}
    return NoiseConfig(values['enabled'], {
        c: std.get(c, NOISE_BY_KIND[kinds[c]] if c in kinds else 0.0) for c in channels})


def measured_channels(vessel: Vessel) -> tuple[str, ...]:
    """Channels the simulated sensors measure, in the order of the noise vector."""
    wind = ('wind_speed', 'wind_dir') if 'wind' in vessel.environment else ()
    return vessel.state_names + vessel.pose_names + vessel.actuator_names + wind


def load_simulation(source: str | Path | Mapping | None = None,
                    vessel: str | None = None) -> SimConfig:
    """
    Load, validate and return a SimConfig from a YAML path, a mapping or the defaults.

    The keys a file or mapping gives are merged over the shipped scenario of its vessel
    (``config/simulation/<vessel>.yaml``, where there is one), that over the defaults of
    ``SCHEMA``. Relative file names (vessel, physics) are looked up next to the YAML
    file, then in the working directory and the packages. ``vessel`` (a vessel file's
    name or path) replaces the scenario's; alone, it simulates that vessel's own scenario.
    """
    base = None
    if source is None:
        source = {'vessel': vessel} if vessel else default_config_path()
    if isinstance(source, Mapping):
        data, label = dict(source), '<config>'
    else:
        path = Path(source)
        label, base = str(path), path.resolve().parent
        data = read_document(path, 'config')
        data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ConfigError(f'{label}: top level: expected a mapping of keys to values, got '
                          f'{type(data).__name__}')
    if vessel:
        data = {**data, 'vessel': vessel}
    name = data.get('vessel', DEFAULT_VESSEL)
    vessel = _vessel(name, base, label) if isinstance(name, str) else None
    flies = vessel is not None and flies_with_rotors(vessel)
    if vessel is not None and not flies and 'flight' in data:
        raise ConfigError(f'{label}: flight: the flight controller flies vehicles with rotors; '
                          f'vessel {vessel.name!r} has none (its operator is the section '
                          f"'operator'); remove the flight section")
    schema = {**SCHEMA, 'flight': FLIGHT_SCHEMA} if flies else SCHEMA
    merged = defaults(schema)
    shipped = vessel_config_path(vessel.name) if vessel is not None else None
    if shipped is not None and shipped.is_file() and not (
            base is not None and shipped.resolve() == Path(source).resolve()):
        merged = _merge(merged, {**read_document(shipped, 'config'), 'vessel': name})
    values = _validate(_merge(merged, data), schema, '', label)
    rate = values['output_rate_hz'] or vessel.rate_hz
    steps = 1.0 / (rate * values['dt'])
    if abs(steps - round(steps)) > 1e-6:
        raise ConfigError(f'{label}: dt: must divide the output period '
                          f'1/output_rate_hz = {1.0 / rate:g} s into '
                          f'whole steps (0 < dt <= {MAX_DT:g} s), got {values["dt"]!r}')
    if values['extra_forces'] is not None:
        load_hook(values['extra_forces'], label)
    elif values['extra_forces_from_s'] is not None:
        raise ConfigError(f'{label}: extra_forces_from_s: switches the extra_forces hook on, '
                          f'but extra_forces is null; name the hook or drop the time')
    physics_file = values['physics'] or vessel.physics
    if physics_file is None:
        raise ConfigError(f'{label}: physics: vessel {vessel.name!r} names no physics file; '
                          f'give the physics to simulate')
    try:
        if values['physics'] is None:     # beside the vessel file that names it
            physics = load_physics(physics_file, vessel)
        else:                             # beside this scenario
            physics = load_physics(find_file(physics_file, [base]).resolve(), vessel)
    except ConfigError as exc:
        raise ConfigError(f'{label}: physics: {exc}') from None
    for name in ('wind', 'waves', 'current'):
        if values[name]['enabled'] and name not in physics.family.environment:
            raise ConfigError(f'{label}: {name}.enabled: the {physics.family.title} feels no '
                              f'{name}; set {name}: {{enabled: false}}')
    if values['wind']['enabled'] and 'wind' not in vessel.environment:
        raise ConfigError(f'{label}: wind.enabled: vessel {vessel.name!r} has no wind input '
                          f'(environment); set wind: {{enabled: false}}')
    sections = {name: cls(**values[name]) for name, cls in _SECTIONS.items()
                if name not in ('operator', 'noise')}
    return SimConfig(vessel=vessel, physics=physics, vessel_file=values['vessel'],
                     physics_file=physics_file, dt=values['dt'], output_rate_hz=rate,
                     warmup_s=values['warmup_s'],
                     operator=derived_operator(values['operator'], vessel, label),
                     noise=_noise(values['noise'], vessel, label),
                     actuators=_servos(values['actuators'], physics, vessel, values['dt'],
                                       label),
                     extra_forces=values['extra_forces'],
                     extra_forces_from_s=values['extra_forces_from_s'],
                     extra_forces_ramp_s=values['extra_forces_ramp_s'],
                     flight=_flight(values['flight']) if flies else None, source=label,
                     **sections)


def flies_with_rotors(vessel: Vessel) -> bool:
    """Whether a flight controller flies the vehicle: it has rotors (a multirotor)."""
    return any(a.kind == 'rotor' for a in vessel.actuators)


def _flight(values: dict) -> FlightConfig:
    """Return the validated flight section as a FlightConfig."""
    return FlightConfig(**{**values, 'controller': ControllerConfig(**values['controller'])})
