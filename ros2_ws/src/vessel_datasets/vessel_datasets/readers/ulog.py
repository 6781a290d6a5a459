"""
The PX4 ULog reader: ``.ulg`` logs (rovers, boats on PX4) -> timed channels.

A log map (a vessel file's ``recordings.logs``, the syntax of a topic map) names uORB
topics -- ``vehicle_local_position``, ``vehicle_attitude``, ``actuator_outputs``; a
topic logged in several instances is ``name[k]`` (multi id k; plain ``name`` is 0) --
and their fields as the log names them (``x``, ``heading``, ``output[0]``). pyulog
parses the log; each sample is timed by its ``timestamp`` (microseconds since boot).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import os
import re
from typing import Any

import numpy as np

from ..sources import ConversionError, Part, Recording, find_files, from_arrays
from ..topic_map import TopicMap

SUFFIXES = ('.ulg',)
_INSTANCE = re.compile(r'^(?P<name>[a-z0-9_]+)(\[(?P<instance>\d+)\])?$')


class ULogRecordings:
    """Reader of PX4 ULog files (``sources.Reader``) through pyulog."""

    tool = 'log_to_dataset'
    section = 'logs'

    def find(self, paths: Iterable[str | os.PathLike]) -> list[Recording]:
        """Return the .ulg files at the paths (one recording each)."""
        return find_files(paths, SUFFIXES, 'ULog files')

    def config(self) -> dict[str, Any]:
        """Return the log format (for the manifest)."""
        return {'log_format': 'px4-ulog'}

    def read(self, recording: Recording, topic_map: TopicMap, opts, report: dict,
             progress: Callable[[int], None] | None) -> tuple[list[Part], TopicMap]:
        """Read the mapped topics of one log; raise ConversionError (one line)."""
        from pyulog import ULog
        wanted = topic_map.candidate_topics
        try:
            ulog = ULog(str(recording.path), sorted({_base(t)[0] for t in wanted}),
                        disable_str_exceptions=True)
        except Exception as exc:  # noqa: BLE001 - pyulog raises anything on a bad file
            raise ConversionError(f'not a ULog file ({type(exc).__name__}: {exc})') from None
        arrays = {}
        for d in ulog.data_list:
            fields = {k: np.asarray(v, float) for k, v in d.data.items() if k != 'timestamp'}
            t_ns = np.asarray(d.data['timestamp'], np.int64) * 1000
            arrays[f'{d.name}[{d.multi_id}]'] = (t_ns, fields)
            if d.multi_id == 0:
                arrays[d.name] = (t_ns, fields)
        used, chosen = topic_map.resolve(set(arrays))
        if chosen:
            report['alternatives'] = chosen
        count = int(sum(len(arrays[t][0]) for t in used.topics if t in arrays))
        report['read'] = [count, 'messages']
        if progress is not None:
            progress(count)
        return [Part(from_arrays(arrays, used, report, 'log'))], used


def _base(topic: str) -> tuple[str, int]:
    match = _INSTANCE.match(topic)
    if not match:
        raise ConversionError(f'{topic!r} is not a ULog topic name (name or name[k])')
    return match['name'], int(match['instance'] or 0)
