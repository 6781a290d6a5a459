"""
A topic map's messages, read and written: channels from a message, messages from a state.

``channel_reader`` reads a topic's channels from any message object with the mapped
fields (the predictor's inputs, the simulator's commands).

Writing is the inverse of conversion (``quantities``), from a vessel's state in the
model's frames to the messages its topic map names: a simulator of any vessel publishes
what the vessel's own sensors would, on the topics, fields, frames and scales of its
vessel file's ``recordings.topics`` (docs/bags.md), so the predictor and the converter
read it like recordings of the real vessel. A 6-DOF vehicle's messages carry the third
components too: heave, pitch rate and pitch, the height (``quantities.to_spatial_columns``
read backwards). Where an entry lists alternatives the first is written. Entries only
recordings can carry (latitude/longitude, earth-frame velocities, a wind speed and
angle, speed over ground) are refused in one line.

``MessageWriter(topic_map, types)`` builds one message per topic from a sample (a
mapping of the vessel's dataset columns: u, v, [w], [p], [q], r, [phi], [theta], psi, x,
y, [z], actuators, wind) with any message classes that have the mapped fields (rclpy's,
rosbags'); frame ids are the world frame for messages that carry a pose, the body frame
otherwise.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from vessel_physics import frames

from .fields import compile_getter, pad_named, parse_path, set_path
from .topic_map import ACTUATOR_PREFIX, TopicMap, TopicMapError

WRITABLE = {'body_velocity': ('surge', 'sway', 'heave', 'roll_rate', 'pitch_rate', 'yaw_rate'),
            'attitude': ('quaternion', 'heading', 'roll', 'pitch'),
            'position': ('point', 'x', 'y', 'z'), 'wind': ('velocity',)}
POSE_GROUPS = ('position', 'attitude')


def channel_values(sample: Mapping[str, float], topic_map: TopicMap) -> dict[str, float]:
    """Every channel of the map in the messages' frames and units (before scale/offset)."""
    if topic_map.vessel.is_spatial:
        return spatial_channel_values(sample, topic_map)
    out: dict[str, float] = {}
    u, v, r = sample['u'], sample['v'], sample['r']
    p, phi = sample.get('p', 0.0), sample.get('phi', 0.0)
    psi = sample['psi']
    body = frames.twist_frd_to_flu(u, v, p, r) if topic_map.frames['body_velocity'] == 'flu' \
        else (u, v, p, r)
    out.update(zip(('surge', 'sway', 'roll_rate', 'yaw_rate'), body, strict=True))
    if topic_map.frames['attitude'] == 'enu_flu':
        q = frames.orientation_ned_to_enu(phi, psi)
        out['heading'] = frames.heading_ned_to_enu(psi)
    else:
        q = frames.quaternion_from_euler(phi, 0.0, psi)
        out['heading'] = psi
    out.update(zip(('qx', 'qy', 'qz', 'qw'), (float(x) for x in q), strict=True))
    out['roll'] = phi
    if topic_map.frames['position'] == 'enu':
        out['pos_x'], out['pos_y'], _ = frames.position_ned_to_enu(sample['x'], sample['y'])
    else:
        out['pos_x'], out['pos_y'] = sample['x'], sample['y']
    for name in topic_map.vessel.actuator_names:
        out[ACTUATOR_PREFIX + name] = sample[name]
    if topic_map.has_group('wind'):
        wx, wy, _ = frames.wind_to_flu(sample['wind_speed'], sample['wind_dir_cos'],
                                       sample['wind_dir_sin'])
        if topic_map.frames['wind'] == 'frd':
            wx, wy, _ = frames.body_flu_to_frd(wx, wy)
        out['wind_x'], out['wind_y'] = wx, wy
    return {k: float(x) for k, x in out.items()}


