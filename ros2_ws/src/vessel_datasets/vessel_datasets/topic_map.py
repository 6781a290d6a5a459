"""
Topic map: which message field of which topic gives each quantity of a vessel.

A topic map is the ``recordings.topics`` section of a vessel file (rosbag2 topics), or
its ``recordings.logs`` section (the messages of an autopilot log: ArduPilot DataFlash
``GPS``, ``ATT``..., PX4 ULog ``vehicle_local_position``...); docs/bags.md documents the
keys. It names quantities in the frame the *messages* use, with a frame tag per group;
the converter turns them into the model's frames through ``vessel_physics.frames``.
Which entries a group needs follows the vessel: a roll rate and roll angle only where
roll is modelled, one entry per actuator it declares, a wind group only where it
declares a wind input. Body velocities may be left out when an ``earth_velocity`` group
gives them, or when the vessel's position track must give them (GPS-only logs); a yaw
rate left out is differentiated from the heading. A 6-DOF vehicle (``Vessel.is_spatial``)
takes the third component of each: heave, pitch rate and pitch, down and the height; its
body rates come from a gyro (all three are required) and its velocities are mapped (body
or earth frame), not taken from the track.

Every entry may carry ``delay_s`` (s, also settable for a whole group): its samples were
measured that long before their stamp, and the converter moves them back. An entry may
list alternatives (a YAML list of entries): the first whose topic a recording has is
used, and the recording's report says which (``resolve``). Loading checks the structure
only; whether topics and fields exist is checked against each recording.

Inside the converter a map is a flat list of :class:`Leaf` -- one scalar read from one
topic -- grouped into *channels* (named series) that are resampled and converted.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
import copy
from dataclasses import dataclass, field, replace
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
    'earth_velocity': ((), None, 'linear'),
    'attitude': (('enu_flu', 'ned_frd'), 'enu_flu', 'linear'),
    'position': (('enu', 'ned'), 'enu', 'linear'),
    'actuators': ((), None, 'hold'),
    'wind': (('flu', 'frd'), 'flu', 'hold'),
    'speed_over_ground': ((), None, 'linear'),
}
# Groups a vessel may lack: wind only where it declares a wind input; velocities can
# come from the track and the heading; speed over ground is only ever a cross-check.
OPTIONAL_GROUPS = ('wind', 'body_velocity', 'earth_velocity', 'speed_over_ground')

# Entries that name a composite field: the components read from it and the channels
# they fill. Scalars fill the channel ``channel_of`` names.
COMPOSITES: dict[str, tuple[tuple[str, str], ...]] = {
    'quaternion': (('x', 'qx'), ('y', 'qy'), ('z', 'qz'), ('w', 'qw')),
    'point': (('x', 'pos_x'), ('y', 'pos_y')),
    'latlon': (('latitude', 'lat'), ('longitude', 'lon')),
    'velocity': (('x', 'wind_x'), ('y', 'wind_y')),
}
# Scalar entries whose channel is not their own name.
SCALAR_CHANNELS = {('position', 'x'): 'pos_x', ('position', 'y'): 'pos_y',
                   ('position', 'z'): 'pos_z',
                   ('earth_velocity', 'north'): 'vel_north',
                   ('earth_velocity', 'east'): 'vel_east',
                   ('earth_velocity', 'down'): 'vel_down',
                   ('speed_over_ground', 'speed'): 'sog'}
# Components a composite entry gives a 6-DOF vehicle besides those of ``COMPOSITES``.
SPATIAL_COMPOSITES: dict[str, tuple[tuple[str, str], ...]] = {'point': (('z', 'pos_z'),)}
ACTUATOR_PREFIX = 'actuator.'
# Composite entries whose components must not be scaled (a unit quaternion, degrees).
UNSCALED = ('quaternion', 'latlon')
# Entries whose samples must come from one message (they are combined per message).
SAME_TOPIC = {'attitude': ('quaternion',), 'wind': ('speed', 'from_angle'),
              'position': ('point', 'latlon', 'x', 'y', 'z', 'lat', 'lon')}
ENTRY_KEYS = ('topic', 'field', 'scale', 'offset', 'type', 'delay_s')
GROUP_KEYS = ('frame', 'resample', 'delay_s')
# Section of a vessel file a map comes from -> whether its topics are ROS names.
KINDS = {'topics': True, 'logs': False, 'columns': False}


def channel_of(group: str, name: str) -> str:
    """Channel a scalar entry fills (actuators are prefixed: their names are the user's)."""
    if group == 'actuators':
        return ACTUATOR_PREFIX + name
    if group == 'wind':
        return f'wind_{name}'
    return SCALAR_CHANNELS.get((group, name), name)


# Entry sets of the groups that differ for a 6-DOF vehicle: three components each, and
# the body rates always.
_RATES = ('roll_rate', 'pitch_rate', 'yaw_rate')
SPATIAL_GROUPS: dict[str, tuple[tuple[str, ...], ...]] = {
    'body_velocity': (('surge', 'sway', 'heave') + _RATES, _RATES),
    'earth_velocity': (('north', 'east', 'down'),),
    'attitude': (('quaternion',), ('heading', 'roll', 'pitch')),
    'position': (('point',), ('x', 'y', 'z')),
}


def _alternatives(group: str, vessel: Vessel) -> tuple[tuple[str, ...], ...]:
    """Entry sets that give ``group`` for this vessel (roll only where it is modelled)."""
    if vessel.is_spatial and group in SPATIAL_GROUPS:
        return SPATIAL_GROUPS[group]
    roll = ('roll_rate',) if vessel.has_roll else ()
    if group == 'body_velocity':  # surge and sway together, or neither; rates optional
        return tuple(v + rr + yr for v in (('surge', 'sway'), ()) for rr in (roll, ())
                     for yr in (('yaw_rate',), ()) if v + rr + yr)
    if group == 'earth_velocity':
        return (('north', 'east'),)
    if group == 'attitude':
        return (('quaternion',), ('heading', 'roll') if vessel.has_roll else ('heading',))
    if group == 'position':
        return (('point',), ('latlon',), ('x', 'y'), ('lat', 'lon'))
    if group == 'actuators':
        return (vessel.actuator_names,)
    if group == 'speed_over_ground':
        return (('speed',),)
    return (('velocity',), ('speed', 'from_angle'))


class TopicMapError(ValueError):
    """A topic map is malformed (its structure, not its match with a recording)."""


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
    delay_s: float = 0.0

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
    delay_s: float = 0.0


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
    # label -> every alternative, the entry in ``entries`` first
    alternatives: Mapping[str, tuple[Entry, ...]] = field(default_factory=dict)
    section: str = 'topics'

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

    @property
    def candidate_topics(self) -> set[str]:
        """Topics of every entry and of every alternative."""
        return {e.topic for e in self.entries} | {
            o.topic for options in self.alternatives.values() for o in options}

    def leaves(self) -> list[Leaf]:
        """Every scalar to read, composite entries expanded into their components."""
        out = []
        spatial = self.vessel.is_spatial
        for e in self.entries:
            if e.name in COMPOSITES and e.group != 'actuators':
                components = COMPOSITES[e.name] + (SPATIAL_COMPOSITES.get(e.name, ())
                                                   if spatial else ())
                for component, channel in components:
                    path = f'{e.field}.{component}' if e.field else component
                    out.append(Leaf(channel, e.group, e.topic, path, e.scale, e.offset,
                                    e.label, e.delay_s))
            else:
                out.append(Leaf(channel_of(e.group, e.name), e.group, e.topic, e.field,
                                e.scale, e.offset, e.label, e.delay_s))
        return out

    def resolve(self, available: Collection[str]) -> tuple[TopicMap, dict[str, str]]:
        """
        Choose among the alternatives what a recording with ``available`` topics has.

        Alternatives form layouts: layout k takes the k-th source of every entry that
        lists several (its last, where it lists fewer), and the first layout whose
        topics are all available is used -- so sources that belong together (a
        simulator's topics and their own delays) are taken together. Where no layout is
        complete, each entry takes its first available source (or its first: the
        recording then lacks it, and the converter says so). Returns the map with those
        entries and, per entry with alternatives, the source chosen.
        """
        if not self.alternatives:
            return self, {}
        depth = max(len(options) for options in self.alternatives.values())
        layouts = [[self.alternatives.get(e.label, (e,))[min(k, len(
            self.alternatives.get(e.label, (e,)))) - 1] for e in self.entries]
            for k in range(1, depth + 1)]
        entries = next((layout for layout in layouts
                        if all(e.topic in available for e in layout)), None)
        if entries is None:
            entries = [next((o for o in self.alternatives.get(e.label, (e,))
                             if o.topic in available), e) for e in self.entries]
        chosen = {e.label: f'{e.topic} {e.field}'.strip() + (
            f' (delay {e.delay_s:g} s)' if e.delay_s else '')
            for e in entries if e.label in self.alternatives}
        return replace(self, entries=tuple(entries)), chosen

    def to_dict(self) -> dict[str, Any]:
        """Return the map as loaded (for the dataset manifest)."""
        return copy.deepcopy(dict(self.source))


def topic_map_for(vessel: Vessel, override: str | os.PathLike | None = None,
                  section: str = 'topics') -> TopicMap:
    """
    Return a topic map of a vessel: its file's ``recordings.<section>``, or an override.

    ``section`` is ``topics`` (rosbag2 topics) or ``logs`` (autopilot log messages). An
    override is a YAML file holding just the map, for a vessel recorded with other
    topics than its description names.
    """
    return recording_map(vessel, section, override,
                         lambda data, v: parse_topic_map(data, v, section), TopicMapError)


def parse_topic_map(data: Any, vessel: Vessel, section: str = 'topics') -> TopicMap:
    """Check a topic map given as a mapping (the parsed YAML) against a vessel; build it."""
    if not isinstance(data, Mapping):
        raise TopicMapError('expected a mapping of groups')
    if data.get('format', FORMAT) != FORMAT:
        raise TopicMapError(f'format {data.get("format")!r}, expected {FORMAT!r}')
    known = set(GROUPS) | {'format', 'stamps', 'max_gap_s'}
    if unknown := sorted(set(data) - known):
        raise TopicMapError(f'unknown keys {unknown}; expected {sorted(known)}')
    entries: list[Entry] = []
    alternatives: dict[str, tuple[Entry, ...]] = {}
    frames: dict[str, str] = {}
    resample: dict[str, str] = {}
    for group, (allowed, default_frame, default_resample) in GROUPS.items():
        spec = data.get(group)
        needed = group not in OPTIONAL_GROUPS or (group == 'wind'
                                                  and group in vessel.environment)
        if group == 'wind' and spec is not None and not needed:
            raise TopicMapError(f'maps a {group!r} group, but vessel {vessel.name!r} declares '
                                f"no {group} input (add it to the vessel's environment, "
                                f'or remove the group)')
        if spec is None and not needed:
            continue
        if not isinstance(spec, Mapping):
            raise TopicMapError(f'missing group {group!r} (a mapping of entries)')
        group_entries, frame, method = _parse_group(
            group, spec, allowed, default_frame, default_resample,
            _alternatives(group, vessel), vessel, KINDS[section])
        for options in group_entries:
            entries.append(options[0])
            alternatives[options[0].label] = options
        if frame is not None:
            frames[group] = frame
        resample[group] = method
    if 'body_velocity' not in frames:
        frames['body_velocity'] = 'frd'  # velocities from the earth frame or the track
    if 'earth_velocity' in resample and any(e.name == 'surge' for e in entries):
        raise TopicMapError('maps both body_velocity surge/sway and earth_velocity; give '
                            'one of them')
    if vessel.is_spatial and 'body_velocity' not in resample:
        raise TopicMapError(f'vehicle {vessel.name!r} is a 6-DOF vehicle: map its body rates '
                            f'(body_velocity roll_rate, pitch_rate, yaw_rate: a gyro)')
    if vessel.is_spatial and 'earth_velocity' not in resample and not any(
            e.name == 'surge' for e in entries):
        raise TopicMapError(f'vehicle {vessel.name!r} is a 6-DOF vehicle: map its velocities '
                            f'(body_velocity surge, sway, heave or earth_velocity north, '
                            f'east, down)')
    stamps = _parse_overrides(data.get('stamps', {}), 'stamps', _time_source)
    gaps = _parse_overrides(data.get('max_gap_s', {}), 'max_gap_s', _positive)
    return TopicMap(vessel=vessel, entries=tuple(entries), frames=frames, resample=resample,
                    stamps=stamps, max_gap_s=gaps, source=plain(data),
                    alternatives={k: v for k, v in alternatives.items() if len(v) > 1},
                    section=section)


def _parse_group(group, spec, allowed, default_frame, default_resample, alternatives,
                 vessel, ros_names):
    frame = spec.get('frame', default_frame)
    if allowed and frame not in allowed:
        raise TopicMapError(f'{group}.frame is {frame!r}; use one of {list(allowed)}')
    if not allowed and 'frame' in spec:
        raise TopicMapError(f'{group} takes no frame')
    method = spec.get('resample', default_resample)
    if method not in RESAMPLE_METHODS:
        raise TopicMapError(f'{group}.resample is {method!r}; use one of '
                            f'{list(RESAMPLE_METHODS)}')
    group_delay = _delay(group, spec.get('delay_s', 0.0))
    names = [k for k in spec if k not in GROUP_KEYS]
    if not vessel.has_roll and (extra := [n for n in names if n in ('roll', 'roll_rate')]):
        raise TopicMapError(f'{group} maps {extra}, but vessel {vessel.name!r} models no roll '
                            f'(states {list(vessel.states)}); remove it')
    chosen = next((alt for alt in alternatives if set(alt) == set(names)), None)
    if chosen is None:
        options = ' or '.join('+'.join(alt) for alt in alternatives)
        raise TopicMapError(f'{group} has entries {names}; expected {options}')
    entries = [_parse_entries(group, name, spec[name], group_delay, ros_names)
               for name in chosen]
    topics = {e.topic for options in entries for e in options[:1]
              if e.name in SAME_TOPIC.get(group, ())}
    if len(topics) > 1:
        raise TopicMapError(f'{group}: {"+".join(chosen)} must come from one topic, '
                            f'got {sorted(topics)}')
    return entries, frame if allowed else None, method


def _parse_entries(group: str, name: str, spec: Any, group_delay: float,
                   ros_names: bool) -> tuple[Entry, ...]:
    """Parse an entry, or a list of alternatives for it (the first present wins)."""
    if isinstance(spec, list):
        if not spec:
            raise TopicMapError(f'{group}.{name}: an empty list of alternatives')
        return tuple(_parse_entry(group, name, s, group_delay, ros_names) for s in spec)
    return (_parse_entry(group, name, spec, group_delay, ros_names),)


def _parse_entry(group: str, name: str, spec: Any, group_delay: float,
                 ros_names: bool) -> Entry:
    label = f'{group}.{name}'
    if not isinstance(spec, Mapping):
        raise TopicMapError(f'{label} must be a mapping with topic and field (or a list '
                            f'of them, alternatives)')
    if unknown := sorted(set(spec) - set(ENTRY_KEYS)):
        raise TopicMapError(f'{label}: unknown keys {unknown}; use {list(ENTRY_KEYS)}')
    topic = spec.get('topic')
    if not isinstance(topic, str) or not topic or (ros_names and not topic.startswith('/')):
        what = 'an absolute topic name' if ros_names else 'a message name'
        raise TopicMapError(f'{label}.topic must be {what}, got {topic!r}')
    composite = group != 'actuators' and name in COMPOSITES
    path = spec.get('field')
    if path is None or not isinstance(path, str) or (not path and not composite):
        raise TopicMapError(f'{label}.field must be a field path, got {path!r}')
    scale, offset = spec.get('scale', 1.0), spec.get('offset', 0.0)
    for key, value in (('scale', scale), ('offset', offset)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or \
                not math.isfinite(value):
            raise TopicMapError(f'{label}.{key} must be a finite number, got {value!r}')
    if composite and name in UNSCALED and (scale != 1.0 or offset != 0.0):
        raise TopicMapError(f'{label} cannot be scaled or offset')
    msgtype = spec.get('type')
    if msgtype is not None and not isinstance(msgtype, str):
        raise TopicMapError(f'{label}.type must be a type name like pkg/msg/Type')
    delay = _delay(label, spec['delay_s']) if 'delay_s' in spec else group_delay
    return Entry(group, name, topic, path, float(scale), float(offset), msgtype, delay)


def _delay(label: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or \
            not math.isfinite(value):
        raise TopicMapError(f'{label}.delay_s must be a number of seconds, got {value!r}')
    return float(value)


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
