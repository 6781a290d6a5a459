"""
Tabular logs (CSV, whitespace-separated .dat) -> a vessel's dataset runs.

A column map -- the ``recordings.columns`` section of a vessel file, or a YAML file of
its own -- says how to read the files and which column gives each quantity, in which
unit, frame and sign::

    format: delimited          # the reader: delimited text (the only one so far)
    sep: whitespace            # whitespace | any one character (',', ';', a tab)
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
    actuators:
      n: {column: rev, unit: rps}
      delta: {column: delta, unit: deg, sign: -1}
    wind: {frame: frd, speed: {column: ws, unit: knots}, from_angle: {column: wd, unit: deg}}

A quantity is a column name (read in the model unit) or ``{column, unit, sign}``; a
group (velocity, position, wind) takes a ``frame``, a shared ``unit`` and one entry
per component. Body quantities are FRD (sway, yaw rate, roll positive to starboard),
headings from north towards east (``north_clockwise``) or ENU yaw from east towards
north (``east_counterclockwise``); earth-frame velocities (north, east) are rotated
into the body by the heading. ``UNITS`` lists the units per kind.

The converter turns each file's columns into the topic map's channels (``surge``,
``psi``, ``pos_x``, ``actuator.<name>`` ...) in model units, drops NaN samples and
spikes (``map_checks``) per channel and counts them, splits runs at time gaps and
restarts, resamples onto the vessel's rate (states linearly, actuators held) with
``resample`` and forms the dataset columns with ``quantities.to_columns``, so tables
and bags meet the same conventions through the same code.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
import math
import os
from pathlib import Path
import re
from typing import Any

import numpy as np
import pandas as pd

from vessel_description import Vessel
from vessel_description.vessel import plain, recording_map
from vessel_physics import frames

from . import format as fmt
from . import map_checks
from .bag_source import sha256
from .convert import versions
from .quantities import polar_to_vector, to_columns
from .resample import period_ns, plan_runs, sample
from .topic_map import ACTUATOR_PREFIX, GROUPS, TopicMap

TOOL = 'offline/table_to_dataset.py'
FORMAT = 'delimited'
KEYS = ('format', 'sep', 'skip_lines', 'header_row', 'names', 'encoding', 'time', 'rate_hz',
        'run', 'velocity', 'yaw_rate', 'roll_rate', 'roll', 'heading', 'position',
        'actuators', 'wind')
ENTRY_KEYS = ('column', 'unit', 'sign')
SUFFIXES = ('.csv', '.dat', '.txt', '.tsv', '.log')
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
ACTUATOR_KIND_UNITS = {'propeller': 'rate', 'rudder': 'angle', 'azimuth': 'angle'}
HEADING_CONVENTIONS = ('north_clockwise', 'east_counterclockwise')
# group -> frame -> (component, kind of unit, channel) in order.
GROUP_FRAMES: dict[str, dict[str, tuple[tuple[str, str, str], ...]]] = {
    'velocity': {'body': (('surge', 'speed', 'surge'), ('sway', 'speed', 'sway')),
                 'earth': (('north', 'speed', 'north'), ('east', 'speed', 'east'))},
    'position': {'ned': (('x', 'length', 'pos_x'), ('y', 'length', 'pos_y')),
                 'enu': (('x', 'length', 'pos_x'), ('y', 'length', 'pos_y')),
                 'latlon': (('lat', 'degrees', 'lat'), ('lon', 'degrees', 'lon'))},
    'wind': {'frd': (('speed', 'speed', 'wind_speed'), ('from_angle', 'angle', 'wind_from')),
             'flu': (('speed', 'speed', 'wind_speed'), ('from_angle', 'angle', 'wind_from'))},
}
# Channel of a state -> its dataset column (the table's channels are FRD, SI already).
STATE_OF = {'surge': 'u', 'sway': 'v', 'roll_rate': 'p', 'yaw_rate': 'r', 'phi': 'phi'}


class ColumnMapError(ValueError):
    """A column map is malformed; the message is one line naming the key."""


class TableError(ValueError):
    """A file cannot be read with its column map (one line says why)."""


@dataclass(frozen=True)
class Source:
    """One column read as a quantity: ``model value = sign * factor * column``."""

    label: str
    column: str
    unit: str
    factor: float = 1.0
    sign: float = 1.0

    def read(self, table: pd.DataFrame) -> np.ndarray:
        """Return the column in the model unit (non-numbers become NaN)."""
        return self.sign * self.factor * _numeric(table[self.column])


@dataclass(frozen=True)
class ColumnMap:
    """A parsed column map, bound to the vessel whose vectors it fills."""

    vessel: Vessel
    sep: str
    skip_lines: int
    header_row: bool
    names: tuple[str, ...] | None
    encoding: str
    time: Source | None
    rate_hz: float | None
    run: str | None
    sources: Mapping[str, Source]
    frames: Mapping[str, str]
    heading_convention: str
    source: Mapping[str, Any] = field(default_factory=dict)

    @property
    def columns(self) -> list[str]:
        """File columns the map reads, in map order."""
        cols = [self.time.column] if self.time else []
        cols += [self.run] if self.run else []
        return list(dict.fromkeys(cols + [s.column for s in self.sources.values()]))

    @property
    def derived(self) -> tuple[str, ...]:
        """State columns differentiated from an angle because no column gives them."""
        out = () if 'yaw_rate' in self.sources else ('r',)
        if self.vessel.has_roll and 'roll_rate' not in self.sources:
            out += ('p',)
        return out

    def topic_map(self) -> TopicMap:
        """Return the topic map ``to_columns`` needs: the table's channels are FRD/NED."""
        position = 'enu' if self.frames['position'] == 'enu' else 'ned'
        frame_of = {'body_velocity': 'frd', 'attitude': 'ned_frd', 'position': position}
        if 'wind' in self.frames:
            frame_of['wind'] = self.frames['wind']
        resample = {g: GROUPS[g][2] for g in GROUPS if g != 'wind' or 'wind' in self.frames}
        return TopicMap(vessel=self.vessel, entries=(), frames=frame_of, resample=resample,
                        source=self.to_dict())

    def methods(self) -> dict[str, str]:
        """Resampling method per channel: states and pose linear, controls held."""
        out = {c: GROUPS['body_velocity'][2] for c in ('surge', 'sway', 'roll_rate',
                                                        'yaw_rate', 'psi', 'phi')}
        out.update({c: GROUPS['position'][2] for c in ('pos_x', 'pos_y', 'lat', 'lon')})
        out.update({ACTUATOR_PREFIX + a: GROUPS['actuators'][2]
                    for a in self.vessel.actuator_names})
        out.update({c: GROUPS['wind'][2] for c in ('wind_x', 'wind_y')})
        return out

    def to_dict(self) -> dict[str, Any]:
        """Return the map as given (for the dataset manifest)."""
        return plain(self.source)


