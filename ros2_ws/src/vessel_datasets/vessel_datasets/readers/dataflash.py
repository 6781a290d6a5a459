"""
The ArduPilot DataFlash reader: ``.bin`` logs (ArduRover boats and rovers) -> channels.

A log map (a vessel file's ``recordings.logs``, the syntax of a topic map) names
DataFlash messages as topics -- ``GPS``, ``ATT``, ``XKF1``, ``RCOU``; ``GPS[1]`` for the
second instance of a message that has several -- and their fields (``Lat``, ``Yaw``,
``C3``). pymavlink's DataFlash reader parses the log (message formats from the log's
own FMT messages, multipliers applied: degrees, m/s); each message is timed by its
``TimeUS`` (microseconds since the autopilot booted), or in logs before 2015 (ArduCopter
3.2/3.3) by its ``TimeMS`` (milliseconds since boot; their GPS message's ``TimeMS`` is
the GPS week's, its boot time ``T``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import contextlib
from functools import lru_cache
import io
import os
import re
from typing import Any

import numpy as np

from ..sources import ConversionError, Part, Recording, find_files, from_arrays
from ..topic_map import TopicMap

SUFFIXES = ('.bin',)
# Boot-time fields, newest first, with their nanoseconds per count.
TIME_FIELDS = (('TimeUS', 1_000), ('TimeMS', 1_000_000))
# Messages of old logs whose TimeMS is not boot time: GPS carries the GPS week's
# milliseconds there and its boot time in T.
OLD_BOOT_TIME = {'GPS': ('T', 1_000_000)}
_INSTANCE = re.compile(r'^(?P<name>[A-Z0-9_]+)(\[(?P<instance>\d+)\])?$')


class DataFlashRecordings:
    """Reader of ArduPilot DataFlash logs (``sources.Reader``) through pymavlink."""

    tool = 'log_to_dataset'
    section = 'logs'

    def find(self, paths: Iterable[str | os.PathLike]) -> list[Recording]:
        """Return the .bin files at the paths (one recording each)."""
        return find_files(paths, SUFFIXES, 'DataFlash logs')

    def config(self) -> dict[str, Any]:
        """Return the log format (for the manifest)."""
        return {'log_format': 'ardupilot-dataflash'}

    def read(self, recording: Recording, topic_map: TopicMap, opts, report: dict,
             progress: Callable[[int], None] | None) -> tuple[list[Part], TopicMap]:
        """Read the mapped messages of one log; raise ConversionError (one line)."""
        # pymavlink prints what it skips: keep it off stdout (the dataset path's) and
        # report it as a loss.
        said = io.StringIO()
        with contextlib.redirect_stdout(said):
            parts, used = self._read(recording, topic_map, report, progress)
        skipped = [line for line in said.getvalue().splitlines() if line.startswith('Skipped')]
        if skipped:
            report['losses'].append(f'{recording.path}: pymavlink skipped {len(skipped)} '
                                    f'damaged stretch(es) of bytes ({skipped[0]})')
        return parts, used

    def _read(self, recording, topic_map, report, progress):
        from pymavlink.DFReader import DFReader_binary
        try:
            log = DFReader_binary(str(recording.path), zero_time_base=True)
        except Exception as exc:  # noqa: BLE001 - pymavlink raises anything on a bad file
            raise ConversionError(f'not a DataFlash log ({type(exc).__name__}: {exc})') \
                from None
        names = set(log.name_to_id)
        wanted = topic_map.candidate_topics
        available = {t for t in wanted if _base(t) in names}
        used, chosen = topic_map.resolve(available)
        if chosen:
            report['alternatives'] = chosen
        columns: dict[str, dict[str, list]] = {t: {} for t in used.topics}
        times: dict[str, list[int]] = {t: [] for t in used.topics}
        fields = {t: {leaf.path for leaf in used.leaves() if leaf.topic == t}
                  for t in used.topics}
        count = 0
        while (m := log.recv_match(type=list({_base(t) for t in used.topics}))) is not None:
            count += 1
            for topic in _topics_of(m, used.topics):
                have = m.get_fieldnames()
                field, ns = _clock(m.get_type(), tuple(have))
                times[topic].append(int(getattr(m, field)) * ns)
                for f in fields[topic] & set(have):
                    columns[topic].setdefault(f, []).append(float(getattr(m, f)))
        if progress is not None:
            progress(count)
        report['read'] = [count, 'messages']
        arrays = {t: (np.asarray(times[t], np.int64),
                      {f: np.asarray(v, float) for f, v in columns[t].items()})
                  for t in used.topics if times[t]}
        return [Part(from_arrays(arrays, used, report, 'log'))], used


@lru_cache(maxsize=256)
def _clock(name: str, fields: tuple[str, ...]) -> tuple[str, int]:
    """Return the boot-time field of a message type and its nanoseconds per count."""
    if 'TimeUS' not in fields and name in OLD_BOOT_TIME and OLD_BOOT_TIME[name][0] in fields:
        return OLD_BOOT_TIME[name]
    for field, ns in TIME_FIELDS:
        if field in fields:
            return field, ns
    raise ConversionError(f'message {name} has none of the fields '
                          f'{[f for f, _ in TIME_FIELDS]} to time it')


def _base(topic: str) -> str:
    match = _INSTANCE.match(topic)
    return match['name'] if match else topic


def _topics_of(m, topics: Iterable[str]) -> list[str]:
    """Return the map's topics a message counts for: its name, or name[instance]."""
    name = m.get_type()
    field = m.fmt.instance_field
    instance = int(getattr(m, field)) if field else 0
    return [t for t in topics if t == f'{name}[{instance}]' or (t == name and instance == 0)]
