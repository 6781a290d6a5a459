"""
One recording pipeline: from a reader's timed channels to a checked, written dataset.

Every format goes the same way (``sources`` defines the reader interface)::

    reader.find -> reader.read -> delays -> derived rates, velocities from the track
      -> spikes -> runs -> resample -> model frames -> map checks -> split -> write

* **delays**: each channel's samples move back by its map entry's ``delay_s``;
* **derived**: a yaw (roll) rate the map does not give is differentiated from the
  heading (roll); body velocities it does not give come from the position track
  (``track``) and are turned into the body by the heading in ``quantities.to_columns``;
* **spikes** (``spikes``): dropped on the raw samples, in model units;
* **coarse channels** (``resolution``): noted in one line each, and the time scale
  the checks need recorded per run;
* **runs**: stretches every channel covers without a gap over its max gap, on the
  multiples of the vessel's sample period (``resample.plan_runs``), sampled linearly
  (states) or held (actuators);
* **checks** (``map_checks``): one gate for all formats; **write**: one manifest.

``convert`` does one recording and never raises for bad input (``Result.error`` says
why); ``convert_all`` does many, in worker processes with ``jobs``; ``to_runs`` returns
one recording's run tables for tests and notebooks.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field, replace
import multiprocessing as mp
import os
from pathlib import Path
import platform
import queue as queue_module
import re
from typing import Any, TextIO

import numpy as np
import pandas as pd

from vessel_description.resources import data_dir, read_yaml
from vessel_physics.integrator import ned_to_body_3d

from . import format as fmt
from . import map_checks, resolution, spikes, track
from .quantities import (
    channel_delays,
    channel_methods,
    earth_to_body,
    latlon_to_local,
    model_column,
    to_columns,
)
from .resample import period_ns, plan_runs, sample
from .sources import (
    ConversionError,
    Reader,
    Recording,
    RecordingError,
    format_ns,
    sha256,
    unique_names,
)
from .topic_map import TopicMap

PROGRESS_POLL_S = 0.2  # how often the parent forwards the workers' progress
EPOCH_NS = 10 ** 17    # times beyond this (1973) are wall-clock stamps, shown as dates
METRES_PER_DEG = 111_195.0  # only to compare latitude and longitude steps in metres


@dataclass(frozen=True)
class Options:
    """Conversion settings; defaults come from ``config/convert.yaml``."""

    time_source: str = 'header'
    max_gap_s: float = 2.5
    min_run_s: float = 10.0
    split: tuple[float, float, float] = fmt.DEFAULT_FRACTIONS
    seed: int = 0

    @classmethod
    def from_yaml(cls, path: str | os.PathLike | None = None, **overrides) -> Options:
        """Defaults from a YAML file (the package's when None), then ``overrides``."""
        path = Path(path) if path else config_dir() / 'convert.yaml'
        data = read_yaml(path, ValueError, 'conversion defaults') or {}
        unknown = set(data) - {f for f in cls.__dataclass_fields__}
        if unknown:
            raise ValueError(f'{path}: unknown keys {sorted(unknown)}')
        if 'split' in data:
            data['split'] = tuple(float(x) for x in data['split'])
        opts = cls(**data)
        return replace(opts, **{k: v for k, v in overrides.items() if v is not None})

    def check(self, rate_hz: float) -> None:
        """Raise ValueError on an impossible setting for a vessel sampled at ``rate_hz``."""
        if self.time_source not in ('header', 'log'):
            raise ValueError(f'time source must be header or log, got {self.time_source!r}')
        if not (self.max_gap_s > 0 and self.min_run_s >= 0):
            raise ValueError('the max gap must be positive and the min run not negative')
        if self.max_gap_s * rate_hz < 1.0:
            raise ValueError(f'max gap {self.max_gap_s} s is shorter than the sample '
                             f'period {1 / rate_hz} s of the vessel')


def config_dir() -> Path:
    """Directory of the package's YAML defaults (source tree or colcon install)."""
    return data_dir('vessel_datasets', __file__, 'config')


@dataclass
class Result:
    """What one recording gave: run tables, their sources, what the checks need, a report."""

    name: str
    runs: dict[str, pd.DataFrame] = field(default_factory=dict)
    run_sources: dict[str, dict] = field(default_factory=dict)
    context: dict[str, dict] = field(default_factory=dict)  # run -> spikes, scales, extras
    report: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


@dataclass
class _Series:
    """One channel's samples: times (ns), values, and the topic or column they came from."""

    t_ns: np.ndarray
    values: np.ndarray
    source: str


# ----------------------------------------------------------------- one recording
def to_runs(path: str | os.PathLike, reader: Reader, topic_map: TopicMap,
            **options) -> dict[str, pd.DataFrame]:
    """Run tables of the recordings at ``path`` (tests, notebooks); raises on failure."""
    opts = Options.from_yaml(**options)
    out: dict[str, pd.DataFrame] = {}
    for recording in reader.find([path]):
        result = convert(recording, reader, topic_map, opts)
        if result.error:
            raise ConversionError(result.error)
        out.update(result.runs)
    return out


def convert(recording: Recording, reader: Reader, topic_map: TopicMap, opts: Options,
            progress: Callable[[int], None] | None = None) -> Result:
    """Convert one recording. Never raises for bad input: ``error`` says what failed."""
    result = Result(recording.name)
    report = result.report
    report.update(name=recording.name, path=str(recording.path), files=[
        {'path': str(f), 'bytes': f.stat().st_size if f.is_file() else None,
         'sha256': sha256(f) if f.is_file() else None} for f in recording.files],
        notes=list(recording.notes), losses=[], sources={}, gaps=[], short_runs=[],
        spikes={}, resolution={}, runs=[])
    try:
        parts, used = reader.read(recording, topic_map, opts, report, progress)
        spans = []
        for part in parts:
            spans += [(part.key, *s) for s in _convert_part(part.samples, used, opts,
                                                             report)]
        if not spans:
            reach = ', '.join(f'{s} {_time(a)} to {_time(b)}' for s, (a, b) in
                              report.pop('_reach', {}).items())
            raise ConversionError(f'no stretch of at least {opts.min_run_s} s where every '
                                  f'quantity has samples without gaps over the max gap '
                                  f'({reach or "nothing read"})')
    except (ConversionError, RecordingError) as exc:
        report.pop('_reach', None)
        text = str(exc)
        result.error = text if text.startswith(str(recording.path)) else \
            f'{recording.path}: {text}'
        return result
    report.pop('_reach', None)
    _name_runs(result, spans)
    return result


def _convert_part(samples, topic_map: TopicMap, opts: Options, report: dict) -> list[tuple]:
    """Delays, derived channels, spikes, runs and resampling of one part of a recording."""
    vessel = topic_map.vessel
    series = _channels(samples, topic_map)
    _complete(series, topic_map)
    found = _drop_spikes(series, topic_map, report)
    scales = _scales(series, topic_map, report)
    dt = period_ns(vessel.rate_hz)
    gap = {c: int(round(topic_map.max_gap_s.get(s.source, opts.max_gap_s) * 1e9))
           for c, s in series.items()}
    min_samples = int(np.floor(opts.min_run_s * vessel.rate_hz + 1e-9)) + 1
    runs, short, gaps = plan_runs({c: s.t_ns for c, s in series.items()}, gap, dt,
                                  min_samples)
    reach = report.setdefault('_reach', {})
    for s in series.values():
        if len(s.t_ns):
            reach[s.source] = (int(s.t_ns[0]), int(s.t_ns[-1]))
    sources_of_gap: dict[tuple[int, int], set[str]] = {}
    for g in gaps:
        sources_of_gap.setdefault((g.start_ns, g.end_ns), set()).add(series[g.topic].source)
    everything = {s.source for s in series.values()}
    report['gaps'] += [{'sources': 'all' if names == everything else sorted(names),
                        'start': _time(a), 'end': _time(b), 'duration_s': (b - a) / 1e9}
                       for (a, b), names in sources_of_gap.items()]
    report['short_runs'] += [{'start': _time(r.start_ns), 'end': _time(r.end_ns),
                              'samples': int(len(r.grid_ns))} for r in short]
    methods = channel_methods(topic_map)
    interval = max((float(np.median(np.diff(s.t_ns))) / 1e9 for s in series.values()
                    if len(s.t_ns) > 1), default=0.0)
    out = []
    for run in runs:
        grid = run.grid_ns
        channels = {c: sample(s.t_ns, s.values[:, None], grid, [methods[c]])[:, 0]
                    for c, s in series.items()}
        extras = {'sog': channels.pop('sog')} if 'sog' in channels else {}
        table = pd.DataFrame({'t': (grid - grid[0]) / 1e9, **to_columns(channels, topic_map)})
        counts = {column: sp.counts((t >= grid[0]) & (t <= grid[-1]))
                  for column, (sp, t) in found.items()}
        source = {'start': _time(int(grid[0])), 'end': _time(int(grid[-1])),
                  'start_ns': int(grid[0])}
        out.append((table, source, {'spikes': counts, 'scales': scales, 'extras': extras,
                                    'interval_s': interval}))
    return out


def _channels(samples, topic_map: TopicMap) -> dict[str, _Series]:
    """Every channel of every source, moved back by its map entry's delay."""
    delays = channel_delays(topic_map)
    out = {}
    for s in samples:
        for i, c in enumerate(s.channels):
            shift = int(round(delays.get(c, 0.0) * 1e9))
            values = np.asarray(s.values[:, i], float)
            ok = np.isfinite(values)  # a missing value costs its channel only
            out[c] = _Series(s.t_ns[ok] - shift, values[ok], s.topic)
    return out


def _complete(series: dict[str, _Series], topic_map: TopicMap) -> None:
    """Add the rates and velocities the map does not give, derived from what it does."""
    sign = -1.0 if topic_map.frames.get('body_velocity') == 'flu' else 1.0
    for rate, angle in (('yaw_rate', 'psi'), ('roll_rate', 'phi')):
        if rate not in series and angle in series and (
                rate == 'yaw_rate' or topic_map.vessel.has_roll):
            s = series[angle]
            derivative = np.gradient(s.values, s.t_ns / 1e9) if len(s.t_ns) > 1 else \
                np.full(len(s.t_ns), np.nan)
            # FRD rates from NED angles; a roll rate keeps its sign in FLU (frames).
            series[rate] = _Series(s.t_ns, (sign if rate == 'yaw_rate' else 1.0)
                                   * derivative, s.source)
    if 'surge' in series or 'vel_north' in series:
        return
    t, north, east, source = _track(series, topic_map)
    try:
        t, v_north, v_east = track.velocity(t, north, east)
    except ValueError as exc:
        raise ConversionError(str(exc)) from None
    series['vel_north'] = _Series(t, v_north, source)
    series['vel_east'] = _Series(t, v_east, source)


def _track(series: Mapping[str, _Series], topic_map: TopicMap):
    """Return the position track in m north and east, with its times and source."""
    if 'lat' in series:
        lat, lon = series['lat'], series['lon']
        north, east = latlon_to_local(lat.values, lon.values)
        return lat.t_ns, north, east, lat.source
    x, y = series['pos_x'], series['pos_y']
    if topic_map.frames.get('position') == 'enu':
        return x.t_ns, y.values, x.values, x.source
    return x.t_ns, x.values, y.values, x.source


def _drop_spikes(series: dict[str, _Series], topic_map: TopicMap, report: dict
                 ) -> dict[str, tuple[spikes.Spikes, np.ndarray]]:
    """Drop the spikes of every state and actuator channel; return them per column."""
    found = {}

    def drop(channels: Sequence[str], column: str, values: np.ndarray) -> np.ndarray:
        sp = spikes.find_spikes(column, values, topic_map.vessel)
        found[column] = (sp, series[channels[0]].t_ns)
        total = report['spikes'].setdefault(column, {'out_of_range': 0, 'jumps': 0,
                                                     'dropped': 0})
        total['out_of_range'] += int(sp.out_of_range.sum())
        total['jumps'] += int(sp.jumps.sum())
        total['dropped'] += int(sp.mask.sum())
        return sp.mask

    for channel, s in list(series.items()):
        model = model_column(channel, s.values, topic_map)
        if model is not None:
            mask = drop([channel], *model)
            series[channel] = _Series(s.t_ns[~mask], s.values[~mask], s.source)
    spatial = topic_map.vessel.is_spatial
    earth = ('vel_north', 'vel_east', 'vel_down') if spatial else ('vel_north', 'vel_east')
    attitude = ('phi', 'theta', 'psi') if spatial else ('psi',)
    if all(c in series for c in earth + attitude) and len(
            {len(series[c].t_ns) for c in earth}) == 1 and min(
            len(series[c].t_ns) for c in attitude) > 1:
        # Earth-frame velocities: their spikes are the body velocities' (u, v[, w]).
        t_ns = series['vel_north'].t_ns
        angles = [np.interp(t_ns, series[c].t_ns, series[c].values) for c in attitude]
        values = [series[c].values for c in earth]
        body = dict(zip('uvw', ned_to_body_3d(*values, *angles) if spatial else
                        earth_to_body(*values, angles[0]), strict=False))
        mask = np.zeros(len(t_ns), bool)
        for state, velocity in body.items():
            mask |= drop(['vel_north'], state, velocity)
        for c in earth:
            series[c] = _Series(series[c].t_ns[~mask], series[c].values[~mask],
                                series[c].source)
    return found


# Quantity -> (channels, unit) whose coarseness the checks must allow for.
COARSE = {'position': (('pos_x', 'pos_y'), 'm'), 'latlon': (('lat', 'lon'), 'deg'),
          'heading': (('psi',), 'rad'), 'velocity': (('surge', 'sway'), 'm/s'),
          'earth_velocity': (('vel_north', 'vel_east'), 'm/s'),
          'yaw_rate': (('yaw_rate',), 'rad/s'), 'roll': (('phi',), 'rad'),
          'roll_rate': (('roll_rate',), 'rad/s'), 'pitch': (('theta',), 'rad'),
          'pitch_rate': (('pitch_rate',), 'rad/s')}


def _scales(series: Mapping[str, _Series], topic_map: TopicMap, report: dict
            ) -> dict[str, float]:
    """Note each coarse quantity once; return the time scale (s) per quantity."""
    labels = map_checks.LABELS[topic_map.section]
    fields = {leaf.channel: leaf.path for leaf in topic_map.leaves()}
    for angle, sources in (('psi', ('heading', 'qx')), ('phi', ('roll', 'qx')),
                           ('theta', ('pitch', 'qx'))):
        if found := [fields[c] for c in sources if c in fields]:
            fields[angle] = found[0]
    out = {}
    for key, (channels, unit) in COARSE.items():
        if not all(c in series and c in fields for c in channels):
            continue  # not read, or derived by the converter (its source is noted)
        s = series[channels[0]]
        values = np.column_stack([series[c].values for c in channels])
        if key == 'latlon':  # compare the two axes in metres
            values = values * [1.0, np.cos(np.radians(np.nanmedian(values[:, 0])))]
        if len({len(series[c].t_ns) for c in channels}) > 1:
            continue
        res = resolution.analyse(key, s.t_ns, values, unit)
        # Repeats that change nothing (a message logged twice) are not worth a line.
        if res is None or (res.scale_s <= map_checks.SMOOTH_S
                           and res.change_s <= 1.5 * topic_map.vessel.dt):
            continue
        quantity = {'latlon': 'position', 'earth_velocity': 'velocity'}.get(key, key)
        out[quantity] = res.scale_s
        label = labels.get(quantity, quantity)
        column = ', '.join(fields.get(c, c) for c in channels)
        line = resolution.note(res, label, column, topic_map.vessel.dt)
        if line not in report['notes']:
            report['notes'].append(line)
        report['resolution'][quantity] = res.to_dict()
    return out


def _name_runs(result: Result, spans: Sequence[tuple]) -> None:
    """Run ids: the recording's name, -<run key>, and -NNN where it gives several."""
    bases = [result.name if key is None else f'{result.name}-{_safe(key)}'
             for key, *_ in spans]
    seen: dict[str, int] = {}
    for base, (key, table, source, context) in zip(bases, spans, strict=True):
        k = seen[base] = seen.get(base, -1) + 1
        run_id = base if bases.count(base) == 1 else f'{base}-{k:03d}'
        result.runs[run_id] = table
        result.run_sources[run_id] = {'recording': result.report['path'], 'run': key,
                                      'source_run': base, **source}
        result.context[run_id] = context
        result.report['runs'].append({'id': run_id, 'samples': len(table), **source})


def _safe(key: Any) -> str:
    return re.sub(r'[^A-Za-z0-9_.-]', '_', str(key)) or 'run'


def _time(ns: int) -> str:
    """Format a sample time: a UTC date for wall-clock stamps, else seconds."""
    return format_ns(ns) if ns > EPOCH_NS else f'{ns / 1e9:.3f} s'


# ----------------------------------------------------------------- many recordings
def convert_all(paths: Iterable[str | os.PathLike], reader: Reader, topic_map: TopicMap,
                opts: Options, jobs: int = 1, progress: Callable[[int], None] | None = None,
                on_result: Callable[[Result], None] | None = None) -> list[Result]:
    """
    Convert recordings, ``jobs`` at a time in separate processes.

    ``progress`` receives read counts as they come; ``on_result`` each finished
    recording. Results come back in the order of the recordings found.
    """
    recordings = unique_names(reader.find(paths))
    if jobs <= 1 or len(recordings) == 1:
        results = []
        for recording in recordings:
            results.append(convert(recording, reader, topic_map, opts, progress))
            if on_result:
                on_result(results[-1])
        return results
    results: dict[int, Result] = {}
    pool, queue = _pool(min(jobs, len(recordings)), progress is not None)
    with pool:
        futures = {pool.submit(_worker, rec, reader, topic_map, opts): i
                   for i, rec in enumerate(recordings)}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=PROGRESS_POLL_S, return_when=FIRST_COMPLETED)
            _drain(queue, progress)
            for f in done:
                results[futures[f]] = f.result()
                if on_result:
                    on_result(results[futures[f]])
    _drain(queue, progress)
    return [results[i] for i in range(len(recordings))]


