"""
Vessel arrays <-> ROS messages, on the topics of docs/conventions.md.

Topic names are relative: they follow the node's namespace (``vessel_ros_bridge.names``;
``/vessel/odom`` in the default one).

Builders make rclpy messages from the physics' quantities (NED/FRD, SI); readers take
any message object with the standard field names, so they serve rclpy messages and
messages deserialized from bags alike. Every frame change goes through
``vessel_physics.frames``, the project's one implementation of it.
"""

from __future__ import annotations

import importlib
import math

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import JointState

from vessel_datasets.topic_map import TopicMapError
from vessel_physics import frames

ODOM_TOPIC = 'odom'
ODOM_TRUE_TOPIC = 'odom_true'  # noise-free state, simulator only
ACTUATORS_TOPIC = 'actuators'
WIND_TOPIC = 'wind'
COMMAND_TOPIC = 'cmd'

PROPELLER = 'propeller'
RUDDER_PORT = 'rudder_port'
RUDDER_STBD = 'rudder_stbd'
# Joint name -> (JointState field, actuator key in the physics).
JOINTS = {PROPELLER: ('velocity', 'n'), RUDDER_PORT: ('position', 'delta_port'),
          RUDDER_STBD: ('position', 'delta_stbd')}


def stamp_from_seconds(seconds: float) -> Time:
    """Return a builtin_interfaces/Time for seconds since the epoch (>= 0)."""
    sec = math.floor(seconds)
    nanosec = int(round((seconds - sec) * 1e9))
    if nanosec >= 1_000_000_000:
        sec, nanosec = sec + 1, nanosec - 1_000_000_000
    return Time(sec=int(sec), nanosec=nanosec)


def seconds_from_stamp(stamp) -> float:
    """Return the seconds of a Time-like object (``sec``, ``nanosec``)."""
    return stamp.sec + stamp.nanosec * 1e-9


def odometry_from_state(state, stamp: Time, world_frame: str, body_frame: str) -> Odometry:
    """
    Build an Odometry from a vessel state in the physics' frames.

    ``state`` maps u, v (m/s), p, r (rad/s) in FRD, phi, psi (rad) and x, y (m, NED) to
    floats. The pose goes to ``world_frame`` (ENU), the twist to ``body_frame`` (FLU).
    """
    msg = Odometry()
    msg.header.stamp = stamp
    msg.header.frame_id = world_frame
    msg.child_frame_id = body_frame
    east, north, _ = frames.position_ned_to_enu(float(state['x']), float(state['y']))
    msg.pose.pose.position.x, msg.pose.pose.position.y = float(east), float(north)
    qx, qy, qz, qw = frames.orientation_ned_to_enu(float(state['phi']), float(state['psi']))
    orientation = msg.pose.pose.orientation
    orientation.x, orientation.y, orientation.z, orientation.w = (
        float(qx), float(qy), float(qz), float(qw))
    vx, vy, wx, wz = frames.twist_frd_to_flu(float(state['u']), float(state['v']),
                                             float(state['p']), float(state['r']))
    twist = msg.twist.twist
    twist.linear.x, twist.linear.y = float(vx), float(vy)
    twist.angular.x, twist.angular.z = float(wx), float(wz)
    return msg


def state_from_odometry(msg) -> dict[str, float]:
    """
    Read u, v, p, r (FRD), phi, psi (rad; psi wrapped) and x, y (m, NED) from an Odometry.

    The heading comes back wrapped; callers that need it continuous unwrap it over time.
    """
    pose, twist = msg.pose.pose, msg.twist.twist
    q = pose.orientation
    phi, _theta, psi = frames.orientation_enu_to_ned(q.x, q.y, q.z, q.w)
    north, east, _ = frames.position_enu_to_ned(pose.position.x, pose.position.y)
    u, v, p, r = frames.twist_flu_to_frd(twist.linear.x, twist.linear.y,
                                         twist.angular.x, twist.angular.z)
    return {'u': float(u), 'v': float(v), 'p': float(p), 'r': float(r), 'phi': float(phi),
            'psi': float(psi), 'x': float(north), 'y': float(east)}


def joint_state_from_actuators(actuators, stamp: Time) -> JointState:
    """Build a JointState from n (rad/s), delta_port and delta_stbd (rad)."""
    msg = JointState()
    msg.header.stamp = stamp
    msg.name = list(JOINTS)
    msg.position = [0.0] * len(JOINTS)
    msg.velocity = [0.0] * len(JOINTS)
    for i, (field, key) in enumerate(JOINTS.values()):
        getattr(msg, field)[i] = float(actuators[key])
    return msg


def actuators_from_joint_state(msg) -> dict[str, float]:
    """
    Read the actuators a JointState names: a dict with any of n, delta_port, delta_stbd.

    Raises ValueError when the message names none of them, or a named joint lacks the
    field that carries its value.
    """
    out = {}
    for i, name in enumerate(msg.name):
        if name not in JOINTS:
            continue
        field, key = JOINTS[name]
        values = getattr(msg, field)
        if len(values) <= i:
            raise ValueError(f'joint {name!r} has no {field} entry '
                             f'({len(values)} {field} values for {len(msg.name)} names)')
        out[key] = float(values[i])
    if not out:
        raise ValueError(f'names none of {sorted(JOINTS)}: got {list(msg.name)}')
    return out


def wind_from_measurement(speed: float, dir_cos: float, dir_sin: float, stamp: Time,
                          body_frame: str) -> Vector3Stamped:
    """Build the true wind velocity (m/s, where the air moves to) in the FLU body frame."""
    msg = Vector3Stamped()
    msg.header.stamp = stamp
    msg.header.frame_id = body_frame
    vx, vy, _ = frames.wind_to_flu(float(speed), float(dir_cos), float(dir_sin))
    msg.vector.x, msg.vector.y = float(vx), float(vy)
    return msg


def measurement_from_wind(msg) -> dict[str, float]:
    """Read wind_speed (m/s), wind_dir_cos and wind_dir_sin from a wind Vector3Stamped."""
    speed, dir_cos, dir_sin = frames.wind_from_flu(msg.vector.x, msg.vector.y)
    return {'wind_speed': float(speed), 'wind_dir_cos': float(dir_cos),
            'wind_dir_sin': float(dir_sin)}


def message_types(topic_map) -> dict:
    """Message class of every topic of a topic map, from the ``type`` its entries name."""
    out = {}
    for topic in topic_map.topics:
        names = {e.msgtype for e in topic_map.entries if e.topic == topic and e.msgtype}
        if len(names) != 1:
            raise TopicMapError(f'vessel {topic_map.vessel.name!r}: topic {topic} needs one '
                                f'type (type: pkg/msg/Name on one of its entries) to be '
                                f'subscribed or published; got {sorted(names) or "none"}')
        package, _, name = names.pop().split('/')
        try:
            out[topic] = getattr(importlib.import_module(f'{package}.msg'), name)
        except (ImportError, AttributeError):
            raise TopicMapError(f'topic {topic}: message type {package}/msg/{name} is not '
                                f'installed (build and source its interface package)') \
                from None
    return out