# ----------------------------------------------------------------- parsing
def column_map_for(vessel: Vessel, override: str | os.PathLike | None = None) -> ColumnMap:
    """Return the column map of a vessel: its ``recordings.columns``, or an override file."""
    return recording_map(vessel, 'columns', override, parse_column_map, ColumnMapError)


def parse_column_map(data: Any, vessel: Vessel) -> ColumnMap:
    """Check a column map given as a mapping (the parsed YAML) against a vessel; build it."""
    if not isinstance(data, Mapping):
        raise ColumnMapError('expected a mapping of keys')
    if unknown := sorted(set(data) - set(KEYS)):
        raise ColumnMapError(f'unknown keys {unknown}; expected some of {list(KEYS)}')
    if data.get('format', FORMAT) != FORMAT:
        raise ColumnMapError(f'format {data.get("format")!r}: the only reader is {FORMAT!r}')
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
    time = _entry('time', data['time'], 'time') if 'time' in data else None
    rate = data.get('rate_hz')
    if rate is not None and (isinstance(rate, bool) or not isinstance(rate, (int, float))
                             or not rate > 0):
        raise ColumnMapError(f'rate_hz must be a positive number, got {rate!r}')
    run = data.get('run')
    if run is not None and not isinstance(run, str):
        raise ColumnMapError(f'run must name a column, got {run!r}')

    sources: dict[str, Source] = {}
    group_frames: dict[str, str] = {}
    for key in ('velocity', 'heading', 'position', 'actuators'):
        if data.get(key) is None:
            raise ColumnMapError(f'missing {key!r}')
    for group in ('velocity', 'position'):
        group_frames[group] = _group(group, data[group], sources)
    if 'wind' in vessel.environment:
        if data.get('wind') is None:
            raise ColumnMapError(f"missing 'wind': vessel {vessel.name!r} has a wind input")
        group_frames['wind'] = _group('wind', data['wind'], sources)
    elif data.get('wind') is not None:
        raise ColumnMapError(f"maps 'wind', but vessel {vessel.name!r} declares no wind input")

    heading = data['heading']
    convention = 'north_clockwise'
    if isinstance(heading, Mapping):
        convention = heading.get('convention', convention)
        if convention not in HEADING_CONVENTIONS:
            raise ColumnMapError(f'heading.convention is {convention!r}; use one of '
                                 f'{list(HEADING_CONVENTIONS)}')
        heading = {k: v for k, v in heading.items() if k != 'convention'}
    sources['heading'] = _entry('heading', heading, 'angle')
    if data.get('yaw_rate') is not None:
        sources['yaw_rate'] = _entry('yaw_rate', data['yaw_rate'], 'rate')
    for key, kind in (('roll', 'angle'), ('roll_rate', 'rate')):
        if data.get(key) is None:
            continue
        if not vessel.has_roll:
            raise ColumnMapError(f'maps {key!r}, but vessel {vessel.name!r} models no roll '
                                 f'(states {list(vessel.states)}); remove it')
        sources[key] = _entry(key, data[key], kind)
    if vessel.has_roll and 'roll' not in sources:
        raise ColumnMapError(f"missing 'roll': vessel {vessel.name!r} models roll")
    _actuators(data['actuators'], vessel, sources)
    return ColumnMap(vessel=vessel, sep=sep, skip_lines=skip, header_row=header_row,
                     names=tuple(names) if names else None, encoding=encoding, time=time,
                     rate_hz=float(rate) if rate is not None else None, run=run,
                     sources=sources, frames=group_frames, heading_convention=convention,
                     source=plain(data))


