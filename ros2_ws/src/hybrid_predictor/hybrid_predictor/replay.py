"""
Replay a run of a dataset over DDS as the vehicle's own messages, and keep what was sent.

A dataset run (model frames, one row per sample) is written back into the messages its
vehicle file's topic map names (``vessel_datasets.topic_messages``, the inverse of
conversion), stamped on the run's own clock from ``start`` (a sensor's stamps, whatever
the sending process's scheduling adds), and published at the vehicle's rate. What was
sent is kept as the predictor reads it (its channel values by topic and stamp), so
``hybrid_predictor.re_forecast.ReForecast`` can recompute every forecast offline.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
import time

import pandas as pd

from vessel_datasets.topic_map import TopicMap
from vessel_datasets.topic_messages import MessageWriter, channel_reader, channel_values
from vessel_ros_bridge.messages import stamp_from_seconds


class RunReplay:
    """Publishers of a topic map's messages on a node, and the samples they sent."""

    def __init__(self, node, topic_map: TopicMap, types: Mapping[str, Callable],
                 depth: int = 100):
        self.topic_map = topic_map
        self.writer = MessageWriter(topic_map, types)
        self.publishers = {t: node.create_publisher(self.writer.types[t], t, depth)
                           for t in self.writer.topics}
        self.readers = {t: channel_reader(topic_map, t) for t in self.writer.topics}
        self.sent: list[tuple[float, str, dict]] = []   # (stamp s, topic, channel values)

    def play(self, table: pd.DataFrame, start: float, wait: Callable[[float], None],
             rate_hz: float | None = None,
             before_row: Callable[[int, float], None] | None = None) -> None:
        """
        Publish every row of ``table`` at ``rate_hz`` (the vehicle's), stamped from ``start``.

        ``wait(seconds)`` is called while the next row is not due (spin an executor
        there); row k is stamped ``start + k / rate_hz`` seconds; ``before_row(k, stamp)``,
        if given, is called just before its messages go (e.g. a controller's plan), which
        are made before the row is due.
        """
        rate = rate_hz or self.topic_map.vessel.rate_hz
        began = time.monotonic()
        for k, row in enumerate(table.to_dict('records')):
            stamp_s = start + k / rate
            # Made before the row is due: at its time the messages are only published,
            # as a sensor's driver sends what it has measured.
            channels = channel_values(row, self.topic_map)
            messages = [(topic, self.writer.message(topic, channels, stamp_from_seconds(
                stamp_s))) for topic in self.writer.topics]
            while (due := k / rate - (time.monotonic() - began)) > 0:
                wait(min(due, 0.001))
            if before_row is not None:
                before_row(k, stamp_s)
            for topic, msg in messages:
                self.publishers[topic].publish(msg)
            self.sent.extend((stamp_s, topic, self.readers[topic](msg))
                             for topic, msg in messages)
