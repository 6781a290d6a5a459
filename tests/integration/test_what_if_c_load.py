"""
The soak's C clients (package what_if_c.load) against a stand-in Predict service, over DDS.

The stand-in answers in turn busy, with success and with a refusal, and counts what it
was sent; the clients' figures must agree with it kind by kind, in the format the soak
merges (offline/benchmarks/soak.py, Load.raw()).
"""

import json
import subprocess
import sys
import threading

import pytest

from .conftest import child_environment, wait_for

pytestmark = pytest.mark.ros

SERVICE = '/what_if_load_test/predict'
REFUSAL = 'plan 0 refused: a reason longer than the sixty characters a failure is kept by'


def success_answer():
    """Return the stand-in's successful answer: two forecasts of 500 steps."""
    from hybrid_predictor_interfaces.msg import Forecast
    from hybrid_predictor_interfaces.srv import Predict

    return Predict.Response(success=True, forecasts=[Forecast(hybrid=[1.0] * 500)] * 2)


class StandIn:
    """A Predict service answering busy, success and refused in turn; counts each kind."""

    KINDS = ('busy', 'success', 'refused')

    def __init__(self):
        import rclpy
        from rclpy.executors import SingleThreadedExecutor

        from hybrid_predictor_interfaces.srv import Predict

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('what_if_load_stand_in', context=self.context)
        self.counts = dict.fromkeys(self.KINDS, 0)
        self.requests = []   # (plans, answer_period) of each request
        self.node.create_service(Predict, SERVICE, self._answer)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _answer(self, request, response):
        kind = self.KINDS[len(self.requests) % len(self.KINDS)]
        self.requests.append((len(request.plans), request.answer_period))
        self.counts[kind] += 1
        response.success = kind == 'success'
        if response.success:
            response.forecasts = success_answer().forecasts
        if kind == 'busy':
            response.message, response.retry_after = 'busy: 1 requests in progress', 0.05
        elif kind == 'refused':
            response.message = REFUSAL
        return response

    def close(self):
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def load_command(tmp_path, *options):
    return [sys.executable, '-m', 'what_if_c.load', '--service', SERVICE,
            '--request', str(tmp_path / 'request.cdr'), '--dir', str(tmp_path),
            '--name', 'c0', *options]


def test_the_c_clients_count_every_answer_as_the_service_gave_it(tmp_path):
    from rclpy.serialization import serialize_message

    from hybrid_predictor_interfaces.msg import ControlPlan
    from hybrid_predictor_interfaces.srv import Predict

    request = Predict.Request(plans=[ControlPlan(plan_id='p', values=[1.0, 2.0])] * 3,
                              answer_period=10.0)
    (tmp_path / 'request.cdr').write_bytes(serialize_message(request))
    stand_in = StandIn()
    process = subprocess.Popen(
        load_command(tmp_path, '--clients', '2', '--concurrency', '3',
                     '--busy-backoff', '0.05', '--settle', '5'),
        env=child_environment(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert wait_for(lambda: (tmp_path / 'c0.ready').exists(), 30), process.poll()
        (tmp_path / 'start.tmp').write_text('1.0')
        (tmp_path / 'start.tmp').rename(tmp_path / 'start')
        assert process.wait(timeout=40) == 0, process.stdout.read()
    finally:
        if process.poll() is None:
            process.kill()
        stand_in.close()
    raw = json.loads((tmp_path / 'c0.json').read_text())
    counts = stand_in.counts
    # Every request the clients sent reached the service whole, and came back.
    assert raw['sent'] == len(stand_in.requests) > 10, (raw['sent'], counts)
    assert set(stand_in.requests) == {(3, 10.0)}
    assert (raw['busy'], raw['success'], raw['failed']) == (
        counts['busy'], counts['success'], counts['refused'])
    assert raw['failures'] == {REFUSAL[:60]: counts['refused']}   # as the Python clients key
    assert len(raw['latencies']) == raw['sent']
    assert len(raw['busy_latencies']) == len(raw['busy_stages']) == raw['busy']
    assert len(raw['success_latencies']) == raw['success']
    assert all(0 < x < 5 for x in raw['latencies'])
    # A busy answer's stages, on the one clock of this machine: (sent, written by the
    # service, received, take begun, taken, done). Each event causes the next but one:
    # a take that begins while DDS is still delivering the answer waits for it, so its
    # beginning may precede the answer's receipt (by 73 us in a CI run), never its taking.
    for stages in raw['busy_stages']:
        sent, written, received, begun, taken, done = stages
        assert sent <= written <= received <= taken <= done and begun <= taken, stages
    assert raw['request_kb'] == round(len(serialize_message(request)) / 1e3, 1)
    assert raw['success_answer_kb'] == round(len(serialize_message(success_answer())) / 1e3, 1)
    assert raw['success_answer_kb'] > 8


@pytest.mark.parametrize('options, says', [
    (['--clients', '0', '--concurrency', '1', '--busy-backoff', '0.2'],
     "--clients takes an integer in [1, 64], got '0'"),
    (['--clients', '1', '--concurrency', '1', '--busy-backoff', 'soon'],
     "--busy-backoff takes seconds >= 0, got 'soon'"),
    (['--clients', '1', '--concurrency', '1'], '--busy-backoff is required'),
])
def test_a_bad_command_line_is_refused_with_one_line(tmp_path, options, says):
    (tmp_path / 'request.cdr').write_bytes(b'\0\1\0\0')
    done = subprocess.run(load_command(tmp_path, *options), env=child_environment(),
                          capture_output=True, text=True, timeout=30)
    assert done.returncode == 2
    assert done.stderr.splitlines()[0] == f'what_if_c.load: error: {says}'


def test_help_says_what_the_clients_do():
    done = subprocess.run([sys.executable, '-m', 'what_if_c.load', '--help'],
                          env=child_environment(), capture_output=True, text=True, timeout=30)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('usage: python -m what_if_c.load --service NAME')
    assert '--busy-backoff' in done.stdout
