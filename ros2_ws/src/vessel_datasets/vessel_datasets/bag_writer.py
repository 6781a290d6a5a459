"""
Write a rosbag2 MCAP directory from serialized messages, split by size or duration.

Each split file is written by rosbags' ``Writer`` (MCAP storage: message definitions
embedded as ``ros2msg``, CDR payloads, summary and index), so ``ros2 bag info``,
Foxglove and the ``mcap`` CLI read it. rosbags writes one file per directory; this
module writes each split into a scratch subdirectory and, when the split is complete,
moves the file up as ``<name>_<index>.mcap`` and rewrites the bag's ``metadata.yaml``
to list every complete file. A recorder that dies therefore leaves a valid bag of the
complete splits plus one unlisted, unfinished file, which ``bag_source`` recovers.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import os
from pathlib import Path
import shutil

from rosbags.interfaces import Qos
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys.store import Typestore
import yaml

METADATA = 'metadata.yaml'
RECORD_OVERHEAD_BYTES = 47  # per message: MCAP record header (31) + message index entry (16)
SUMMARY_OVERHEAD_BYTES = 1024  # header, footer, statistics and indexes of one file
TOPIC_OVERHEAD_BYTES = 600  # its channel records and its entry in the embedded metadata


class BagWriterError(ValueError):
    """The output cannot be written (exists, unknown topic or type)."""


@dataclass
class _Topic:
    name: str
    msgtype: str
    qos: tuple[Qos, ...]


class SplitBagWriter:
    """
    Write serialized messages into a rosbag2 directory, splitting files as asked.

    ``max_bytes`` and ``max_duration_ns`` (of log time) start a new file when reached;
    None never splits. Topics may be added at any time (a publisher appearing late).
    """

    def __init__(self, out: str | os.PathLike, store: Typestore, *,
                 max_bytes: int | None = None, max_duration_ns: int | None = None):
        self.out = Path(out)
        if self.out.exists() and any(self.out.iterdir()):
            raise BagWriterError(f'{self.out} exists and is not empty; rosbag2 will not '
                                 f'record into it')
        self.out.mkdir(parents=True, exist_ok=True)
        self.name = self.out.name
        self.store = store
        self.max_bytes = max_bytes
        self.max_duration_ns = max_duration_ns
        self.topics: dict[str, _Topic] = {}
        self.counts: dict[str, int] = {}
        self._infos: list[dict] = []  # metadata of the completed splits
        self._writer: Writer | None = None
        self._conns: dict = {}
        self._index = 0
        self._split_bytes = 0
        self._split_start: int | None = None

    @property
    def message_count(self) -> int:
        """Messages written so far."""
        return sum(self.counts.values())

    @property
    def files(self) -> list[Path]:
        """Completed split files."""
        return [self.out / p for info in self._infos for p in info['relative_file_paths']]

    def add_topic(self, topic: str, msgtype: str, qos: Sequence[Qos] = ()) -> None:
        """Register a topic; its type must be in the typestore (definitions are embedded)."""
        if topic in self.topics:
            return
        if msgtype not in self.store.fielddefs:
            raise BagWriterError(f'no message definition for {msgtype} (topic {topic})')
        self.topics[topic] = _Topic(topic, msgtype, tuple(qos))
        self.counts[topic] = 0
        if self._writer is not None:
            self._connect(self.topics[topic])

    def write(self, topic: str, log_ns: int, data: bytes | memoryview) -> None:
        """Append one serialized (CDR) message received at ``log_ns``."""
        if self._writer is not None and self._split_due(log_ns, len(data)):
            self._finish_split()
        if self._writer is None:
            self._open_split(log_ns)
        self._writer.write(self._conns[topic], log_ns, data)
        self.counts[topic] += 1
        self._split_bytes += len(data) + RECORD_OVERHEAD_BYTES

    def close(self) -> None:
        """Finish the open split and write the final metadata.yaml."""
        if self._writer is not None:
            self._finish_split()
        elif not self._infos:
            self._write_metadata()  # an empty but valid bag

    def _split_due(self, log_ns: int, size: int) -> bool:
        if self.max_bytes and self._split_bytes and \
                self._split_bytes + size + RECORD_OVERHEAD_BYTES > self.max_bytes:
            return True
        return bool(self.max_duration_ns and self._split_start is not None
                    and log_ns - self._split_start >= self.max_duration_ns)

    def _scratch(self) -> Path:
        return self.out / f'{self.name}_{self._index}'

    def _open_split(self, log_ns: int) -> None:
        self._writer = Writer(self._scratch(), version=Writer.VERSION_LATEST,
                              storage_plugin=StoragePlugin.MCAP)
        self._writer.open()
        self._conns = {}
        self._split_bytes = SUMMARY_OVERHEAD_BYTES
        for topic in self.topics.values():
            self._connect(topic)
        self._split_start = log_ns

    def _connect(self, topic: _Topic) -> None:
        self._conns[topic.name] = conn = self._writer.add_connection(
            topic.name, topic.msgtype, typestore=self.store,
            offered_qos_profiles=list(topic.qos))
        # Each file holds every definition twice: before its messages and in its summary.
        self._split_bytes += 2 * len(conn.msgdef.data) + TOPIC_OVERHEAD_BYTES

    def _finish_split(self) -> None:
        writer, self._writer = self._writer, None
        writer.close()
        scratch = self._scratch()
        info = yaml.safe_load((scratch / METADATA).read_text())['rosbag2_bagfile_information']
        for rel in info['relative_file_paths']:
            (scratch / rel).replace(self.out / rel)
        shutil.rmtree(scratch)
        self._infos.append(info)
        self._index += 1
        self._write_metadata()

    def _write_metadata(self) -> None:
        """Merge the splits' metadata into the bag's, written atomically."""
        infos = self._infos
        starts = [i['starting_time']['nanoseconds_since_epoch'] for i in infos
                  if i['message_count']]
        ends = [i['starting_time']['nanoseconds_since_epoch'] + i['duration']['nanoseconds']
                for i in infos if i['message_count']]
        topics: dict[str, dict] = {}
        for info in infos:
            for entry in info['topics_with_message_count']:
                name = entry['topic_metadata']['name']
                if name in topics:
                    topics[name]['message_count'] += entry['message_count']
                else:
                    topics[name] = {'topic_metadata': entry['topic_metadata'],
                                    'message_count': entry['message_count']}
        merged = {
            'version': infos[-1]['version'] if infos else Writer.VERSION_LATEST,
            'storage_identifier': 'mcap',
            'relative_file_paths': [p for i in infos for p in i['relative_file_paths']],
            'duration': {'nanoseconds': (max(ends) - min(starts)) if starts else 0},
            'starting_time': {'nanoseconds_since_epoch': min(starts) if starts else 0},
            'message_count': sum(i['message_count'] for i in infos),
            'topics_with_message_count': list(topics.values()),
            'compression_format': '',
            'compression_mode': '',
            'files': [f for i in infos for f in i['files']],
            'custom_data': None,
            'ros_distro': infos[-1].get('ros_distro', 'rosbags') if infos else 'rosbags',
        }
        tmp = self.out / (METADATA + '.tmp')
        tmp.write_text(yaml.safe_dump({'rosbag2_bagfile_information': merged},
                                      sort_keys=False))
        tmp.replace(self.out / METADATA)
