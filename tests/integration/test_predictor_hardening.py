"""
The predictor under hostile inputs and plans, over real DDS (issue #14).

One predictor, fed live by this test process, serves every test of this module, in
order: plans, absurd inputs, a future stamp, runtime parameters, silence (last: it
stops the feeder). The test process spins its node in a background thread, so the
feeder keeps publishing while a test waits. Restarts and load:
test_predictor_restart_load.py.
"""

import math
import sys
import time

import numpy as np
import pytest

from .conftest import TEST_PROCESS_PROFILE, Graph, Launcher, wait_for
from .test_predictor_node import Feeder

pytestmark = pytest.mark.ros

RATE_HZ = 5.0          # live input rate of the feeder
WINDOW_S = 60.0        # the patrol boat's window
SILENCE_PERIOD = 2.0   # forecast period during the silence test (s)
BURST = 20000          # messages of the burst test
BURST_SILENCE = 3.0    # longest wall silence (s) allowed while it is read: 2 periods + 1 s


class LiveFeeder:
    """Publish a window of history at once, then live samples at RATE_HZ (wall clock)."""

    def __init__(self, graph: Graph):
        self.feeder = Feeder(graph.node)
        self.running = True
        self.ticks = []   # monotonic s of each live sample sent
        # A sample sent before its new publisher has matched the predictor is lost:
        # without the history, the window would take a minute of live samples to fill.
        publishers = (self.feeder.odom, self.feeder.act, self.feeder.wind)
        assert wait_for(lambda: all(p.get_subscription_count() for p in publishers), 10)
        now = time.time()
        for k in range(int(WINDOW_S) + 5):
            self.feeder.sample(now - WINDOW_S - 5 + k)
        graph.node.create_timer(1.0 / RATE_HZ, self._tick)

    def _tick(self) -> None:
        if self.running:
            self.feeder.sample(time.time())
            self.ticks.append(time.monotonic())


@pytest.fixture(scope='module')
def fed(tmp_path_factory):
    """Start a predictor fed live by this process; yield (graph, predictor process)."""
    launcher = Launcher(tmp_path_factory.mktemp('fed'))
    graph = Graph('hardening_fed')
    predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                    '-p', 'diagnostics_period:=0.25')
    try:
        assert wait_for(lambda: graph.node.count_subscribers('/vessel/odom') > 0 and
                        graph.node.count_publishers('/vessel/forecast') > 0, 90), \
            predictor.output()[-3000:]
        time.sleep(1.0)   # let discovery settle before the history burst
        graph.feeder = LiveFeeder(graph)
        assert wait_for(lambda: graph.forecasts, 30), (
            graph.values(), predictor.output()[-3000:])
        yield graph, predictor
    finally:
        graph.close()
        launcher.stop_all()


ACTUATORS = ['n', 'delta_port', 'delta_stbd']
WIND = ['wind_speed', 'wind_dir_cos', 'wind_dir_sin']
UNITS = {'n': 'rad/s', 'delta_port': 'rad', 'delta_stbd': 'rad', 'wind_speed': 'm/s',
         'wind_dir_cos': '1', 'wind_dir_sin': '1'}


def plan(n=900, row=(85.0, 0.01, 0.01), names=ACTUATORS, units=None, plan_id=''):
    """Return a ControlPlan of ``n`` equal rows in the patrol boat's controls."""
    from hybrid_predictor_interfaces.msg import ControlPlan

    units = [UNITS[name] for name in names] if units is None else units
    return ControlPlan(plan_id=plan_id, control_names=list(names), control_units=units,
                       values=list(row) * n)


