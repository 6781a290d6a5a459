"""
Convert recordings into a dataset: read, clean, resample, change frames, report.

``convert_bag`` turns one recording into run tables plus a JSON-able report of what
was read, dropped, lost and why; ``convert_bags`` does that for many recordings in
parallel processes; ``write`` stores the result through ``vessel_datasets.format``
with a manifest that lets anyone trace every run back to its source bytes.

Library use (for example a round-trip test against the batch simulator)::

    from vessel_datasets.convert import bag_to_runs
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel
    runs = bag_to_runs('recording/', topic_map_for(load_vessel('patrol_boat')))
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
from typing import Any

import numpy as np
import pandas as pd

from vessel_description.resources import data_dir, read_yaml

from . import format as fmt
from .bag_source import Bag, BagError, BagReader, MessageDefinitions, find_bags, format_ns, sha256
from .extract import DROP_REASONS, TopicExtractor, TopicSamples
from .fields import FieldError, check_path, has_header_stamp, numeric_paths
from .quantities import channel_methods, derive, to_columns
from .resample import period_ns, plan_runs, sample
from .topic_map import TopicMap

TOOL = 'offline/bag_to_dataset.py'
PROGRESS_EVERY = 20_000  # messages between progress callbacks
PROGRESS_POLL_S = 0.2  # how often the parent forwards the workers' progress


class ConversionError(ValueError):
    """A recording cannot be converted at all (one line says why)."""


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
        if not self.max_gap_s > 0:
            raise ValueError(f'max_gap_s must be positive, got {self.max_gap_s}')
        if self.max_gap_s * rate_hz < 1.0:
            raise ValueError(f'max gap {self.max_gap_s} s is shorter than the sample '
                             f'period {1 / rate_hz} s of the vessel')


def config_dir() -> Path:
    """Directory of the package's YAML defaults (source tree or colcon install)."""
    return data_dir('vessel_datasets', __file__, 'config')


@dataclass
class BagResult:
    """What one recording gave: run tables, their sources, and a report."""

    name: str
    runs: dict[str, pd.DataFrame] = field(default_factory=dict)
    run_sources: dict[str, dict] = field(default_factory=dict)
    report: dict[str, Any] = field(default_factory=dict)
    error: str | None = None


def bag_to_runs(path: str | os.PathLike, topic_map: TopicMap,
                definitions: MessageDefinitions | None = None,
                **options) -> dict[str, pd.DataFrame]:
    """Run tables of one recording (for tests and notebooks); raises on failure."""
    bags = find_bags([path])
    opts = Options.from_yaml(**options)
    out: dict[str, pd.DataFrame] = {}
    for bag in bags:
        result = convert_bag(bag, topic_map, opts, definitions=definitions)
        if result.error:
            raise ConversionError(result.error)
        out.update(result.runs)
    return out


def convert_bag(bag: Bag, topic_map: TopicMap, opts: Options,
                progress: Callable[[int], None] | None = None,
                definitions: MessageDefinitions | None = None) -> BagResult:
    """
    Convert one recording. Never raises for bad input: ``error`` says what failed.

    ``definitions``: ``.msg`` files for message types the bag does not define.
    """
    result = BagResult(bag.name)
    report = result.report
    report.update(name=bag.name, path=str(bag.path), files=[], notes=[], losses=[],
                  topics={}, gaps=[], short_runs=[], runs=[])
    for f in bag.files:
        report['files'].append({'path': str(f), 'bytes': f.stat().st_size if f.is_file()
                                else None, 'sha256': sha256(f) if f.is_file() else None})
    try:
        with BagReader(bag, definitions) as reader:
            samples = _read(reader, topic_map, opts, progress, report)
    except ConversionError as exc:
        result.error = f'{bag.path}: {exc}'
        return result
    try:
        _resample(result, samples, topic_map, opts)
    except ConversionError as exc:
        result.error = f'{bag.path}: {exc}'
    return result


