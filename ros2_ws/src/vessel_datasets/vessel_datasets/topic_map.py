"""
Topic map: which message field of which topic gives each quantity of a vessel.

A topic map is the ``recordings.topics`` section of a vessel file (vessel_description;
docs/bags.md documents the keys). It names quantities in the frame the *messages* use,
with a frame tag per group; the converter turns them into the model's frames through
``vessel_physics.frames``. Which entries a group needs follows the vessel: a roll rate
and roll angle only where roll is modelled, one entry per actuator it declares, a wind
group only where it declares a wind input. Loading checks the structure only; whether
the topics and fields exist is checked against each bag (``fields.py``).

Inside the converter a map is a flat list of :class:`Leaf` -- one scalar read from one
topic -- grouped into *channels* (named series) that are resampled and converted.
"""

from __future__ import annotations

from collections.abc import Mapping
import copy
from dataclasses import dataclass, field
import math
import os
from typing import Any

from vessel_description import Vessel
from vessel_description.vessel import plain, recording_map

FORMAT = 'vessel-topic-map/1'
RESAMPLE_METHODS = ('linear', 'hold')
TIME_SOURCES = ('header', 'log')

# Group -> (allowed frames, default frame, default resampling). Which entries a group
# takes depends on the vessel (``_alternatives``).
GROUPS: dict[str, tuple[tuple[str, ...], str | None, str]] = {
    'body_velocity': (('flu', 'frd'), 'flu', 'linear'),
    'attitude': (('enu_flu', 'ned_frd'), 'enu_flu', 'linear'),
    'position': (('enu', 'ned'), 'enu', 'linear'),
    'actuators': ((), None, 'hold'),
    'wind': (('flu', 'frd'), 'flu', 'hold'),
}
# Groups a vessel may lack: wind only where it declares a wind input.
OPTIONAL_GROUPS = ('wind',)

# Entries that name a composite field: the components read from it and the channels
# they fill. Scalars fill the channel ``channel_of`` names.
COMPOSITES: dict[str, tuple[tuple[str, str], ...]] = {
    'quaternion': (('x', 'qx'), ('y', 'qy'), ('z', 'qz'), ('w', 'qw')),
    'point': (('x', 'pos_x'), ('y', 'pos_y')),
    'latlon': (('latitude', 'lat'), ('longitude', 'lon')),
    'velocity': (('x', 'wind_x'), ('y', 'wind_y')),
}
# Scalar position entries fill the same channels as a point's components.
POSITION_SCALARS = {'x': 'pos_x', 'y': 'pos_y'}
ACTUATOR_PREFIX = 'actuator.'
# Composite entries whose components must not be scaled (a unit quaternion, degrees).
UNSCALED = ('quaternion', 'latlon')
# Entries whose samples must come from one message (they are combined per message).
SAME_TOPIC = {'attitude': ('quaternion',), 'wind': ('speed', 'from_angle'),
              'position': ('point', 'latlon', 'x', 'y')}
ENTRY_KEYS = ('topic', 'field', 'scale', 'offset', 'type')


def channel_of(group: str, name: str) -> str:
    """Channel a scalar entry fills (actuators are prefixed: their names are the user's)."""
    if group == 'actuators':
        return ACTUATOR_PREFIX + name
    if group == 'wind':
        return f'wind_{name}'
    if group == 'position':
        return POSITION_SCALARS[name]
    return name


