"""
The nodes' MultiThreadedExecutor submits every ready task once (ros2/rclpy#1452).

rclpy 7.1's executor yields a task again while it waits in the thread pool's queue and
submits it again at once, in a loop that holds the GIL; this one must not. The verdict
counts submissions, it reads no clock.
"""

import threading
import time
import warnings

import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

pytestmark = pytest.mark.ros

BUSY_S = 0.05   # each callback keeps the only worker busy this long
RUN_S = 1.5


def test_a_task_waiting_for_a_worker_is_submitted_once():
    import rclpy
    from rclpy.callback_groups import MutuallyExclusiveCallbackGroup

    from vessel_ros_bridge.executors import MultiThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('executor_once', context=context)
    ran = {'a': 0, 'b': 0}

    def busy(name):
        ran[name] += 1
        time.sleep(BUSY_S)

    # Two timers in groups of their own and one worker: whenever one runs, the other's
    # task is ready and waits in the pool's queue.
    for name in ran:
        node.create_timer(BUSY_S / 2, lambda name=name: busy(name),
                          callback_group=MutuallyExclusiveCallbackGroup())
    with warnings.catch_warnings():   # one worker on purpose: rclpy warns about it
        warnings.simplefilter('ignore', UserWarning)
        executor = MultiThreadedExecutor(num_threads=1, context=context)
    submitted, queued, twice = [], set(), []
    lock = threading.Lock()
    pool_submit = executor._executor.submit

    def counting_submit(fn, task, *args):
        with lock:
            if task in queued:
                twice.append(task)
            queued.add(task)
            submitted.append(task)

        def run():
            with lock:
                queued.discard(task)
            fn(task, *args)
        return pool_submit(run)

    executor._executor.submit = counting_submit
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    time.sleep(RUN_S)
    executor.shutdown(timeout_sec=5)
    node.destroy_node()
    rclpy.try_shutdown(context=context)
    assert ran['a'] >= 3 and ran['b'] >= 3, ran    # both kept being served
    assert not twice, f'{len(twice)} of {len(submitted)} submissions were of a queued task'
    # Every submission ran a callback (the stock executor queues thousands that do not).
    assert len(submitted) <= ran['a'] + ran['b'] + 2, (len(submitted), ran)


# Every request queued is kept (the default keeps the newest 10), as the predictor does.
KEEP_ALL = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)


class DrainServer:
    """A service that refuses unread every request its ``admit`` predicate turns down."""

    def __init__(self, context, admit):
        import rclpy

        from hybrid_predictor_interfaces.srv import Predict
        from vessel_ros_bridge.executors import MultiThreadedExecutor
        from vessel_ros_bridge.lean_take import TAKEN, AdmittingType

        self.node = rclpy.create_node('drain_server', context=context)

        def answer(request, response):
            response.success = request is not TAKEN
            response.message = 'served' if response.success else 'busy'
            return response

        service = self.node.create_service(Predict, 'drain_test', answer,
                                           qos_profile=KEEP_ALL)
        service.srv_type = AdmittingType(Predict, admit)
        self.executor = MultiThreadedExecutor(num_threads=2, context=context)
        self.turns = 0   # takes begun by the executor: one per turn of the spinning thread
        take = self.executor._take_service

        def counted_take(srv):
            self.turns += 1
            return take(srv)
        self.executor._take_service = counted_take
        self.executor.add_node(self.node)


def answers_in_turns(admit, requests: int = 20) -> tuple[list[str], int]:
    """
    Return the answers' messages and the turns taken, for requests queued before serving.

    ``requests`` requests wait at a server that is not spinning; then it serves them.
    """
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from hybrid_predictor_interfaces.srv import Predict

    context = rclpy.Context()
    rclpy.init(context=context)
    server = DrainServer(context, admit)
    client_node = rclpy.create_node('drain_client', context=context)
    client = client_node.create_client(Predict, 'drain_test', qos_profile=KEEP_ALL)
    client_executor = SingleThreadedExecutor(context=context)
    client_executor.add_node(client_node)
    try:
        assert client.wait_for_service(timeout_sec=10)
        time.sleep(0.5)   # the server's response writer matches the client's reader
        futures = [client.call_async(Predict.Request()) for _ in range(requests)]
        time.sleep(1.0)   # every request waits in the server's queue
        spinner = threading.Thread(target=server.executor.spin, daemon=True)
        spinner.start()
        deadline = time.monotonic() + 20
        while not all(f.done() for f in futures) and time.monotonic() < deadline:
            client_executor.spin_once(timeout_sec=0.1)
        assert all(f.done() for f in futures), 'a request was not answered'
        return [f.result().message for f in futures], server.turns
    finally:
        server.executor.shutdown(timeout_sec=5)
        client_executor.shutdown(timeout_sec=5)
        server.node.destroy_node()
        client_node.destroy_node()
        rclpy.try_shutdown(context=context)


def test_requests_refused_unread_are_answered_in_one_turn():
    messages, turns = answers_in_turns(lambda: False)
    assert messages == ['busy'] * 20
    # rclpy takes one request a turn (20 turns); the rest of a turn's turns come from
    # requests arriving while it drains, none here.
    assert turns <= 2, turns


def test_a_request_to_serve_ends_the_turn_and_is_served():
    takes = iter(range(1000))
    messages, turns = answers_in_turns(lambda: next(takes) in (5, 12))
    assert messages.count('served') == 2 and messages.count('busy') == 18, messages
    assert turns <= 4, turns   # 0-5, 6-12, 13-19 and maybe one finding none left


def test_a_turn_answers_at_most_drain_limit_requests(monkeypatch):
    from vessel_ros_bridge import executors

    monkeypatch.setattr(executors, 'DRAIN_LIMIT', 4)
    messages, turns = answers_in_turns(lambda: False)
    assert messages == ['busy'] * 20
    assert turns >= 5, turns
