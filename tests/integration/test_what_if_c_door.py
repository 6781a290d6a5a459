"""
The predictor's what-if door (what_if_c.door) on a node of its own, over DDS.

A Predict service whose admitted requests a test thread answers: the door admits at
most its capacity, answers every other request "busy" itself with the time to come
back, refuses answers it did not ask for, and stops cleanly.
"""

from contextlib import contextmanager
import threading
import time

import pytest

pytestmark = pytest.mark.ros

SERVICE = '/what_if_door_test/door/predict'
HOLD_S = 0.4   # each admitted request is answered this long after it was taken


@pytest.fixture
def graph():
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    context = rclpy.Context()
    rclpy.init(context=context)
    server = rclpy.create_node('door', namespace='/what_if_door_test', context=context)
    client = rclpy.create_node('door_client', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(client)
    yield server, client, executor
    client.destroy_node()
    server.destroy_node()
    rclpy.try_shutdown(context=context)


@contextmanager
def serving(server, capacity: int):
    """
    Yield a door on ``server`` and the tokens of the requests it admitted.

    Each admitted request is answered HOLD_S after it was taken, saying how many plans it
    had; afterwards the door is closed and its taking thread must have ended (take()
    gives None once the door is closed).
    """
    from what_if_c.door import open_door

    from hybrid_predictor_interfaces.srv import Predict

    door = open_door(server, '~/predict', capacity, 5.0)
    tokens = []

    def serve():
        while (taken := door.take()) is not None:
            token, request = taken
            tokens.append(token)
            time.sleep(HOLD_S)
            try:
                door.answer(token, Predict.Response(success=True,
                                                    message=f'{len(request.plans)} plans'))
            except RuntimeError as exc:   # closed meanwhile, as the node's pool may see it
                assert str(exc) == 'the door is closed'
                return

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield door, tokens
    finally:
        door.close()
    thread.join(timeout=5)
    assert not thread.is_alive()


def call_all(client_node, executor, requests: int, plans: int = 3) -> list:
    from hybrid_predictor_interfaces.msg import ControlPlan
    from hybrid_predictor_interfaces.srv import Predict

    client = client_node.create_client(Predict, SERVICE)
    assert client.wait_for_service(timeout_sec=10)
    request = Predict.Request(plans=[ControlPlan(plan_id='p')] * plans)
    futures = [client.call_async(request) for _ in range(requests)]
    deadline = time.monotonic() + 20
    while not all(f.done() for f in futures) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    assert all(f.done() for f in futures), 'requests left unanswered'
    return [f.result() for f in futures]


def test_the_door_admits_its_capacity_and_refuses_the_rest_with_a_time(graph):
    server, client, executor = graph
    with serving(server, 1) as (door, held):
        answers = call_all(client, executor, 6)
    served = [a for a in answers if a.success]
    busy = [a for a in answers if not a.success]
    # One at a time: the first is served, the burst behind it refused, each later
    # refused client told a later time, none longer than 5 s.
    assert served and all(a.message == '3 plans' and a.retry_after == 0 for a in served)
    assert busy and all(a.message.startswith('busy: 1 requests in progress; retry in ')
                        for a in busy)
    hints = [a.retry_after for a in busy]
    assert all(0 < h <= 5.0 for h in hints) and len(set(hints)) == len(hints), hints
    assert door.counts() == {'requests': 6, 'refused': len(busy)}
    assert door.failure is None and len(held) == len(served)


def test_the_door_refuses_answers_it_did_not_ask_for(graph):
    from hybrid_predictor_interfaces.srv import Predict

    server, client, executor = graph
    with serving(server, 2) as (door, tokens):
        assert all(a.success for a in call_all(client, executor, 1))
        thread_token = tokens[0]
        with pytest.raises(ValueError, match='no request in progress has token'):
            door.answer(thread_token, Predict.Response(success=True))   # answered already
        with pytest.raises(TypeError, match='Response'):
            door.answer(thread_token, Predict.Request())
    assert door.take() is None
    with pytest.raises(RuntimeError, match='the door is closed'):
        door.answer(thread_token, Predict.Response())


@pytest.mark.parametrize('capacity, longest, says', [
    (0, 5.0, 'capacity must be in'), (65, 5.0, 'capacity must be in'),
    (1, 0.0, 'longest must be > 0'),
])
def test_bad_settings_are_refused_before_the_service_exists(graph, capacity, longest, says):
    from what_if_c.door import open_door

    server, _, _ = graph
    with pytest.raises(ValueError, match=says):
        open_door(server, '~/predict', capacity, longest)
    assert SERVICE not in dict(server.get_service_names_and_types())


def test_closing_while_requests_keep_coming_neither_crashes_nor_hangs(graph):
    from hybrid_predictor_interfaces.srv import Predict

    server, client_node, executor = graph
    client = client_node.create_client(Predict, SERVICE)
    with serving(server, 2) as (door, tokens):
        assert client.wait_for_service(timeout_sec=10)
        futures = [client.call_async(Predict.Request()) for _ in range(60)]
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.02)
    # Closed with requests queued, admitted and in transport (serving checked that the
    # taking thread ended); what was answered was answered whole.
    counts = door.counts()
    answered = [f.result() for f in futures if f.done()]
    assert counts['requests'] <= 60 and counts['refused'] <= counts['requests']
    assert all(a.success or a.message.startswith('busy') for a in answered)
    assert door.take() is None and door.failure is None


def test_a_door_for_another_service_type_is_refused(graph):
    from rclpy.type_support import check_for_type_support
    from std_srvs.srv import Trigger
    from what_if_c.door import Door

    server, _, _ = graph
    check_for_type_support(Trigger)
    with pytest.raises(TypeError, match='Predict only'):
        Door(server.handle.pointer, server.context.handle.pointer, '~/predict', Trigger, 1, 5.0)
    assert SERVICE not in dict(server.get_service_names_and_types())
