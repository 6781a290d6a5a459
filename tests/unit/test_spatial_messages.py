"""
A 6-DOF vehicle's state written to messages and read back through the converter.

The simulator node publishes what ``topic_messages`` writes (``channel_values``,
``MessageWriter``); the converter reads it (``channel_reader``, ``quantities.derive``,
``quantities.to_spatial_columns``). Written and read back, a state must come out as it
went in: every velocity, rate and angle across the flight envelope, in the Crazyflie's
map (Odometry: ENU pose, FLU twist) and in a map of NED/FRD scalars with the pitch as an
angle of its own; and a simulated flight recorded as a bag and converted is the flight.
"""

import math

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from vessel_datasets.extract import TopicSamples
from vessel_datasets.quantities import derive, to_spatial_columns
from vessel_datasets.readers.bags import bag_to_runs
from vessel_datasets.synthetic import default_message, write_simulated_bag
from vessel_datasets.topic_map import TopicMapError, parse_topic_map, topic_map_for
from vessel_datasets.topic_messages import (
    MessageWriter,
    channel_reader,
    channel_values,
    check_writable,
)
from vessel_description import load_vessel
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.simulator import Simulator

CRAZYFLIE = load_vessel('crazyflie_brushless')
STORE = get_typestore(Stores.ROS2_JAZZY)
STATES = ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta')
# The same vehicle read from scalars in NED/FRD: heading, roll and pitch angles, x y z.
NED_MAP = {
    'body_velocity': {'frame': 'frd', **{name: {'topic': '/state', 'field': f'{field}',
                                                **({'type': 'custom/msg/State'}
                                                   if name == 'surge' else {})}
                                         for name, field in (
        ('surge', 'u'), ('sway', 'v'), ('heave', 'w'), ('roll_rate', 'p'),
        ('pitch_rate', 'q'), ('yaw_rate', 'r'))}},
    'attitude': {'frame': 'ned_frd', 'heading': {'topic': '/state', 'field': 'psi'},
                 'roll': {'topic': '/state', 'field': 'phi'},
                 'pitch': {'topic': '/state', 'field': 'theta'}},
    'position': {'frame': 'ned', 'x': {'topic': '/state', 'field': 'north'},
                 'y': {'topic': '/state', 'field': 'east'},
                 'z': {'topic': '/state', 'field': 'down'}},
    'actuators': {m: {'topic': '/state', 'field': f'rotor{m[1]}'} for m in
                  ('m1', 'm2', 'm3', 'm4')},
}


class State:
    """A plain message with the NED map's fields."""

    def __init__(self):
        self.header = None
        for name in ('u', 'v', 'w', 'p', 'q', 'r', 'psi', 'phi', 'theta', 'north', 'east',
                     'down', 'rotor1', 'rotor2', 'rotor3', 'rotor4'):
            setattr(self, name, 0.0)


def flight_envelope(n=200, seed=0):
    """Return samples (dict of arrays) of every state across a multirotor's envelope."""
    rng = np.random.default_rng(seed)
    out = {name: rng.uniform(-3.0, 3.0, n) for name in ('u', 'v', 'w')}
    out.update({name: rng.uniform(-8.0, 8.0, n) for name in ('p', 'q', 'r')})
    out['phi'], out['theta'] = rng.uniform(-1.4, 1.4, n), rng.uniform(-1.3, 1.3, n)
    out['psi'] = rng.uniform(-2.5, 2.5, n) + np.linspace(0.0, 9.0, n)    # unwrapped, past pi
    out.update({name: rng.uniform(-50.0, 50.0, n) for name in ('x', 'y', 'z')})
    out.update({name: rng.uniform(0.0, 3100.0, n) for name in ('m1', 'm2', 'm3', 'm4')})
    return out


def read_back(samples, topic_map, factories):
    """Write every sample as messages and convert them back into dataset columns."""
    writer = MessageWriter(topic_map, factories)
    n = len(samples['u'])
    channels: dict[str, list] = {}
    for i in range(n):
        values = channel_values({k: float(v[i]) for k, v in samples.items()}, topic_map)
        for topic in writer.topics:
            read = channel_reader(topic_map, topic)(writer.message(topic, values))
            for channel, value in read.items():
                channels.setdefault(topic, {}).setdefault(channel, []).append(value)
    merged = {}
    for topic, columns in channels.items():
        names = tuple(columns)
        raw = TopicSamples(topic, '', names, np.arange(n, dtype=np.int64) * 10_000_000,
                           np.column_stack([columns[c] for c in names]))
        derived = derive(raw, topic_map)
        merged.update({c: derived.column(c) for c in derived.channels})
    return to_spatial_columns(merged, topic_map, relative=False)


