"""
The rosbag2 reader: bags (MCAP or sqlite3, damaged ones too) -> timed channels.

Discovery, recovery of damaged files and message types are ``bag_source``; this reader
checks the topic map against a bag's topics and types (choosing among alternatives
the first topic the bag has), reads the mapped fields of every message of those topics
(``extract.TopicExtractor``: learnt byte layouts, else rosbags) timed by header stamp
or log time, drops and counts NaN, duplicate and out-of-order samples, and hands the
samples to the pipeline. Other topics are never deserialized.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import os
from typing import Any

from ..bag_source import BagReader, MessageDefinitions, find_bags
from ..extract import TopicExtractor
from ..fields import FieldError, check_path, has_header_stamp, numeric_paths
from ..quantities import derive
from ..sources import ConversionError, Part, Recording
from ..topic_map import TopicMap

PROGRESS_EVERY = 20_000  # messages between progress callbacks


class BagRecordings:
    """Reader of rosbag2 recordings (``sources.Reader``); ``.msg`` files for custom types."""

    tool = 'bag_to_dataset'
    section = 'topics'

    def __init__(self, definitions: MessageDefinitions | None = None):
        self.definitions = definitions or MessageDefinitions()

    def find(self, paths: Iterable[str | os.PathLike]) -> list[Recording]:
        """Return the bags at the paths (``bag_source.find_bags``)."""
        return find_bags(paths)

    def config(self) -> dict[str, Any]:
        """Return the ``--msg-dir`` folders and ``--msg-package`` (for the manifest)."""
        return self.definitions.to_dict()

    def read(self, bag, topic_map: TopicMap, opts, report: dict,
             progress: Callable[[int], None] | None) -> tuple[list[Part], TopicMap]:
        """Read the mapped topics of one bag; raise ConversionError (one line)."""
        with BagReader(bag, self.definitions) as reader:
            report['losses'] = reader.losses  # what opening found; reading may add more
            used, chosen = topic_map.resolve(reader.topics)
            if chosen:
                report['alternatives'] = chosen
            report['notes'] += reader.notes
            report['notes'] += [line for line in reader.undecodable_lines()
                                if not any(line.startswith(f'topic {t} ') for t in used.topics)]
            extractors = _extractors(reader, used, opts.time_source, report)
            count = 0
            for topic, log_ns, raw in reader.messages(extractors):
                extractors[topic].add(log_ns, raw)
                count += 1
                if progress is not None and count % PROGRESS_EVERY == 0:
                    progress(PROGRESS_EVERY)
            if progress is not None:
                progress(count % PROGRESS_EVERY)
            report['losses'] = list(reader.losses)
        report['read'] = [count, 'messages']
        samples = []
        for topic, ex in extractors.items():
            s = ex.finish()
            samples.append(derive(s, used))
            entry = {'type': s.msgtype, 'received': s.received, 'kept': len(s.t_ns),
                     'dropped': s.dropped, 'unreadable': s.unreadable,
                     'time_source': 'header' if ex.use_header else 'log'}
            if ex.first_error:
                entry['first_error'] = ex.first_error
            report['sources'][topic] = entry
            if not len(s.t_ns):
                raise ConversionError(f'topic {topic} has no usable samples '
                                      f'({s.received} received, dropped {s.dropped}, '
                                      f'{s.unreadable} unreadable)')
        return [Part(samples)], used


def _extractors(reader: BagReader, topic_map: TopicMap, time_source: str,
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
        wanted = topic_map.stamps.get(topic, time_source)
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


def bag_to_runs(path, topic_map: TopicMap, definitions: MessageDefinitions | None = None,
                **options):
    """Run tables of the bags at ``path`` (tests, notebooks); raises ConversionError."""
    from ..pipeline import to_runs
    return to_runs(path, BagRecordings(definitions), topic_map, **options)


def convert_bag(bag, topic_map: TopicMap, definitions: MessageDefinitions | None = None,
                **options):
    """Convert one found bag with the default options (tests, notebooks): a Result."""
    from ..pipeline import Options, convert
    return convert(bag, BagRecordings(definitions), topic_map, Options.from_yaml(**options))