def _entry(label: str, spec: Any, kind: str | None, unit: str | None = None,
           fixed_unit: str | None = None) -> Source:
    """Parse a column name or ``{column, unit, sign}`` read as a quantity of ``kind``."""
    where = f'columns.{label}'
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
    unit = spec.get('unit', unit)
    if kind is None:  # thrusters and other inputs: recorded in their declared unit
        if unit is not None and unit != fixed_unit:
            raise ColumnMapError(f'{label}.unit is {unit!r}; this input is read as '
                                 f'recorded, in its declared unit {fixed_unit!r}')
        return Source(where, column, fixed_unit or '', 1.0, float(sign))
    units = UNITS[kind]
    unit = next(iter(units)) if unit is None else unit
    if unit not in units:
        raise ColumnMapError(f'{label}.unit {unit!r} is not a known {kind} unit; use one '
                             f'of {", ".join(units)}')
    return Source(where, column, unit, units[unit], float(sign))


def _group(group: str, spec: Any, sources: dict[str, Source]) -> str:
    options = GROUP_FRAMES[group]
    if not isinstance(spec, Mapping):
        raise ColumnMapError(f'{group} must be a mapping with a frame and its components')
    frame = spec.get('frame')
    if frame not in options:
        raise ColumnMapError(f'{group}.frame is {frame!r}; use one of {list(options)}')
    components = options[frame]
    allowed = {'frame', 'unit'} | {c for c, _, _ in components}
    if unknown := sorted(set(spec) - allowed):
        raise ColumnMapError(f'{group} (frame {frame}): unknown keys {unknown}; use '
                             f'{sorted(allowed)}')
    for name, kind, channel in components:
        if name not in spec:
            raise ColumnMapError(f'{group} (frame {frame}) lacks {name!r}')
        sources[channel] = _entry(f'{group}.{name}', spec[name], kind, spec.get('unit'))
    return frame


