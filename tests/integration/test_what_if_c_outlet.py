"""
The predictor's outlet (what_if_c.outlet): its forecasts published without the lock.

Over DDS on a graph of its own: a subscriber receives exactly what the outlet sent, a
message of another type is refused in one line, and another Python thread runs while
rcl sends, where rclpy's own publish lets none run.
"""

import sys
import threading
import time

import pytest

from .conftest import wait_for

pytestmark = pytest.mark.ros
UNTIL_S = 10.0


@pytest.fixture
def graph():
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from hybrid_predictor_interfaces.msg import Forecast

    context = rclpy.Context()
    rclpy.init(context=context)
    sender = rclpy.create_node('outlet_sender', namespace='/outlet_test', context=context)
    receiver = rclpy.create_node('outlet_receiver', namespace='/outlet_test', context=context)
    received = []
    receiver.create_subscription(Forecast, '/outlet_test/forecast', received.append, 100)
    publisher = sender.create_publisher(Forecast, '/outlet_test/forecast', 100)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(receiver)
    spinning = threading.Thread(target=executor.spin, daemon=True)
    spinning.start()
    wait_for(publisher.get_subscription_count, 10.0)
    assert publisher.get_subscription_count() == 1
    yield publisher, received
    executor.shutdown()
    sender.destroy_node()
    receiver.destroy_node()
    rclpy.try_shutdown(context=context)


def forecast(k: int):
    """Return a Forecast the size of a quadrotor's (12 states x 100 steps, two bands)."""
    import numpy as np

    from hybrid_predictor.forecast_messages import doubles
    from hybrid_predictor_interfaces.msg import Forecast

    rng = np.random.default_rng(k)
    msg = Forecast(model_id=f'outlet test {k}', horizon=100, state_names=['u'] * 12)
    msg.hybrid, msg.physics = doubles(rng.normal(size=1200)), doubles(rng.normal(size=1200))
    msg.band_lower, msg.band_upper = doubles(rng.normal(size=2400)), doubles(rng.normal(size=2400))
    msg.x, msg.y, msg.z, msg.heading = (doubles(rng.normal(size=100)) for _ in range(4))
    return msg


def other_thread_progress(publish, messages, until_it_ran: bool = False) -> int:
    """
    Return how often another thread ran Python while ``publish`` sent ``messages``.

    The counting thread gives the interpreter lock back after every count and the switch
    interval is longer than the whole measurement, so it runs only when the publishing
    thread lets the lock go of its own accord. ``until_it_ran``: the messages are sent
    again and again until it did, for at most UNTIL_S (on a loaded machine a thread woken
    when the lock is let go may find it taken again).
    """
    counted, stop = [0], threading.Event()

    def count():
        while not stop.is_set():
            counted[0] += 1
            time.sleep(0)

    interval = sys.getswitchinterval()
    counting = threading.Thread(target=count)
    counting.start()
    time.sleep(0.05)
    sys.setswitchinterval(2 * UNTIL_S)
    try:
        # A wait for the lock the counter began under the old interval asks for the lock
        # after 5 ms, and gets it at the publishing thread's next bytecode: on a loaded
        # machine it counted once beside rclpy's publish (2 of 10 runs). Once the counter
        # has run under the new interval, its every wait is as long as the measurement.
        ran = counted[0]
        while counted[0] == ran:
            time.sleep(0.001)
        before, deadline = counted[0], time.monotonic() + UNTIL_S
        for msg in messages:
            publish(msg)
        while until_it_ran and counted[0] == before and time.monotonic() < deadline:
            for msg in messages:
                publish(msg)
        during = counted[0] - before
    finally:
        sys.setswitchinterval(interval)
        stop.set()
        counting.join()
    return during


def test_the_outlet_sends_what_rclpy_would_and_refuses_another_type(graph):
    from what_if_c.outlet import Outlet

    publisher, received = graph
    sent = [forecast(k) for k in range(5)]
    outlet = Outlet(publisher)
    for msg in sent:
        outlet.publish(msg)
    wait_for(lambda: len(received) >= len(sent), 10.0)
    assert received == sent
    with pytest.raises(TypeError, match='expected Forecast, got str'):
        outlet.publish('a forecast')


def test_other_threads_run_while_the_outlet_sends_and_not_while_rclpy_does(graph):
    from what_if_c.outlet import Outlet

    publisher, _ = graph
    messages = [forecast(k) for k in range(200)]
    # rclpy holds the interpreter lock through rcl's send: the counter cannot move.
    assert other_thread_progress(publisher.publish, messages) == 0
    assert other_thread_progress(Outlet(publisher).publish, messages, until_it_ran=True) > 0
