"""
From the topic map's channels (message frames) to the dataset's columns (model frames).

Two steps around resampling:

* ``derive`` works per topic on the raw samples, where one message's components belong
  together: an orientation becomes roll ``phi`` and an unwrapped heading ``psi``
  (angles must be unwrapped before they are interpolated), a wind speed and angle
  become a velocity vector.
* ``to_columns`` works on one run's resampled grid and produces the vessel's dataset
  columns: body velocities in FRD (measured in the body, or earth-frame velocities
  ``vel_north``/``vel_east`` rotated into it by the heading), roll only where the vessel
  models it, position north/east of the run's start (latitude/longitude projected with
  pyproj), its actuators, and, where it has a wind input, the wind's speed and
  direction relative to the bow. A 6-DOF vehicle's columns (``to_spatial_columns``)
  take all three components: heave, pitch rate and pitch, down and the height, with
  earth-frame velocities turned into the body by the whole attitude.

Every ENU/FLU <-> NED/FRD change goes through ``vessel_physics.frames``, the one place
that defines it; this module only chooses which conversion a topic map's frame tag
asks for (``model_column`` does it sample by sample, for the spike policy).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import lru_cache
import math

import numpy as np
from pyproj import Transformer

from vessel_physics import frames
from vessel_physics.integrator import ned_to_body_3d

from .extract import TopicSamples
from .topic_map import ACTUATOR_PREFIX, TopicMap

# Group of each channel ``derive`` (or the converter: rates from angles, velocities from
# the track) creates, for its resampling method.
DERIVED_GROUP = {'phi': 'attitude', 'psi': 'attitude', 'theta': 'attitude', 'wind_x': 'wind',
                 'wind_y': 'wind', 'yaw_rate': 'body_velocity', 'roll_rate': 'body_velocity',
                 'vel_north': 'earth_velocity', 'vel_east': 'earth_velocity'}
# Body channel -> (dataset state, sign of the FLU -> FRD change: frames.body_flu_to_frd).
BODY_STATES = {'surge': ('u', 1.0), 'sway': ('v', -1.0), 'heave': ('w', -1.0),
               'roll_rate': ('p', 1.0), 'pitch_rate': ('q', -1.0), 'yaw_rate': ('r', -1.0)}


def derive(samples: TopicSamples, topic_map: TopicMap) -> TopicSamples:
    """Replace one topic's per-message composite channels by the scalars to resample."""
    cols = {c: samples.column(c) for c in samples.channels}
    attitude = topic_map.frames['attitude']
    if {'qx', 'qy', 'qz', 'qw'} <= cols.keys():
        q = np.column_stack([cols.pop(c) for c in ('qx', 'qy', 'qz', 'qw')])
        q = q / np.linalg.norm(q, axis=1, keepdims=True)  # sensors round their quaternions
        if attitude == 'enu_flu':
            phi, theta, psi = frames.orientation_enu_to_ned(*q.T)
        else:
            phi, theta, psi = frames.euler_from_quaternion(*q.T)
        cols['phi'], cols['psi'] = phi, psi
        if topic_map.vessel.is_spatial:
            cols['theta'] = theta
    if 'pitch' in cols:   # FLU pitch turns about the y axis FRD reverses
        pitch = cols.pop('pitch')
        cols['theta'] = -pitch if attitude == 'enu_flu' else pitch
    if 'heading' in cols:
        heading = cols.pop('heading')
        cols['psi'] = frames.heading_enu_to_ned(heading) if attitude == 'enu_flu' else heading
    if 'roll' in cols:
        cols['phi'] = cols.pop('roll')  # the same angle about the shared x axis
    if 'psi' in cols:
        cols['psi'] = unwrap(cols['psi'])
    if {'wind_speed', 'wind_from_angle'} <= cols.keys():
        cols['wind_x'], cols['wind_y'] = polar_to_vector(cols.pop('wind_speed'),
                                                         cols.pop('wind_from_angle'))
    names = tuple(cols)
    values = np.column_stack([cols[c] for c in names]) if names else samples.values
    return TopicSamples(samples.topic, samples.msgtype, names, samples.t_ns, values,
                        received=samples.received, dropped=samples.dropped,
                        unreadable=samples.unreadable)


