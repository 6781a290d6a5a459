"""Topic maps: the simulator's default, foreign layouts, and one-line errors."""

import pytest
from rosbags.typesys import Stores, get_typestore
import yaml

from vessel_datasets.fields import FieldError, check_path, compile_getter, numeric_paths
from vessel_datasets.topic_map import TopicMapError, load_topic_map, parse_topic_map

FOREIGN = """
body_velocity:
  frame: flu
  surge: {topic: /nav/twist, field: twist.linear.x, type: geometry_msgs/msg/TwistStamped}
  sway: {topic: /nav/twist, field: twist.linear.y}
  roll_rate: {topic: /imu/data, field: angular_velocity.x}
  yaw_rate: {topic: /imu/data, field: angular_velocity.z}
attitude:
  frame: enu_flu
  quaternion: {topic: /imu/data, field: orientation, type: sensor_msgs/msg/Imu}
position:
  latlon: {topic: /gps/fix, field: ''}
actuators:
  shaft_speed: {topic: /propulsion/joints, field: 'velocity[shaft]', scale: 0.10471975511965977}
  rudder_port: {topic: /propulsion/joints, field: 'position[azimuth_ps]',
                scale: -0.017453292519943295}
  rudder_stbd: {topic: /propulsion/joints, field: 'position[azimuth_sb]',
                scale: -0.017453292519943295}
wind:
  frame: frd
  speed: {topic: /weather/wind, field: speed_knots, scale: 0.5144444444444445}
  from_angle: {topic: /weather/wind, field: angle_deg, scale: 0.017453292519943295}
stamps: {/weather/wind: log}
max_gap_s: {/gps/fix: 5.0}
"""


def test_default_map_matches_the_simulator_topics():
    topic_map = load_topic_map()
    assert topic_map.topics == ['/vessel/odom', '/vessel/actuators', '/vessel/wind']
    assert topic_map.frames == {'body_velocity': 'flu', 'attitude': 'enu_flu',
                                'position': 'enu', 'wind': 'flu'}
    channels = [leaf.channel for leaf in topic_map.leaves()]
    assert channels == ['surge', 'sway', 'roll_rate', 'yaw_rate', 'qx', 'qy', 'qz', 'qw',
                        'pos_x', 'pos_y', 'shaft_speed', 'rudder_port', 'rudder_stbd',
                        'wind_x', 'wind_y']
    assert topic_map.resample['actuators'] == 'hold'


def test_foreign_map_parses_without_code():
    topic_map = parse_topic_map(yaml.safe_load(FOREIGN))
    assert topic_map.topics == ['/nav/twist', '/imu/data', '/gps/fix', '/propulsion/joints',
                                '/weather/wind']
    leaves = {leaf.channel: leaf for leaf in topic_map.leaves()}
    assert leaves['lat'].path == 'latitude' and leaves['lon'].path == 'longitude'
    assert leaves['wind_from_angle'].scale == pytest.approx(0.0174533, rel=1e-5)
    assert topic_map.stamps == {'/weather/wind': 'log'}
    assert topic_map.max_gap_s == {'/gps/fix': 5.0}


@pytest.mark.parametrize('edit, message', [
    (lambda d: d.pop('wind'), "missing group 'wind'"),
    (lambda d: d['attitude'].update(frame='ned'), "attitude.frame is 'ned'"),
    (lambda d: d['attitude'].update(roll={'topic': '/a', 'field': 'x'}),
     'expected quaternion or roll+heading'),
    (lambda d: d['attitude']['quaternion'].update(scale=2.0), 'cannot be scaled'),
    (lambda d: d['actuators']['shaft_speed'].update(topic='vessel/act'),
     'must be an absolute topic name'),
    (lambda d: d['actuators']['shaft_speed'].update(unit='rpm'), "unknown keys ['unit']"),
    (lambda d: d.update(wind={'speed': {'topic': '/a', 'field': 's'},
                              'from_angle': {'topic': '/b', 'field': 'a'}}),
     'must come from one topic'),
    (lambda d: d['body_velocity'].update(resample='cubic'), "resample is 'cubic'"),
])
def test_malformed_maps_give_one_clear_line(edit, message):
    data = load_topic_map().to_dict()
    edit(data)
    with pytest.raises(TopicMapError) as info:
        parse_topic_map(data)
    assert message in str(info.value)
    assert '\n' not in str(info.value)


def test_unreadable_file_names_the_path(tmp_path):
    with pytest.raises(TopicMapError, match='cannot read'):
        load_topic_map(tmp_path / 'nope.yaml')
    (tmp_path / 'bad.yaml').write_text('a: [1, 2')
    with pytest.raises(TopicMapError, match='not valid YAML'):
        load_topic_map(tmp_path / 'bad.yaml')


def test_field_paths_are_checked_against_the_type():
    defs = get_typestore(Stores.ROS2_JAZZY).fielddefs
    check_path(defs, 'sensor_msgs/msg/JointState', 'velocity[propeller]')
    check_path(defs, 'nav_msgs/msg/Odometry', 'pose.covariance[35]')
    with pytest.raises(FieldError, match="no field 'linear' in geometry_msgs/msg/"
                                         'TwistWithCovariance'):
        check_path(defs, 'nav_msgs/msg/Odometry', 'twist.linear.x')
    with pytest.raises(FieldError, match='not a number'):
        check_path(defs, 'nav_msgs/msg/Odometry', 'header.frame_id')
    with pytest.raises(FieldError, match='cannot be indexed'):
        check_path(defs, 'nav_msgs/msg/Odometry', 'pose.pose[0]')
    with pytest.raises(FieldError, match="needs a 'name' string list"):
        check_path(defs, 'nav_msgs/msg/Odometry', 'pose.covariance[x]')
    assert 'twist.twist.angular.z' in numeric_paths(defs, 'nav_msgs/msg/Odometry')


def test_name_index_reads_by_joint_name_and_gives_nan_when_absent():
    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    msg = T['sensor_msgs/msg/JointState'](
        header=T['std_msgs/msg/Header'](stamp=T['builtin_interfaces/msg/Time'](sec=0,
                                                                                nanosec=0),
                                        frame_id=''),
        name=['rudder_stbd', 'propeller'], position=[0.5, 0.0], velocity=[0.0, 12.0],
        effort=[])
    assert compile_getter('velocity[propeller]')(msg) == 12.0
    assert compile_getter('position[0]')(msg) == 0.5
    assert compile_getter('position[rudder_port]')(msg) != compile_getter(
        'position[rudder_port]')(msg)  # NaN