def test_malformed_plans_are_refused_on_the_service_and_the_topic(fed):
    from hybrid_predictor_interfaces.msg import ControlPlan
    from hybrid_predictor_interfaces.srv import Predict

    graph, predictor = fed
    client = graph.node.create_client(Predict, '/vessel/predictor/predict')
    assert client.wait_for_service(timeout_sec=30)
    windy = ACTUATORS + WIND
    for plans, why in (([plan(names=ACTUATORS + ['wind_speed'], row=(85.0, 0, 0, 5.0))],
                         "give ['wind_speed', 'wind_dir_cos', 'wind_dir_sin'] together"),
                       ([plan(names=['shaft_speed', 'rudder_port', 'rudder_stbd'],
                              units=['rad/s', 'rad', 'rad'])],
                        "not among the controls of vessel 'patrol_boat': n [rad/s]"),
                       ([plan(), plan(n=899)], 'plan 1: 899 steps of 3 controls, need 900'),
                       ([plan(units=['rpm', 'rad', 'rad'])],
                        "plan 0: n in 'rpm'; vessel 'patrol_boat' declares it in 'rad/s'"),
                       # Every field against the vessel's declared range (#25): 1e6 m/s of
                       # wind used to pass and came back as a non-finite forecast.
                       ([plan(names=windy, row=(85.0, 0, 0, 1e6, 1.0, 0.0))],
                        'wind_speed[0] = 1e+06 outside [0, 40] m/s'),
                       ([plan(row=(-5.0, 0, 0))], 'n[0] = -5 outside')):
        answer = graph.call(client, Predict.Request(plans=plans))
        assert not answer.success and why in answer.message, answer.message
        assert '\n' not in answer.message and len(answer.forecasts) == 0
    good = graph.call(client, Predict.Request(plans=[plan(
        names=windy, row=(85.0, 0.01, 0.01, 5.0, math.cos(0.3), math.sin(0.3)))]))
    assert good.success, good.message

    pub = graph.node.create_publisher(ControlPlan, '/vessel/control_plan', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0, 10)
    bad = plan(names=ACTUATORS + ['wind_speed'], row=(85.0, 0, 0, 5.0))
    bad.header.stamp = graph.node.get_clock().now().to_msg()
    pub.publish(bad)
    assert wait_for(lambda: graph.count('plans_rejected') >= 1, 10), graph.values()
    count = len(graph.forecasts)
    assert wait_for(lambda: len(graph.forecasts) >= count + 2, 10)
    assert predictor.alive()


def test_a_forecast_says_which_plan_it_followed_or_that_it_held_the_controls(fed):
    from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
    from hybrid_predictor_interfaces.srv import Predict
    from vessel_ros_bridge import messages as m

    graph, _ = fed
    held = graph.forecasts[-1][1]
    assert held.controls_assumed == Forecast.CONTROLS_HELD and held.plan_id == ''
    assert held.relative_threshold == 0.15 and held.bounded
    pub = graph.node.create_publisher(ControlPlan, '/vessel/control_plan', 10)
    assert wait_for(lambda: pub.get_subscription_count() > 0, 10)
    stamp = time.time()
    topic_plan = plan(n=1000, plan_id='turn-7')
    topic_plan.header.stamp = m.stamp_from_seconds(stamp)
    pub.publish(topic_plan)

    def following():
        return [f for _, f in graph.forecasts if f.controls_assumed == Forecast.CONTROLS_PLAN]
    assert wait_for(following, 10), [f.controls_assumed for _, f in graph.forecasts[-3:]]
    first = following()[0]
    assert first.plan_id == 'turn-7'
    assert m.seconds_from_stamp(first.plan_stamp) == pytest.approx(stamp, abs=1e-6)
    # plan_timeout (5 s of message time) later the plan has lapsed, and the forecast says so.
    time.sleep(5.5)
    count = len(graph.forecasts)
    assert wait_for(lambda: len(graph.forecasts) >= count + 2, 10)
    assert graph.forecasts[-1][1].controls_assumed == Forecast.CONTROLS_HELD
    # What-if answers name the request's plan.
    client = graph.node.create_client(Predict, '/vessel/predictor/predict')
    assert client.wait_for_service(timeout_sec=30)
    answer = graph.call(client, Predict.Request(plans=[plan(plan_id='a'), plan(plan_id='b')]))
    assert answer.success, answer.message
    assert [(f.controls_assumed, f.plan_id) for f in answer.forecasts] == [
        (Forecast.CONTROLS_PLAN, 'a'), (Forecast.CONTROLS_PLAN, 'b')]