def assert_same_state(back, samples):
    for key in STATES + ('x', 'y', 'z', 'm1', 'm2', 'm3', 'm4'):
        np.testing.assert_allclose(back[key], samples[key], rtol=1e-12, atol=1e-9,
                                   err_msg=key)
    turns = (back['psi'] - samples['psi']) / (2 * math.pi)
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-10)     # the same heading


def test_the_crazyflies_odometry_and_rotor_speeds_give_the_state_back():
    topic_map = topic_map_for(CRAZYFLIE)
    factories = {'/vessel/odom': lambda: default_message(STORE, 'nav_msgs/msg/Odometry'),
                 '/vessel/actuators': lambda: default_message(STORE,
                                                              'sensor_msgs/msg/JointState')}
    samples = flight_envelope()
    assert_same_state(read_back(samples, topic_map, factories), samples)
    # The messages themselves: ENU position, FLU twist, a unit quaternion, named rotors.
    writer = MessageWriter(topic_map, factories)
    one = {k: float(v[0]) for k, v in samples.items()}
    values = channel_values(one, topic_map)
    odom, joints = (writer.message(t, values) for t in ('/vessel/odom', '/vessel/actuators'))
    assert (odom.pose.pose.position.x, odom.pose.pose.position.z) == (one['y'], -one['z'])
    assert (odom.twist.twist.linear.z, odom.twist.twist.angular.y) == (-one['w'], -one['q'])
    q = odom.pose.pose.orientation
    assert math.isclose(q.x ** 2 + q.y ** 2 + q.z ** 2 + q.w ** 2, 1.0, rel_tol=1e-12)
    assert list(joints.name) == ['m1', 'm2', 'm3', 'm4'] and joints.velocity[2] == one['m3']


def test_scalars_in_ned_frd_with_the_pitch_as_an_angle_give_the_state_back():
    topic_map = parse_topic_map(NED_MAP, CRAZYFLIE)
    samples = flight_envelope(seed=1)
    assert_same_state(read_back(samples, topic_map, {'/state': State}), samples)


def test_a_pitch_written_with_the_wrong_sign_would_be_caught():
    topic_map = topic_map_for(CRAZYFLIE)
    factories = {'/vessel/odom': lambda: default_message(STORE, 'nav_msgs/msg/Odometry'),
                 '/vessel/actuators': lambda: default_message(STORE,
                                                              'sensor_msgs/msg/JointState')}
    samples = flight_envelope(n=20, seed=2)
    flipped = {**samples, 'theta': -samples['theta']}
    back = read_back(flipped, topic_map, factories)
    with pytest.raises(AssertionError):
        assert_same_state(back, samples)


def test_a_simulated_flight_recorded_as_a_bag_converts_to_the_flight(tmp_path):
    cfg = load_simulation({'vessel': CRAZYFLIE.name, 'noise': {'enabled': False},
                           'flight': {'kinds': ['aggressive']}})
    data = Simulator(cfg, seed=0, run_offset=3).run(2.0)
    bag = write_simulated_bag(tmp_path / 'flight', data, 0, CRAZYFLIE)
    (table,) = bag_to_runs(bag, topic_map_for(CRAZYFLIE), min_run_s=1.0).values()
    assert list(table.columns) == list(CRAZYFLIE.dataset_columns)
    assert len(table) == 201 and table['t'].iloc[-1] == pytest.approx(2.0)
    assert np.abs(data['theta'][0]).max() > 0.3                     # it flew
    for key in CRAZYFLIE.dataset_columns[1:]:
        expected = data[key][0]
        if key == 'psi':
            expected = expected - 2 * math.pi * round(expected[0] / (2 * math.pi))
        np.testing.assert_allclose(table[key], expected, rtol=1e-9, atol=1e-9, err_msg=key)


def test_only_what_a_simulator_can_publish_is_writable():
    data = topic_map_for(CRAZYFLIE).to_dict()
    data.pop('body_velocity')
    data['earth_velocity'] = {key: {'topic': '/vessel/odom', 'field': f'twist.twist.linear.{a}'}
                              for key, a in (('north', 'x'), ('east', 'y'), ('down', 'z'))}
    data['body_velocity'] = {key: {'topic': '/vessel/odom', 'field': f'twist.twist.angular.{a}'}
                             for key, a in (('roll_rate', 'x'), ('pitch_rate', 'y'),
                                            ('yaw_rate', 'z'))}
    with pytest.raises(TopicMapError, match='earth_velocity.north'):
        check_writable(parse_topic_map(data, CRAZYFLIE))
