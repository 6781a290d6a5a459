r"""
Record ROS 2 topics into a rosbag2 MCAP directory (like `ros2 bag record -s mcap`).

Subscribes generically (serialized messages, no deserialization) to the given topics,
with each topic's type taken from the ROS graph, and writes a rosbag2 directory
(metadata.yaml + <name>_<i>.mcap with the message definitions embedded) that
`ros2 bag info`, Foxglove, the `mcap` CLI and offline/bag_to_dataset.py read. Topics
that have no publisher yet are subscribed when one appears. SIGINT (Ctrl-C) or SIGTERM
stops recording: messages already received are written and the bag is closed.
Progress goes to stderr.

Exit status: 0 after a clean stop, 1 if no requested topic was ever published, 2 on a
usage error. Set ROS_DOMAIN_ID / ROS_AUTOMATIC_DISCOVERY_RANGE as for any node.

Run it as, for instance,
  ros2 run vessel_recorder record --out trial1          # the simulator's topics
  ros2 run vessel_recorder record --topics /vessel/odom /imu/data --out trial2 \
      --max-bag-duration 3600
  python offline/record.py --out trial1                  # the same, from the repository
"""

import argparse
import importlib
import os
from pathlib import Path
import signal
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Nodetype

from vessel_datasets.bag_writer import BagWriterError, SplitBagWriter
from vessel_datasets.synthetic import SIM_TOPICS

EXIT_OK, EXIT_NOTHING, EXIT_USAGE = 0, 1, 2
DISCOVERY_PERIOD_S = 0.5   # how often the graph is searched for missing topics
DRAIN_TIMEOUT_S = 2.0      # after a stop signal, how long queued messages are taken
SPIN_TIMEOUT_S = 0.1       # executor wait; bounds the reaction time to a signal


def parse_args(argv):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--topics', nargs='+', default=list(SIM_TOPICS), metavar='TOPIC',
                        help='topics to record (default: ' + ' '.join(SIM_TOPICS) + ')')
    parser.add_argument('--out', required=True, metavar='DIR',
                        help='bag directory to create (must not exist or be empty)')
    parser.add_argument('--max-bag-size', type=int, default=0, metavar='BYTES',
                        help='start a new file when the current one reaches this size '
                             '(0: never)')
    parser.add_argument('--max-bag-duration', type=float, default=0.0, metavar='S',
                        help='start a new file after this many seconds (0: never)')
    parser.add_argument('--wait', type=float, default=10.0, metavar='S',
                        help='how long to wait for publishers before giving up if none '
                             'of the topics has one (default 10 s)')
    parser.add_argument('--progress-interval', type=float, default=5.0, metavar='S',
                        help='seconds between progress lines on stderr (0: none)')
    parser.add_argument('--use-sim-time', action='store_true',
                        help='time messages by /clock instead of the system clock')
    args = parser.parse_args(argv)
    if any(not t.startswith('/') for t in args.topics):
        parser.error('topics must be absolute names like /vessel/odom')
    if args.max_bag_size < 0 or args.max_bag_duration < 0 or args.wait < 0:
        parser.error('sizes, durations and waits must not be negative')
    return args


class Recorder:
    """Subscribe to topics as they appear and hand their serialized messages to a writer."""

    def __init__(self, node: Node, topics: list[str], writer_factory):
        self.node = node
        self.wanted = list(dict.fromkeys(topics))
        self.writer_factory = writer_factory
        self.writer: SplitBagWriter | None = None
        self.store = get_typestore(Stores.ROS2_JAZZY)
        self.subscriptions = {}
        self.refused: dict[str, str] = {}
        self.received = 0

    @property
    def missing(self) -> list[str]:
        """Return the requested topics not subscribed yet."""
        return [t for t in self.wanted if t not in self.subscriptions]

    def discover(self) -> None:
        """Subscribe to every requested topic that now has a publisher."""
        types = dict(self.node.get_topic_names_and_types())
        for topic in self.missing:
            if topic in self.refused or topic not in types:
                continue
            if not self.node.get_publishers_info_by_topic(topic):
                continue  # only subscribers so far: the type may not be final
            msgtype = types[topic][0]
            try:
                self._subscribe(topic, msgtype)
            except (ImportError, AttributeError, LookupError, OSError, BagWriterError,
                    ValueError) as exc:
                self.refused[topic] = str(exc)
                log(f'cannot record {topic} ({msgtype}): {exc}')

    def _subscribe(self, topic: str, msgtype: str) -> None:
        pkg, _, name = msgtype.split('/')
        cls = getattr(importlib.import_module(f'{pkg}.msg'), name)
        ensure_definition(self.store, msgtype)
        infos = self.node.get_publishers_info_by_topic(topic)
        qos = subscription_qos([i.qos_profile for i in infos])
        if self.writer is None:
            self.writer = self.writer_factory(self.store)
        self.writer.add_topic(topic, msgtype, [to_bag_qos(i.qos_profile) for i in infos])

        def on_message(data: bytes, topic=topic) -> None:
            self.writer.write(topic, self.node.get_clock().now().nanoseconds, data)
            self.received += 1

        self.subscriptions[topic] = self.node.create_subscription(cls, topic, on_message, qos,
                                                                  raw=True)
        log(f'recording {topic} ({msgtype})')

    def close(self) -> None:
        """Write what was received and close the bag."""
        if self.writer is not None:
            self.writer.close()