def _actuators(spec: Any, vessel: Vessel, sources: dict[str, Source]) -> None:
    names = vessel.actuator_names
    if not isinstance(spec, Mapping) or set(spec) != set(names):
        have = sorted(spec) if isinstance(spec, Mapping) else spec
        raise ColumnMapError(f'actuators maps {have}; vessel {vessel.name!r} has {list(names)}')
    for name in names:
        a = vessel.actuator(name)
        kind = ACTUATOR_KIND_UNITS.get(a.kind)
        sources[ACTUATOR_PREFIX + name] = _entry(f'actuators.{name}', spec[name], kind,
                                                 fixed_unit=a.unit)


# ----------------------------------------------------------------- reading
def find_tables(paths: Iterable[str | os.PathLike], pattern: str | None = None
                ) -> list[Path]:
    """Files given, and the files in folders given (``pattern`` or the usual suffixes)."""
    out: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in (p.glob(pattern) if pattern else p.iterdir())
                           if f.is_file() and not f.name.startswith('.')
                           and (pattern or f.suffix.lower() in SUFFIXES))
            if not found:
                raise TableError(f'{p}: no table files in this folder (looked for '
                                 f'{pattern or ", ".join(SUFFIXES)})')
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise TableError(f'{p}: no such file or folder')
    return out


def read_table(path: str | os.PathLike, cmap: ColumnMap) -> pd.DataFrame:
    """Read one file as the column map says; raise TableError (one line) when it cannot."""
    path = Path(path)
    sep = r'\s+' if cmap.sep == 'whitespace' else cmap.sep
    try:
        table = pd.read_csv(path, sep=sep, skiprows=cmap.skip_lines,
                            header=0 if cmap.header_row else None, encoding=cmap.encoding,
                            index_col=False, skip_blank_lines=True)
    except UnicodeDecodeError as exc:
        raise TableError(f'{path}: not {cmap.encoding} text ({exc.reason} at byte '
                         f'{exc.start}); set columns.encoding') from None
    except (pd.errors.ParserError, pd.errors.EmptyDataError, OSError) as exc:
        raise TableError(f'{path}: cannot read as a {cmap.sep!r}-separated table after '
                         f'{cmap.skip_lines} skipped lines ({str(exc).splitlines()[0]})') \
            from None
    if cmap.names:
        if table.shape[1] != len(cmap.names):
            raise TableError(f'{path}: the table has {table.shape[1]} columns, but '
                             f'columns.names lists {len(cmap.names)}')
        table.columns = list(cmap.names)
    elif cmap.header_row:
        table.columns = [str(c).strip() for c in table.columns]
    else:
        table.columns = [f'col{i + 1}' for i in range(table.shape[1])]
    missing = [c for c in cmap.columns if c not in table.columns]
    if missing:
        label = next(s.label for s in _all_sources(cmap) if s.column == missing[0]) \
            if missing[0] != cmap.run else 'columns.run'
        raise TableError(f'{path}: {label} names column {missing[0]!r}, which the file '
                         f'lacks; it has {", ".join(map(str, table.columns))}')
    return table


def _all_sources(cmap: ColumnMap) -> list[Source]:
    return ([cmap.time] if cmap.time else []) + list(cmap.sources.values())


def _numeric(series: pd.Series) -> np.ndarray:
    if pd.api.types.is_numeric_dtype(series):
        return series.to_numpy(dtype=float)
    return pd.to_numeric(series, errors='coerce').to_numpy(dtype=float)


