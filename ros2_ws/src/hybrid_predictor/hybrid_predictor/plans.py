"""
Control plans for a forecast: validation and the model's future-control matrix (no ROS).

A forecast needs one control vector per step, c = [n, delta_port, delta_stbd,
wind_speed, wind_dir_cos, wind_dir_sin] (docs/conventions.md). Controllers give the
actuator set-points; the wind is either given too or held at its latest measurement.
Plans are checked before they reach the model against what the vessel file declares:
a wrong length, a non-finite value, a set-point outside its actuator's ``range`` or a
wind speed outside ``limits.wind_speed`` is refused with a reason.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from hybrid_models.metrics import dead_reckoning

ACTUATOR_FIELDS = ('shaft_speed', 'rudder_port', 'rudder_stbd')
WIND_FIELDS = ('wind_speed', 'wind_direction')
PLAN_FIELDS = ACTUATOR_FIELDS + WIND_FIELDS
# The vessel controls a ControlPlan message gives (its fields are the patrol boat's),
# and the vessel quantity whose declared range bounds each field.
PLAN_CONTROLS = ('n', 'delta_port', 'delta_stbd', 'wind_speed', 'wind_dir_cos',
                 'wind_dir_sin')
FIELD_QUANTITY = {'shaft_speed': 'n', 'rudder_port': 'delta_port',
                  'rudder_stbd': 'delta_stbd', 'wind_speed': 'wind_speed'}


class PlanError(ValueError):
    """A control plan cannot be used; the message says why."""


@dataclass(frozen=True)
class PlanLimits:
    """
    Declared ranges of the plan fields: field -> (low, high, unit), or None if undeclared.

    ``wind_direction`` is an angle (rad, relative to the bow): any finite value is one.
    """

    vessel: str
    ranges: dict

    @classmethod
    def of(cls, vessel) -> PlanLimits | None:
        """Return a vessel's plan limits, or None if its controls are not the plan's."""
        if vessel.control_names != PLAN_CONTROLS:
            return None
        ranges = {}
        for field, quantity in FIELD_QUANTITY.items():
            if quantity in vessel.actuator_names:
                actuator = vessel.actuator(quantity)
                ranges[field] = (actuator.low, actuator.high, actuator.unit)
            elif quantity in vessel.limits:
                ranges[field] = (*vessel.limits[quantity], 'm/s')
            else:
                ranges[field] = None
        return cls(vessel.name, ranges)


def hold_latest(latest_control: np.ndarray, horizon: int) -> np.ndarray:
    """Return the future controls (1, horizon, 6) that keep the latest controls."""
    return np.broadcast_to(latest_control, (1, horizon, latest_control.shape[-1])).copy()


def check_plan(plan: dict[str, np.ndarray], horizon: int, limits: PlanLimits,
               index: int = 0, exact: bool = True) -> dict[str, np.ndarray]:
    """
    Validate a whole plan before any array work; return its fields as float arrays.

    ``plan`` maps the field names of hybrid_predictor_interfaces/ControlPlan to arrays.
    The actuator fields must all have the same length: exactly ``horizon`` entries
    (``exact``), or at least ``horizon`` (a plan on the topic, which may start before
    the forecast does). The wind fields are given together with that length or both
    left empty (documented default: the latest measured wind holds). Every value must
    be finite, and inside its declared range (``limits``); a wind speed is >= 0 on any
    vessel. Raise PlanError.
    """
    where = f'plan {index}'
    arrays = {}
    for name in ACTUATOR_FIELDS + WIND_FIELDS:
        try:
            arrays[name] = np.asarray(plan.get(name, ()), dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise PlanError(f'{where}: {name} is not a sequence of numbers') from None
    length = len(arrays[ACTUATOR_FIELDS[0]])
    if length != horizon if exact else length < horizon:
        need = horizon if exact else f'at least {horizon}'
        raise PlanError(f'{where}: {ACTUATOR_FIELDS[0]} has {length} entries, need {need}')
    wind = [len(arrays[name]) for name in WIND_FIELDS]
    if wind != [0, 0] and wind != [length, length]:
        raise PlanError(f'{where}: {WIND_FIELDS[0]} has {wind[0]} entries and '
                        f'{WIND_FIELDS[1]} {wind[1]}; give both with {length} entries '
                        f'each, or neither (the latest measured wind then holds)')
    for name, values in arrays.items():
        if len(values) != length and name in ACTUATOR_FIELDS:
            raise PlanError(f'{where}: {name} has {len(values)} entries, need {length} '
                            f'(as {ACTUATOR_FIELDS[0]})')
        bad = np.flatnonzero(~np.isfinite(values))
        if len(bad):
            raise PlanError(f'{where}: {name}[{bad[0]}] is {values[bad[0]]}')
    if np.any(arrays['wind_speed'] < 0):
        raise PlanError(f'{where}: wind_speed must be >= 0')
    for name, declared in limits.ranges.items():
        values = arrays[name]
        if not len(values):
            continue
        if declared is None:
            raise PlanError(f'{where}: vessel {limits.vessel!r} declares no range for '
                            f'{name} (limits.{FIELD_QUANTITY[name]} in its vessel file); '
                            f'leave it out')
        low, high, unit = declared
        bad = np.flatnonzero((values < low) | (values > high))
        if len(bad):
            raise PlanError(f'{where}: {name}[{bad[0]}] = {values[bad[0]]:.6g} outside '
                            f'[{low:.6g}, {high:.6g}] {unit}')
    return arrays


def plan_controls(plan: dict[str, np.ndarray], latest_control: np.ndarray, horizon: int,
                  limits: PlanLimits, index: int = 0) -> np.ndarray:
    """
    Return one plan's future controls (horizon, 6), or raise PlanError.

    The plan is validated as a whole first (``check_plan`` with exactly ``horizon``
    entries); only a valid plan is turned into the model's control matrix.
    """
    arrays = check_plan(plan, horizon, limits, index)
    out = np.empty((horizon, 6))
    out[:, 0], out[:, 1], out[:, 2] = (arrays[n] for n in ACTUATOR_FIELDS)
    if len(arrays['wind_speed']):
        out[:, 3] = arrays['wind_speed']
        out[:, 4] = np.cos(arrays['wind_direction'])
        out[:, 5] = np.sin(arrays['wind_direction'])
    else:
        out[:, 3:] = latest_control[3:]
    return out


def track(states: np.ndarray, pose: tuple[float, float, float], spec,
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """
    Return the forecast track: north, east (m, NED) and heading (rad) per step.

    ``hybrid_models.metrics.dead_reckoning`` integrates the track from the origin with
    heading 0, as the trajectory error does; starting from ``pose`` = (x, y, psi)
    instead only rotates that track by psi and shifts it, so the published track is
    exactly what the trajectory error measures. ``spec`` is the model's vessel.
    """
    x0, y0, psi0 = pose
    local, heading = dead_reckoning(states, spec)   # (..., H, 2) north, east; (..., H)
    cos_p, sin_p = math.cos(psi0), math.sin(psi0)
    north = x0 + cos_p * local[..., 0] - sin_p * local[..., 1]
    east = y0 + sin_p * local[..., 0] + cos_p * local[..., 1]
    return north, east, psi0 + heading


def bound_hit_fraction(hybrid: np.ndarray, physics: np.ndarray, bound: np.ndarray,
                       margin: float = 0.99) -> float:
    """Fraction of forecast values whose LSTM correction reaches ``margin`` x its bound."""
    finite = np.isfinite(bound)
    if not finite.any():
        return 0.0
    correction = np.abs(hybrid - physics)[..., finite]
    return float(np.mean(correction >= margin * bound[finite]))