def unwrap(angle: np.ndarray) -> np.ndarray:
    """Unwrap an angle across its finite samples only (a NaN would spoil the rest)."""
    out = np.array(angle, float)
    ok = np.isfinite(out)
    if ok.any():
        out[ok] = np.unwrap(out[ok])
    return out


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
    out.update({c: topic_map.resample.get(g, 'linear') for c, g in DERIVED_GROUP.items()
                if g != 'wind' or topic_map.has_group(g)})
    return out


# Channels ``derive`` makes -> the leaf channels whose entry's delay they take.
DELAY_FROM = {'psi': ('heading', 'qx'), 'phi': ('roll', 'qx'), 'theta': ('pitch', 'qx'),
              'wind_x': ('wind_x', 'wind_speed'), 'wind_y': ('wind_y', 'wind_speed')}


def channel_delays(topic_map: TopicMap) -> dict[str, float]:
    """Delay (s) of every channel, derived ones included: the ``delay_s`` of its entry."""
    out = {leaf.channel: leaf.delay_s for leaf in topic_map.leaves()}
    for channel, sources in DELAY_FROM.items():
        found = [out[c] for c in sources if c in out]
        if found:
            out.setdefault(channel, found[0])
    return out


def model_column(channel: str, values: np.ndarray, topic_map: TopicMap
                 ) -> tuple[str, np.ndarray] | None:
    """
    Return the dataset column a channel gives and its values in the model's frame.

    Only channels that are a state or an actuator on their own (sample by sample) have
    one; others (positions, angles to combine) give None.
    """
    vessel = topic_map.vessel
    if channel in BODY_STATES:
        state, flu_sign = BODY_STATES[channel]
        sign = flu_sign if topic_map.frames.get('body_velocity') == 'flu' else 1.0
        return (state, sign * values) if state in vessel.states else None
    if channel == 'phi' and vessel.has_roll:
        return 'phi', values
    if channel == 'theta' and vessel.is_spatial:
        return 'theta', values
    if channel.startswith(ACTUATOR_PREFIX):
        return channel[len(ACTUATOR_PREFIX):], values
    return None


def to_columns(ch: Mapping[str, np.ndarray], topic_map: TopicMap,
               relative: bool = True) -> dict[str, np.ndarray]:
    """
    Return the map's vessel's dataset columns (docs/conventions.md) from channels.

    ``relative``: position north/east of the first sample (a dataset run); otherwise in
    the recording's own frame origin (the predictor's published track).
    """
    vessel = topic_map.vessel
    if vessel.is_spatial:
        return to_spatial_columns(ch, topic_map, relative)
    out: dict[str, np.ndarray] = {}
    psi = np.asarray(ch['psi'], float)
    phi = np.asarray(ch['phi'], float) if vessel.has_roll else np.zeros_like(psi)
    zero = np.zeros_like(psi)
    surge, sway = ch.get('surge', zero), ch.get('sway', zero)
    body = (surge, sway, ch.get('roll_rate', zero), ch['yaw_rate'])
    if topic_map.frames['body_velocity'] == 'flu':
        body = frames.twist_flu_to_frd(*body)
    u, v, p, r = (np.asarray(a, float) for a in body)
    if 'surge' not in ch:  # earth-frame velocities, measured or from the track
        u, v = earth_to_body(ch['vel_north'], ch['vel_east'], psi, phi)
    out['u'], out['v'], out['r'] = u, v, r
    if vessel.has_roll:
        out['p'], out['phi'] = p, phi

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

    out.update(actuator_columns(ch, topic_map))

    if 'wind' in vessel.environment:
        wx, wy = np.asarray(ch['wind_x'], float), np.asarray(ch['wind_y'], float)
        if topic_map.frames['wind'] == 'frd':
            wx, wy, _ = frames.body_frd_to_flu(wx, wy)
        speed, cos, sin = frames.wind_from_flu(wx, wy)
        out['wind_speed'] = np.asarray(speed, float)
        out['wind_dir_cos'], out['wind_dir_sin'] = (np.asarray(cos, float),
                                                    np.asarray(sin, float))
    return {c: out[c] for c in vessel.dataset_columns[1:]}


