"""
Synthetic recordings of the simulator's topics, for tests, benchmarks and examples.

``simulation_vessel`` and ``simulated_run_table`` turn the batch simulator's output into
dataset tables of its vessel file (``offline/simulate.py``, the diagnosis scenarios).

``demo_trajectory`` makes a smooth, plausible manoeuvre in the model's frames (NED/FRD,
docs/conventions.md); ``sim_messages`` turns it into the messages the simulator
publishes (ENU/FLU, through ``vessel_physics.frames``), and ``write_bag`` records them
as a rosbag2 MCAP directory the way the recorder does. Converting such a bag must give
the trajectory back, which tests the whole chain without a simulator.

``write_simulated_bag`` records a batch simulator run of any vehicle as the simulator
node publishes it: its vessel file's topic map written by ``topic_messages.MessageWriter``
into rosbags' message classes (``default_message``), so converting the bag tests the
node's writer and the converter against each other.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, replace
import math
import os
from pathlib import Path

import numpy as np
import pandas as pd
from rosbags.interfaces import Nodetype
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from vessel_description import Vessel, load_vessel
from vessel_physics import frames
from vessel_physics.simulation.config import DEFAULT_VESSEL

from .format import TRUE_SUFFIX
from .topic_map import topic_map_for
from .topic_messages import MessageWriter, channel_values

SIM_VESSEL = DEFAULT_VESSEL  # the vessel whose topics the simulator publishes by default
SIM_TOPICS = {
    '/vessel/odom': 'nav_msgs/msg/Odometry',
    '/vessel/actuators': 'sensor_msgs/msg/JointState',
    '/vessel/wind': 'geometry_msgs/msg/Vector3Stamped',
}
JOINT_NAMES = ('propeller', 'rudder_port', 'rudder_stbd')
DEFAULT_START_NS = 1_700_000_000 * 1_000_000_000  # 2023-11-14, an arbitrary fixed epoch
DEFAULT_LOG_DELAY_NS = 2_000_000  # recorders receive a message ~ms after its stamp


def simulation_vessel(config) -> Vessel:
    """Return a simulation's vessel file at its output rate (``SimConfig``)."""
    return replace(config.vessel, rate_hz=float(config.output_rate_hz))


def simulated_run_table(data: dict, j: int, vessel: Vessel) -> pd.DataFrame:
    """Run ``j`` of a batch simulator result as a dataset table, noise-free truth included."""
    truth = vessel.state_names + vessel.pose_names
    columns = vessel.dataset_columns + tuple(k + TRUE_SUFFIX for k in truth)
    return pd.DataFrame({c: data[c][j] for c in columns})


@dataclass
class Trajectory:
    """Samples of every dataset column at times ``t_ns`` (model frames, absolute x, y)."""

    t_ns: np.ndarray
    columns: dict[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.t_ns)


def demo_trajectory(n: int, rate_hz: float = 1.0, start_ns: int = DEFAULT_START_NS,
                    seed: int = 0) -> Trajectory:
    """
    Return a smooth manoeuvre of ``n`` samples: zig-zag turns, rolling, gusty wind.

    Kinematics are consistent (psi integrates r, x and y integrate the velocities) so
    the trajectory looks like a ship, but no physics is simulated.
    """
    rng = np.random.default_rng(seed)
    dt = 1.0 / rate_hz
    t = np.arange(n) * dt
    phase = rng.uniform(0, 2 * math.pi, 6)
    u = 4.0 + 0.5 * np.sin(2 * math.pi * t / 600 + phase[0])
    v = 0.2 * np.sin(2 * math.pi * t / 240 + phase[1])
    r = 0.03 * np.sin(2 * math.pi * t / 180 + phase[2])
    phi = 0.04 * np.sin(2 * math.pi * t / 9 + phase[3])
    p = 0.04 * 2 * math.pi / 9 * np.cos(2 * math.pi * t / 9 + phase[3])
    psi = 0.3 + np.cumsum(r) * dt
    x = np.cumsum(u * np.cos(psi) - v * np.sin(psi)) * dt
    y = np.cumsum(u * np.sin(psi) + v * np.cos(psi)) * dt
    shaft = 20.0 + 2.0 * np.round(np.sin(2 * math.pi * t / 900 + phase[4]))
    rudder = -0.25 * np.sign(r) * (np.abs(r) > 0.01)
    wind_speed = np.abs(6.0 + 1.5 * np.sin(2 * math.pi * t / 120 + phase[5]))
    wind_dir = 0.8 + 0.3 * np.sin(2 * math.pi * t / 1000)
    columns = {'u': u, 'v': v, 'p': p, 'r': r, 'phi': phi, 'psi': psi, 'x': x, 'y': y,
               'n': shaft, 'delta_port': rudder, 'delta_stbd': rudder.copy(),
               'wind_speed': wind_speed, 'wind_dir_cos': np.cos(wind_dir),
               'wind_dir_sin': np.sin(wind_dir)}
    assert set(columns) == set(load_vessel(SIM_VESSEL).dataset_columns[1:])
    return Trajectory(start_ns + np.round(t * 1e9).astype(np.int64), columns)


