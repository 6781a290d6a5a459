"""
Column map: how to read a text table and which column gives each quantity.

A column map -- the ``recordings.columns`` section of a vessel file, or a YAML file of
its own -- says how to read the files and which column gives each quantity, in which
unit, frame and sign::

    format: delimited          # the reader: delimited text (or parquet: no sep, skip_lines,
    sep: whitespace            #   names, encoding) | whitespace | any one character (',', ';')
    skip_lines: 4              # lines before the table (titles, comments)
    header_row: false          # true: the first line after them names the columns
    names: [time, x0, y0, psi, ve, vn, r_deg, phi_deg, delta, rev]  # else col1, col2, ...
    encoding: cp1252           # default utf-8
    time: {column: time, unit: s}   # s | ms; or instead rate_hz: 20 (rows equally spaced)
    run: null                  # a column naming runs within a file; else one run per file
    velocity: {frame: earth, north: ve, east: vn, unit: m/s}  # or frame: body, surge, sway
    yaw_rate: {column: r_deg, unit: deg/s}   # optional: else d(heading)/dt
    roll: {column: phi_deg, unit: deg}       # vessels with roll only; roll_rate optional
    heading: {column: psi, unit: deg, convention: north_clockwise}
    position: {frame: ned, x: x0, y: y0, unit: m}  # ned | enu (x, y) | latlon (lat, lon)
    speed_over_ground: {column: sog, unit: knots}  # optional: a cross-check, never surge
    actuators:
      n: {column: rev, unit: rps}
      delta: {column: delta, unit: deg, sign: -1}
    wind: {frame: frd, speed: {column: ws, unit: knots}, from_angle: {column: wd, unit: deg}}

A 6-DOF vehicle (a multirotor) maps the third component of each group (velocity ``down``
or ``heave``, position ``z``), ``pitch`` and all three body rates (``roll_rate``,
``pitch_rate``, ``yaw_rate``: a gyro); its roll and pitch are in the frame of its heading
convention (``east_counterclockwise``: ENU/FLU angles, pitch positive nose down).

A quantity is a column name (read in the model unit) or ``{column, unit, sign, scale,
delay_s}`` (``scale`` a factor after the unit, e.g. 1/6 for a motor's electrical rpm with
six pole pairs given as ``unit: rpm``); a group (velocity, position, wind) takes a
``frame``, a shared ``unit``, a shared ``delay_s`` and one entry per component. Body
quantities are FRD (sway, yaw rate, roll positive to starboard), headings from north
towards east
(``north_clockwise``) or ENU yaw from east towards north (``east_counterclockwise``);
earth-frame velocities (north, east) are turned into the body by the heading. Without
``velocity`` the body velocities come from the position track and the heading.
``UNITS`` lists the units per kind.

Parsing gives a :class:`ColumnMap`: the reading format, and the quantities as a
``topic_map.TopicMap`` of the ``columns`` section (every column an entry of one source,
the table), so tables take the one pipeline of every recording from there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace
import math
import os
from typing import Any

from vessel_description import Vessel
from vessel_description.vessel import plain, recording_map

from .topic_map import TopicMap, TopicMapError, parse_topic_map

FORMAT = 'delimited'
FORMATS = (FORMAT, 'parquet')   # the readers: delimited text, Apache Parquet columns
TEXT_KEYS = ('sep', 'skip_lines', 'header_row', 'names', 'encoding')  # delimited text only
TABLE = 'table'   # the one source every column of a file belongs to
KEYS = ('format', 'sep', 'skip_lines', 'header_row', 'names', 'encoding', 'time', 'rate_hz',
        'run', 'velocity', 'yaw_rate', 'roll_rate', 'pitch_rate', 'roll', 'pitch', 'heading',
        'position', 'speed_over_ground', 'actuators', 'wind')
ENTRY_KEYS = ('column', 'unit', 'sign', 'scale', 'delay_s')
KNOT = 1852.0 / 3600.0
# kind -> unit -> factor to the model unit (the first of each kind).
UNITS: dict[str, dict[str, float]] = {
    'speed': {'m/s': 1.0, 'knots': KNOT, 'kn': KNOT, 'km/h': 1 / 3.6},
    'angle': {'rad': 1.0, 'deg': math.pi / 180},
    'rate': {'rad/s': 1.0, 'deg/s': math.pi / 180, 'rpm': 2 * math.pi / 60,
             'rps': 2 * math.pi},
    'length': {'m': 1.0, 'km': 1000.0},
    'time': {'s': 1.0, 'ms': 1e-3},
    'degrees': {'deg': 1.0},  # latitude and longitude stay in degrees
}
ACTUATOR_KIND_UNITS = {'propeller': 'rate', 'rotor': 'rate', 'rudder': 'angle',
                       'azimuth': 'angle'}
HEADING_FRAMES = {'north_clockwise': 'ned_frd', 'east_counterclockwise': 'enu_flu'}
# column-map group -> frame -> (topic-map group, frame, ((component, kind, entry), ...)).
GROUP_FRAMES: dict[str, dict[str, tuple[str, str | None, tuple[tuple[str, str, str], ...]]]] = {
    'velocity': {'body': ('body_velocity', 'frd', (('surge', 'speed', 'surge'),
                                                   ('sway', 'speed', 'sway'))),
                 'earth': ('earth_velocity', None, (('north', 'speed', 'north'),
                                                    ('east', 'speed', 'east')))},
    'position': {'ned': ('position', 'ned', (('x', 'length', 'x'), ('y', 'length', 'y'))),
                 'enu': ('position', 'enu', (('x', 'length', 'x'), ('y', 'length', 'y'))),
                 'latlon': ('position', None, (('lat', 'degrees', 'lat'),
                                               ('lon', 'degrees', 'lon')))},
    'wind': {f: ('wind', f, (('speed', 'speed', 'speed'), ('from_angle', 'angle', 'from_angle')))
             for f in ('frd', 'flu')},
}
# The third component a 6-DOF vehicle's group takes in each frame.
SPATIAL_COMPONENTS = {('velocity', 'body'): ('heave', 'speed', 'heave'),
                      ('velocity', 'earth'): ('down', 'speed', 'down'),
                      ('position', 'ned'): ('z', 'length', 'z'),
                      ('position', 'enu'): ('z', 'length', 'z')}
# Angles and rates beyond the heading: key -> (kind, topic-map group, who maps it).
ATTITUDE_KEYS = {'yaw_rate': ('rate', 'body_velocity', 'any'),
                 'roll_rate': ('rate', 'body_velocity', 'roll'),
                 'roll': ('angle', 'attitude', 'roll'),
                 'pitch_rate': ('rate', 'body_velocity', 'spatial'),
                 'pitch': ('angle', 'attitude', 'spatial')}


# Topic-map entry -> the column-map key it came from, where the two differ.
COLUMN_LABELS = {'body_velocity.yaw_rate': 'yaw_rate', 'body_velocity.roll_rate': 'roll_rate',
                 'body_velocity.pitch_rate': 'pitch_rate', 'attitude.heading': 'heading',
                 'attitude.roll': 'roll', 'attitude.pitch': 'pitch',
                 'speed_over_ground.speed': 'speed_over_ground'}


class ColumnMapError(ValueError):
    """A column map is malformed; the message is one line naming the key."""


@dataclass(frozen=True)
class Column:
    """A column read as a number: ``value = factor * column`` (seconds for the time)."""

    column: str
    factor: float = 1.0


@dataclass(frozen=True)
class TableFormat:
    """How to read the files of a column map."""

    format: str
    sep: str
    skip_lines: int
    header_row: bool
    names: tuple[str, ...] | None
    encoding: str
    time: Column | None
    rate_hz: float | None
    run: str | None


@dataclass(frozen=True)
class ColumnMap:
    """A parsed column map: how to read the files, and the quantities they give."""

    table: TableFormat
    topic_map: TopicMap

    @property
    def columns(self) -> list[str]:
        """File columns the map reads, in map order."""
        cols = [self.table.time.column] if self.table.time else []
        cols += [self.table.run] if self.table.run else []
        return list(dict.fromkeys(cols + [leaf.path for leaf in self.topic_map.leaves()]))

    def label_of(self, column: str) -> str:
        """Name the map entry that reads ``column`` (for one-line errors)."""
        if self.table.time and column == self.table.time.column:
            return 'columns.time'
        if column == self.table.run:
            return 'columns.run'
        label = next(leaf.label for leaf in self.topic_map.leaves() if leaf.path == column)
        return 'columns.' + COLUMN_LABELS.get(label, label.replace(
            'body_velocity.', 'velocity.').replace('earth_velocity.', 'velocity.'))


def column_map_for(vessel: Vessel, override: str | os.PathLike | None = None) -> ColumnMap:
    """Return the column map of a vessel: its ``recordings.columns``, or an override file."""
    return recording_map(vessel, 'columns', override, parse_column_map, ColumnMapError)


def parse_column_map(data: Any, vessel: Vessel) -> ColumnMap:
    """Check a column map given as a mapping (the parsed YAML) against a vessel; build it."""
    if not isinstance(data, Mapping):
        raise ColumnMapError('expected a mapping of keys')
    if unknown := sorted(set(data) - set(KEYS)):
        raise ColumnMapError(f'unknown keys {unknown}; expected some of {list(KEYS)}')
    table = _table_format(data)
    topics: dict[str, Any] = {}
    for key in ('heading', 'position', 'actuators'):
        if data.get(key) is None:
            raise ColumnMapError(f'missing {key!r}')
    for group in ('velocity', 'position'):
        if data.get(group) is not None:
            _group(group, data[group], topics, vessel)
    if 'wind' in vessel.environment:
        if data.get('wind') is None:
            raise ColumnMapError(f"missing 'wind': vessel {vessel.name!r} has a wind input")
        _group('wind', data['wind'], topics, vessel)
    elif data.get('wind') is not None:
        raise ColumnMapError(f"maps 'wind', but vessel {vessel.name!r} declares no wind input")
    heading = data['heading']
    convention = 'north_clockwise'
    if isinstance(heading, Mapping):
        convention = heading.get('convention', convention)
        if convention not in HEADING_FRAMES:
            raise ColumnMapError(f'heading.convention is {convention!r}; use one of '
                                 f'{list(HEADING_FRAMES)}')
        heading = {k: v for k, v in heading.items() if k != 'convention'}
    topics['attitude'] = {'frame': HEADING_FRAMES[convention],
                          'heading': _entry('heading', heading, 'angle')}
    modelled = {'any': True, 'roll': vessel.has_roll, 'spatial': vessel.is_spatial}
    for key, (kind, group, needs) in ATTITUDE_KEYS.items():
        if data.get(key) is None:
            if vessel.is_spatial or (key == 'roll' and vessel.has_roll):
                raise ColumnMapError(f'missing {key!r}: vehicle {vessel.name!r} models it '
                                     f'(states {list(vessel.states)})')
            continue
        if not modelled[needs]:
            raise ColumnMapError(f'maps {key!r}, but vessel {vessel.name!r} models no '
                                 f'{"roll" if needs == "roll" else "pitch"} (states '
                                 f'{list(vessel.states)}); remove it')
        if group == 'attitude':  # angles are in the heading convention's frame
            topics['attitude'][key] = _entry(key, data[key], kind)
        else:
            topics.setdefault(group, {'frame': 'frd'})[key] = _entry(key, data[key], kind)
    if data.get('speed_over_ground') is not None:
        topics['speed_over_ground'] = {
            'speed': _entry('speed_over_ground', data['speed_over_ground'], 'speed')}
    topics['actuators'] = _actuators(data['actuators'], vessel)
    try:
        topic_map = parse_topic_map(topics, vessel, section='columns')
    except TopicMapError as exc:
        raise ColumnMapError(str(exc)) from None
    return ColumnMap(table, replace(topic_map, source=plain(data)))


def _table_format(data: Mapping[str, Any]) -> TableFormat:
    fmt = data.get('format', FORMAT)
    if fmt not in FORMATS:
        raise ColumnMapError(f'format {fmt!r}: the readers are {", ".join(FORMATS)}')
    if fmt != FORMAT and (text := [k for k in TEXT_KEYS if k in data]):
        raise ColumnMapError(f'format {fmt}: {text} apply to delimited text only (a {fmt} '
                             f'file names and types its own columns)')
    sep = data.get('sep', ',')
    if not isinstance(sep, str) or not (sep == 'whitespace' or len(sep) == 1):
        raise ColumnMapError(f"sep is {sep!r}; use 'whitespace' or one character like ','")
    skip = data.get('skip_lines', 0)
    if isinstance(skip, bool) or not isinstance(skip, int) or skip < 0:
        raise ColumnMapError(f'skip_lines must be a whole number >= 0, got {skip!r}')
    header_row = data.get('header_row', False)
    if not isinstance(header_row, bool):
        raise ColumnMapError(f'header_row must be true or false, got {header_row!r}')
    names = data.get('names')
    if names is not None and not (isinstance(names, list) and names and all(
            isinstance(n, str) for n in names) and len(set(names)) == len(names)):
        raise ColumnMapError('names must list distinct column names')
    encoding = data.get('encoding', 'utf-8')
    try:
        ''.encode(encoding)
    except (LookupError, TypeError):
        raise ColumnMapError(f'encoding {encoding!r} is not known to Python') from None
    if ('time' in data) == ('rate_hz' in data):
        raise ColumnMapError('give either time (a time column) or rate_hz (rows equally '
                             'spaced), not both or neither')
    time = None
    if 'time' in data:
        entry = _entry('time', data['time'], 'time')
        time = Column(entry['field'], entry['scale'])
    rate = data.get('rate_hz')
    if rate is not None and (isinstance(rate, bool) or not isinstance(rate, (int, float))
                             or not rate > 0):
        raise ColumnMapError(f'rate_hz must be a positive number, got {rate!r}')
    run = data.get('run')
    if run is not None and not isinstance(run, str):
        raise ColumnMapError(f'run must name a column, got {run!r}')
    return TableFormat(fmt, sep, skip, header_row, tuple(names) if names else None, encoding,
                       time, float(rate) if rate is not None else None, run)


def _entry(label: str, spec: Any, kind: str | None, unit: str | None = None,
           fixed_unit: str | None = None, delay: Any = None) -> dict[str, Any]:
    """Parse a column name or ``{column, unit, sign, delay_s}``: a topic-map entry."""
    if isinstance(spec, str):
        spec = {'column': spec}
    if not isinstance(spec, Mapping):
        raise ColumnMapError(f'{label} must be a column name or a mapping with '
                             f'{list(ENTRY_KEYS)}')
    if unknown := sorted(set(spec) - set(ENTRY_KEYS)):
        raise ColumnMapError(f'{label}: unknown keys {unknown}; use {list(ENTRY_KEYS)}')
    column = spec.get('column')
    if not isinstance(column, str) or not column:
        raise ColumnMapError(f'{label}.column must name a column, got {column!r}')
    sign = spec.get('sign', 1)
    if sign not in (1, -1) or isinstance(sign, bool):
        raise ColumnMapError(f'{label}.sign must be 1 or -1, got {sign!r}')
    factor = spec.get('scale', 1.0)
    if isinstance(factor, bool) or not isinstance(factor, (int, float)) or not (
            math.isfinite(factor) and factor > 0):
        raise ColumnMapError(f'{label}.scale must be a positive number (the sign is sign), '
                             f'got {factor!r}')
    sign = sign * float(factor)
    unit = spec.get('unit', unit)
    entry = {'topic': TABLE, 'field': column}
    delay = spec.get('delay_s', delay)
    if delay is not None:
        entry['delay_s'] = delay
    if kind is None:  # thrusters and other inputs: recorded in their declared unit
        if unit is not None and unit != fixed_unit:
            raise ColumnMapError(f'{label}.unit is {unit!r}; this input is read as '
                                 f'recorded, in its declared unit {fixed_unit!r}')
        return {**entry, 'scale': float(sign)}
    units = UNITS[kind]
    unit = next(iter(units)) if unit is None else unit
    if unit not in units:
        raise ColumnMapError(f'{label}.unit {unit!r} is not a known {kind} unit; use one '
                             f'of {", ".join(units)}')
    return {**entry, 'scale': sign * units[unit]}


def _group(group: str, spec: Any, topics: dict[str, Any], vessel: Vessel) -> None:
    options = GROUP_FRAMES[group]
    if not isinstance(spec, Mapping):
        raise ColumnMapError(f'{group} must be a mapping with a frame and its components')
    frame = spec.get('frame')
    if frame not in options:
        raise ColumnMapError(f'{group}.frame is {frame!r}; use one of {list(options)}')
    target, target_frame, components = options[frame]
    if vessel.is_spatial:
        if (group, frame) not in SPATIAL_COMPONENTS:
            raise ColumnMapError(f'{group}.frame {frame} gives no third component; a 6-DOF '
                                 f'vehicle takes one of '
                                 f'{[f for g, f in SPATIAL_COMPONENTS if g == group]}')
        components = components + (SPATIAL_COMPONENTS[group, frame],)
    allowed = {'frame', 'unit', 'delay_s'} | {c for c, _, _ in components}
    if unknown := sorted(set(spec) - allowed):
        raise ColumnMapError(f'{group} (frame {frame}): unknown keys {unknown}; use '
                             f'{sorted(allowed)}')
    out = topics.setdefault(target, {})
    if target_frame:
        out['frame'] = target_frame
    for name, kind, entry in components:
        if name not in spec:
            raise ColumnMapError(f'{group} (frame {frame}) lacks {name!r}')
        out[entry] = _entry(f'{group}.{name}', spec[name], kind, spec.get('unit'),
                            delay=spec.get('delay_s'))


def _actuators(spec: Any, vessel: Vessel) -> dict[str, Any]:
    names = vessel.actuator_names
    if not isinstance(spec, Mapping) or set(spec) != set(names):
        have = sorted(spec) if isinstance(spec, Mapping) else spec
        raise ColumnMapError(f'actuators maps {have}; vessel {vessel.name!r} has {list(names)}')
    out = {}
    for name in names:
        a = vessel.actuator(name)
        out[name] = _entry(f'actuators.{name}', spec[name], ACTUATOR_KIND_UNITS.get(a.kind),
                           fixed_unit=a.unit)
    return out
