"""vessel_ros_bridge: message conversions and parameter specs (no ROS graph needed)."""

import math

import pytest

from vessel_ros_bridge import messages
from vessel_ros_bridge.parameters import parse_specs

STATE = {'u': 7.5, 'v': -0.3, 'p': 0.02, 'r': -0.01, 'phi': 0.05, 'psi': 2.0,
         'x': 120.0, 'y': -40.0}


def test_odometry_round_trip_is_exact_and_uses_ros_frames():
    stamp = messages.stamp_from_seconds(1234.5)
    msg = messages.odometry_from_state(STATE, stamp, 'odom', 'base_link')
    # ENU/FLU by hand: east = y_ned, north = x_ned; sway and yaw rate change sign.
    assert (msg.pose.pose.position.x, msg.pose.pose.position.y) == (-40.0, 120.0)
    assert msg.twist.twist.linear.y == 0.3 and msg.twist.twist.angular.z == 0.01
    assert msg.twist.twist.angular.x == 0.02
    back = messages.state_from_odometry(msg)
    for key, value in STATE.items():
        assert back[key] == pytest.approx(value, abs=1e-12), key
    assert messages.seconds_from_stamp(msg.header.stamp) == 1234.5


def test_heading_north_faces_enu_y_axis():
    stamp = messages.stamp_from_seconds(0)
    msg = messages.odometry_from_state(dict(STATE, psi=0.0, phi=0.0), stamp, 'odom', 'base_link')
    q = msg.pose.pose.orientation
    yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y**2 + q.z**2))
    assert yaw == pytest.approx(math.pi / 2)


def test_joint_state_round_trip_and_partial_commands():
    actuators = {'n': 80.0, 'delta_port': 0.1, 'delta_stbd': -0.05}
    msg = messages.joint_state_from_actuators(actuators, messages.stamp_from_seconds(1.0))
    assert messages.actuators_from_joint_state(msg) == actuators
    msg.name, msg.position, msg.velocity = ['rudder_stbd'], [0.2], []
    assert messages.actuators_from_joint_state(msg) == {'delta_stbd': 0.2}


@pytest.mark.parametrize('names, position, velocity, match', [
    (['thruster'], [0.0], [1.0], 'names none of'),
    (['propeller'], [0.0], [], 'no velocity entry'),
])
def test_malformed_joint_states_are_explained(names, position, velocity, match):
    from sensor_msgs.msg import JointState

    msg = JointState(name=names, position=position, velocity=velocity)
    with pytest.raises(ValueError, match=match):
        messages.actuators_from_joint_state(msg)


def test_wind_from_port_blows_towards_starboard_in_flu():
    # From port: angle -pi/2 relative to the bow; the air moves to starboard = -y in FLU.
    msg = messages.wind_from_measurement(5.0, 0.0, -1.0, messages.stamp_from_seconds(0), 'b')
    assert msg.vector.x == pytest.approx(0.0) and msg.vector.y == pytest.approx(-5.0)
    back = messages.measurement_from_wind(msg)
    assert back == pytest.approx({'wind_speed': 5.0, 'wind_dir_cos': 0.0, 'wind_dir_sin': -1.0})


def test_stamp_rounding_never_overflows_nanoseconds():
    stamp = messages.stamp_from_seconds(9.9999999999)
    assert (stamp.sec, stamp.nanosec) == (10, 0)


def test_parameter_specs_give_descriptors_with_ranges():
    specs = parse_specs({'rate': {'default': 1.0, 'description': 'Hz', 'range': [0.1, 5]},
                         'steps': {'default': 3, 'range': [1, 10], 'read_only': True},
                         'name': {'default': 'x'}}, 'spec.yaml')
    rate, steps, name = specs
    assert rate.descriptor().floating_point_range[0].to_value == 5.0
    assert steps.descriptor().integer_range[0].from_value == 1 and steps.read_only
    assert name.value_range is None and name.descriptor().description == ''


def test_a_parameter_may_stay_unset_with_a_declared_type():
    (threshold,) = parse_specs({'t': {'default': None, 'type': 'double', 'range': [0, 2]}},
                               'spec.yaml')
    assert threshold.default is None and threshold.value_type is float
    assert threshold.descriptor().floating_point_range[0].to_value == 2.0


@pytest.mark.parametrize('data, match', [
    ({'a': {'default': 1, 'rnage': [0, 2]}}, "unknown keys \\['rnage'\\]"),
    ({'a': {'default': 5, 'range': [0, 2]}}, 'around the numeric default'),
    ({'a': {'description': 'no default'}}, 'at least a default'),
    ({'a': {'default': 'x', 'range': [0, 1]}}, 'around the numeric default'),
    ({'a': {'default': None}}, 'default null needs a type'),
    ({'a': {'default': 1.0, 'type': 'double'}}, 'give type only with default null'),
    ({'a': {'default': None, 'type': 'string', 'range': [0, 1]}}, 'numeric default'),
])
def test_bad_parameter_specs_name_the_file_and_parameter(data, match):
    with pytest.raises(ValueError, match=match) as info:
        parse_specs(data, 'spec.yaml')
    assert "spec.yaml: parameter 'a'" in str(info.value)
