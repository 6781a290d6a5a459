"""
From the topic map's channels (message frames) to the dataset's columns (model frames).

Two steps around resampling:

* ``derive`` works per topic on the raw samples, where one message's components belong
  together: an orientation becomes roll ``phi`` and an unwrapped heading ``psi``
  (angles must be unwrapped before they are interpolated), a wind speed and angle
  become a velocity vector.
* ``to_columns`` works on one run's resampled grid and produces the vessel's dataset
  columns: body velocities in FRD (roll only where the vessel models it), position
  north/east of the run's start, its actuators, and, where it has a wind input, the
  wind's speed and direction relative to the bow.

Every ENU/FLU <-> NED/FRD change goes through ``vessel_physics.frames``, the one place
that defines it; this module only chooses which conversion a topic map's frame tag
asks for.
"""

from __future__ import annotations

from collections.abc import Mapping
import math

import numpy as np

from vessel_physics import frames

from .extract import TopicSamples
from .topic_map import ACTUATOR_PREFIX, TopicMap

# WGS 84 ellipsoid, for projecting latitude/longitude onto a local north/east plane.
WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563

# Group of each channel ``derive`` creates (for its resampling method).
DERIVED_GROUP = {'phi': 'attitude', 'psi': 'attitude', 'wind_x': 'wind', 'wind_y': 'wind'}


def derive(samples: TopicSamples, topic_map: TopicMap) -> TopicSamples:
    """Replace one topic's per-message composite channels by the scalars to resample."""
    cols = {c: samples.column(c) for c in samples.channels}
    attitude = topic_map.frames['attitude']
    if {'qx', 'qy', 'qz', 'qw'} <= cols.keys():
        q = np.column_stack([cols.pop(c) for c in ('qx', 'qy', 'qz', 'qw')])
        q = q / np.linalg.norm(q, axis=1, keepdims=True)  # sensors round their quaternions
        if attitude == 'enu_flu':
            phi, _, psi = frames.orientation_enu_to_ned(*q.T)
        else:
            phi, _, psi = frames.euler_from_quaternion(*q.T)
        cols['phi'], cols['psi'] = phi, psi
    if 'heading' in cols:
        heading = cols.pop('heading')
        cols['psi'] = frames.heading_enu_to_ned(heading) if attitude == 'enu_flu' else heading
    if 'roll' in cols:
        cols['phi'] = cols.pop('roll')  # the same angle about the shared x axis
    if 'psi' in cols:
        cols['psi'] = np.unwrap(cols['psi']) if len(cols['psi']) else cols['psi']
    if {'wind_speed', 'wind_from_angle'} <= cols.keys():
        cols['wind_x'], cols['wind_y'] = polar_to_vector(cols.pop('wind_speed'),
                                                         cols.pop('wind_from_angle'))
    names = tuple(cols)
    values = np.column_stack([cols[c] for c in names]) if names else samples.values
    return TopicSamples(samples.topic, samples.msgtype, names, samples.t_ns, values,
                        received=samples.received, dropped=samples.dropped,
                        unreadable=samples.unreadable)


def polar_to_vector(speed, from_angle) -> tuple[np.ndarray, np.ndarray]:
    """
    Velocity (x, y) of air moving at ``speed`` and coming from ``from_angle``.

    The angle is measured from the body x axis towards its y axis, so the vector is in
    the frame the angle was given in (FLU: positive to port; FRD: to starboard).
    """
    speed, angle = np.asarray(speed, float), np.asarray(from_angle, float)
    return -speed * np.cos(angle), -speed * np.sin(angle)


def channel_methods(topic_map: TopicMap) -> dict[str, str]:
    """Resampling method of every channel, derived ones included."""
    out = {leaf.channel: topic_map.resample[leaf.group] for leaf in topic_map.leaves()}
    out.update({c: topic_map.resample[g] for c, g in DERIVED_GROUP.items()
                if topic_map.has_group(g)})
    return out


def to_columns(ch: Mapping[str, np.ndarray], topic_map: TopicMap,
               relative: bool = True) -> dict[str, np.ndarray]:
    """
    Return the map's vessel's dataset columns (docs/conventions.md) from channels.

    ``relative``: position north/east of the first sample (a dataset run); otherwise in
    the recording's own frame origin (the predictor's published track).
    """
    vessel = topic_map.vessel
    out: dict[str, np.ndarray] = {}
    zero = np.zeros_like(np.asarray(ch['surge'], float))
    body = (ch['surge'], ch['sway'], ch.get('roll_rate', zero), ch['yaw_rate'])
    if topic_map.frames['body_velocity'] == 'flu':
        body = frames.twist_flu_to_frd(*body)
    u, v, p, r = (np.asarray(a, float) for a in body)
    out['u'], out['v'], out['r'] = u, v, r
    if vessel.has_roll:
        out['p'], out['phi'] = p, np.asarray(ch['phi'], float)

    psi = np.asarray(ch['psi'], float)
    # Unwrapping leaves a multiple of 2 pi; start every run inside [-pi, pi].
    out['psi'] = psi - 2.0 * math.pi * np.round(psi[0] / (2.0 * math.pi))

    if 'lat' in ch:
        north, east = latlon_to_local(ch['lat'], ch['lon'])
    elif topic_map.frames['position'] == 'enu':
        north, east, _ = frames.position_enu_to_ned(ch['pos_x'], ch['pos_y'])
    else:
        north, east = ch['pos_x'], ch['pos_y']
    north, east = np.asarray(north, float), np.asarray(east, float)
    if relative:
        north, east = north - north[0], east - east[0]
    out['x'], out['y'] = north, east

    for name in vessel.actuator_names:
        out[name] = np.asarray(ch[ACTUATOR_PREFIX + name], float)

    if 'wind' in vessel.environment:
        wx, wy = np.asarray(ch['wind_x'], float), np.asarray(ch['wind_y'], float)
        if topic_map.frames['wind'] == 'frd':
            wx, wy, _ = frames.body_frd_to_flu(wx, wy)
        speed, cos, sin = frames.wind_from_flu(wx, wy)
        out['wind_speed'] = np.asarray(speed, float)
        out['wind_dir_cos'], out['wind_dir_sin'] = (np.asarray(cos, float),
                                                    np.asarray(sin, float))
    return {c: out[c] for c in vessel.dataset_columns[1:]}


def latlon_to_local(lat_deg, lon_deg) -> tuple[np.ndarray, np.ndarray]:
    """
    North and east (m) of the first fix, on the plane tangent at that fix.

    Uses the WGS 84 radii of curvature at the first latitude; over the few kilometres
    of a run the error is far below GNSS noise.
    """
    lat, lon = np.radians(np.asarray(lat_deg, float)), np.radians(np.asarray(lon_deg, float))
    e2 = WGS84_F * (2.0 - WGS84_F)
    s = math.sin(lat[0])
    w = math.sqrt(1.0 - e2 * s * s)
    meridian = WGS84_A_M * (1.0 - e2) / w ** 3
    prime = WGS84_A_M / w
    dlon = np.angle(np.exp(1j * (lon - lon[0])))  # across the antimeridian too
    return (lat - lat[0]) * meridian, dlon * prime * math.cos(lat[0])