def spatial_channel_values(sample: Mapping[str, float], topic_map: TopicMap
                           ) -> dict[str, float]:
    """``channel_values`` of a 6-DOF vehicle: all three components of each quantity."""
    velocity = (sample['u'], sample['v'], sample['w'])
    rates = (sample['p'], sample['q'], sample['r'])
    if topic_map.frames['body_velocity'] == 'flu':
        velocity, rates = frames.body_frd_to_flu(*velocity), frames.body_frd_to_flu(*rates)
    out = dict(zip(('surge', 'sway', 'heave', 'roll_rate', 'pitch_rate', 'yaw_rate'),
                   (*velocity, *rates), strict=True))
    phi, theta, psi = sample['phi'], sample['theta'], sample['psi']
    if topic_map.frames['attitude'] == 'enu_flu':     # pitch turns about FLU's y: -theta
        q = frames.orientation_ned_to_enu(phi, psi, theta)
        out['heading'], out['pitch'] = frames.heading_ned_to_enu(psi), -theta
    else:
        q = frames.quaternion_from_euler(phi, theta, psi)
        out['heading'], out['pitch'] = psi, theta
    out.update(zip(('qx', 'qy', 'qz', 'qw'), (float(x) for x in q), strict=True))
    out['roll'] = phi
    point = (sample['x'], sample['y'], sample['z'])
    if topic_map.frames['position'] == 'enu':
        point = frames.position_ned_to_enu(*point)
    out['pos_x'], out['pos_y'], out['pos_z'] = point
    for name in topic_map.vessel.actuator_names:
        out[ACTUATOR_PREFIX + name] = sample[name]
    return {k: float(x) for k, x in out.items()}


def check_writable(topic_map: TopicMap) -> None:
    """Raise TopicMapError (one line) for an entry a simulator cannot publish."""
    for entry in topic_map.entries:
        if entry.group != 'actuators' and entry.name not in WRITABLE.get(entry.group, ()):
            raise TopicMapError(f'vessel {topic_map.vessel.name!r}: {entry.label} '
                                f'({entry.topic}) is what only a recording carries; the '
                                f'simulator publishes {sorted(WRITABLE)} groups and '
                                f'actuators (map alternatives that it can write first)')


class MessageWriter:
    """Build a topic map's messages from samples (module docstring)."""

    def __init__(self, topic_map: TopicMap, types: Mapping[str, Callable],
                 world_frame: str = 'odom', body_frame: str = 'base_link'):
        check_writable(topic_map)
        self.topic_map = topic_map
        self.types = dict(types)
        self.world_frame, self.body_frame = world_frame, body_frame
        self.leaves = {topic: [leaf for leaf in topic_map.leaves() if leaf.topic == topic]
                       for topic in topic_map.topics}
        # Elements indexed by name (JointState's velocity[m1]) pad their arrays to the names.
        self.named = {topic: [leaf.path for leaf in leaves
                              if isinstance(parse_path(leaf.path)[-1].key, str)]
                      for topic, leaves in self.leaves.items()}
        self.frame = {topic: world_frame if any(leaf.group in POSE_GROUPS for leaf in leaves)
                      else body_frame for topic, leaves in self.leaves.items()}

    @property
    def topics(self) -> list[str]:
        """Return the topics, the state's last (a reader holding a state has the sample)."""
        state = next(e.topic for e in self.topic_map.entries if e.group == 'body_velocity')
        return [t for t in self.topic_map.topics if t != state] + [state]

    def message(self, topic: str, channels: Mapping[str, float], stamp=None):
        """Return the message of ``topic`` carrying ``channels`` (``channel_values``)."""
        msg = self.types[topic]()
        for leaf in self.leaves[topic]:
            set_path(msg, leaf.path, (channels[leaf.channel] - leaf.offset) / leaf.scale)
        for path in self.named[topic]:
            pad_named(msg, path)
        header = getattr(msg, 'header', None)
        if header is not None:
            if stamp is not None:
                header.stamp = stamp
            header.frame_id = self.frame[topic]
        if hasattr(msg, 'child_frame_id'):
            msg.child_frame_id = self.body_frame
        return msg


def channel_reader(topic_map: TopicMap, topic: str):
    """
    Return a function reading a topic's channel values from one of its messages.

    It takes any message object with the mapped fields (rclpy or rosbags) and returns
    ``{channel: scale * field + offset}``. An element a message does not carry (a joint
    it does not name) is left out, so the stream completes it from its last sample; a
    message carrying none of the topic's channels raises ValueError.
    """
    leaves = [leaf for leaf in topic_map.leaves() if leaf.topic == topic]
    reads = [(leaf.channel, compile_getter(leaf.path, absent=None), leaf.scale, leaf.offset)
             for leaf in leaves]
    fields = ', '.join(leaf.path for leaf in leaves)

    def read(msg) -> dict[str, float]:
        out = {}
        for channel, get, scale, offset in reads:
            value = get(msg)
            if value is not None:
                out[channel] = scale * float(value) + offset
        if not out:
            raise ValueError(f'carries none of the mapped fields ({fields})')
        return out

    return read