def _pool(workers: int, with_progress: bool) -> tuple[ProcessPoolExecutor, Any]:
    """Start ``workers`` conversion processes once for all recordings."""
    # 'forkserver': a clean server process imports this module once and forks every
    # worker from it, so a worker costs a fork rather than an interpreter start plus
    # imports (~2 s), and inherits none of the caller's threads or their held locks
    # (tqdm's monitor, torch's pools), which 'fork' from the caller would. Nothing here
    # initialises rclpy/DDS.
    ctx = mp.get_context('forkserver')
    ctx.set_forkserver_preload([__name__])
    queue = ctx.Queue() if with_progress else None
    # Workers live for all recordings: measured on 216,000-message bags, a worker's
    # resident set rises from 78 MB to 171 MB with its first bag and stays there bag
    # after bag (peak 254 MB), so it is bounded by the largest recording. (Python 3.11's
    # max_tasks_per_child > 1 deadlocks with queued tasks, CPython gh-115634.)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                               initargs=(queue,))
    return pool, queue


_QUEUE = None


def _init_worker(queue) -> None:
    global _QUEUE
    _QUEUE = queue


def _worker(recording: Recording, reader: Reader, topic_map: TopicMap,
            opts: Options) -> Result:
    return convert(recording, reader, topic_map, opts,
                   _QUEUE.put if _QUEUE is not None else None)


