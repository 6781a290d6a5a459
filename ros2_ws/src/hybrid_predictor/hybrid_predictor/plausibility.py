"""
Physical plausibility of one input sample, from the vessel description (no ROS).

A finite value can still be absurd (a surge of 10^6 m/s, a quaternion of norm 7). Each
sample is checked, in the model's quantities, against what the vessel file declares:

- body velocities (surge, sway, heave, roll, pitch and yaw rate, turned into FRD
  ``u, v, w, p, q, r`` by ``vessel_physics.frames``) and the roll and pitch angles
  ``phi``, ``theta`` against ``limits`` of the vessel file ("plausible ranges of the
  states; samples outside are spikes");
- every actuator against its declared ``range`` (shaft speed, rudder angles);
- the measured wind speed against ``limits.wind_speed`` where the vessel file gives it;
- an orientation quaternion must have unit norm within ``quaternion_tolerance``;
- a message whose values are frame-dependent (velocities, attitude, position, wind)
  must name its frame: an empty ``frame_id`` is rejected (``no_frame_id``).

A vessel file without a limit for one of its states is refused at start-up in one line:
the predictor cannot tell a spike from a state without it. Heading, position and wind
direction have no declared bounds and are only checked for being finite (by the
window).
``forecast_problem`` holds every forecast to the same limits before it is published.
"""

from __future__ import annotations

import math

import numpy as np

from vessel_datasets.topic_map import ACTUATOR_PREFIX, TopicMap
from vessel_description import VesselError
from vessel_physics import frames

QUATERNION = ('qx', 'qy', 'qz', 'qw')
# Channels of a body-velocity group, the FRD state each becomes, and its sign from FLU
# (frames.body_flu_to_frd: y and z change sign).
BODY_CHANNELS = (('surge', 'u', 1.0), ('sway', 'v', -1.0), ('heave', 'w', -1.0),
                 ('roll_rate', 'p', 1.0), ('pitch_rate', 'q', -1.0), ('yaw_rate', 'r', -1.0))
# Groups whose values mean nothing without the frame they are given in.
FRAMED_GROUPS = ('body_velocity', 'attitude', 'position', 'wind')


class Plausibility:
    """Checks of one vessel's input samples; ``check`` says why a sample is absurd."""

    def __init__(self, topic_map: TopicMap, quaternion_tolerance: float):
        vessel = topic_map.vessel
        missing = [s for s in vessel.states if s not in vessel.limits]
        if missing:
            raise VesselError(f'vessel {vessel.name!r} ({vessel.source}): limits lack '
                              f'{missing}; the predictor needs a plausible range for every '
                              f'state to reject absurd inputs (docs/vessels.md)')
        self.quaternion_tolerance = quaternion_tolerance
        # channel -> (sign to the model's frame, model quantity, low, high)
        self.bounds: dict[str, tuple[float, str, float, float]] = {}
        flu = topic_map.frames.get('body_velocity') == 'flu'
        for channel, state, sign in BODY_CHANNELS:
            if state in vessel.states:
                self.bounds[channel] = (sign if flu else 1.0, state, *vessel.limits[state])
        self.enu = topic_map.frames.get('attitude') == 'enu_flu'
        if vessel.has_roll:
            self.bounds['roll'] = (1.0, 'phi', *vessel.limits['phi'])
        if vessel.is_spatial:   # FLU pitch turns about the axis FRD reverses
            self.bounds['pitch'] = (-1.0 if self.enu else 1.0, 'theta',
                                    *vessel.limits['theta'])
        for actuator in vessel.actuators:
            self.bounds[ACTUATOR_PREFIX + actuator.name] = (
                1.0, actuator.name, actuator.low, actuator.high)
        # Angles a quaternion gives, with their limits: roll, and pitch for 6-DOF.
        self.angle_limits = {k: vessel.limits[name] for k, name in ((0, 'phi'), (1, 'theta'))
                             if name in vessel.states}
        self.wind_speed_limits = vessel.limits.get('wind_speed')
        self.framed_topics = {leaf.topic for leaf in topic_map.leaves()
                              if leaf.group in FRAMED_GROUPS}

    def check(self, topic: str, values: dict[str, float],
              frame_id: str | None) -> tuple[str, str] | None:
        """
        Return (reason, message) if a finite sample is absurd, else None.

        ``values`` are the channels one message carries (after the map's scale);
        ``frame_id`` is its header's frame, or None for a message without a header.
        Reasons: ``no_frame_id``, ``bad_quaternion``, ``implausible``.
        """
        if frame_id == '' and topic in self.framed_topics:
            return 'no_frame_id', f'{topic}: empty header.frame_id'
        if all(c in values for c in QUATERNION):
            reason = self._quaternion(topic, [values[c] for c in QUATERNION])
            if reason:
                return reason
        if self.wind_speed_limits is not None:
            speed = wind_speed(values)
            low, high = self.wind_speed_limits
            if speed is not None and not low <= speed <= high:
                return 'implausible', (f'{topic}: wind speed = {speed:.6g} outside the '
                                       f'vessel limits [{low:g}, {high:g}]')
        for channel, value in values.items():
            bound = self.bounds.get(channel)
            if bound is None:
                continue
            sign, name, low, high = bound
            if not low <= sign * value <= high:
                return 'implausible', (f'{topic}: {name} = {sign * value:.6g} outside the '
                                       f'vessel limits [{low:g}, {high:g}]')
        return None

    def _quaternion(self, topic: str, q: list[float]) -> tuple[str, str] | None:
        norm = math.sqrt(sum(c * c for c in q))
        if not abs(norm - 1.0) <= self.quaternion_tolerance:
            return 'bad_quaternion', (f'{topic}: orientation quaternion has norm {norm:.6g}, '
                                      f'not 1 +- {self.quaternion_tolerance:g}')
        if not self.angle_limits:
            return None
        unit = [c / norm for c in q]
        convert = frames.orientation_enu_to_ned if self.enu else frames.euler_from_quaternion
        angles = convert(*unit)
        for k, (low, high) in self.angle_limits.items():
            value = float(angles[k])
            if not low <= value <= high:
                return 'implausible', (f'{topic}: {("phi", "theta")[k]} = {value:.6g} outside '
                                       f'the vessel limits [{low:g}, {high:g}]')
        return None