def _read(reader: BagReader, topic_map: TopicMap, opts: Options, progress,
          report: dict) -> dict[str, TopicSamples]:
    report['notes'] += reader.notes
    report['losses'] += reader.losses
    report['notes'] += [line for line in reader.undecodable_lines()
                        if not any(line.startswith(f'topic {t} ') for t in topic_map.topics)]
    extractors = _extractors(reader, topic_map, opts, report)
    count = 0
    for topic, log_ns, raw in reader.messages(extractors):
        extractors[topic].add(log_ns, raw)
        count += 1
        if progress is not None and count % PROGRESS_EVERY == 0:
            progress(PROGRESS_EVERY)
    if progress is not None:
        progress(count % PROGRESS_EVERY)
    report['losses'] = list(reader.losses)
    report['messages_read'] = count
    samples = {}
    for topic, ex in extractors.items():
        s = ex.finish()
        samples[topic] = derive(s, topic_map)
        entry = {'type': s.msgtype, 'received': s.received, 'kept': len(s.t_ns),
                 'dropped': s.dropped, 'unreadable': s.unreadable,
                 'time_source': 'header' if ex.use_header else 'log'}
        if ex.first_error:
            entry['first_error'] = ex.first_error
        report['topics'][topic] = entry
        if not len(s.t_ns):
            raise ConversionError(f'topic {topic} has no usable samples '
                                  f'({s.received} received, dropped {s.dropped}, '
                                  f'{s.unreadable} unreadable)')
    return samples


def _extractors(reader: BagReader, topic_map: TopicMap, opts: Options,
                report: dict) -> dict[str, TopicExtractor]:
    """Check the map against the bag's topics and types; one extractor per topic."""
    have = '; it has: ' + (', '.join(f'{t} ({i.msgtype}, {_count(i.count)})'
                                     for t, i in reader.topics.items()) or 'no readable topics')
    leaves_by_topic: dict[str, list] = {}
    for leaf in topic_map.leaves():
        leaves_by_topic.setdefault(leaf.topic, []).append(leaf)
    missing = [t for t in leaves_by_topic if t not in reader.topics]
    if missing:
        needs = ', '.join(f'{t} ({_labels(leaves_by_topic[t])})' for t in missing)
        raise ConversionError(f'the topic map needs {needs}, which the bag lacks{have}')
    defs = reader.typestore.fielddefs
    extractors = {}
    for topic, leaves in leaves_by_topic.items():
        info = reader.topics[topic]
        if info.problem:
            raise ConversionError(f'topic {topic} has type {info.msgtype}, which '
                                  f'{info.problem}; it cannot be read')
        for entry in topic_map.entries:
            if entry.topic == topic and entry.msgtype and entry.msgtype != info.msgtype:
                raise ConversionError(f'the topic map expects {topic} ({entry.label}) to be '
                                      f'{entry.msgtype}, but the bag has {info.msgtype}')
        for leaf in leaves:
            try:
                check_path(defs, info.msgtype, leaf.path)
            except FieldError as exc:
                raise ConversionError(
                    f'the topic map reads {leaf.path!r} ({leaf.label}) from {topic} '
                    f'({info.msgtype}): {exc}; its numeric fields are: '
                    f'{", ".join(numeric_paths(defs, info.msgtype))}') from None
        header = has_header_stamp(defs, info.msgtype)
        wanted = topic_map.stamps.get(topic, opts.time_source)
        if wanted == 'header' and not header:
            report['notes'].append(f'topic {topic} ({info.msgtype}) has no header; its '
                                   f'samples are timed by log time')
        extractors[topic] = TopicExtractor(topic, info.msgtype, leaves, reader.typestore,
                                           use_header=wanted == 'header' and header)
    return extractors


def _labels(leaves) -> str:
    return ', '.join(dict.fromkeys(leaf.label for leaf in leaves))


def _count(n: int | None) -> str:
    return 'count unknown' if n is None else f'{n} msgs'


