"""
Topic map: which message field of which topic gives each quantity of the dataset.

A topic map is a YAML file (``config/topic_map.yaml`` is the simulator's; docs/bags.md
documents the keys). It names quantities in the frame the *messages* use, with a frame
tag per group; the converter turns them into the model's frames through
``vessel_physics.frames``. Loading checks the structure only; whether the topics and
fields exist is checked against each bag (``fields.py``).

Inside the converter a map is a flat list of :class:`Leaf` -- one scalar read from one
topic -- grouped into *channels* (named series) that are resampled and converted.
"""

from __future__ import annotations

from collections.abc import Mapping
import copy
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
from typing import Any

import yaml

FORMAT = 'vessel-topic-map/1'
RESAMPLE_METHODS = ('linear', 'hold')
TIME_SOURCES = ('header', 'log')

# Group -> (allowed frames, default frame, default resampling, alternatives). Each
# alternative is a tuple of entry names that together give the group.
GROUPS: dict[str, tuple[tuple[str, ...], str | None, str, tuple[tuple[str, ...], ...]]] = {
    'body_velocity': (('flu', 'frd'), 'flu', 'linear',
                      (('surge', 'sway', 'roll_rate', 'yaw_rate'),)),
    'attitude': (('enu_flu', 'ned_frd'), 'enu_flu', 'linear',
                 (('quaternion',), ('roll', 'heading'))),
    'position': (('enu', 'ned'), 'enu', 'linear', (('point',), ('latlon',))),
    'actuators': ((), None, 'hold', (('shaft_speed', 'rudder_port', 'rudder_stbd'),)),
    'wind': (('flu', 'frd'), 'flu', 'hold', (('velocity',), ('speed', 'from_angle'))),
}

# Entries that name a composite field: the components read from it and the channels
# they fill. Scalars fill a channel of their own name ('wind_' + name for wind).
COMPOSITES: dict[str, tuple[tuple[str, str], ...]] = {
    'quaternion': (('x', 'qx'), ('y', 'qy'), ('z', 'qz'), ('w', 'qw')),
    'point': (('x', 'pos_x'), ('y', 'pos_y')),
    'latlon': (('latitude', 'lat'), ('longitude', 'lon')),
    'velocity': (('x', 'wind_x'), ('y', 'wind_y')),
}
# Composite entries whose components must not be scaled (a unit quaternion, degrees).
UNSCALED = ('quaternion', 'latlon')
# Entries whose samples must come from one message (they are combined per message).
SAME_TOPIC = {'attitude': ('quaternion',), 'wind': ('speed', 'from_angle'),
              'position': ('point', 'latlon')}
ENTRY_KEYS = ('topic', 'field', 'scale', 'offset', 'type')


class TopicMapError(ValueError):
    """A topic map is malformed (its structure, not its match with a bag)."""


@dataclass(frozen=True)
class Entry:
    """One topic-map entry: a (possibly composite) field of one topic."""

    group: str
    name: str
    topic: str
    field: str
    scale: float = 1.0
    offset: float = 0.0
    msgtype: str | None = None

    @property
    def label(self) -> str:
        """``group.name``, as written in the YAML file."""
        return f'{self.group}.{self.name}'


@dataclass(frozen=True)
class Leaf:
    """One scalar read from a message: ``value = scale * message.<path> + offset``."""

    channel: str
    group: str
    topic: str
    path: str
    scale: float
    offset: float
    label: str


@dataclass(frozen=True)
class TopicMap:
    """A parsed topic map."""

    entries: tuple[Entry, ...]
    frames: Mapping[str, str]
    resample: Mapping[str, str]
    stamps: Mapping[str, str] = field(default_factory=dict)
    max_gap_s: Mapping[str, float] = field(default_factory=dict)
    source: Mapping[str, Any] = field(default_factory=dict)

    def has(self, name: str) -> bool:
        """Whether an entry of this name (e.g. 'quaternion', 'latlon') is mapped."""
        return any(e.name == name for e in self.entries)

    @property
    def topics(self) -> list[str]:
        """Topics the map reads, in first-use order."""
        return list(dict.fromkeys(e.topic for e in self.entries))

    def leaves(self) -> list[Leaf]:
        """Every scalar to read, composite entries expanded into their components."""
        out = []
        for e in self.entries:
            if e.name in COMPOSITES:
                for component, channel in COMPOSITES[e.name]:
                    path = f'{e.field}.{component}' if e.field else component
                    out.append(Leaf(channel, e.group, e.topic, path, e.scale, e.offset,
                                    e.label))
            else:
                channel = f'wind_{e.name}' if e.group == 'wind' else e.name
                out.append(Leaf(channel, e.group, e.topic, e.field, e.scale, e.offset,
                                e.label))
        return out

    def to_dict(self) -> dict[str, Any]:
        """Return the map as loaded (for the dataset manifest)."""
        return copy.deepcopy(dict(self.source))


def default_path() -> Path:
    """Path of the simulator's topic map shipped with the package."""
    return config_dir() / 'topic_map.yaml'


def config_dir() -> Path:
    """Directory of the package's YAML defaults (source tree or colcon install)."""
    source = Path(__file__).resolve().parent.parent / 'config'
    if source.is_dir():
        return source
    try:  # installed by colcon: the config lives in the package's share directory
        from ament_index_python.packages import get_package_share_directory
        return Path(get_package_share_directory('vessel_datasets')) / 'config'
    except (ImportError, LookupError):
        return source