# ----------------------------------------------------------------- conversion
@dataclass
class TableResult:
    """What one file gave: run tables, their sources, spike counts, and a report."""

    name: str
    runs: dict[str, pd.DataFrame] = field(default_factory=dict)
    run_sources: dict[str, dict] = field(default_factory=dict)
    spikes: dict[str, dict] = field(default_factory=dict)
    report: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


@dataclass(frozen=True)
class TableOptions:
    """Conversion settings (s); the defaults are the bag converter's."""

    max_gap_s: float = 2.5
    min_run_s: float = 10.0


def table_to_runs(path: str | os.PathLike, cmap: ColumnMap,
                  opts: TableOptions | None = None) -> dict[str, pd.DataFrame]:
    """Run tables of one file (for tests and notebooks); raises TableError on failure."""
    result = convert_table(path, cmap, opts or TableOptions())
    if result.error:
        raise TableError(result.error)
    return result.runs


def convert_table(path: str | os.PathLike, cmap: ColumnMap, opts: TableOptions
                  ) -> TableResult:
    """Convert one file. Never raises for bad input: ``error`` says what failed."""
    path = Path(path)
    result = TableResult(path.stem)
    report = result.report
    report.update(name=path.stem, path=str(path), files=[{
        'path': str(path), 'bytes': path.stat().st_size, 'sha256': sha256(path)}],
        rows=0, nan={}, nan_rows=0, duplicate_times=0, time_restarts=0, gaps=[],
        short_runs=[], spikes={}, runs=[])
    try:
        table = read_table(path, cmap)
        report['rows'] = len(table)
        data = {c: _numeric(table[c]) for c in cmap.columns if c != cmap.run}
        report['nan'] = {c: int((~np.isfinite(v)).sum()) for c, v in data.items()
                         if (~np.isfinite(v)).any()}
        report['nan_rows'] = int((~np.all([np.isfinite(v) for v in data.values()],
                                          axis=0)).sum()) if data else 0
        if cmap.run:
            keys = table[cmap.run].astype(str).str.strip()
            groups = [(k, np.nonzero((keys == k).to_numpy())[0]) for k in dict.fromkeys(keys)]
        else:
            groups = [(None, np.arange(len(table)))]
        spans = []
        for key, rows in groups:
            base = path.stem if key is None else f'{path.stem}-{_safe(key)}'
            spans += _convert_rows(table.iloc[rows], cmap, opts, base, report)
        if not spans:
            raise TableError(f'no stretch of at least {opts.min_run_s} s with every mapped '
                             f'quantity present and no time gap over {opts.max_gap_s} s '
                             f'({report["rows"]} rows)')
    except (TableError, ColumnMapError) as exc:
        msg = str(exc)
        result.error = msg if msg.startswith(str(path)) else f'{path}: {msg}'
        return result
    counts: dict[str, int] = {}
    for base, *_ in spans:
        counts[base] = counts.get(base, 0) + 1
    seen: dict[str, int] = {}
    for base, key, run_table, source, spikes in spans:
        k = seen[base] = seen.get(base, -1) + 1
        run_id = base if counts[base] == 1 else f'{base}-{k:03d}'
        result.runs[run_id] = run_table
        result.run_sources[run_id] = {'file': str(path), 'run': key, 'source_run': base,
                                      **source}
        result.spikes[run_id] = spikes
        report['runs'].append({'id': run_id, 'samples': len(run_table), **source})
    return result


def _safe(key: Any) -> str:
    return re.sub(r'[^A-Za-z0-9_.-]', '_', str(key)) or 'run'