def _resample(result: BagResult, samples: Mapping[str, TopicSamples], topic_map: TopicMap,
              opts: Options) -> None:
    rate_hz = topic_map.vessel.rate_hz
    dt = period_ns(rate_hz)
    max_gap = {t: int(round(topic_map.max_gap_s.get(t, opts.max_gap_s) * 1e9))
               for t in samples}
    min_samples = int(np.floor(opts.min_run_s * rate_hz + 1e-9)) + 1
    runs, short, gaps = plan_runs({t: s.t_ns for t, s in samples.items()}, max_gap, dt,
                                  min_samples)
    report = result.report
    report['gaps'] = [{'topic': g.topic, 'start': format_ns(g.start_ns),
                       'end': format_ns(g.end_ns), 'duration_s': g.duration_s} for g in gaps]
    report['short_runs'] = [{'start': format_ns(r.start_ns), 'end': format_ns(r.end_ns),
                             'samples': int(len(r.grid_ns))} for r in short]
    if not runs:
        spans = ', '.join(f'{t} {format_ns(int(s.t_ns[0]))} to {format_ns(int(s.t_ns[-1]))}'
                          for t, s in samples.items())
        raise ConversionError(f'no stretch of at least {opts.min_run_s} s where every topic '
                              f'has samples without gaps over the max gap ({spans})')
    methods = channel_methods(topic_map)
    for k, run in enumerate(runs):
        channels: dict[str, np.ndarray] = {}
        for s in samples.values():
            values = sample(s.t_ns, s.values, run.grid_ns, [methods[c] for c in s.channels])
            channels.update({c: values[:, i] for i, c in enumerate(s.channels)})
        columns = to_columns(channels, topic_map)
        table = pd.DataFrame({'t': (run.grid_ns - run.grid_ns[0]) / 1e9, **columns})
        run_id = f'{result.name}-{k:03d}'
        result.runs[run_id] = table
        source = {'bag': str(result.report['path']), 'start': format_ns(int(run.grid_ns[0])),
                  'end': format_ns(int(run.grid_ns[-1])), 'start_ns': int(run.grid_ns[0])}
        result.run_sources[run_id] = source
        report['runs'].append({'id': run_id, 'samples': len(table), **source})


def convert_bags(paths: Iterable[str | os.PathLike], topic_map: TopicMap, opts: Options,
                 jobs: int = 1, progress: Callable[[int], None] | None = None,
                 on_result: Callable[[BagResult], None] | None = None,
                 definitions: MessageDefinitions | None = None) -> list[BagResult]:
    """
    Convert recordings, ``jobs`` bags at a time in separate processes.

    ``progress`` receives message counts as they are read; ``on_result`` each finished
    bag. Results come back in the order of the bags found. ``definitions``: ``.msg``
    files for message types the bags do not define.
    """
    bags = find_bags(paths)
    if jobs <= 1 or len(bags) == 1:
        results = []
        for bag in bags:
            results.append(convert_bag(bag, topic_map, opts, progress, definitions))
            if on_result:
                on_result(results[-1])
        return results
    results: dict[int, BagResult] = {}
    pool, queue = _pool(min(jobs, len(bags)), progress is not None)
    with pool:
        futures = {pool.submit(_worker, bag, topic_map, opts, definitions): i
                   for i, bag in enumerate(bags)}
        pending = set(futures)
        while pending:
            done, pending = wait(pending, timeout=PROGRESS_POLL_S, return_when=FIRST_COMPLETED)
            _drain(queue, progress)
            for f in done:
                results[futures[f]] = f.result()
                if on_result:
                    on_result(results[futures[f]])
    _drain(queue, progress)
    return [results[i] for i in range(len(bags))]