def _alternatives(group: str, vessel: Vessel) -> tuple[tuple[str, ...], ...]:
    """Entry sets that give ``group`` for this vessel (roll only where it is modelled)."""
    roll = vessel.has_roll
    if group == 'body_velocity':
        return (('surge', 'sway') + (('roll_rate',) if roll else ()) + ('yaw_rate',),)
    if group == 'attitude':
        return (('quaternion',), ('heading', 'roll') if roll else ('heading',))
    if group == 'position':
        return (('point',), ('latlon',), ('x', 'y'))
    if group == 'actuators':
        return (vessel.actuator_names,)
    return (('velocity',), ('speed', 'from_angle'))


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
    """A parsed topic map, bound to the vessel whose vectors it fills."""

    vessel: Vessel
    entries: tuple[Entry, ...]
    frames: Mapping[str, str]
    resample: Mapping[str, str]
    stamps: Mapping[str, str] = field(default_factory=dict)
    max_gap_s: Mapping[str, float] = field(default_factory=dict)
    source: Mapping[str, Any] = field(default_factory=dict)

    def has(self, name: str) -> bool:
        """Whether an entry of this name (e.g. 'quaternion', 'latlon') is mapped."""
        return any(e.name == name for e in self.entries)

    def has_group(self, group: str) -> bool:
        """Whether the map reads ``group`` (e.g. 'wind')."""
        return group in self.resample

    @property
    def topics(self) -> list[str]:
        """Topics the map reads, in first-use order."""
        return list(dict.fromkeys(e.topic for e in self.entries))

    def leaves(self) -> list[Leaf]:
        """Every scalar to read, composite entries expanded into their components."""
        out = []
        for e in self.entries:
            if e.name in COMPOSITES and e.group != 'actuators':
                for component, channel in COMPOSITES[e.name]:
                    path = f'{e.field}.{component}' if e.field else component
                    out.append(Leaf(channel, e.group, e.topic, path, e.scale, e.offset,
                                    e.label))
            else:
                out.append(Leaf(channel_of(e.group, e.name), e.group, e.topic, e.field,
                                e.scale, e.offset, e.label))
        return out

    def to_dict(self) -> dict[str, Any]:
        """Return the map as loaded (for the dataset manifest)."""
        return copy.deepcopy(dict(self.source))


def topic_map_for(vessel: Vessel, override: str | os.PathLike | None = None) -> TopicMap:
    """
    Return the topic map of a vessel: its file's ``recordings.topics``, or an override file.

    An override is a YAML file holding just the topic map, for a vessel recorded with
    other topics than its description names.
    """
    return recording_map(vessel, 'topics', override, parse_topic_map, TopicMapError)


def parse_topic_map(data: Any, vessel: Vessel) -> TopicMap:
    """Check a topic map given as a mapping (the parsed YAML) against a vessel; build it."""
    if not isinstance(data, Mapping):
        raise TopicMapError('expected a mapping of groups')
    if data.get('format', FORMAT) != FORMAT:
        raise TopicMapError(f'format {data.get("format")!r}, expected {FORMAT!r}')
    known = set(GROUPS) | {'format', 'stamps', 'max_gap_s'}
    if unknown := sorted(set(data) - known):
        raise TopicMapError(f'unknown keys {unknown}; expected {sorted(known)}')
    entries: list[Entry] = []
    frames: dict[str, str] = {}
    resample: dict[str, str] = {}
    for group, (allowed, default_frame, default_resample) in GROUPS.items():
        spec = data.get(group)
        needed = group not in OPTIONAL_GROUPS or group in vessel.environment
        if spec is None and not needed:
            continue
        if spec is not None and not needed:
            raise TopicMapError(f'maps a {group!r} group, but vessel {vessel.name!r} declares '
                                f"no {group} input (add it to the vessel's environment, "
                                f'or remove the group)')
        if not isinstance(spec, Mapping):
            raise TopicMapError(f'missing group {group!r} (a mapping of entries)')
        group_entries, frame, method = _parse_group(
            group, spec, allowed, default_frame, default_resample,
            _alternatives(group, vessel))
        entries += group_entries
        if frame is not None:
            frames[group] = frame
        resample[group] = method
    stamps = _parse_overrides(data.get('stamps', {}), 'stamps', _time_source)
    gaps = _parse_overrides(data.get('max_gap_s', {}), 'max_gap_s', _positive)
    return TopicMap(vessel=vessel, entries=tuple(entries), frames=frames, resample=resample,
                    stamps=stamps, max_gap_s=gaps, source=plain(data))


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
    composite = group != 'actuators' and name in COMPOSITES
    path = spec.get('field')
    if path is None or not isinstance(path, str) or (not path and not composite):
        raise TopicMapError(f'{label}.field must be a field path, got {path!r}')
    scale, offset = spec.get('scale', 1.0), spec.get('offset', 0.0)
    for key, value in (('scale', scale), ('offset', offset)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise TopicMapError(f'{label}.{key} must be a finite number, got {value!r}')
    if composite and name in UNSCALED and (scale != 1.0 or offset != 0.0):
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