def _convert_rows(rows: pd.DataFrame, cmap: ColumnMap, opts: TableOptions, base: str,
                  report: dict) -> list[tuple]:
    """Convert one run's rows: time, channels, spikes, run spans, resampling."""
    if cmap.time is not None:
        t = cmap.time.read(rows)
    else:
        t = np.arange(len(rows)) / cmap.rate_hz
    keep, segment = _time_order(t, opts.max_gap_s, report)
    out = []
    for seg in np.unique(segment[keep]):
        idx = np.nonzero(keep & (segment == seg))[0]
        if len(idx) < 2:
            continue
        out += _convert_segment(rows.iloc[idx], t[idx], cmap, opts, base, report)
    return out


def _time_order(t: np.ndarray, max_gap_s: float, report: dict) -> tuple[np.ndarray, np.ndarray]:
    """
    Rows to keep and their segment number.

    NaN times and times not after the newest are dropped (duplicates, jitter); a time
    more than ``max_gap_s`` before the newest starts a new segment (a restarted clock).
    """
    keep = np.zeros(len(t), bool)
    segment = np.zeros(len(t), int)
    newest, seg = -math.inf, 0
    for i, ti in enumerate(t):
        if not math.isfinite(ti):
            continue
        if ti < newest - max_gap_s:
            seg += 1
            report['time_restarts'] += 1
        elif ti <= newest:
            report['duplicate_times'] += 1
            continue
        newest = ti
        keep[i], segment[i] = True, seg
    return keep, segment


def _channels(rows: pd.DataFrame, t: np.ndarray, cmap: ColumnMap) -> dict[str, np.ndarray]:
    """Return the topic map's channels at the file's rows (model units, FRD/NED)."""
    src = cmap.sources
    vessel = cmap.vessel
    ch: dict[str, np.ndarray] = {}
    heading = src['heading'].read(rows)
    if cmap.heading_convention == 'east_counterclockwise':
        heading = frames.heading_enu_to_ned(heading)
    ch['psi'] = _unwrap(heading)
    if vessel.has_roll:
        ch['phi'] = src['roll'].read(rows)
    phi = ch.get('phi', np.zeros(len(t)))
    if cmap.frames['velocity'] == 'body':
        ch['surge'], ch['sway'] = src['surge'].read(rows), src['sway'].read(rows)
    else:
        ch['surge'], ch['sway'] = earth_to_body(src['north'].read(rows), src['east'].read(rows),
                                                ch['psi'], phi)
    ch['yaw_rate'] = src['yaw_rate'].read(rows) if 'yaw_rate' in src else _rate(ch['psi'], t)
    if vessel.has_roll:
        ch['roll_rate'] = (src['roll_rate'].read(rows) if 'roll_rate' in src
                           else _rate(ch['phi'], t))
    for c in ('pos_x', 'pos_y', 'lat', 'lon'):
        if c in src:
            ch[c] = src[c].read(rows)
    for name in vessel.actuator_names:
        ch[ACTUATOR_PREFIX + name] = src[ACTUATOR_PREFIX + name].read(rows)
    if 'wind' in cmap.frames:
        ch['wind_x'], ch['wind_y'] = polar_to_vector(src['wind_speed'].read(rows),
                                                     src['wind_from'].read(rows))
    return ch


