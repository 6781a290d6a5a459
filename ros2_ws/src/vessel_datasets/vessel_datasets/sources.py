"""
What a recording reader is: the one interface every format implements.

A *reader* (``vessel_datasets.readers``: rosbag2 bags, text tables, ArduPilot DataFlash,
PX4 ULog) does two things and nothing else:

* ``find(paths)`` turns command-line paths into :class:`Recording` objects;
* ``read(recording, topic_map, opts, report, progress)`` chooses among the map's
  alternatives what the recording has (``TopicMap.resolve``), reads those quantities
  and returns them as :class:`Part` objects -- per source (a topic, a message, a file's
  rows) one ``extract.TopicSamples``: strictly increasing times in integer ns and the
  map's channels, scaled, after ``quantities.derive`` -- together with the resolved map.
  It adds what it alone knows to ``report`` (per source its counts, losses, notes,
  alternatives chosen) and raises ``ConversionError`` (one line) when the recording
  cannot give the map's quantities. ``samples`` builds a source's samples from arrays.

Everything after that -- delays, derived rates and track velocities, spikes, runs,
resampling, frames, checks, split and writing -- is ``vessel_datasets.pipeline``, the
same for every format.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
import hashlib
import os
from pathlib import Path
import re
from typing import Any, Protocol

import numpy as np

from .extract import TopicSamples
from .quantities import derive
from .topic_map import Leaf, TopicMap


class ConversionError(ValueError):
    """A recording cannot be converted at all (one line says why)."""


class RecordingError(ValueError):
    """A path holds no recording of the reader's format (one line says why)."""


@dataclass
class Recording:
    """One recording: its name (run ids start with it), where it is, its files."""

    name: str
    path: Path
    files: list[Path]
    notes: list[str] = field(default_factory=list)


@dataclass
class Part:
    """A stretch of a recording read as channels: per source, its samples."""

    samples: list[TopicSamples]
    key: str | None = None      # a run column's value (tables); None for the whole


class Reader(Protocol):
    """The interface of a recording format (see the module docstring)."""

    tool: str       # the program that converts this format (for the manifest)
    section: str    # the vessel file's recordings.<section> map it reads: topics|columns|logs

    def find(self, paths: Iterable[str | os.PathLike]) -> list[Recording]:
        """Turn command-line paths into recordings; raise RecordingError (one line)."""

    def read(self, recording: Recording, topic_map: TopicMap, opts: Any, report: dict,
             progress: Callable[[int], None] | None
             ) -> tuple[Sequence[Part], TopicMap]:
        """Read the map's quantities: the parts and the map resolved; ConversionError."""

    def config(self) -> dict[str, Any]:
        """Reader settings worth recording in the manifest."""

def find_files(paths: Iterable[str | os.PathLike], suffixes: Sequence[str], what: str,
               pattern: str | None = None) -> list[Recording]:
    """
    Files given, and the files in folders given (``pattern``, or the ``suffixes``).

    One recording per file, named by its stem; raises RecordingError for a path that
    does not exist or a folder without such files.
    """
    out: list[Recording] = []
    for p in map(Path, paths):
        if p.is_dir():
            found = sorted(f for f in (p.glob(pattern) if pattern else p.iterdir())
                           if f.is_file() and not f.name.startswith('.')
                           and (pattern or f.suffix.lower() in suffixes))
            if not found:
                raise RecordingError(f'{p}: no {what} in this folder (looked for '
                                     f'{pattern or ", ".join(suffixes)})')
            out += [Recording(f.stem, f, [f]) for f in found]
        elif p.is_file():
            out.append(Recording(p.stem, p, [p]))
        else:
            raise RecordingError(f'{p}: no such file or folder')
    return out


