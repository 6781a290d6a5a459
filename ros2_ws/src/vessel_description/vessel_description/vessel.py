"""
A vessel description: the one source of a vessel's state and control vectors.

A YAML file per vessel (``vessels/patrol_boat.yaml`` is the simulator's; docs/vessels.md
documents every key) names the states, the actuators with units and ranges, the
environment inputs, the sample rate, the forecast window and horizon in seconds, the
main particulars and how recordings map onto those vectors. Datasets, checkpoints,
models, metrics, the predictor and the diagnosis read their layout from it; a
checkpoint or dataset carries the description it was made with.

Loading checks the whole description and refuses it with one line per error.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
import copy
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import re
from typing import Any

from .resources import data_dir, read_yaml
from .vocabulary import (
    ACTUATOR_KINDS,
    ENVIRONMENT,
    ENVIRONMENT_MIRROR,
    LIMITED_ENVIRONMENT,
    PLANAR_POSE,
    PLANAR_STATES,
    POSE,
    ROLL_STATES,
    SPATIAL_STATES,
    STATE_MIRROR,
    STATES,
    WATERS,
)

FORMAT = 'vessel-description/1'
VESSELS_DIR = 'vessels'
_NAME = re.compile(r'^[A-Za-z][A-Za-z0-9_]*$')
TOP_KEYS = ('format', 'name', 'description', 'rate_hz', 'window_s', 'horizon_s', 'states',
            'limits', 'actuators', 'environment', 'waters', 'particulars', 'physics',
            'recordings', 'mirror')
REQUIRED_KEYS = ('name', 'rate_hz', 'window_s', 'horizon_s', 'states', 'actuators',
                 'particulars')
ACTUATOR_KEYS = ('kind', 'unit', 'range', 'description')
RECORDING_KINDS = ('topics', 'columns', 'logs')  # bags, text tables, autopilot logs
DEFAULT_WATERS = 'open'   # a vessel file that says nothing sails where currents can act


class VesselError(ValueError):
    """A vessel description is malformed; the message is one line naming the key."""


@dataclass(frozen=True)
class Actuator:
    """One control input: its kind, model unit and the range its values stay in."""

    name: str
    kind: str
    unit: str
    low: float
    high: float
    description: str = ''


@dataclass(frozen=True)
class Vessel:
    """A parsed vessel description (see the module docstring)."""

    name: str
    rate_hz: float
    window_s: float
    horizon_s: float
    states: tuple[str, ...]
    actuators: tuple[Actuator, ...]
    environment: tuple[str, ...]
    particulars: Mapping[str, float]
    limits: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    physics: str | None = None
    recordings: Mapping[str, Any] = field(default_factory=dict)
    description: str = ''
    source: str = '<inline>'
    waters: str = DEFAULT_WATERS
    # Port/starboard symmetry: each actuator's mirror image ('-' for a sign change), or
    # None when the vessel does not declare itself symmetric.
    mirror: Mapping[str, str] | None = None

    # ------------------------------------------------------------- vector contract
    @property
    def state_names(self) -> tuple[str, ...]:
        """Model state vector z, in order."""
        return self.states

    @property
    def state_units(self) -> tuple[str, ...]:
        """Units of z."""
        return tuple(STATES[s][0] for s in self.states)

    @property
    def actuator_names(self) -> tuple[str, ...]:
        """Names of the actuators, in order."""
        return tuple(a.name for a in self.actuators)

    @property
    def environment_columns(self) -> tuple[str, ...]:
        """Model columns the environment inputs expand into."""
        return tuple(c[0] for env in self.environment for c in ENVIRONMENT[env])

    @property
    def control_names(self) -> tuple[str, ...]:
        """Model control vector c: actuators, then environment columns."""
        return self.actuator_names + self.environment_columns

    @property
    def control_units(self) -> tuple[str, ...]:
        """Units of c."""
        return tuple(a.unit for a in self.actuators) + tuple(
            c[1] for env in self.environment for c in ENVIRONMENT[env])

    @property
    def n_state(self) -> int:
        """Return the number of state variables."""
        return len(self.states)

    @property
    def n_control(self) -> int:
        """Return the number of control inputs (actuators and environment columns)."""
        return len(self.control_names)

    @property
    def dt(self) -> float:
        """Sample period (s)."""
        return 1.0 / self.rate_hz

    @property
    def window(self) -> int:
        """Return the initialization window in samples."""
        return max(2, int(round(self.window_s * self.rate_hz)))

    @property
    def horizon(self) -> int:
        """Return the forecast horizon in samples."""
        return max(1, int(round(self.horizon_s * self.rate_hz)))

    @property
    def has_roll(self) -> bool:
        """Whether roll (p, phi) is modelled (4-DOF, 6-DOF) or not (3-DOF)."""
        return 'phi' in self.states

    @property
    def is_spatial(self) -> bool:
        """Whether the vehicle moves in all six DOF (w, q, theta modelled: a multirotor)."""
        return 'theta' in self.states

    @property
    def pose_names(self) -> tuple[str, ...]:
        """Pose columns of its datasets: heading, position north and east (and down)."""
        return PLANAR_POSE + (('z',) if self.is_spatial else ())

    def require_planar(self, tool: str) -> None:
        """Refuse a 6-DOF vehicle (VesselError, one line) in a tool made for the plane."""
        if self.is_spatial:
            raise VesselError(f'{tool} is for vessels in the plane; vehicle {self.name!r} '
                              f'({self.source}) is a 6-DOF vehicle (states '
                              f'{list(self.states)})')

    @property
    def length_m(self) -> float:
        """Length between perpendiculars (m)."""
        return float(self.particulars['length_m'])

    def state_index(self, name: str) -> int:
        """Column of a state variable."""
        return self.states.index(name)

    def control_index(self, name: str) -> int:
        """Column of a control input."""
        return self.control_names.index(name)

    def actuator(self, name: str) -> Actuator:
        """Return the actuator of this name."""
        for a in self.actuators:
            if a.name == name:
                return a
        raise KeyError(f'vessel {self.name!r} has no actuator {name!r}')

    def column_docs(self) -> dict[str, dict[str, str]]:
        """Return unit and meaning of every dataset column of this vessel."""
        docs = {'t': {'unit': 's', 'description': "time since the run's first sample"}}
        docs.update({s: {'unit': STATES[s][0], 'description': STATES[s][1]}
                     for s in self.states})
        docs.update({k: {'unit': POSE[k][0], 'description': POSE[k][1]}
                     for k in self.pose_names})
        for a in self.actuators:
            docs[a.name] = {'unit': a.unit,
                            'description': a.description or ACTUATOR_KINDS[a.kind][1]}
        for env in self.environment:
            docs.update({c: {'unit': u, 'description': d} for c, u, d in ENVIRONMENT[env]})
        return docs

    @property
    def dataset_columns(self) -> tuple[str, ...]:
        """Columns every run table of this vessel has: time, states, pose, controls."""
        return ('t',) + self.states + self.pose_names + self.control_names

    def mirror_maps(self) -> tuple[list[float], list[int], list[float]]:
        """
        Return how the mirror image of a motion is made from it, in the model vectors.

        (state signs, control source columns, control signs): the mirrored z is
        ``z * state_signs`` and the mirrored c is ``c[..., sources] * control_signs``.
        Refused (VesselError) for a vessel whose file declares no ``mirror``.
        """
        if self.mirror is None:
            raise VesselError(f'vessel {self.name!r} ({self.source}) declares no mirror '
                              f'image (key mirror): it is not known to be symmetric')
        sources, signs = [], []
        for name in self.control_names:
            image = self.mirror.get(name)
            if image is None:   # an environment column
                sources.append(self.control_index(name))
                signs.append(ENVIRONMENT_MIRROR[name])
                continue
            sources.append(self.control_index(image.lstrip('-')))
            signs.append(-1.0 if image.startswith('-') else 1.0)
        return [STATE_MIRROR[s] for s in self.states], sources, signs

    # ------------------------------------------------------------- identity
    def contract(self) -> dict[str, Any]:
        """Return what a model of this vessel depends on: vectors and sample rate."""
        return {'name': self.name, 'states': list(self.states),
                'controls': list(self.control_names), 'rate_hz': self.rate_hz}

    def check_compatible(self, other: Vessel, what: str) -> None:
        """Raise VesselError (one line) unless ``other`` has this vessel's contract."""
        mine, theirs = self.contract(), other.contract()
        diffs = [f'{k} {theirs[k]} vs {mine[k]}' for k in mine if mine[k] != theirs[k]]
        if diffs:
            raise VesselError(f'{what} was made for vessel {other.name!r} '
                              f'({other.source}), not {self.name!r} ({self.source}): '
                              + '; '.join(diffs))

    def to_dict(self) -> dict[str, Any]:
        """Return the description as a YAML/JSON-ready mapping (see ``parse_vessel``)."""
        out: dict[str, Any] = {
            'format': FORMAT, 'name': self.name, 'description': self.description,
            'rate_hz': self.rate_hz, 'window_s': self.window_s, 'horizon_s': self.horizon_s,
            'states': list(self.states),
            'limits': {k: list(v) for k, v in self.limits.items()},
            # A list, not a mapping: the order is the control vector's, and YAML dumpers
            # sort mapping keys.
            'actuators': [{'name': a.name, 'kind': a.kind, 'unit': a.unit,
                           'range': [a.low, a.high], 'description': a.description}
                          for a in self.actuators],
            'environment': list(self.environment),
            'waters': self.waters,
            'particulars': dict(self.particulars),
            'physics': self.physics,
            'recordings': copy.deepcopy(dict(self.recordings)),
        }
        if self.mirror is not None:
            out['mirror'] = dict(self.mirror)
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str = '<inline>') -> Vessel:
        """Parse a description stored in a dataset manifest or a checkpoint."""
        return parse_vessel(data, source)


