"""
The predictor's inlet (what_if_c.inlet): its input topics read in the order they arrived.

Over DDS on a graph of its own: messages of two topics sent interleaved come back in the
order sent, stamped as received; a take waits for its timeout; destroying the inlet
wakes a take under way; names follow the node's namespace; bad topics are refused in
one line.
"""

import threading
import time

import pytest

from .conftest import wait_for

pytestmark = pytest.mark.ros
NAMESPACE = '/inlet_test'


@pytest.fixture
def nodes():
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context)
    reader = rclpy.create_node('inlet_reader', namespace=NAMESPACE, context=context)
    sender = rclpy.create_node('inlet_sender', context=context)
    yield reader, sender
    sender.destroy_node()
    reader.destroy_node()
    rclpy.try_shutdown(context=context)


def open_two(reader, sender, depth=100):
    """Return an inlet of 'words' (relative) and '/inlet_test/numbers', and their publishers."""
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Float64, String
    from what_if_c.inlet import open_inlet

    qos = QoSProfile(depth=depth)
    inlet = open_inlet(reader, [('words', String, qos), (f'{NAMESPACE}/numbers', Float64, qos)])
    publishers = (sender.create_publisher(String, f'{NAMESPACE}/words', depth),
                  sender.create_publisher(Float64, f'{NAMESPACE}/numbers', depth))
    assert wait_for(lambda: all(p.get_subscription_count() for p in publishers), 10)
    return inlet, publishers


def test_messages_of_two_topics_come_back_in_the_order_sent(nodes):
    from std_msgs.msg import Float64, String

    inlet, (words, numbers) = open_two(*nodes)
    try:
        # A backlog on one topic with the other's messages amid it, all queued before the
        # first take: a reader by topic would give every word first.
        sent = []
        for k in range(60):
            if k % 20 == 19:
                numbers.publish(Float64(data=float(k)))
                sent.append((1, float(k)))
            else:
                words.publish(String(data=str(k)))
                sent.append((0, str(k)))
            time.sleep(0.001)
        time.sleep(0.5)
        before = time.time_ns()
        taken = []
        while len(taken) < len(sent):
            batch = inlet.take(5.0)
            assert batch, taken
            taken += batch
        assert [(k, m.data) for k, m, _ in taken] == sent
        stamps = [r for _, _, r in taken]
        assert stamps == sorted(stamps) and 0 < stamps[0] and stamps[-1] < before
        assert inlet.take(0.0) == []
    finally:
        inlet.destroy()


def test_a_take_waits_its_timeout_and_destroying_wakes_it(nodes):
    inlet, _ = open_two(*nodes)
    started = time.monotonic()
    assert inlet.take(0.2) == []
    assert 0.15 < time.monotonic() - started < 5
    got = []
    taking = threading.Thread(target=lambda: got.append(inlet.take()))
    taking.start()
    time.sleep(0.3)
    assert taking.is_alive()   # waiting for ever, with the lock released
    inlet.destroy()
    taking.join(5)
    assert not taking.is_alive() and got == [None]
    assert inlet.take(0.0) is None
    inlet.destroy()   # twice is harmless


def test_a_closed_inlet_gives_none_and_its_subscriptions_go_on_destroy(nodes):
    reader, sender = nodes
    inlet, (words, _) = open_two(reader, sender)
    inlet.close()
    assert inlet.take(1.0) is None
    assert words.get_subscription_count() == 1
    inlet.destroy()
    assert wait_for(lambda: words.get_subscription_count() == 0, 10)


@pytest.mark.parametrize('topic, says', [
    (('words', 'not a class', 10, True), 'not a ROS message class'),
    (('words', None, 0, True), 'depth must be >= 1, got 0'),
    (('words',), 'takes exactly 4 arguments'),
])
def test_a_bad_topic_is_refused_in_one_line(nodes, topic, says):
    from std_msgs.msg import String
    from what_if_c._inlet import Inlet

    reader, _ = nodes
    topic = tuple(String if x is None else x for x in topic)
    with pytest.raises((TypeError, ValueError), match=says):
        Inlet(reader.handle.pointer, reader.context.handle.pointer, [topic])
    with pytest.raises(ValueError, match='at least one topic'):
        Inlet(reader.handle.pointer, reader.context.handle.pointer, [])


def test_an_inlet_refuses_a_history_it_cannot_keep(nodes):
    from rclpy.qos import HistoryPolicy, QoSProfile
    from std_msgs.msg import String
    from what_if_c.inlet import open_inlet

    with pytest.raises(ValueError, match='words: an inlet keeps the last messages only'):
        open_inlet(nodes[0], [('words', String, QoSProfile(history=HistoryPolicy.KEEP_ALL))])