def to_spatial_columns(ch: Mapping[str, np.ndarray], topic_map: TopicMap,
                       relative: bool = True) -> dict[str, np.ndarray]:
    """``to_columns`` of a 6-DOF vehicle: body velocities and rates, roll, pitch, pose."""
    vessel = topic_map.vessel
    phi, theta = np.asarray(ch['phi'], float), np.asarray(ch['theta'], float)
    psi = np.asarray(ch['psi'], float)
    flu = topic_map.frames['body_velocity'] == 'flu'
    rates = (ch['roll_rate'], ch['pitch_rate'], ch['yaw_rate'])
    p, q, r = frames.body_flu_to_frd(*rates) if flu else rates
    if 'surge' in ch:
        velocity = (ch['surge'], ch['sway'], ch['heave'])
        u, v, w = frames.body_flu_to_frd(*velocity) if flu else velocity
    else:
        u, v, w = ned_to_body_3d(ch['vel_north'], ch['vel_east'], ch['vel_down'], phi, theta,
                                 psi)
    out = dict(zip(('u', 'v', 'w', 'p', 'q', 'r'),
                   (np.asarray(a, float) for a in (u, v, w, p, q, r)), strict=True))
    out['phi'], out['theta'] = phi, theta
    out['psi'] = psi - 2.0 * math.pi * np.round(psi[0] / (2.0 * math.pi))
    point = (ch['pos_x'], ch['pos_y'], ch['pos_z'])
    north, east, down = (np.asarray(a, float) for a in (
        frames.position_enu_to_ned(*point) if topic_map.frames['position'] == 'enu'
        else point))
    if relative:
        north, east, down = north - north[0], east - east[0], down - down[0]
    out['x'], out['y'], out['z'] = north, east, down
    out.update(actuator_columns(ch, topic_map))
    return {c: out[c] for c in vessel.dataset_columns[1:]}


def actuator_columns(ch: Mapping[str, np.ndarray], topic_map: TopicMap
                     ) -> dict[str, np.ndarray]:
    """Return the vessel's actuator columns from their channels."""
    return {name: np.asarray(ch[ACTUATOR_PREFIX + name], float)
            for name in topic_map.vessel.actuator_names}


def earth_to_body(north, east, psi, phi=0.0) -> tuple[np.ndarray, np.ndarray]:
    """
    Return FRD (u, v) (m/s) whose NED velocity is (north, east) at heading psi, roll phi.

    The inverse of ``vessel_physics.integrator.kinematics``: the horizontal velocity is
    R(psi) (u, v cos phi).
    """
    north, east, psi = (np.asarray(a, float) for a in (north, east, psi))
    u, v_level = frames.ned_to_body(north, east, psi)
    return u, v_level / np.cos(phi)


def latlon_to_local(lat_deg, lon_deg) -> tuple[np.ndarray, np.ndarray]:
    """
    North and east (m) of the first fix, in an azimuthal equidistant projection there.

    pyproj (PROJ) projects on the WGS 84 ellipsoid; over the few kilometres of a run
    distances and bearings from the first fix are exact to far below GNSS noise.
    """
    lat, lon = np.asarray(lat_deg, float), np.asarray(lon_deg, float)
    east, north = local_projection(float(lat[0]), float(lon[0])).transform(lon, lat)
    return np.asarray(north, float), np.asarray(east, float)


@lru_cache(maxsize=64)
def local_projection(lat0: float, lon0: float) -> Transformer:
    """Return the WGS 84 -> local (east, north) m transformer centred on a fix (deg)."""
    return Transformer.from_crs(
        'EPSG:4326', f'+proj=aeqd +lat_0={lat0!r} +lon_0={lon0!r} +datum=WGS84 +units=m',
        always_xy=True)