# ----------------------------------------------------------------- parsing
def parse_vessel(data: Any, source: str = '<inline>') -> Vessel:
    """Check a description given as a mapping (the parsed YAML) and build it."""
    where = f'vessel {source}'
    if not isinstance(data, Mapping):
        raise VesselError(f'{where}: expected a mapping at the top level')
    if data.get('format', FORMAT) != FORMAT:
        raise VesselError(f'{where}: format {data.get("format")!r}, expected {FORMAT!r}')
    if unknown := sorted(set(data) - set(TOP_KEYS)):
        raise VesselError(f'{where}: unknown keys {unknown}; expected some of {list(TOP_KEYS)}')
    if missing := [k for k in REQUIRED_KEYS if k not in data]:
        raise VesselError(f'{where}: missing keys {missing}')
    name = data['name']
    if not isinstance(name, str) or not _NAME.match(name):
        raise VesselError(f'{where}: name must be an identifier, got {name!r}')
    rate = _positive(data['rate_hz'], f'{where}: rate_hz')
    window_s = _positive(data['window_s'], f'{where}: window_s')
    horizon_s = _positive(data['horizon_s'], f'{where}: horizon_s')
    if window_s * rate < 2:
        raise VesselError(f'{where}: window_s {window_s} gives fewer than 2 samples at '
                          f'{rate} Hz')
    states = _states(data['states'], where)
    actuators = _actuators(data['actuators'], where)
    environment = _environment(data.get('environment') or [], where)
    names = [a.name for a in actuators] + [c[0] for e in environment for c in ENVIRONMENT[e]]
    clash = sorted({n for n in names if names.count(n) > 1 or n in STATES or n in POSE
                    or n == 't'})
    if clash:
        raise VesselError(f'{where}: actuator names {clash} repeat or clash with states, '
                          f'pose or time')
    particulars = _particulars(data['particulars'], where)
    waters = data.get('waters', DEFAULT_WATERS)
    if waters not in WATERS:
        raise VesselError(f'{where}: waters must be one of {list(WATERS)}, got {waters!r}')
    limits = _limits(data.get('limits') or {}, states, where,
                     tuple(c for env in environment for c in LIMITED_ENVIRONMENT.get(env, ())))
    physics = data.get('physics')
    if physics is not None and not isinstance(physics, str):
        raise VesselError(f'{where}: physics must name a hull parameter file, got {physics!r}')
    recordings = data.get('recordings') or {}
    if not isinstance(recordings, Mapping) or set(recordings) - set(RECORDING_KINDS):
        raise VesselError(f'{where}: recordings takes {list(RECORDING_KINDS)} mappings')
    description = data.get('description') or ''
    mirror = _mirror(data.get('mirror'), actuators, where)
    return Vessel(name=name, rate_hz=rate, window_s=window_s, horizon_s=horizon_s,
                  states=states, actuators=actuators, environment=environment,
                  particulars=particulars, limits=limits, physics=physics,
                  recordings=plain(recordings), description=str(description), source=source,
                  waters=waters, mirror=mirror)


