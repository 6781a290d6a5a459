"""
Simulation configuration: schema, defaults, validation and loading.

``load_config(path or mapping)`` returns a frozen ``SimConfig``. Every key has a type, a
default and an allowed range in ``SCHEMA``; a mapping only needs the keys it changes.
The default scenario, ``config/simulation.yaml``, spells out every default. Any invalid
key or value raises ``ConfigError`` whose message is one line naming the key and the
allowed values (unknown keys get a did-you-mean).

Unmodelled-effect hook. ``extra_forces: "package.module:function"`` names a callable
(module importable from PYTHONPATH) that the simulator calls at every RK4 stage::

    function(t, state, controls, environment) -> array of shape (n_runs, 4)

- ``t``: float, simulation time in s (0 at the first sample; negative in warm-up);
- ``state``: dict of float64 arrays of shape (n_runs,): ``u``, ``v`` (body velocity over
  ground, m/s, FRD), ``u_water``, ``v_water`` (through the water, m/s), ``p``, ``r``
  (rad/s, FRD), ``phi``, ``psi`` (rad, NED, psi unwrapped), ``x``, ``y`` (m, NED, from
  the first sample; during warm-up, from where the warm-up began);
- ``controls``: dict of arrays (n_runs,): actual actuator states ``n`` (rad/s),
  ``delta_port``, ``delta_stbd`` (rad, positive turns the thrust to starboard);
- ``environment``: dict of arrays (n_runs,): ``wind_speed`` (m/s, true),
  ``wind_dir`` (rad, where the true wind comes from relative to the bow, + starboard),
  ``current_north``, ``current_east`` (m/s, NED), ``wave_elevation`` (m, at CO);
- returns the extra generalized forces [X, Y, K, N] about CO in FRD (N, N, N m, N m),
  added to the physics before the mass matrix. It must be a smooth function of its
  arguments (RK4 evaluates it four times per step) and must not modify its inputs.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field, fields
import importlib
import math
from pathlib import Path
from typing import Any

from vessel_physics.errors import ConfigError, did_you_mean
from vessel_physics.files import read_yaml
from vessel_physics.params import VesselParams, config_dir, load_named_vessel

__all__ = ['ConfigError', 'SimConfig', 'load_config', 'load_hook', 'default_config_path']

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

    def allowed(self) -> str:
        kind = 'an integer' if self.integer else 'a number'
        left = '<' if self.lo_open else '<='
        unit = f' ({self.unit})' if self.unit else ''
        return f'{kind} {self.lo:g} {left} value <= {self.hi:g}{unit}'

    def check(self, value: Any) -> float | int:
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

    def allowed(self) -> str:
        left = '<' if self.lo_open else '<='
        unit = f' ({self.unit})' if self.unit else ''
        return f'[lo, hi] with {self.lo:g} {left} lo <= hi <= {self.hi:g}{unit}'

    def check(self, value: Any) -> tuple[float, float]:
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
    """Open-loop operator (see vessel_physics.operator)."""

    enabled: bool
    shaft_speed_rpm: tuple[float, float]
    shaft_hold_s: tuple[float, float]
    rudder_hold_s: tuple[float, float]
    rudder_routine_rad: float
    turn_probability: float
    rudder_turn_rad: tuple[float, float]
    turn_hold_s: tuple[float, float]
    rudder_difference_rad: float


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
class NoiseConfig:
    """Gaussian sensor noise standard deviations (SI units of each channel)."""

    enabled: bool
    std: Mapping[str, float]


@dataclass(frozen=True)
class SimConfig:
    """A validated simulation configuration."""

    vessel: VesselParams
    vessel_file: str
    dt: float
    output_rate_hz: float
    warmup_s: float
    operator: OperatorConfig
    wind: WindConfig
    waves: WavesConfig
    current: CurrentConfig
    noise: NoiseConfig
    extra_forces: str | None
    source: str = field(default='<defaults>', compare=False)

    @property
    def steps_per_sample(self) -> int:
        """RK4 steps per output period."""
        return int(round(1.0 / (self.output_rate_hz * self.dt)))

    def to_dict(self) -> dict:
        """Return a plain, YAML/JSON-able dict (the vessel as its full parameter set)."""
        out = {'vessel_file': self.vessel_file, 'vessel': asdict(self.vessel)}
        for f in fields(self):
            if f.name in ('vessel', 'vessel_file', 'source'):
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


NOISE_CHANNELS = {
    'u': (0.02, 'm/s'), 'v': (0.02, 'm/s'), 'p': (0.001, 'rad/s'), 'r': (0.0005, 'rad/s'),
    'phi': (0.002, 'rad'), 'psi': (0.002, 'rad'), 'x': (1.0, 'm'), 'y': (1.0, 'm'),
    'n': (0.5, 'rad/s'), 'delta_port': (0.002, 'rad'), 'delta_stbd': (0.002, 'rad'),
    'wind_speed': (0.2, 'm/s'), 'wind_dir': (0.05, 'rad'),
}

SCHEMA: dict[str, Any] = {
    'vessel': Text('patrol_vessel.yaml', 'a vessel YAML file name or path'),
    'dt': Number(0.1, 0.0, MAX_DT, 's', lo_open=True),
    'output_rate_hz': Number(1.0, 0.0, 100.0, 'Hz', lo_open=True),
    'warmup_s': Number(60.0, 0.0, 3600.0, 's'),
    'operator': {
        'enabled': Flag(True),
        'shaft_speed_rpm': Interval((366.0, 980.0), 0.0, 1000.0, 'rpm'),
        'shaft_hold_s': Interval((60.0, 900.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_hold_s': Interval((10.0, 120.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_routine_rad': Number(0.05, 0.0, 0.785, 'rad'),
        'turn_probability': Number(0.1, 0.0, 1.0),
        'rudder_turn_rad': Interval((0.1, 0.3), 0.0, 0.785, 'rad'),
        'turn_hold_s': Interval((20.0, 90.0), 0.0, 86400.0, 's', lo_open=True),
        'rudder_difference_rad': Number(0.003, 0.0, 0.1, 'rad'),
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
        'std': {name: Number(default, 0.0, 1e3, unit)
                for name, (default, unit) in NOISE_CHANNELS.items()},
    },
    'extra_forces': Text(None, "a hook 'module:function'", optional=True),
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


def default_config_path() -> Path:
    """Path of the default scenario, config/simulation.yaml."""
    return config_dir() / 'simulation.yaml'


def load_config(source: str | Path | Mapping | None = None) -> SimConfig:
    """
    Load, validate and return a SimConfig from a YAML path, a mapping or the defaults.

    A mapping is merged over the defaults. Relative vessel file names are looked up next
    to the YAML file, then in the package's config directory.
    """
    base = None
    if source is None:
        source = default_config_path()
    if isinstance(source, Mapping):
        data, label = dict(source), '<config>'
    else:
        path = Path(source)
        label, base = str(path), path.resolve().parent
        data = read_yaml(path, 'config')
        data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ConfigError(f'{label}: top level: expected a mapping of keys to values, got '
                          f'{type(data).__name__}')
    values = _validate(_merge(defaults(), data), SCHEMA, '', label)
    steps = 1.0 / (values['output_rate_hz'] * values['dt'])
    if abs(steps - round(steps)) > 1e-6:
        raise ConfigError(f'{label}: dt: must divide the output period '
                          f'1/output_rate_hz = {1.0 / values["output_rate_hz"]:g} s into '
                          f'whole steps (0 < dt <= {MAX_DT:g} s), got {values["dt"]!r}')
    if values['extra_forces'] is not None:
        load_hook(values['extra_forces'], label)
    vessel = load_named_vessel(values['vessel'], base)
    sections = {}
    for name, cls in _SECTIONS.items():
        sections[name] = cls(**values[name])
    return SimConfig(vessel=vessel, vessel_file=values['vessel'], dt=values['dt'],
                     output_rate_hz=values['output_rate_hz'], warmup_s=values['warmup_s'],
                     extra_forces=values['extra_forces'], source=label, **sections)