def _drain(queue, progress) -> None:
    if queue is None:
        return
    while True:
        try:
            progress(queue.get_nowait())
        except queue_module.Empty:
            return


# ----------------------------------------------------------------- checks, split, write
def run_checks(results: Sequence[Result], topic_map: TopicMap, refuse_spikes: bool
               ) -> dict[str, list[map_checks.Check]]:
    """Return the map checks of every run of the results, per run id."""
    per_run = {}
    for r in results:
        for run_id, table in r.runs.items():
            c = r.context[run_id]
            ctx = map_checks.context_for(topic_map, c['scales'], c['extras'], c['interval_s'])
            per_run[run_id] = map_checks.check_run(table, topic_map, ctx, c['spikes'],
                                                   refuse_spikes)
    return per_run


def check(results: Sequence[Result], topic_map: TopicMap, accept: bool,
          refuse_spikes: bool, stream: TextIO) -> tuple[bool, dict[str, Any]]:
    """
    Check every run, print the checks, decide whether to write: the one gate.

    Stores each recording's checks in its report (so in the manifest) and returns
    (go on, the checks for the manifest).
    """
    go_on, data = map_checks.gate(run_checks(results, topic_map, refuse_spikes),
                                  map_checks.context_for(topic_map), accept, refuse_spikes,
                                  stream)
    for r in results:
        r.report['checks'] = {run_id: data['runs'][run_id] for run_id in r.runs}
    return go_on, data