def _positive(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (
            math.isfinite(value) and value > 0):
        raise VesselError(f'{where} must be a positive number, got {value!r}')
    return float(value)


def _states(value: Any, where: str) -> tuple[str, ...]:
    order = list(STATES)
    if not isinstance(value, list) or not all(isinstance(s, str) for s in value):
        raise VesselError(f'{where}: states must be a list of names among {order}')
    if unknown := [s for s in value if s not in STATES]:
        raise VesselError(f'{where}: unknown states {unknown}; known: {order}')
    if missing := [s for s in PLANAR_STATES if s not in value]:
        raise VesselError(f'{where}: states lack {missing}; every vessel has {PLANAR_STATES}')
    if any(s in value for s in ROLL_STATES) and not all(s in value for s in ROLL_STATES):
        raise VesselError(f'{where}: roll needs both {list(ROLL_STATES)} or neither')
    spatial = SPATIAL_STATES + ROLL_STATES
    if any(s in value for s in SPATIAL_STATES) and not all(s in value for s in spatial):
        raise VesselError(f'{where}: a 6-DOF vehicle has all of {list(spatial)} (heave, '
                          f'pitch and roll), got {value}')
    if value != [s for s in order if s in value]:
        raise VesselError(f'{where}: list states in the order {order}, got {value}')
    return tuple(value)


def _actuators(value: Any, where: str) -> tuple[Actuator, ...]:
    if isinstance(value, list) and all(isinstance(a, Mapping) and 'name' in a for a in value):
        value = {a['name']: {k: v for k, v in a.items() if k != 'name'} for a in value}
    if not isinstance(value, Mapping) or not value:
        raise VesselError(f'{where}: actuators must map names to {{kind, unit, range}} '
                          f'(or list them with a name each)')
    out = []
    for name, spec in value.items():
        label = f'{where}: actuators.{name}'
        if not isinstance(name, str) or not _NAME.match(name):
            raise VesselError(f'{label}: the name must be an identifier')
        if not isinstance(spec, Mapping):
            raise VesselError(f'{label} must be a mapping with kind, unit and range')
        if unknown := sorted(set(spec) - set(ACTUATOR_KEYS)):
            raise VesselError(f'{label}: unknown keys {unknown}; use {list(ACTUATOR_KEYS)}')
        kind = spec.get('kind')
        if kind not in ACTUATOR_KINDS:
            raise VesselError(f'{label}.kind is {kind!r}; use one of {list(ACTUATOR_KINDS)}')
        unit = spec.get('unit', ACTUATOR_KINDS[kind][0])
        fixed = ACTUATOR_KINDS[kind][0]
        if not isinstance(unit, str) or (fixed is not None and unit != fixed):
            raise VesselError(f'{label}.unit is {unit!r}; a {kind} is in {fixed} (convert '
                              f"the recording with the map's scale)")
        rng = spec.get('range')
        if not (isinstance(rng, list) and len(rng) == 2 and all(
                isinstance(x, (int, float)) and math.isfinite(x) for x in rng)
                and rng[0] < rng[1]):
            raise VesselError(f'{label}.range must be [low, high] with low < high, got {rng!r}')
        out.append(Actuator(name, kind, unit, float(rng[0]), float(rng[1]),
                            str(spec.get('description') or '')))
    return tuple(out)


def _environment(value: Any, where: str) -> tuple[str, ...]:
    if not isinstance(value, list) or any(e not in ENVIRONMENT for e in value) or len(
            set(value)) != len(value):
        raise VesselError(f'{where}: environment must list inputs among {list(ENVIRONMENT)} '
                          f'(or be empty), got {value!r}')
    return tuple(value)


def _particulars(value: Any, where: str) -> dict[str, float]:
    if not isinstance(value, Mapping) or 'length_m' not in value:
        raise VesselError(f'{where}: particulars must give at least length_m (length '
                          f'between perpendiculars, m)')
    out = {}
    for key, number in value.items():
        out[str(key)] = _positive(number, f'{where}: particulars.{key}')
    return out


def _limits(value: Any, states: tuple[str, ...], where: str,
            environment: tuple[str, ...] = ()) -> dict[str, tuple[float, float]]:
    if not isinstance(value, Mapping):
        raise VesselError(f'{where}: limits must map states to [low, high]')
    out = {}
    for key, rng in value.items():
        if key not in states + environment:
            raise VesselError(f'{where}: limits.{key}: not a state of this vessel {states} '
                              f'nor one of its environment inputs {environment}')
        if not (isinstance(rng, list) and len(rng) == 2 and all(
                isinstance(x, (int, float)) for x in rng) and rng[0] < rng[1]):
            raise VesselError(f'{where}: limits.{key} must be [low, high], got {rng!r}')
        out[key] = (float(rng[0]), float(rng[1]))
    return out


def _mirror(value: Any, actuators: tuple[Actuator, ...], where: str) -> dict | None:
    """Check a mirror declaration: every actuator's image, of its kind, mirrored back."""
    if value is None:
        return None
    label = f'{where}: mirror'
    names = {a.name: a for a in actuators}
    if not isinstance(value, Mapping) or set(value) != set(names) or not all(
            isinstance(v, str) for v in value.values()):
        raise VesselError(f'{label} must give every actuator {sorted(names)} its mirror '
                          f"image: itself, another actuator, '-' before it for a sign change")
    for name, image in value.items():
        target = image.lstrip('-')
        if target not in names or image.count('-') > 1:
            raise VesselError(f'{label}.{name}: {image!r} is not an actuator (or -actuator)')
        if names[target].kind != names[name].kind:
            raise VesselError(f'{label}.{name}: its image {target} is a {names[target].kind}, '
                              f'not a {names[name].kind}')
        back = value[target]
        if back.lstrip('-') != name or (back.startswith('-') != image.startswith('-')):
            raise VesselError(f'{label}.{name}: the mirror of the mirror must be the actuator '
                              f'itself ({name} -> {image} -> {back})')
    return {str(k): str(v) for k, v in value.items()}


def plain(value: Any) -> Any:
    """Copy YAML data into plain dicts and lists (JSON-serializable)."""
    if isinstance(value, Mapping):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


# ----------------------------------------------------------------- files
def vessels_dir() -> Path:
    """Directory of the vessel files shipped with the package (source tree or install)."""
    return data_dir('vessel_description', __file__, VESSELS_DIR)


def shipped_vessels() -> list[str]:
    """Names of the vessel files shipped with the package."""
    return sorted(p.stem for p in vessels_dir().glob('*.yaml'))


def load_vessel(name_or_path: str | os.PathLike) -> Vessel:
    """Load a vessel file by path, or by the name of a shipped one (e.g. 'patrol_boat')."""
    path = Path(name_or_path)
    if not path.is_file():
        shipped = vessels_dir() / f'{name_or_path}.yaml'
        if path.suffix or not shipped.is_file():
            raise VesselError(f'vessel {name_or_path}: no such file, and not a shipped vessel '
                              f'({", ".join(shipped_vessels())})')
        path = shipped
    data = read_yaml(path, VesselError, 'vessel')
    return parse_vessel(data, str(path))


def recording_map(vessel: Vessel, kind: str, override: str | os.PathLike | None,
                  parse: Callable[[Any, Vessel], Any], error: type[Exception]) -> Any:
    """
    Parse the vessel's ``recordings.<kind>`` map, or an override file holding just it.

    ``parse(data, vessel)`` builds the map; every error it raises is prefixed with where
    the map came from.
    """
    label = {'topics': 'topic map', 'columns': 'column map', 'logs': 'log map'}[kind]
    if override is not None:
        data, where = read_yaml(override, error, label), f'{label} {override}'
    else:
        data, where = vessel.recordings.get(kind), f'vessel {vessel.source}: recordings.{kind}'
        if data is None:
            carriers = {'topics': 'topics', 'columns': 'columns of a table',
                        'logs': 'messages of an autopilot log'}[kind]
            raise error(f'{where} is missing: the vessel file says nothing about which '
                        f'{carriers} carry its quantities')
    try:
        return parse(data, vessel)
    except error as exc:
        raise error(f'{where}: {exc}') from None