def _pool(workers: int, with_progress: bool) -> tuple[ProcessPoolExecutor, Any]:
    """Start ``workers`` conversion processes once for all bags; return them and a queue."""
    # 'forkserver': a clean server process imports this module once and forks every
    # worker from it, so a worker costs a fork rather than an interpreter start plus
    # imports (~2 s), and inherits none of the caller's threads or their held locks
    # (tqdm's monitor, torch's pools), which 'fork' from the caller would. Nothing here
    # initialises rclpy/DDS: bags are read with rosbags and mcap.
    ctx = mp.get_context('forkserver')
    ctx.set_forkserver_preload([__name__])
    queue = ctx.Queue() if with_progress else None
    # Workers live for all bags: measured on 216,000-message bags, a worker's resident set
    # rises from 78 MB to 171 MB with its first bag and stays there bag after bag (peak
    # 254 MB), so it is bounded by the largest bag without a process per bag. (Python
    # 3.11's max_tasks_per_child > 1 deadlocks with queued tasks, CPython gh-115634.)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                               initargs=(queue,))
    return pool, queue


_QUEUE = None


def _init_worker(queue) -> None:
    global _QUEUE
    _QUEUE = queue


def _worker(bag: Bag, topic_map: TopicMap, opts: Options,
            definitions: MessageDefinitions | None) -> BagResult:
    return convert_bag(bag, topic_map, opts, _QUEUE.put if _QUEUE is not None else None,
                       definitions)


def _drain(queue, progress) -> None:
    if queue is None:
        return
    while True:
        try:
            progress(queue.get_nowait())
        except queue_module.Empty:
            return


def write(out: str | os.PathLike, results: Sequence[BagResult], topic_map: TopicMap,
          opts: Options, argv: Sequence[str] | None = None,
          definitions: MessageDefinitions | None = None) -> Path:
    """Write the runs of every result as a dataset with its manifest; return its path."""
    runs: dict[str, pd.DataFrame] = {}
    sources: dict[str, dict] = {}
    for r in results:
        runs.update(r.runs)
        sources.update(r.run_sources)
    if not runs:
        raise fmt.DatasetError('no runs to write')
    totals = {reason: sum(t['dropped'][reason] for r in results
                          for t in r.report.get('topics', {}).values())
              for reason in DROP_REASONS}
    files = [f for r in results for f in r.report.get('files', [])]
    provenance = {
        'tool': TOOL,
        'argv': list(argv) if argv is not None else None,
        'config': {**asdict(opts), 'vessel': topic_map.vessel.source,
                   'topic_map': topic_map.to_dict(),
                   **(definitions or MessageDefinitions()).to_dict()},
        'seed': opts.seed,
        'versions': versions(),
        'sources': files,
    }
    conversion = {
        'rate_hz': topic_map.vessel.rate_hz,
        'time_source': opts.time_source,
        'max_gap_s': opts.max_gap_s,
        'min_run_s': opts.min_run_s,
        'dropped_samples': totals,
        'bags': [{**r.report, 'error': r.error} for r in results],
    }
    # Whole recordings go to one split: runs cut from one bag share its conditions, so
    # splitting them would let a test run's twin train the model.
    with_runs = [r for r in results if r.runs]
    by_bag = fmt.split_runs([r.name for r in with_runs], opts.seed, opts.split)
    split = {name: [run for r in with_runs if r.name in bags for run in r.runs]
             for name, bags in by_bag.items()}
    return fmt.write_dataset(out, runs, vessel=topic_map.vessel, provenance=provenance,
                             seed=opts.seed, fractions=opts.split, split=split,
                             run_sources=sources,
                             extra={'conversion': conversion, 'split_by': 'recording'})


def versions() -> dict[str, str]:
    """Versions of the libraries a conversion depends on."""
    from importlib.metadata import PackageNotFoundError, version
    out = {'python': platform.python_version()}
    for name in ('rosbags', 'mcap', 'numpy', 'pandas', 'pyarrow'):
        try:
            out[name] = version(name)
        except PackageNotFoundError:
            out[name] = 'unknown'
    return out


__all__ = ['BagError', 'BagResult', 'ConversionError', 'Options', 'bag_to_runs',
           'convert_bag', 'convert_bags', 'versions', 'write']
