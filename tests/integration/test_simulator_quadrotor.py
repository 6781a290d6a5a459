"""
The simulator node flying the Crazyflie, over real DDS: its vehicle file's topics at 100 Hz.

``ship_sim_node simulator -p vessel:=crazyflie_brushless`` must publish the vehicle
file's ``recordings.topics`` (nav_msgs/Odometry with the pose in ENU and the twist in
FLU, the rotor speeds as a JointState of m1..m4) every 0.01 s of simulated time and
fly: the state it publishes converts back into a Crazyflie's state that moves in all six
degrees of freedom. How closely it keeps real time's pace, and at what CPU, is a speed
figure: ``bench.py forecast`` measures it (rate.simulator_node).
"""

import math

import numpy as np
import pytest

from .conftest import spin_until

pytestmark = pytest.mark.ros

START = 2000.0    # stamp of simulated t = 0
ROTORS = ['m1', 'm2', 'm3', 'm4']


def test_the_quadrotor_flies_and_publishes_its_topics_at_100_hz(launcher, ros_node):
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState

    from vessel_datasets.topic_map import topic_map_for
    from vessel_datasets.topic_messages import channel_reader
    from vessel_description import load_vessel
    from vessel_ros_bridge.messages import seconds_from_stamp

    odom, joints = [], []
    ros_node.create_subscription(Odometry, '/vessel/odom', odom.append, 200)
    ros_node.create_subscription(JointState, '/vessel/actuators', joints.append, 200)
    sim = launcher.start_node('ship_sim_node', 'simulator', '--ros-args', '-p',
                              'vessel:=crazyflie_brushless', '-p', f'start_time:={START}',
                              name='sim_crazyflie')
    assert spin_until(ros_node, lambda: len(odom) >= 200 and joints, 60), sim.output()
    assert 'simulating crazyflie_brushless (multirotor rigid-body model)' in sim.output()
    count0 = len(odom)
    assert spin_until(ros_node, lambda: len(odom) >= count0 + 500, 60), sim.output()

    # Every 0.01 s of simulated time. What a period costs the node and the rate it keeps
    # are speed figures: `bench.py forecast` prints them (rate.simulator_node; 5.5 ms of
    # CPU a period idle), where a loaded machine cannot fail a check that is no defect.
    stamps = np.array([seconds_from_stamp(m.header.stamp) for m in odom]) - START
    np.testing.assert_allclose(np.diff(stamps), 0.01, atol=1e-6)

    # Frames and shapes.
    msg = odom[-1]
    assert (msg.header.frame_id, msg.child_frame_id) == ('odom', 'base_link')
    q = msg.pose.pose.orientation
    assert math.isclose(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2, 1.0, rel_tol=1e-9)
    last = joints[-1]
    assert list(last.name) == ROTORS and len(last.velocity) == 4
    assert all(300.0 < n < 3100.0 for m in joints[-100:] for n in m.velocity)

    # It flies: read back as the converter reads it, every state moves.
    crazyflie = load_vessel('crazyflie_brushless')
    read = channel_reader(topic_map_for(crazyflie), '/vessel/odom')
    channels = [read(m) for m in odom]
    for name in ('surge', 'sway', 'heave', 'roll_rate', 'pitch_rate', 'yaw_rate', 'pos_z'):
        values = np.array([c[name] for c in channels])
        assert np.ptp(values) > 0.05, name
    height = np.array([c['pos_z'] for c in channels])
    assert np.abs(height).max() < 2.0              # ENU z from the start, +-1 m or so
