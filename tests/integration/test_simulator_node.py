"""The simulator node over real DDS: topics, frames, batch equivalence, commands, reset."""

import math

import numpy as np
import pytest

from .conftest import spin_until

pytestmark = pytest.mark.ros

START = 1000.0  # stamp of simulated t = 0, so t = stamp - START


def start_simulator(launcher, *params, name='simulator'):
    args = ['--ros-args', '-p', f'start_time:={START}']
    for p in params:
        args += ['-p', p]
    return launcher.start_node('ship_sim_node', 'simulator', *args, name=name)


class Collector:
    """Keep messages of one topic by simulated time t (s)."""

    def __init__(self, node, msg_type, topic):
        from vessel_ros_bridge.messages import seconds_from_stamp

        self.by_t = {}
        self.all = []

        def keep(msg):
            self.all.append(msg)
            self.by_t[round(seconds_from_stamp(msg.header.stamp) - START, 6)] = msg

        node.create_subscription(msg_type, topic, keep, 50)


def test_publishes_state_actuators_and_wind_in_ros_frames(launcher, ros_node):
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState

    odom = Collector(ros_node, Odometry, '/vessel/odom')
    actuators = Collector(ros_node, JointState, '/vessel/actuators')
    wind = Collector(ros_node, Vector3Stamped, '/vessel/wind')
    clocks = []
    ros_node.create_subscription(Clock, '/clock', clocks.append, 50)
    sim = start_simulator(launcher, 'real_time_factor:=40.0')

    assert spin_until(ros_node, lambda: len(odom.all) >= 10 and wind.all and actuators.all, 30)
    # Its log says which Fast DDS profile it runs with (its own: the tests give none).
    assert 'fastdds_simulator.xml' in sim.output() and 'heartbeats every 0.1 s' in sim.output()
    # and that its console entry limited the malloc arenas (vessel_ros_bridge.allocator).
    assert 'malloc: 2 arenas shared by all threads' in sim.output()
    stamps = sorted(odom.by_t)
    assert all(float(t).is_integer() for t in stamps), 'outputs are on whole simulated seconds'
    assert np.all(np.diff(stamps) >= 1.0)
    msg = odom.all[-1]
    assert (msg.header.frame_id, msg.child_frame_id) == ('odom', 'base_link')
    speed = math.hypot(msg.twist.twist.linear.x, msg.twist.twist.linear.y)
    assert 1.0 < speed < 12.0, f'cruising speed {speed} m/s is implausible'
    q = msg.pose.pose.orientation
    assert math.isclose(q.x**2 + q.y**2 + q.z**2 + q.w**2, 1.0, rel_tol=1e-9)
    joint = actuators.all[-1]
    assert list(joint.name) == ['propeller', 'rudder_port', 'rudder_stbd']
    assert 0.0 < joint.velocity[0] < 110.0, 'shaft speed in rad/s'
    assert wind.all[-1].header.frame_id == 'base_link'
    assert clocks and clocks[-1].clock.sec >= int(START)


def test_node_reproduces_the_batch_run_of_the_same_seed(launcher, ros_node):
    from nav_msgs.msg import Odometry

    from vessel_physics.simulation.config import load_simulation as load_config
    from vessel_physics.simulation.simulator import Simulator
    from vessel_ros_bridge.messages import state_from_odometry

    odom = Collector(ros_node, Odometry, '/vessel/odom')
    truth = Collector(ros_node, Odometry, '/vessel/odom_true')
    start_simulator(launcher, 'seed:=7', 'run_index:=2', 'publish_truth:=true',
                    'real_time_factor:=40.0')
    assert spin_until(ros_node, lambda: len(odom.by_t) >= 15 and len(truth.by_t) >= 15, 40)

    horizon = int(max(max(odom.by_t), max(truth.by_t)))
    batch = Simulator(load_config(), n_runs=3, seed=7).run(horizon)
    for t, msg in odom.by_t.items():
        got, k = state_from_odometry(msg), int(t)
        for key in ('u', 'v', 'p', 'r', 'phi', 'x', 'y'):
            assert got[key] == pytest.approx(batch[key][2, k], abs=1e-9), (key, t)
        wrapped = math.remainder(got['psi'] - batch['psi'][2, k], 2 * math.pi)
        assert abs(wrapped) < 1e-9
    # The two topics are compared separately: when the wait ends, a stamp may have been
    # heard on one and still be in flight on the other.
    for t, msg in truth.by_t.items():
        got_true = state_from_odometry(msg)
        assert got_true['u'] == pytest.approx(batch['u_true'][2, int(t)], abs=1e-9), t
        assert got_true['u'] != pytest.approx(batch['u'][2, int(t)], abs=1e-9), 'noise-free'


