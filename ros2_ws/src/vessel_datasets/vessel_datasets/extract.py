"""
Turn one topic's raw messages into a clean, time-ordered table of numbers.

The mapped fields are read in batches, through a learnt byte layout where messages
share one (``layout``) and by the bag's typestore otherwise (``fields.compile_getter``);
the sample's time is its header stamp or its log time.
Cleaning then drops, and counts, samples with a NaN/Inf or absent field, samples whose
stamp equals the newest accepted one (duplicate) and samples older than it
(out of order), processing messages in the order they were received (log time).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import layout
from .fields import compile_getter
from .topic_map import Leaf

DROP_REASONS = ('nan', 'duplicate', 'out_of_order')
STAMP_PATHS = ('header.stamp.sec', 'header.stamp.nanosec')
BATCH = 50_000  # messages read together; bounds the raw bytes held per topic
MIN_LAYOUT_GROUP = 32  # fewer same-length messages than this are not worth a layout


@dataclass
class TopicSamples:
    """Clean samples of one topic: strictly increasing times and finite values."""

    topic: str
    msgtype: str
    channels: tuple[str, ...]
    t_ns: np.ndarray          # int64, sample times (ns)
    values: np.ndarray        # float64, (n, len(channels)), scaled, in the message's frame
    received: int = 0         # messages read
    dropped: dict[str, int] = field(default_factory=dict)
    unreadable: int = 0       # messages that failed to deserialize

    def column(self, channel: str) -> np.ndarray:
        """One channel's values."""
        return self.values[:, self.channels.index(channel)]


class TopicExtractor:
    """
    Collect the mapped fields of one topic.

    Messages are buffered and read in batches: those sharing a learnt byte layout are
    read with numpy (``layout``), the others deserialized one by one by rosbags. Both
    give the same numbers; ``fast=False`` uses rosbags for every message.
    """

    def __init__(self, topic: str, msgtype: str, leaves: list[Leaf], typestore,
                 use_header: bool, fast: bool = True):
        self.topic = topic
        self.msgtype = msgtype
        self.leaves = leaves
        self.use_header = use_header
        self.fast = fast
        self._store = typestore
        self._getters = tuple(compile_getter(leaf.path) for leaf in leaves)
        self._paths = [leaf.path for leaf in leaves] + (list(STAMP_PATHS) if use_header else [])
        self._layouts: dict[int, layout.Layout | None] = {}
        self._raws: list[bytes] = []
        self._logs: list[int] = []
        self._batches: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.unreadable = 0
        self.first_error: str | None = None

    def add(self, log_ns: int, raw: bytes) -> None:
        """Queue one message received at ``log_ns``."""
        self._raws.append(raw)
        self._logs.append(log_ns)
        if len(self._raws) >= BATCH:
            self._flush()

    def _flush(self) -> None:
        raws, logs = self._raws, np.asarray(self._logs, dtype=np.int64)
        self._raws, self._logs = [], []
        n, k = len(raws), len(self._paths)
        values = np.empty((n, k))
        ok = np.zeros(n, dtype=bool)
        slow = []
        groups: dict[int, list[int]] = {}
        for i, raw in enumerate(raws):
            groups.setdefault(len(raw), []).append(i)
        for length, idx in groups.items():
            found = self._layout(length, raws[idx[0]]) if self.fast and \
                len(idx) >= MIN_LAYOUT_GROUP else None
            if found is None:
                slow += idx
                continue
            match, read = layout.read(found, [raws[i] for i in idx])
            idx = np.asarray(idx)
            values[idx[match]] = read
            ok[idx[match]] = True
            slow += idx[~match].tolist()
        for i in slow:
            row = self._deserialize(raws[i])
            if row is not None:
                values[i], ok[i] = row, True
        if self.use_header:
            stamps = values[:, -2].astype(np.int64) * 1_000_000_000 + \
                values[:, -1].astype(np.int64)
            values = values[:, :-2]
        else:
            stamps = logs
        self._batches.append((logs[ok], stamps[ok], values[ok]))

    def _layout(self, length: int, raw: bytes) -> layout.Layout | None:
        if length not in self._layouts:
            try:
                self._layouts[length] = layout.learn(raw, self.msgtype, self._paths,
                                                     self._store)
            except Exception:  # noqa: BLE001 - no layout: every message takes the slow path
                self._layouts[length] = None
        return self._layouts[length]

    def _deserialize(self, raw: bytes) -> list[float] | None:
        """Read one message with rosbags; None (and counted) if it cannot be read."""
        try:
            msg = self._store.deserialize_cdr(raw, self.msgtype)
            row = [float(get(msg)) for get in self._getters]
            if self.use_header:
                row += [msg.header.stamp.sec, msg.header.stamp.nanosec]
        except Exception as exc:  # noqa: BLE001 - a corrupt message must not stop the bag
            self.unreadable += 1
            if self.first_error is None:
                self.first_error = f'{type(exc).__name__}: {exc}'
            return None
        return row

    def finish(self) -> TopicSamples:
        """Scale, order by log time and clean the collected samples."""
        if self._raws:
            self._flush()
        k = len(self.leaves)
        empty = (np.empty(0, np.int64), np.empty(0, np.int64), np.empty((0, k)))
        log, stamp, values = (np.concatenate(parts) for parts in
                              zip(*self._batches, strict=True)) if self._batches else empty
        scale = np.array([leaf.scale for leaf in self.leaves])
        offset = np.array([leaf.offset for leaf in self.leaves])
        values = values * scale + offset
        order = np.argsort(log, kind='stable')  # files may come in any order
        t, values, dropped = clean(stamp[order], values[order])
        return TopicSamples(self.topic, self.msgtype, tuple(leaf.channel for leaf in self.leaves),
                            t, values, received=len(log) + self.unreadable, dropped=dropped,
                            unreadable=self.unreadable)


def clean(t_ns: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, dict]:
    """
    Drop non-finite, duplicate and out-of-order samples (given in arrival order).

    A sample is kept if all its values are finite and its time is later than every
    earlier kept sample's. Returns the kept times, values and the count per reason.
    """
    finite = np.isfinite(values).all(axis=1) if values.size else np.ones(len(t_ns), bool)
    t_ok = t_ns[finite]
    # The newest kept time before each sample equals the running maximum of all earlier
    # finite samples: a rejected sample never exceeds it, so it cannot raise it.
    before = np.empty_like(t_ok)
    if len(t_ok):
        before[0] = np.iinfo(np.int64).min
        before[1:] = np.maximum.accumulate(t_ok)[:-1]
    duplicate = t_ok == before
    older = t_ok < before
    keep = ~(duplicate | older)
    dropped = {'nan': int((~finite).sum()), 'duplicate': int(duplicate.sum()),
               'out_of_order': int(older.sum())}
    return t_ok[keep], values[finite][keep], dropped