def sim_messages(traj: Trajectory, store: Typestore | None = None
                 ) -> Iterator[tuple[str, int, object]]:
    """Yield ``(topic, stamp_ns, message)`` as the simulator publishes the trajectory."""
    store = store or get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    c = traj.columns
    ex, ny, _ = frames.position_ned_to_enu(c['x'], c['y'])
    qx, qy, qz, qw = frames.orientation_ned_to_enu(c['phi'], c['psi'])
    vx, vy, wx, wz = frames.twist_frd_to_flu(c['u'], c['v'], c['p'], c['r'])
    windx, windy, _ = frames.wind_to_flu(c['wind_speed'], c['wind_dir_cos'],
                                         c['wind_dir_sin'])
    zero36 = np.zeros(36)
    empty = np.zeros(0)
    Vector3, Header, Time = (T['geometry_msgs/msg/Vector3'], T['std_msgs/msg/Header'],
                             T['builtin_interfaces/msg/Time'])
    for i, ns in enumerate(traj.t_ns.tolist()):
        stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        odom = T['nav_msgs/msg/Odometry'](
            header=Header(stamp=stamp, frame_id='odom'), child_frame_id='base_link',
            pose=T['geometry_msgs/msg/PoseWithCovariance'](
                pose=T['geometry_msgs/msg/Pose'](
                    position=T['geometry_msgs/msg/Point'](x=float(ex[i]), y=float(ny[i]),
                                                          z=0.0),
                    orientation=T['geometry_msgs/msg/Quaternion'](
                        x=float(qx[i]), y=float(qy[i]), z=float(qz[i]), w=float(qw[i]))),
                covariance=zero36),
            twist=T['geometry_msgs/msg/TwistWithCovariance'](
                twist=T['geometry_msgs/msg/Twist'](
                    linear=Vector3(x=float(vx[i]), y=float(vy[i]), z=0.0),
                    angular=Vector3(x=float(wx[i]), y=0.0, z=float(wz[i]))),
                covariance=zero36))
        yield '/vessel/odom', ns, odom
        body = Header(stamp=stamp, frame_id='base_link')
        yield '/vessel/actuators', ns, T['sensor_msgs/msg/JointState'](
            header=body, name=list(JOINT_NAMES),
            position=np.array([0.0, c['delta_port'][i], c['delta_stbd'][i]]),
            velocity=np.array([c['n'][i], 0.0, 0.0]), effort=empty)
        yield '/vessel/wind', ns, T['geometry_msgs/msg/Vector3Stamped'](
            header=body, vector=Vector3(x=float(windx[i]), y=float(windy[i]), z=0.0))


def write_bag(path: str | os.PathLike, traj: Trajectory, store: Typestore | None = None,
              log_delay_ns: int = DEFAULT_LOG_DELAY_NS) -> Path:
    """Record the trajectory's messages as a rosbag2 MCAP directory; return its path."""
    store = store or get_typestore(Stores.ROS2_JAZZY)
    path = Path(path)
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {topic: w.add_connection(topic, msgtype, typestore=store)
                 for topic, msgtype in SIM_TOPICS.items()}
        serialize = store.serialize_cdr
        for topic, ns, msg in sim_messages(traj, store):
            w.write(conns[topic], ns + log_delay_ns, serialize(msg, SIM_TOPICS[topic]))
    return path


def default_message(store: Typestore, msgtype: str):
    """Return a rosbags message of ``msgtype`` with every field zero or empty."""
    _, fields = store.fielddefs[msgtype]
    return store.types[msgtype](**{name: _default_field(store, node, detail)
                                   for name, (node, detail) in fields})


def _default_field(store: Typestore, node, detail):
    if node == Nodetype.BASE:
        kind = detail[0]
        return '' if kind == 'string' else False if kind == 'bool' else \
            0.0 if kind.startswith('float') else 0
    if node == Nodetype.NAME:
        return default_message(store, detail)
    (sub_node, sub_detail), length = detail
    size = length if node == Nodetype.ARRAY else 0
    if sub_node == Nodetype.BASE and sub_detail[0] not in ('string', 'bool'):
        return np.zeros(size, dtype=np.dtype(sub_detail[0].replace('byte', 'uint8')
                                             .replace('char', 'uint8')))
    return [_default_field(store, sub_node, sub_detail) for _ in range(size)]


def write_simulated_bag(path: str | os.PathLike, data: dict, j: int, vessel: Vessel,
                        store: Typestore | None = None, start_ns: int = DEFAULT_START_NS,
                        log_delay_ns: int = DEFAULT_LOG_DELAY_NS) -> Path:
    """
    Record run ``j`` of a batch simulator result (``Simulator.run``) as the node would.

    The topics, types and fields of the vessel file's ``recordings.topics``, written
    with ``MessageWriter`` from the measured columns; stamps ``start_ns`` + t.
    """
    store = store or get_typestore(Stores.ROS2_JAZZY)
    topic_map = topic_map_for(vessel)
    msgtypes = {e.topic: e.msgtype for e in topic_map.entries if e.msgtype}
    writer = MessageWriter(topic_map, {topic: (lambda m=msgtype: default_message(store, m))
                                       for topic, msgtype in msgtypes.items()})
    Time = store.types['builtin_interfaces/msg/Time']
    path = Path(path)
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {topic: w.add_connection(topic, msgtypes[topic], typestore=store)
                 for topic in writer.topics}
        for i in range(data['t'].shape[1]):
            sample = {key: float(values[j, i]) for key, values in data.items()}
            ns = start_ns + round(sample['t'] * 1e9)
            stamp = Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
            channels = channel_values(sample, topic_map)
            for topic in writer.topics:
                msg = writer.message(topic, channels, stamp)
                w.write(conns[topic], ns + log_delay_ns, store.serialize_cdr(msg, msgtypes[topic]))
    return path