def earth_to_body(north, east, psi, phi=0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return FRD (u, v) (m/s) whose NED velocity is (north, east) at heading psi, roll phi.

    The inverse of ``vessel_physics.integrator.kinematics``: the horizontal velocity is
    R(psi) (u, v cos phi).
    """
    north, east, psi = (np.asarray(a, float) for a in (north, east, psi))
    c, s = np.cos(psi), np.sin(psi)
    return north * c + east * s, (-north * s + east * c) / np.cos(phi)


def _unwrap(angle: np.ndarray) -> np.ndarray:
    """Unwrap an angle across its finite samples only (a NaN would spoil the rest)."""
    out = np.array(angle, float)
    ok = np.isfinite(out)
    if ok.any():
        out[ok] = np.unwrap(out[ok])
    return out


def _rate(angle: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Return d(angle)/dt over its finite samples (NaN elsewhere)."""
    out = np.full(len(angle), np.nan)
    ok = np.isfinite(angle)
    if ok.sum() >= 2:
        out[ok] = np.gradient(angle[ok], t[ok])
    return out


def _convert_segment(rows: pd.DataFrame, t: np.ndarray, cmap: ColumnMap,
                     opts: TableOptions, base: str, report: dict) -> list[tuple]:
    vessel = cmap.vessel
    t_ns = np.round(t * 1e9).astype(np.int64)
    ch = _channels(rows, t, cmap)
    found: dict[str, tuple[map_checks.Spikes, np.ndarray]] = {}
    for channel, values in ch.items():
        column = STATE_OF.get(channel) or (channel[len(ACTUATOR_PREFIX):] if
                                           channel.startswith(ACTUATOR_PREFIX) else None)
        if column is None or column not in vessel.states + vessel.actuator_names:
            continue
        spikes = map_checks.find_spikes(column, values, vessel)
        found[column] = (spikes, np.isfinite(values))
        total = report['spikes'].setdefault(column, {'out_of_range': 0, 'jumps': 0,
                                                     'dropped': 0})
        total['out_of_range'] += int(spikes.out_of_range.sum())
        total['jumps'] += int(spikes.jumps.sum())
        total['dropped'] += int(spikes.mask.sum())
        values[spikes.mask] = np.nan
    valid = {c: np.isfinite(v) for c, v in ch.items()}
    empty = [c for c, ok in valid.items() if not ok.any()]
    if empty:
        raise TableError(f'no finite values for {", ".join(empty)}')
    dt = period_ns(vessel.rate_hz)
    gap = int(round(opts.max_gap_s * 1e9))
    min_samples = int(np.floor(opts.min_run_s * vessel.rate_hz + 1e-9)) + 1
    spans, short, gaps = plan_runs({c: t_ns[ok] for c, ok in valid.items()},
                                   {c: gap for c in ch}, dt, min_samples)
    # A time gap shows in every channel: report it once, as 'all'.
    by_span: dict[tuple[int, int], list[str]] = {}
    for g in gaps:
        by_span.setdefault((g.start_ns, g.end_ns), []).append(g.topic)
    report['gaps'] += [{'channels': 'all' if len(names) == len(ch) else names,
                        'start_s': start / 1e9, 'end_s': end / 1e9,
                        'duration_s': (end - start) / 1e9}
                       for (start, end), names in by_span.items()]
    report['short_runs'] += [{'start_s': r.start_ns / 1e9, 'end_s': r.end_ns / 1e9,
                              'samples': int(len(r.grid_ns))} for r in short]
    methods = cmap.methods()
    topic_map = cmap.topic_map()
    out = []
    key = rows[cmap.run].iloc[0] if cmap.run else None
    for span in spans:
        grid = span.grid_ns
        channels = {c: sample(t_ns[valid[c]], v[valid[c]][:, None], grid, [methods[c]])[:, 0]
                    for c, v in ch.items()}
        columns = to_columns(channels, topic_map)
        run_table = pd.DataFrame({'t': (grid - grid[0]) / 1e9, **columns})
        inside = (t_ns >= grid[0]) & (t_ns <= grid[-1])
        spikes = {column: {'samples': int((finite & inside).sum()),
                           'out_of_range': int((sp.out_of_range & inside).sum()),
                           'jumps': int((sp.jumps & inside).sum()),
                           'dropped': bool(sp.droppable),
                           'bounds': list(sp.bounds) if sp.bounds else None}
                  for column, (sp, finite) in found.items()}
        source = {'start_s': float(grid[0] / 1e9), 'end_s': float(grid[-1] / 1e9),
                  'rows': int(inside.sum())}
        out.append((base, None if key is None else str(key), run_table, source, spikes))
    return out


def convert_tables(paths: Sequence[Path], cmap: ColumnMap, opts: TableOptions,
                   on_result: Callable[[TableResult], None] | None = None
                   ) -> list[TableResult]:
    """Convert files one after the other; ``on_result`` gets each finished file."""
    results = []
    for path in paths:
        results.append(convert_table(path, cmap, opts))
        if on_result:
            on_result(results[-1])
    ids = [r for res in results for r in res.runs]
    if dup := sorted({r for r in ids if ids.count(r) > 1}):
        raise TableError(f'run ids {dup} come from more than one file (files with the same '
                         f'name in different folders); rename one')
    return results


# ----------------------------------------------------------------- checks and writing
def check_results(results: Sequence[TableResult], cmap: ColumnMap, refuse_spikes: bool
                  ) -> dict[str, list[map_checks.Check]]:
    """Run the map checks on every run of the results (spikes were dropped already)."""
    return {run_id: map_checks.check_run(table, cmap.vessel, map_checks.COLUMN_LABELS,
                                         r.spikes[run_id], cmap.derived, refuse_spikes)
            for r in results for run_id, table in r.runs.items()}


def assign_split(results: Sequence[TableResult], test: Sequence[str], val: Sequence[str],
                 seed: int, fractions: Sequence[float]) -> dict[str, list[str]] | None:
    """
    Return an explicit split for whole-run hold-outs, or None for the seeded split.

    ``test`` and ``val`` name runs by id or by source run (a file stem, or stem-run);
    the runs not named share the fractions of the splits given no runs.
    """
    if not test and not val:
        return None
    sources = {run_id: r.run_sources[run_id]['source_run'] for r in results
               for run_id in r.runs}
    fixed: dict[str, list[str]] = {}
    for name, wanted in (('test', test), ('val', val)):
        ids = []
        for w in wanted:
            hit = [r for r, base in sources.items() if w in (r, base)]
            if not hit:
                raise ValueError(f'--{"holdout" if name == "test" else "val"} {w}: no such '
                                 f'run; runs are {", ".join(sorted(sources))}')
            ids += hit
        fixed[name] = ids
    if twice := sorted(set(fixed['test']) & set(fixed['val'])):
        raise ValueError(f'runs {twice} are both held out for test and for validation')
    rest = sorted(set(sources) - set(fixed['test']) - set(fixed['val']))
    share = [f if not fixed.get(s) else 0.0 for s, f in zip(fmt.SPLITS, fractions,
                                                             strict=True)]
    share = [f / sum(share) for f in share] if sum(share) > 0 else [1.0, 0.0, 0.0]
    split = fmt.split_runs(rest, seed, share)
    return {s: sorted(split[s] + fixed.get(s, [])) for s in fmt.SPLITS}


def write(out: str | os.PathLike, results: Sequence[TableResult], cmap: ColumnMap,
          opts: TableOptions, *, seed: int, fractions: Sequence[float],
          split: Mapping[str, Sequence[str]] | None = None, checks: Mapping | None = None,
          argv: Sequence[str] | None = None) -> Path:
    """Write the runs of every result as a dataset with its manifest; return its path."""
    runs: dict[str, pd.DataFrame] = {}
    sources: dict[str, dict] = {}
    for r in results:
        runs.update(r.runs)
        sources.update(r.run_sources)
    provenance = {
        'tool': TOOL,
        'argv': list(argv) if argv is not None else None,
        'config': {**asdict(opts), 'vessel': cmap.vessel.source,
                   'column_map': cmap.to_dict(), 'seed': seed,
                   'fractions': list(fractions)},
        'seed': seed,
        'versions': versions(),
        'sources': [f for r in results for f in r.report.get('files', [])],
    }
    conversion = {
        'rate_hz': cmap.vessel.rate_hz,
        'max_gap_s': opts.max_gap_s,
        'min_run_s': opts.min_run_s,
        'derived': list(cmap.derived),
        'files': [{**r.report, 'error': r.error} for r in results],
    }
    extra = {'conversion': conversion}
    if checks is not None:
        extra['checks'] = checks
    return fmt.write_dataset(out, runs, vessel=cmap.vessel, provenance=provenance,
                             seed=seed, fractions=fractions, split=split,
                             run_sources=sources, extra=extra)
