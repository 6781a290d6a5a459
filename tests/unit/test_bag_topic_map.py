"""Topic maps: the simulator's default, foreign layouts, and one-line errors."""

import pytest
from rosbags.typesys import Stores, get_typestore
import yaml

from vessel_datasets.fields import FieldError, check_path, compile_getter, numeric_paths
from vessel_datasets.topic_map import TopicMapError, parse_topic_map, topic_map_for
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

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
  n: {topic: /propulsion/joints, field: 'velocity[shaft]', scale: 0.10471975511965977}
  delta_port: {topic: /propulsion/joints, field: 'position[azimuth_ps]',
               scale: -0.017453292519943295}
  delta_stbd: {topic: /propulsion/joints, field: 'position[azimuth_sb]',
               scale: -0.017453292519943295}
wind:
  frame: frd
  speed: {topic: /weather/wind, field: speed_knots, scale: 0.5144444444444445}
  from_angle: {topic: /weather/wind, field: angle_deg, scale: 0.017453292519943295}
stamps: {/weather/wind: log}
max_gap_s: {/gps/fix: 5.0}
"""


def test_default_map_matches_the_simulator_topics():
    topic_map = topic_map_for(SHIP)
    assert topic_map.topics == ['/vessel/odom', '/vessel/actuators', '/vessel/wind']
    assert topic_map.frames == {'body_velocity': 'flu', 'attitude': 'enu_flu',
                                'position': 'enu', 'wind': 'flu'}
    channels = [leaf.channel for leaf in topic_map.leaves()]
    assert channels == ['surge', 'sway', 'roll_rate', 'yaw_rate', 'qx', 'qy', 'qz', 'qw',
                        'pos_x', 'pos_y', 'actuator.n', 'actuator.delta_port',
                        'actuator.delta_stbd', 'wind_x', 'wind_y']
    assert topic_map.resample['actuators'] == 'hold'


def test_foreign_map_parses_without_code():
    topic_map = parse_topic_map(yaml.safe_load(FOREIGN), SHIP)
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
     'expected quaternion or heading+roll'),
    (lambda d: d['attitude']['quaternion'].update(scale=2.0), 'cannot be scaled'),
    (lambda d: d['actuators']['n'].update(topic='vessel/act'),
     'must be an absolute topic name'),
    (lambda d: d['actuators']['n'].update(unit='rpm'), "unknown keys ['unit']"),
    (lambda d: d['actuators'].pop('delta_stbd'), 'expected n+delta_port+delta_stbd'),
    (lambda d: d.update(wind={'speed': {'topic': '/a', 'field': 's'},
                              'from_angle': {'topic': '/b', 'field': 'a'}}),
     'must come from one topic'),
    (lambda d: d['body_velocity'].update(resample='cubic'), "resample is 'cubic'"),
])
def test_malformed_maps_give_one_clear_line(edit, message):
    data = topic_map_for(SHIP).to_dict()
    edit(data)
    with pytest.raises(TopicMapError) as info:
        parse_topic_map(data, SHIP)
    assert message in str(info.value)
    assert '\n' not in str(info.value)


def test_unreadable_file_names_the_path(tmp_path):
    with pytest.raises(TopicMapError, match='cannot read'):
        topic_map_for(SHIP, tmp_path / 'nope.yaml')
    (tmp_path / 'bad.yaml').write_text('a: [1, 2')
    with pytest.raises(TopicMapError, match='not valid YAML'):
        topic_map_for(SHIP, tmp_path / 'bad.yaml')


SMALL_BOAT = yaml.safe_load("""
name: small_boat
rate_hz: 10.0
window_s: 5.0
horizon_s: 30.0
states: [u, v, r]
actuators:
  rpm: {kind: propeller, range: [-200.0, 200.0]}
  rudder: {kind: rudder, range: [-0.6, 0.6]}
particulars: {length_m: 1.2}
recordings:
  topics:
    body_velocity:
      frame: frd
      surge: {topic: /sensor, field: 'vel[0]'}
      sway: {topic: /sensor, field: 'vel[1]'}
      yaw_rate: {topic: /sensor, field: 'vel[2]', scale: 0.017453292519943295}
    attitude:
      frame: ned_frd
      heading: {topic: /sensor, field: 'pose[2]', scale: 0.017453292519943295}
    position:
      frame: ned
      x: {topic: /sensor, field: 'pose[0]'}
      y: {topic: /sensor, field: 'pose[1]'}
    actuators:
      rpm: {topic: /ctrl, field: 'ctrl[0]', scale: 0.10471975511965977}
      rudder: {topic: /ctrl, field: 'ctrl[2]', scale: 0.017453292519943295}
""")


def test_a_3dof_vessel_maps_array_elements_and_needs_no_roll_or_wind():
    from vessel_description import parse_vessel
    vessel = parse_vessel(SMALL_BOAT)
    topic_map = topic_map_for(vessel)
    channels = {leaf.channel: leaf.path for leaf in topic_map.leaves()}
    assert channels == {'surge': 'vel[0]', 'sway': 'vel[1]', 'yaw_rate': 'vel[2]',
                        'heading': 'pose[2]', 'pos_x': 'pose[0]', 'pos_y': 'pose[1]',
                        'actuator.rpm': 'ctrl[0]', 'actuator.rudder': 'ctrl[2]'}
    assert not topic_map.has_group('wind')


@pytest.mark.parametrize('edit, message', [
    (lambda d: d.update(wind={'velocity': {'topic': '/w', 'field': 'v'}}),
     'declares no wind input'),
    (lambda d: d['body_velocity'].update(roll_rate={'topic': '/s', 'field': 'vel[3]'}),
     "body_velocity maps ['roll_rate'], but vessel 'small_boat' models no roll"),
    (lambda d: d['attitude'].update(roll={'topic': '/s', 'field': 'pose[3]'}),
     "attitude maps ['roll'], but vessel 'small_boat' models no roll"),
    (lambda d: d['position'].pop('y'), 'expected point or latlon or x+y'),
])
def test_a_3dof_vessel_refuses_what_it_does_not_have(edit, message):
    from vessel_description import parse_vessel
    vessel = parse_vessel(SMALL_BOAT)
    data = dict(SMALL_BOAT['recordings']['topics'])
    data = yaml.safe_load(yaml.safe_dump(data))
    edit(data)
    with pytest.raises(TopicMapError) as info:
        parse_topic_map(data, vessel)
    assert message in str(info.value)


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
