"""The batch fast path reads exactly what rosbags' deserializer reads, or stands aside."""

import numpy as np
import pytest
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from vessel_datasets import layout, synthetic
from vessel_datasets.extract import TopicExtractor
from vessel_datasets.topic_map import Leaf

STORE = get_typestore(Stores.ROS2_JAZZY)
STORE.register(get_types_from_msg('std_msgs/Header header\nfloat32 speed\nint16 code\n'
                                  'float64[] samples\n', 'acme_msgs/msg/Reading'))
T = STORE.types


def leaves(topic, *paths):
    return [Leaf(f'c{i}', 'g', topic, p, 1.0, 0.0, 'g.c') for i, p in enumerate(paths)]


def header(i, frame='base_link'):
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=1000 + i, nanosec=i * 1000), frame_id=frame)


def extract(msgtype, raws, paths, fast):
    ex = TopicExtractor('/t', msgtype, leaves('/t', *paths), STORE, use_header=True, fast=fast)
    for i, raw in enumerate(raws):
        ex.add(i, raw)
    return ex, ex.finish()


def assert_same(msgtype, raws, paths):
    fast_ex, fast = extract(msgtype, raws, paths, fast=True)
    _, slow = extract(msgtype, raws, paths, fast=False)
    assert np.array_equal(fast.t_ns, slow.t_ns)
    assert np.array_equal(fast.values, slow.values, equal_nan=True)
    return fast_ex, fast


def serialize(msg, msgtype):
    return bytes(STORE.serialize_cdr(msg, msgtype))


def test_odometry_joint_state_and_wind_as_the_simulator_sends_them():
    messages = list(synthetic.sim_messages(synthetic.demo_trajectory(100), STORE))
    for topic, paths in (('/vessel/odom', ['twist.twist.linear.x', 'pose.pose.orientation.w',
                                           'pose.covariance[35]']),
                         ('/vessel/actuators', ['velocity[propeller]', 'position[rudder_stbd]']),
                         ('/vessel/wind', ['vector.x', 'vector.y'])):
        msgtype = synthetic.SIM_TOPICS[topic]
        raws = [serialize(m, msgtype) for t, _, m in messages if t == topic]
        ex, out = assert_same(msgtype, raws, paths)
        assert [lay is not None for lay in ex._layouts.values()] == [True]  # fast path used
        assert len(out.t_ns) == 100


def test_messages_of_another_layout_take_the_slow_path():
    msgtype = 'sensor_msgs/msg/JointState'
    raws = []
    for i in range(100):
        names = ['propeller', 'rudder_port', 'rudder_stbd']
        if i % 7 == 0:
            names = names[::-1]  # same length, other order: velocity[propeller] moves
        frame = 'base_link' if i % 11 else 'base_lonk'  # same length, other string
        raws.append(serialize(T[msgtype](
            header=header(i, frame), name=names, position=np.array([0.1, 0.2, 0.3]) * i,
            velocity=np.array([1.0, 2.0, 3.0]) * i, effort=np.zeros(0)), msgtype))
    paths = ['velocity[propeller]', 'position[rudder_port]']
    assert_same(msgtype, raws, paths)  # whichever message the layout was learnt from
    match, values = layout.read(layout.learn(raws[1], msgtype, paths, STORE), raws)
    odd = [i for i in range(100) if i % 7 == 0 or i % 11 == 0]
    assert np.flatnonzero(~match).tolist() == odd
    assert values[:3].tolist() == [[1.0 * i, 0.2 * i] for i in (1, 2, 3)]


def test_custom_type_with_float32_int16_and_a_sequence():
    msgtype = 'acme_msgs/msg/Reading'
    raws = [serialize(T[msgtype](header=header(i), speed=np.float32(i / 3), code=i,
                                 samples=np.arange(3.0) + i), msgtype) for i in range(64)]
    ex, out = assert_same(msgtype, raws, ['speed', 'samples[2]'])
    assert out.values[5, 0] == np.float32(5 / 3)
    # code (int16) varies, and 2-byte numbers cannot be located: the slow path decides.
    assert list(ex._layouts.values()) == [ex._layouts[len(raws[0])]]


def test_nonzero_padding_is_not_learnt():
    msgtype = 'geometry_msgs/msg/Vector3Stamped'
    raw = bytearray(serialize(T[msgtype](header=header(0, 'ab'),
                                         vector=T['geometry_msgs/msg/Vector3'](x=1.0, y=2.0,
                                                                               z=3.0)),
                              msgtype))
    # After the 4-byte encapsulation header, 'ab\0' ends at payload byte 15; byte 19 of
    # the message pads vector.x to an 8-byte boundary of the payload.
    raw[19] = 0xEE
    assert STORE.deserialize_cdr(bytes(raw), msgtype).vector.x == 1.0
    assert layout.learn(bytes(raw), msgtype, ['vector.x'], STORE) is None


@pytest.mark.parametrize('path', ['position[9]', 'velocity[nozzle]'])
def test_absent_element_gives_no_layout(path):
    msgtype = 'sensor_msgs/msg/JointState'
    raw = serialize(T[msgtype](header=header(0), name=['a'], position=np.zeros(1),
                               velocity=np.zeros(1), effort=np.zeros(0)), msgtype)
    assert layout.learn(raw, msgtype, [path], STORE) is None