def unique_names(recordings: list[Recording]) -> list[Recording]:
    """Make names safe for run ids and unique: a repeated name gets .2, .3, ..."""
    seen: Counter[str] = Counter()
    for rec in recordings:
        base = re.sub(r'[^A-Za-z0-9_.-]+', '_', rec.name) or 'recording'
        seen[base] += 1
        rec.name = base if seen[base] == 1 else f'{base}.{seen[base]}'
    return recordings


def samples(topic: str, t_ns: np.ndarray, columns: dict[str, np.ndarray],
            leaves: Sequence[Leaf], topic_map: TopicMap, report: dict) -> TopicSamples:
    """
    Return one source's samples from its fields' arrays: scaled, in order, derived.

    ``columns`` maps each leaf's field path to its values at ``t_ns`` (in the order
    logged); a time not after the newest kept one (a repeat, or out of order) drops its
    sample, counted in ``report['sources'][topic]``. Non-finite values stay:
    the pipeline drops them channel by channel.
    """
    t_ns = np.asarray(t_ns, np.int64)
    values = np.column_stack([leaf.scale * np.asarray(columns[leaf.path], float)
                              + leaf.offset for leaf in leaves]) if leaves else \
        np.empty((len(t_ns), 0))
    newest = np.maximum.accumulate(t_ns) if len(t_ns) else t_ns
    keep = np.ones(len(t_ns), bool)
    keep[1:] = t_ns[1:] > newest[:-1]
    repeats = int((t_ns[1:][~keep[1:]] == newest[:-1][~keep[1:]]).sum())
    report['sources'][topic] = {'received': int(len(t_ns)), 'kept': int(keep.sum()),
                                'dropped': {'duplicate': repeats,
                                            'out_of_order': int((~keep).sum()) - repeats}}
    raw = TopicSamples(topic, '', tuple(leaf.channel for leaf in leaves), t_ns[keep],
                       values[keep], received=int(len(t_ns)))
    return derive(raw, topic_map)


def from_arrays(arrays: Mapping[str, tuple[np.ndarray, Mapping[str, np.ndarray]]],
                topic_map: TopicMap, report: dict, what: str) -> list[TopicSamples]:
    """
    Return the map's sources from whole arrays: per topic its times (ns) and fields.

    For formats read whole (autopilot logs); raises ConversionError naming a topic or
    field the map needs and ``what`` (the recording) lacks, with what it has.
    """
    by_topic: dict[str, list[Leaf]] = {}
    for leaf in topic_map.leaves():
        by_topic.setdefault(leaf.topic, []).append(leaf)
    missing = [t for t in by_topic if t not in arrays]
    if missing:
        needs = ', '.join(f'{t} ({", ".join(dict.fromkeys(x.label for x in by_topic[t]))})'
                          for t in missing)
        have = ', '.join(f'{t} ({len(arrays[t][0])} msgs)' for t in sorted(arrays)) or 'none'
        raise ConversionError(f'the {topic_map.section[:-1]} map needs {needs}, which the '
                              f'{what} lacks; it has: {have}')
    out = []
    for topic, leaves in by_topic.items():
        t_ns, fields = arrays[topic]
        for leaf in leaves:
            if leaf.path not in fields:
                raise ConversionError(f'the {topic_map.section[:-1]} map reads {leaf.path!r} '
                                      f'({leaf.label}) from {topic}, which has no such field; '
                                      f'its fields are: {", ".join(fields)}')
        out.append(samples(topic, t_ns, fields, leaves, topic_map, report))
    return out


def sha256(path: Path, block: int = 1 << 20) -> str:
    """SHA-256 of a file's bytes, hex."""
    digest = hashlib.sha256()
    with path.open('rb') as f:
        while chunk := f.read(block):
            digest.update(chunk)
    return digest.hexdigest()


def format_ns(ns: int) -> str:
    """Format a log time (ns since the epoch) as ISO 8601 UTC, to the millisecond."""
    return datetime.fromtimestamp(ns / 1e9, tz=UTC).isoformat(timespec='milliseconds')