def test_external_command_overrides_the_operator_and_bad_ones_are_rejected(launcher,
                                                                           ros_node):
    from sensor_msgs.msg import JointState

    actuators = Collector(ros_node, JointState, '/vessel/actuators')
    command_pub = ros_node.create_publisher(JointState, '/vessel/cmd', 10)
    sim = start_simulator(launcher, 'real_time_factor:=20.0', 'command_timeout:=600.0')
    assert spin_until(ros_node, lambda: actuators.all, 30)

    def command(n, rudder):
        msg = JointState(name=['propeller', 'rudder_port', 'rudder_stbd'])
        msg.velocity = [n, 0.0, 0.0]
        msg.position = [0.0, rudder, rudder]
        return msg

    # The actuator readings carry sensor noise (std 0.002 rad, 0.5 rad/s): allow 5 sigma.
    # A bad command that got through would move the rudder by 0.2 rad or more.
    rudder_tol, shaft_tol = 0.01, 2.5
    good = command(50.0, 0.2)
    target_reached = lambda: actuators.all and abs(actuators.all[-1].position[1] - 0.2) \
        < rudder_tol and abs(actuators.all[-1].velocity[0] - 50.0) < shaft_tol  # noqa: E731
    for _ in range(100):
        command_pub.publish(good)
        if spin_until(ros_node, target_reached, 0.5):
            break
    assert target_reached(), 'the rudder and shaft never reached the commanded set-points'

    for bad in (command(float('nan'), 0.0), command(50.0, 3.0), command(-5.0, 0.0)):
        command_pub.publish(bad)
    spin_until(ros_node, lambda: False, 2.0)
    assert sim.alive()
    last = actuators.all[-1]
    assert last.position[1] == pytest.approx(0.2, abs=rudder_tol), 'the last good command holds'
    assert last.velocity[0] == pytest.approx(50.0, abs=shaft_tol)
    log = sim.output()
    assert 'rejected command' in log and 'not finite' in log


def test_reset_service_restarts_the_run(launcher, ros_node):
    from nav_msgs.msg import Odometry
    from std_srvs.srv import Trigger

    from vessel_ros_bridge.messages import seconds_from_stamp

    odom = Collector(ros_node, Odometry, '/vessel/odom')
    start_simulator(launcher, 'real_time_factor:=40.0')
    assert spin_until(ros_node, lambda: max(odom.by_t, default=0) >= 10, 30)
    client = ros_node.create_client(Trigger, '/vessel/simulator/reset')
    assert client.wait_for_service(timeout_sec=10)
    future = client.call_async(Trigger.Request())
    assert spin_until(ros_node, future.done, 10) and future.result().success
    count = len(odom.all)
    assert spin_until(ros_node, lambda: len(odom.all) > count + 2, 10)
    after = [seconds_from_stamp(m.header.stamp) - START for m in odom.all[count:]]
    assert min(after) < 3.0, 'simulated time restarts near 0 after a reset'


@pytest.mark.parametrize('param, expected', [
    ('real_time_factor:=0.0', 'real_time_factor'),
    ('scenario:=/nonexistent/scenario.yaml', 'scenario.yaml'),
])
def test_bad_parameters_fail_with_one_line(launcher, param, expected):
    process = start_simulator(launcher, param)
    assert process.popen.wait(30) == 2
    errors = [line for line in process.output().splitlines() if 'simulator: error:' in line]
    assert len(errors) == 1 and expected in errors[0], process.output()