def test_absurd_values_and_bad_quaternions_are_rejected_and_counted(fed):
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState

    from vessel_ros_bridge import messages as m

    graph, predictor = fed
    before = graph.values()
    odom = graph.feeder.feeder.odom
    stamp = m.stamp_from_seconds(time.time())

    def odometry(u=6.0, q=(0.0, 0.0, 0.0, 1.0), frame='odom'):
        msg = Odometry()
        msg.header.stamp, msg.header.frame_id, msg.child_frame_id = stamp, frame, 'base_link'
        msg.twist.twist.linear.x = u
        o = msg.pose.pose.orientation
        o.x, o.y, o.z, o.w = q
        return msg

    for msg in (odometry(u=1e6), odometry(q=(0.0, 0.0, 0.0, math.inf)),
                odometry(q=(0.0, 0.0, 0.0, 7.0)), odometry(q=(0.0, 0.0, 0.0, 0.0)),
                odometry(frame='')):
        odom.publish(msg)
    graph.feeder.feeder.act.publish(JointState(
        header=odometry().header, name=['propeller', 'rudder_port', 'rudder_stbd'],
        position=[0.0, 10.0, 0.0], velocity=[85.0, 0.0, 0.0]))

    def grew(key, by):
        return graph.count(key) >= int(before.get(key, 0)) + by

    assert wait_for(lambda: grew('rejected_implausible', 2) and grew('rejected_non_finite', 1)
                    and grew('rejected_bad_quaternion', 2) and grew('rejected_no_frame_id', 1),
                    10), graph.values()
    count = len(graph.forecasts)
    assert wait_for(lambda: len(graph.forecasts) >= count + 2, 10)
    for _, forecast in graph.forecasts:
        hybrid = np.reshape(forecast.hybrid, (-1, 5))
        assert np.isfinite(hybrid).all() and np.abs(hybrid[:, 0]).max() <= 12.0
    assert predictor.alive()


def test_a_stamp_far_in_the_future_does_not_stop_forecasting(fed):
    from vessel_ros_bridge import messages as m

    graph, _ = fed
    future = time.time() + 1e6
    graph.feeder.feeder.odom.publish(m.odometry_from_state(
        {'u': 6.0, 'v': 0.0, 'p': 0.0, 'r': 0.0, 'phi': 0.0, 'psi': 0.0, 'x': 0.0, 'y': 0.0},
        m.stamp_from_seconds(future), 'odom', 'base_link'))
    published = time.time()
    assert wait_for(lambda: graph.count('rejected_future') >= 1, 10), graph.values()
    # Genuine data after it is forecast at once (well within one window).
    assert wait_for(lambda: graph.stamp() > published + 1.0, 10), graph.values()
    assert graph.stamp() < published + 60


def set_parameter(graph, name, value):
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    client = graph.node.create_client(SetParameters, '/vessel/predictor/set_parameters')
    assert client.wait_for_service(timeout_sec=10)
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    (result,) = graph.call(client, request).results
    return result


def forecasts_in(graph, seconds: float) -> int:
    start = len(graph.forecasts)
    time.sleep(seconds)
    return len(graph.forecasts) - start


# Slow: three 4 s counts; it also failed once in three full runs on an idle machine
# (9 forecasts in 4 s at 0.2 s, 12 asked) and never alone: the cause is not found yet.
@pytest.mark.slow
def test_a_runtime_forecast_period_change_shows_in_the_publish_rate(fed):
    graph, _ = fed
    assert not set_parameter(graph, 'model_path', '/tmp/x.safetensors').successful
    refused = set_parameter(graph, 'restart_span', 1.0)
    assert not refused.successful and 'at least max_age' in refused.reason
    at_1s = forecasts_in(graph, 4.0)
    assert set_parameter(graph, 'forecast_period', 0.2).successful
    time.sleep(0.5)
    at_02s = forecasts_in(graph, 4.0)
    assert set_parameter(graph, 'forecast_period', 5.0).successful
    time.sleep(1.0)
    at_5s = forecasts_in(graph, 4.0)
    assert 2 <= at_1s <= 6 and at_02s >= 12 and at_5s <= 1, (at_1s, at_02s, at_5s)


# A replay of one old message, as fast as a process publishes, from a process of its
# own: published from the test process it would starve this process's live feeder and
# listener too, and the silence measured would be the test's, not the predictor's.
BURST_SCRIPT = """
import sys, time
import rclpy
from nav_msgs.msg import Odometry
from vessel_ros_bridge import messages as m
rclpy.init()
node = rclpy.create_node('burst')
pub = node.create_publisher(Odometry, '/vessel/' + m.ODOM_TOPIC, 200)
while pub.get_subscription_count() == 0:
    time.sleep(0.05)
old = m.odometry_from_state(dict(u=6.0, v=0.0, p=0.0, r=0.0, phi=0.0, psi=0.0, x=0.0, y=0.0),
                            m.stamp_from_seconds(time.time() - 30.0), 'odom', 'base_link')
started = time.monotonic()
for _ in range(int(sys.argv[1])):
    pub.publish(old)
print(f'burst sent in {time.monotonic() - started:.2f} s', flush=True)
time.sleep(1.0)
"""