def wind_speed(values: dict[str, float]) -> float | None:
    """Return the wind speed a sample carries (its vector's length, or the speed), or None."""
    if 'wind_x' in values and 'wind_y' in values:
        return math.hypot(values['wind_x'], values['wind_y'])
    return values.get('wind_speed')


def forecast_problem(hybrid: np.ndarray, track: tuple[np.ndarray, ...], vessel) -> str | None:
    """
    Return why a forecast must be withheld, or None.

    ``hybrid`` is (..., horizon, n_state) in the vessel's state order; ``track`` the
    trajectory arrays (x, y, heading[, z]). Every value must be finite and every state inside
    the vessel's ``limits`` (the same plausible ranges the inputs are held to).
    """
    if not np.isfinite(hybrid).all() or not all(np.isfinite(a).all() for a in track):
        return 'non-finite values'
    for i, name in enumerate(vessel.states):
        low, high = vessel.limits[name]
        column = hybrid[..., i]
        worst = column.min() if column.min() < low else column.max()
        if not low <= worst <= high:
            return f'{name} reaches {worst:.6g}, outside the vessel limits [{low:g}, {high:g}]'
    return None


def forecast_problems(hybrid: np.ndarray, track: tuple[np.ndarray, ...], vessel
                      ) -> list[str | None]:
    """
    Return ``forecast_problem`` of each forecast of a batch, judged at once.

    ``hybrid`` (B, horizon, n_state); ``track`` arrays (B, horizon), or an empty z. A
    thousand plans of a what-if request are judged in one pass over the arrays; only
    the forecasts withheld are looked at one by one, for the reason they are given.
    """
    low, high = (np.array([vessel.limits[n][k] for n in vessel.states]) for k in (0, 1))
    # NaN fails both comparisons: a non-finite forecast is never judged fit here.
    fit = ((hybrid >= low) & (hybrid <= high)).all(axis=(1, 2))
    for a in track:
        if a.size:
            fit &= np.isfinite(a).all(axis=1)
    return [None if ok else forecast_problem(hybrid[i], tuple(a[i] if a.size else a
                                                                for a in track), vessel)
            for i, ok in enumerate(fit)]