def ensure_definition(store, msgtype: str) -> None:
    """
    Make sure ``store`` knows ``msgtype``, loading .msg files of installed packages.

    ROS 2 Jazzy's standard types are built in; a custom type's definition is read from
    its package's share directory so the bag embeds it.
    """
    if msgtype in store.fielddefs:
        return
    from ament_index_python.packages import get_package_share_directory
    pkg, _, name = msgtype.split('/')
    path = Path(get_package_share_directory(pkg)) / 'msg' / f'{name}.msg'
    typs = get_types_from_msg(path.read_text(), msgtype)
    for _, desc in typs[msgtype][1]:
        for nested in _nested_names(desc):
            ensure_definition(store, nested)
    store.register(typs)


def _nested_names(desc):
    kind, detail = desc
    if kind == Nodetype.NAME:
        yield detail
    elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        yield from _nested_names(detail[0])


def subscription_qos(offered) -> QoSProfile:
    """Return a QoS matching every publisher: reliable/transient only if all offer it."""
    reliable = all(p.reliability == ReliabilityPolicy.RELIABLE for p in offered)
    latched = bool(offered) and all(p.durability == DurabilityPolicy.TRANSIENT_LOCAL
                                    for p in offered)
    # KEEP_ALL: a slow write never makes the middleware discard a received message.
    return QoSProfile(history=HistoryPolicy.KEEP_ALL,
                      reliability=(ReliabilityPolicy.RELIABLE if reliable
                                   else ReliabilityPolicy.BEST_EFFORT),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


def to_bag_qos(profile) -> Qos:
    """Convert a publisher's QoS to rosbags' form (the topic's offered QoS in the bag)."""
    def duration(d):
        ns = d.nanoseconds
        return QosTime(ns // 1_000_000_000, ns % 1_000_000_000)

    return Qos(history=QosHistory(int(profile.history)), depth=int(profile.depth),
               reliability=QosReliability(int(profile.reliability)),
               durability=QosDurability(int(profile.durability)),
               deadline=duration(profile.deadline), lifespan=duration(profile.lifespan),
               liveliness=QosLiveliness(int(profile.liveliness)),
               liveliness_lease_duration=duration(profile.liveliness_lease_duration),
               avoid_ros_namespace_conventions=bool(
                   profile.avoid_ros_namespace_conventions))


def log(text: str) -> None:
    """One line to stderr."""
    print(f'[record] {text}', file=sys.stderr, flush=True)


def main(argv=None) -> int:
    """Record until SIGINT/SIGTERM; return the exit status."""
    # `ros2 run` and launch may append --ros-args ...; they are not ours to parse.
    args = parse_args(remove_ros_args(sys.argv)[1:] if argv is None else argv)
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        log(f'error: {out} exists and is not an empty directory')
        return EXIT_USAGE
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))

    rclpy.init(args=None, signal_handler_options=SignalHandlerOptions.NO)
    overrides = [Parameter('use_sim_time', value=True)] if args.use_sim_time else []
    node = Node(f'bag_recorder_{os.getpid()}', parameter_overrides=overrides)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    recorder = Recorder(node, args.topics, lambda store: SplitBagWriter(
        out, store, max_bytes=args.max_bag_size or None,
        max_duration_ns=int(args.max_bag_duration * 1e9) or None))
    status = EXIT_OK
    log(f'waiting for publishers on {" ".join(recorder.wanted)}')
    try:
        status = _record(args, executor, recorder, stop)
    finally:
        recorder.close()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    if recorder.writer is not None:
        log(f'wrote {recorder.writer.message_count} messages to {out} '
            f'({", ".join(p.name for p in recorder.writer.files)})')
    return status


def _record(args, executor, recorder: Recorder, stop: list) -> int:
    start = time.monotonic()
    next_discovery = next_progress = start
    warned = False
    while not stop:
        now = time.monotonic()
        if recorder.missing and now >= next_discovery:
            recorder.discover()
            next_discovery = now + DISCOVERY_PERIOD_S
        if now - start > args.wait and not warned and recorder.missing:
            warned = True
            if not recorder.subscriptions:
                graph = ', '.join(f'{n} ({t[0]})' for n, t in
                                  recorder.node.get_topic_names_and_types()) or 'no topics'
                log(f'error: no publisher on {" ".join(recorder.wanted)} after '
                    f'{args.wait:g} s; the graph has: {graph}')
                return EXIT_NOTHING
            log(f'not published (yet): {" ".join(recorder.missing)}; recording the others '
                f'and subscribing when they appear')
        if args.progress_interval and now >= next_progress and recorder.writer:
            log(f'{recorder.received} messages recorded ' + ', '.join(
                f'{t} {n}' for t, n in recorder.writer.counts.items()))
            next_progress = now + args.progress_interval
        executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
    # Take what already arrived before closing: nothing received is lost.
    deadline = time.monotonic() + DRAIN_TIMEOUT_S
    before = -1
    while recorder.received != before and time.monotonic() < deadline:
        before = recorder.received
        executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
    log(f'stopping on {signal.Signals(stop[0]).name}: {recorder.received} messages received')
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