def node_trace(graph, start: float, end: float) -> dict:
    """
    Who was silent over [start, end] (monotonic s): this process or the predictor.

    'feeder_gap_s': the longest wait between live samples this process sent (a stalled
    test process stops its feeder and its listener alike); 'node': the predictor's own
    account, one row per status (arrival s after start, forecasts published, inputs
    accepted, window status, wall s since its last state and since its last forecast):
    a forecast counted by the node but not received was held in transport to this
    process; a state sent but not counted never reached the node.
    """
    ticks = [t for t in graph.feeder.ticks if start <= t <= end]
    keys = ('forecasts_published', 'inputs_accepted', 'window_status',
            'wall_s_since_last_state', 'wall_s_since_last_forecast')
    rows = []
    for t, msg in graph.diagnostics:
        if start <= t <= end:
            values = {kv.key: kv.value for kv in msg.status[0].values}
            rows.append((round(t - start, 2), *(values.get(k) for k in keys)))
    return {'feeder_gap_s': round(float(np.diff([start, *ticks, end]).max()), 2),
            'node': rows}


def test_a_burst_of_20000_messages_is_read_through_while_forecasts_go_on(fed, tmp_path):
    graph, _ = fed
    assert set_parameter(graph, 'forecast_period', 1.0).successful
    count = len(graph.forecasts)
    assert wait_for(lambda: len(graph.forecasts) >= count + 2, 5)
    before = graph.count('rejected_out_of_order')
    launcher = Launcher(tmp_path)
    try:
        # The burst writer repairs what the predictor's reliable reader lost as fast as the
        # live feeders do: with Fast DDS's 3 s heartbeat its unrepaired samples fill the
        # reader's history and hold the live states back until its next heartbeat (a
        # failed run: no state accepted for 3.1-3.3 s, then a 3.2 s forecast gap in the
        # next test), the sender's repair period, which this test does not judge.
        burst = launcher.start([sys.executable, '-c', BURST_SCRIPT, str(BURST)], 'burst',
                               env={'FASTRTPS_DEFAULT_PROFILES_FILE': str(TEST_PROCESS_PROFILE)})
        started, started_wall = time.monotonic(), time.time()
        assert burst.popen.wait(60) == 0, burst.output()[-2000:]
        time.sleep(2.0)
        ended = time.monotonic()
    finally:
        launcher.stop_all()
    received = [(t, graph.stamp(k)) for k, (t, _) in enumerate(graph.forecasts)
                if started <= t <= ended]
    gaps = np.diff([started, *(t for t, _ in received), ended])
    # Arrival and stamp of each forecast (s after the start): a forecast arriving long
    # after its stamp was held in transport, one missing was never made.
    # A string: pytest abbreviates a tuple's long items in the failure report.
    assert gaps.max() <= BURST_SILENCE, (
        f'silent {gaps.max():.2f} s; arrivals and stamps '
        f'{[(round(t - started, 2), round(stamp - started_wall, 2)) for t, stamp in received]}'
        f'; {burst.output()[-100:].strip()}; {node_trace(graph, started, ended)}')
    # The burst was read (keep-last queues, the publisher's and the node's, drop part
    # of it) and the newest real samples are still the ones forecast.
    assert graph.count('rejected_out_of_order') > before, graph.values()
    assert graph.stamp() >= time.time() - 3.0, graph.stamp() - time.time()


def test_silence_turns_diagnostics_error_within_two_forecast_periods(fed):
    graph, _ = fed
    assert set_parameter(graph, 'forecast_period', SILENCE_PERIOD).successful
    count = len(graph.forecasts)
    assert wait_for(lambda: len(graph.forecasts) >= count + 2, 4 * SILENCE_PERIOD)
    assert graph.status().level == b'\x00', (
        graph.status().message, graph.values(),
        f'longest forecast gaps {sorted(np.diff([t for t, _ in graph.forecasts]))[-3:]}')
    graph.feeder.running = False
    time.sleep(0.3)   # forecasts in flight arrive
    last = graph.forecasts[-1][0]

    def error():
        status = graph.status(since=last)
        return status is not None and status.level == b'\x02'
    assert wait_for(error, 4 * SILENCE_PERIOD)
    first_error = next(t for t, msg in graph.diagnostics if t >= last and
                       msg.status[0].level == b'\x02')
    assert first_error - last <= 2 * SILENCE_PERIOD, (first_error - last,
                                                      graph.status().message)
    # Two checks see this silence: the input watchdog (3 s of wall time after the last
    # accepted state) and the forecast silence (1.5 periods, 3 s, after the last
    # forecast's publish). When the last state is the one forecast last, its forecast is
    # published up to a sync wait and a compute after it, so the watchdog may say ERROR
    # one status earlier (3 of 21 runs under load named only the inputs at first): the
    # order is a race, and each must speak within two periods.
    assert wait_for(lambda: 'no forecast for' in graph.status().message, 2 * SILENCE_PERIOD)
    said = [t for t, msg in graph.diagnostics
            if t >= last and 'no forecast for' in msg.status[0].message]
    assert said[0] - last <= 2 * SILENCE_PERIOD, (said[0] - last, graph.status().message)
    # Later the inputs are stale by the node's clock, and their age keeps growing.
    assert wait_for(lambda: 'inputs stale' in graph.status().message, 10)
    age = float(graph.values()['input_age_s'])
    time.sleep(1.0)
    assert float(graph.values()['input_age_s']) >= age + 0.5