def assign_split(results: Sequence[Result], test: Sequence[str], val: Sequence[str],
                 seed: int, fractions: Sequence[float]) -> dict[str, list[str]]:
    """
    Assign whole recordings (or a table's runs by their key) to train/val/test.

    ``test`` and ``val`` name runs by id or by source run (a recording's name, or
    name-key); they are held out whole, and the rest share the fractions of the splits
    given no runs by a seeded shuffle. Runs cut from one source run always share a
    split: they share its conditions, so splitting them would let a test run's twin
    train the model.
    """
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
    rest = sorted({base for r, base in sources.items()
                   if r not in fixed['test'] and r not in fixed['val']})
    share = [f if not fixed.get(s) else 0.0 for s, f in zip(fmt.SPLITS, fractions,
                                                             strict=True)]
    share = [f / sum(share) for f in share] if sum(share) > 0 else [1.0, 0.0, 0.0]
    by_base = fmt.split_runs(rest, seed, share)
    return {s: sorted(fixed.get(s, []) + [r for r, base in sources.items()
                                          if base in by_base[s] and r not in fixed['test']
                                          and r not in fixed['val']])
            for s in fmt.SPLITS}


def write(out: str | os.PathLike, results: Sequence[Result], reader: Reader,
          topic_map: TopicMap, opts: Options, split: Mapping[str, Sequence[str]],
          checks: Mapping | None = None, argv: Sequence[str] | None = None) -> Path:
    """Write the runs of every result as a dataset with its manifest; return its path."""
    runs: dict[str, pd.DataFrame] = {}
    sources: dict[str, dict] = {}
    for r in results:
        runs.update(r.runs)
        sources.update(r.run_sources)
    if not runs:
        raise fmt.DatasetError('no runs to write')
    provenance = {
        'tool': reader.tool,
        'argv': list(argv) if argv is not None else None,
        'config': {**asdict(opts), 'vessel': topic_map.vessel.source,
                   'map_section': topic_map.section, 'map': topic_map.to_dict(),
                   **reader.config()},
        'seed': opts.seed,
        'versions': versions(),
        'sources': [f for r in results for f in r.report.get('files', [])],
    }
    dropped: dict[str, int] = {}
    for r in results:
        for source in r.report.get('sources', {}).values():
            for reason, n in source.get('dropped', {}).items():
                dropped[reason] = dropped.get(reason, 0) + n
    conversion = {
        'rate_hz': topic_map.vessel.rate_hz,
        'max_gap_s': opts.max_gap_s,
        'dropped_samples': dropped,
        'min_run_s': opts.min_run_s,
        'derived': list(map_checks.context_for(topic_map).derived),
        'recordings': [{**r.report, 'error': r.error} for r in results],
    }
    extra = {'conversion': conversion, 'split_by': 'recording'}
    if checks is not None:
        extra['checks'] = checks
    return fmt.write_dataset(out, runs, vessel=topic_map.vessel, provenance=provenance,
                             seed=opts.seed, fractions=opts.split, split=split,
                             run_sources=sources, extra=extra)


def versions() -> dict[str, str]:
    """Versions of the libraries a conversion depends on."""
    from importlib.metadata import PackageNotFoundError, version
    out = {'python': platform.python_version()}
    for name in ('rosbags', 'mcap', 'pymavlink', 'pyulog', 'pyproj', 'numpy', 'scipy',
                 'pandas', 'pyarrow'):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = 'unknown'
    return out