def load_topic_map(path: str | os.PathLike | None = None) -> TopicMap:
    """Load and check a topic-map YAML file (the simulator's when ``path`` is None)."""
    path = Path(path) if path is not None else default_path()
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as exc:
        raise TopicMapError(f'topic map {path}: cannot read ({exc.strerror})') from None
    except yaml.YAMLError as exc:
        raise TopicMapError(f'topic map {path}: not valid YAML ({exc})') from None
    try:
        return parse_topic_map(data)
    except TopicMapError as exc:
        raise TopicMapError(f'topic map {path}: {exc}') from None


def parse_topic_map(data: Any) -> TopicMap:
    """Check a topic map given as a mapping (the parsed YAML) and build it."""
    if not isinstance(data, Mapping):
        raise TopicMapError('expected a mapping at the top level')
    if data.get('format', FORMAT) != FORMAT:
        raise TopicMapError(f'format {data.get("format")!r}, expected {FORMAT!r}')
    known = set(GROUPS) | {'format', 'stamps', 'max_gap_s'}
    if unknown := sorted(set(data) - known):
        raise TopicMapError(f'unknown keys {unknown}; expected {sorted(known)}')
    entries: list[Entry] = []
    frames: dict[str, str] = {}
    resample: dict[str, str] = {}
    for group, (allowed, default_frame, default_resample, alternatives) in GROUPS.items():
        spec = data.get(group)
        if not isinstance(spec, Mapping):
            raise TopicMapError(f'missing group {group!r} (a mapping of entries)')
        group_entries, frame, method = _parse_group(group, spec, allowed, default_frame,
                                                    default_resample, alternatives)
        entries += group_entries
        if frame is not None:
            frames[group] = frame
        resample[group] = method
    stamps = _parse_overrides(data.get('stamps', {}), 'stamps', _time_source)
    gaps = _parse_overrides(data.get('max_gap_s', {}), 'max_gap_s', _positive)
    return TopicMap(entries=tuple(entries), frames=frames, resample=resample,
                    stamps=stamps, max_gap_s=gaps, source=_plain(data))


def _parse_group(group, spec, allowed, default_frame, default_resample, alternatives):
    frame = spec.get('frame', default_frame)
    if allowed and frame not in allowed:
        raise TopicMapError(f'{group}.frame is {frame!r}; use one of {list(allowed)}')
    if not allowed and 'frame' in spec:
        raise TopicMapError(f'{group} takes no frame')
    method = spec.get('resample', default_resample)
    if method not in RESAMPLE_METHODS:
        raise TopicMapError(f'{group}.resample is {method!r}; use one of '
                            f'{list(RESAMPLE_METHODS)}')
    names = [k for k in spec if k not in ('frame', 'resample')]
    chosen = next((alt for alt in alternatives if set(alt) == set(names)), None)
    if chosen is None:
        options = ' or '.join('+'.join(alt) for alt in alternatives)
        raise TopicMapError(f'{group} has entries {names}; expected {options}')
    entries = [_parse_entry(group, name, spec[name]) for name in chosen]
    topics = {e.topic for e in entries if e.name in SAME_TOPIC.get(group, ())}
    if len(topics) > 1:
        raise TopicMapError(f'{group}: {"+".join(chosen)} must come from one topic, '
                            f'got {sorted(topics)}')
    return entries, frame if allowed else None, method


def _parse_entry(group: str, name: str, spec: Any) -> Entry:
    label = f'{group}.{name}'
    if not isinstance(spec, Mapping):
        raise TopicMapError(f'{label} must be a mapping with topic and field')
    if unknown := sorted(set(spec) - set(ENTRY_KEYS)):
        raise TopicMapError(f'{label}: unknown keys {unknown}; use {list(ENTRY_KEYS)}')
    topic = spec.get('topic')
    if not isinstance(topic, str) or not topic.startswith('/'):
        raise TopicMapError(f'{label}.topic must be an absolute topic name, got {topic!r}')
    path = spec.get('field')
    if path is None or not isinstance(path, str) or (not path and name not in COMPOSITES):
        raise TopicMapError(f'{label}.field must be a field path, got {path!r}')
    scale, offset = spec.get('scale', 1.0), spec.get('offset', 0.0)
    for key, value in (('scale', scale), ('offset', offset)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise TopicMapError(f'{label}.{key} must be a finite number, got {value!r}')
    if name in UNSCALED and (scale != 1.0 or offset != 0.0):
        raise TopicMapError(f'{label} cannot be scaled or offset')
    msgtype = spec.get('type')
    if msgtype is not None and not isinstance(msgtype, str):
        raise TopicMapError(f'{label}.type must be a type name like pkg/msg/Type')
    return Entry(group, name, topic, path, float(scale), float(offset), msgtype)


def _parse_overrides(value: Any, key: str, check) -> dict:
    if not isinstance(value, Mapping):
        raise TopicMapError(f'{key} must map topic names to values')
    return {str(topic): check(key, topic, v) for topic, v in value.items()}


def _time_source(key, topic, value):
    if value not in TIME_SOURCES:
        raise TopicMapError(f'{key}[{topic}] is {value!r}; use one of {list(TIME_SOURCES)}')
    return value


def _positive(key, topic, value):
    if not isinstance(value, (int, float)) or not value > 0:
        raise TopicMapError(f'{key}[{topic}] must be a positive number of seconds')
    return float(value)


def _plain(value: Any) -> Any:
    """Copy YAML data into plain dicts and lists (JSON-serializable)."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value