@pytest.mark.slow  # about 40 s: two more predictors compile their model
def test_an_unbounded_model_is_a_warning_unless_the_user_allowed_it(tmp_path):
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy

    from hybrid_models.cli.set_threshold import set_threshold
    from hybrid_predictor.node import default_model_path
    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_ros_bridge.executors import MultiThreadedExecutor

    model = tmp_path / 'unbounded.safetensors'
    set_threshold(default_model_path(), None, model)
    launcher = Launcher(tmp_path)
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node('unbounded_test', context=context)
    forecasts = {'warned': [], 'allowed': []}
    statuses = {}
    for ns in forecasts:
        node.create_subscription(Forecast, f'/{ns}/forecast', forecasts[ns].append, 10)
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda msg: statuses.update(
        {s.name: s for s in msg.status}), 50)
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(node)
    try:
        for ns, allowed in (('warned', 'false'), ('allowed', 'true')):
            launcher.start_node('hybrid_predictor', 'predictor', '--ros-args', '-r',
                                f'__ns:=/{ns}', '-p', f'model_path:={model}',
                                '-p', f'allow_unbounded:={allowed}', name=f'predictor_{ns}')
        feeders = [Feeder(node, f'/{ns}') for ns in forecasts]
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and not all(
                node.count_subscribers(f'/{ns}/odom') for ns in forecasts):
            executor.spin_once(timeout_sec=0.1)
        time.sleep(1.0)
        now = time.time()
        for k in range(int(WINDOW_S) + 5):
            for feeder in feeders:
                feeder.sample(now - WINDOW_S - 5 + k)

        def reported(ns):
            # A status published before the node's first forecast says "waiting for input";
            # the one judged must be of a node that has forecast.
            status = statuses.get(f'/{ns}/predictor: forecast')
            values = {} if status is None else {kv.key: kv.value for kv in status.values}
            return int(values.get('forecasts_published', '0')) > 0

        while time.monotonic() < deadline and not all(
                len(forecasts[ns]) >= 4 and reported(ns) for ns in forecasts):
            for feeder in feeders:
                feeder.sample(time.time())
            end = time.monotonic() + 0.2
            while time.monotonic() < end:
                executor.spin_once(timeout_sec=0.05)
        assert all(len(f) >= 4 for f in forecasts.values()), launcher.processes[0].output()
        assert all(reported(ns) for ns in forecasts), statuses
        for ns in forecasts:
            assert not forecasts[ns][-1].bounded
            assert math.isnan(forecasts[ns][-1].relative_threshold)
        warned, allowed = (statuses[f'/{ns}/predictor: forecast'] for ns in forecasts)
        assert warned.level == b'\x01' and 'served unbounded' in warned.message, warned
        assert 'served unbounded' not in allowed.message, allowed
        assert {kv.key: kv.value for kv in allowed.values}['bounded'] == 'false'
    finally:
        executor.shutdown(timeout_sec=5)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
        launcher.stop_all()


def test_a_gpu_jax_does_not_see_is_refused_at_start_in_one_line(launcher):
    import jax

    from hybrid_models.engine import platform_devices

    try:
        platform_devices('gpu')
    except ValueError:
        pass
    else:
        pytest.skip('jax sees a GPU here: the node would start on it')
    predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                    '-p', 'compute_platform:=gpu')
    assert predictor.popen.wait(60) == 2
    errors = [line for line in predictor.output().splitlines() if 'error' in line.lower()]
    assert errors == [f"predictor: error: compute platform 'gpu': jax {jax.__version__} sees "
                      'no GPU here (its CUDA build: tools/setup.sh gpu, on a machine with an '
                      'NVIDIA driver); use cpu'], predictor.output()
