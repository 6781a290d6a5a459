"""
Control plans for a forecast, in the vessel's own controls: checks and the model's matrix.

A plan names its columns with the vessel's control names (``Vessel.control_names``:
the actuators, then the environment columns, e.g. ``n, delta_port, delta_stbd,
wind_speed, wind_dir_cos, wind_dir_sin`` for the patrol boat or ``n, delta`` for the
KVLCC2 model), gives each column's unit, and holds a matrix of rows x controls, one row
per forecast step or one per ``step_period`` seconds (zero-order hold). Every
actuator is planned; an environment input (wind) is planned with all its columns or
left out, and then its latest measurement holds. Plans are checked as a whole before
they reach the model against what the vessel file declares: names, units (exactly the
vessel's), a whole number of rows, finite values, each actuator's ``range``, the
``limits`` of an environment column (``wind_speed``; a vessel that declares none takes
plans without wind only) and unit direction vectors. Refusals are one line. A what-if
answer may carry every ``answer_period`` seconds' step instead of all (``answer_stride``).
No ROS.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
import math

import numpy as np

from hybrid_models.metrics import dead_reckoning
from vessel_description.vocabulary import (
    ENVIRONMENT,
    ENVIRONMENT_DIRECTIONS,
    LIMITED_ENVIRONMENT,
)

# |cos^2 + sin^2 - 1| a planned direction may have (float rounding of cos and sin of
# one angle is ~1e-16; a pair off by more is not a direction).
DIRECTION_TOLERANCE = 1e-6
# Relative slack of "a whole multiple of the step period" (0.3 / 0.1 is 2.9999999999999996).
MULTIPLE_TOLERANCE = 1e-9


class PlanError(ValueError):
    """A control plan cannot be used; the message says why."""


@dataclass(frozen=True)
class PlanLimits:
    """
    What a plan for one vessel must satisfy (from its vessel file, ``PlanLimits.of``).

    ``names`` and ``units`` are the vessel's control vector; ``ranges`` maps a control
    to (low, high), or to None when a plan may not give it (no declared range);
    ``actuators`` must be planned; each of ``groups`` (an environment input's columns)
    is planned whole or not at all; each of ``directions`` is a (cos, sin) pair;
    ``dt`` (s) is the forecast's step period.
    """

    vessel: str
    dt: float
    names: tuple[str, ...]
    units: tuple[str, ...]
    ranges: dict
    actuators: tuple[str, ...]
    groups: tuple[tuple[str, ...], ...] = ()
    directions: tuple[tuple[str, str], ...] = ()

    @classmethod
    def of(cls, vessel) -> PlanLimits:
        """Return the plan limits of a vessel description (any vessel)."""
        ranges = {a.name: (a.low, a.high) for a in vessel.actuators}
        groups, directions = [], []
        for env in vessel.environment:
            columns = tuple(c[0] for c in ENVIRONMENT[env])
            groups.append(columns)
            pair = ENVIRONMENT_DIRECTIONS.get(env)
            if pair:
                directions.append(pair)
            for column in columns:
                if column in LIMITED_ENVIRONMENT.get(env, ()):
                    ranges[column] = vessel.limits.get(column)
                else:   # a direction component
                    ranges[column] = (-1.0, 1.0)
        return cls(vessel.name, float(vessel.dt), tuple(vessel.control_names),
                   tuple(vessel.control_units), ranges, tuple(vessel.actuator_names),
                   tuple(groups), tuple(directions))

    def describe(self) -> str:
        """Return the plan columns this vessel takes, with units, for messages."""
        return ', '.join(f'{n} [{u}]' for n, u in zip(self.names, self.units, strict=True))


def hold_latest(latest_control: np.ndarray, horizon: int) -> np.ndarray:
    """Return the future controls (1, horizon, n_control) that keep the latest controls."""
    return np.broadcast_to(latest_control, (1, horizon, latest_control.shape[-1])).copy()


def steps_per_period(period: float, dt: float, what: str) -> int:
    """
    Return how many forecast steps of ``dt`` s a ``period`` (s) spans; 0 means one.

    Raise PlanError (one line naming ``what``) unless the period is 0 or a positive
    whole multiple of ``dt``.
    """
    if period == 0:
        return 1
    ratio = period / dt if math.isfinite(period) and period > 0 else math.nan
    steps = round(ratio) if math.isfinite(ratio) else 0
    if steps < 1 or abs(ratio - steps) > MULTIPLE_TOLERANCE * ratio:
        raise PlanError(f'{what} must be 0 (every step) or a whole multiple of the '
                        f'forecast step {dt:g} s, got {period!r}')
    return steps


def plan_length(horizon: int, step_period: float, dt: float, what: str = 'step_period'
                ) -> tuple[int, int]:
    """
    Return (forecast steps a row holds, rows a plan needs) for ``horizon`` steps of ``dt`` s.

    Rows of ``step_period`` s (0: one a step; ``steps_per_period`` checks it, naming
    ``what``); the last row may reach past the horizon.
    """
    hold = steps_per_period(step_period, dt, what)
    return hold, -(-horizon // hold)


def answer_stride(answer_period: float, dt: float, horizon: int) -> int:
    """
    Return the stride of a what-if answer's steps (``Predict`` request's answer_period).

    The answer carries the steps ending at every ``answer_period`` s (``answer_steps``);
    the period must be 0 (every step) or a whole multiple of ``dt`` dividing the horizon.
    """
    stride = steps_per_period(answer_period, dt, 'answer_period')
    if horizon % stride:
        raise PlanError(f'answer_period {answer_period:g} s does not divide the horizon '
                        f'({horizon} steps of {dt:g} s)')
    return stride


def answer_steps(horizon: int, stride: int) -> np.ndarray:
    """Return the indices of the forecast steps an answer of ``stride`` carries (the last too)."""
    return np.arange(horizon)[answer_slice(stride)]


def answer_slice(stride: int) -> slice:
    """Return ``answer_steps`` as a slice of the step axis (a view, where indices copy)."""
    return slice(stride - 1, None, stride)


def check_plan(names: Sequence[str], units: Sequence[str], values, horizon: int,
               limits: PlanLimits, index: int = 0, exact: bool = True,
               step_period: float = 0.0) -> np.ndarray:
    """
    Validate a whole plan before any array work; return its (steps, n_control) matrix.

    ``names`` and ``units`` label the columns of ``values`` (row-major rows x columns,
    flat or 2-D), as ``hybrid_predictor_interfaces/ControlPlan`` carries them; each row
    holds for ``step_period`` s (0: one forecast step, ``limits.dt``). The matrix is
    returned one row per forecast step, in the vessel's control order, NaN in the
    columns of an environment input left out. Rows: exactly enough for ``horizon``
    steps (``exact``) or at least that many (a plan on the topic, which may start
    before the forecast does). Raise PlanError with one line naming the plan
    (``index``) and what is wrong.
    """
    where = f'plan {index}'
    hold, needed = plan_length(horizon, step_period, limits.dt, f'{where}: step_period')
    names, units = [str(n) for n in names], [str(u) for u in units]
    if not names:
        raise PlanError(f'{where}: no control_names; vessel {limits.vessel!r} takes '
                        f'{limits.describe()}')
    unknown = [n for n in names if n not in limits.names]
    if unknown:
        raise PlanError(f'{where}: {unknown} not among the controls of vessel '
                        f'{limits.vessel!r}: {limits.describe()}')
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise PlanError(f'{where}: {repeated} given more than once')
    missing = [n for n in limits.actuators if n not in names]
    if missing:
        raise PlanError(f'{where}: actuators {missing} missing; every plan of vessel '
                        f'{limits.vessel!r} gives {list(limits.actuators)}')
    for group in limits.groups:
        given = [n for n in group if n in names]
        if given and len(given) != len(group):
            raise PlanError(f'{where}: give {list(group)} together, or none of them (the '
                            f'latest measurement then holds); got only {given}')
    if len(units) != len(names):
        raise PlanError(f'{where}: {len(units)} control_units for {len(names)} '
                        f'control_names; give one unit per control')
    for name, unit in zip(names, units, strict=True):
        declared = limits.units[limits.names.index(name)]
        if unit != declared:
            raise PlanError(f'{where}: {name} in {unit!r}; vessel {limits.vessel!r} '
                            f'declares it in {declared!r}')
    try:
        flat = np.asarray(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise PlanError(f'{where}: values is not a sequence of numbers') from None
    if len(flat) % len(names):
        raise PlanError(f'{where}: {len(flat)} values are not whole rows of '
                        f'{len(names)} controls')
    rows = flat.reshape(-1, len(names))
    steps = len(rows)
    if steps != needed if exact else steps < needed:
        need = needed if exact else f'at least {needed}'
        if hold == 1:
            raise PlanError(f'{where}: {steps} steps of {len(names)} controls, need {need}')
        raise PlanError(f'{where}: {steps} rows of {step_period:g} s, need {need} for '
                        f'{horizon} forecast steps of {limits.dt:g} s')
    nonfinite, outside, directions = _value_faults(rows, names, limits)
    bad = np.argwhere(nonfinite)
    if len(bad):
        k, j = bad[0]
        raise PlanError(f'{where}: {names[j]}[{k}] is {rows[k, j]}')
    for j, name in enumerate(names):
        declared = limits.ranges[name]
        if declared is None:
            raise PlanError(f'{where}: vessel {limits.vessel!r} declares no range for '
                            f'{name} (limits.{name} in its vessel file); leave it out')
        out = np.flatnonzero(outside[:, j])
        if len(out):
            k = out[0]
            raise PlanError(f'{where}: {name}[{k}] = {rows[k, j]:.6g} outside '
                            f'[{declared[0]:.6g}, {declared[1]:.6g}] {units[j]}')
    for cos_name, sin_name, off_rows in directions:
        off = np.flatnonzero(off_rows)
        if len(off):
            k = off[0]
            c, s = (rows[k, names.index(n)] for n in (cos_name, sin_name))
            raise PlanError(f'{where}: ({cos_name}, {sin_name})[{k}] = ({c:.6g}, '
                            f'{s:.6g}) is not a unit direction')
    matrix = np.repeat(_in_vessel_order(rows, names, limits), hold, axis=0)   # a row a step
    return matrix[:horizon] if exact else matrix


def _value_faults(rows: np.ndarray, names: list[str], limits: PlanLimits):
    """
    Return where plan rows (..., R, m) of columns ``names`` break the value rules.

    (non-finite (..., R, m); outside the declared range (..., R, m), never in a column
    without one; [(cos, sin, not a unit direction (..., R))] per direction given). The
    one statement of the rules: ``check_plan`` names a plan's first fault from them,
    ``check_plan_messages`` asks which plans of a stack have any.
    """
    low, high = np.array([limits.ranges[n] or (np.nan, np.nan) for n in names]).T
    outside = (rows < low) | (rows > high)   # NaN, value or bound, is never outside
    directions = []
    for cos_name, sin_name in limits.directions:
        if cos_name in names:
            c, s = (rows[..., names.index(n)] for n in (cos_name, sin_name))
            directions.append((cos_name, sin_name,
                               np.abs(c * c + s * s - 1.0) > DIRECTION_TOLERANCE))
    return ~np.isfinite(rows), outside, directions


def _in_vessel_order(rows: np.ndarray, names: list[str], limits: PlanLimits) -> np.ndarray:
    """Return rows (..., R, m) of columns ``names`` in the vessel's controls, NaN elsewhere."""
    matrix = np.full(rows.shape[:-1] + (len(limits.names),), np.nan)
    matrix[..., [limits.names.index(n) for n in names]] = rows
    return matrix


def check_plan_message(plan, horizon: int, limits: PlanLimits, index: int = 0,
                       exact: bool = True) -> np.ndarray:
    """
    Return ``check_plan``'s matrix of a ControlPlan message (or a recorded one).

    A plan recorded before plans had a step period has one row per forecast step.
    """
    return check_plan(list(plan.control_names), list(plan.control_units),
                      np.asarray(plan.values), horizon, limits, index=index, exact=exact,
                      step_period=getattr(plan, 'step_period', 0.0))


def _header(plan) -> tuple:
    """Return what a ControlPlan's matrix layout depends on: columns, units, step period."""
    return (tuple(plan.control_names), tuple(plan.control_units),
            getattr(plan, 'step_period', 0.0), len(plan.values))


def check_plan_messages(plans, horizon: int, limits: PlanLimits) -> np.ndarray:
    """
    Return ``check_plan_message``'s matrices of a request's plans (B, horizon, n_control).

    Raise the PlanError of its first plan at fault.

    Plans that share their columns, units, step period and length (a planner's thousand
    candidates) are checked as one stack: the first plan alone (columns, units, length),
    then every value of all of them at once; the first plan found at fault is checked
    alone again, which raises the line naming it, as checking them one by one would.
    """
    def one_by_one():
        return np.stack([check_plan_message(p, horizon, limits, index=i)
                         for i, p in enumerate(plans)])

    if len({_header(p) for p in plans}) != 1:
        return one_by_one()
    check_plan_message(plans[0], horizon, limits)
    names = list(plans[0].control_names)
    try:
        rows = np.stack([np.asarray(p.values, dtype=float) for p in plans]).reshape(
            len(plans), -1, len(names))
    except (TypeError, ValueError):   # values that are no numbers: said plan by plan
        return one_by_one()
    nonfinite, outside, directions = _value_faults(rows, names, limits)
    unfit = (nonfinite | outside).any(axis=(1, 2))
    for *_, off in directions:
        unfit |= off.any(axis=1)
    for i in np.flatnonzero(unfit):
        check_plan_message(plans[i], horizon, limits, index=int(i))   # raises its line
    hold, _ = plan_length(horizon, getattr(plans[0], 'step_period', 0.0), limits.dt)
    matrix = np.repeat(_in_vessel_order(rows, names, limits), hold, axis=1)   # a row a step
    return matrix[:, :horizon]


def plan_rows(matrix: np.ndarray, plan_start: float, t_end: float, dt: float,
              horizon: int, timeout: float) -> tuple[np.ndarray | None, str]:
    """
    Return the rows of a plan a forecast from the window ending at ``t_end`` follows.

    Row k of ``matrix`` (``check_plan``'s) holds the controls at ``plan_start + k dt``
    (s, the plan's stamp); the forecast's first control is the one at ``t_end``, the
    last window sample (``hybrid_models.data``). Return (rows (horizon, n_control), '');
    (None, '') when ``t_end`` lies outside the plan's time, before its start or more
    than ``timeout`` s after it; (None, why) when fewer than ``horizon`` rows are left.
    """
    age = t_end - plan_start
    if not 0.0 <= age <= timeout:
        return None, ''
    shift = int(round(age / dt))
    rows = matrix[shift:shift + horizon]
    if len(rows) < horizon:
        return None, (f'from {age:.1f} s before the forecast: {len(matrix) - shift} of '
                      f'its steps are left, need {horizon}')
    return rows, ''


def plan_controls(matrix: np.ndarray, latest_control: np.ndarray) -> np.ndarray:
    """
    Return a checked plan's future controls (steps, n_control) for the model.

    ``matrix`` is ``check_plan``'s (or rows of it); the columns it leaves out (NaN: an
    environment input not planned) hold ``latest_control``, the latest measured controls.
    """
    return np.where(np.isnan(matrix), latest_control, matrix)


@dataclass(frozen=True)
class Track:
    """A forecast's track per step: north, east (m, NED), heading (rad); down for 6-DOF."""

    north: np.ndarray
    east: np.ndarray
    heading: np.ndarray
    down: np.ndarray | None = None   # m, NED; None for a vessel in the plane


def track(states: np.ndarray, pose: tuple[float, ...], spec) -> Track:
    """
    Return the forecast track from the window's pose: (x, y, psi) or, 6-DOF, (x, y, psi, z).

    ``hybrid_models.metrics.dead_reckoning`` integrates the track from the origin with
    heading 0, as the trajectory error does; starting from ``pose`` instead only rotates
    that track by psi about the vertical and shifts it, so the published track is
    exactly what the trajectory error measures. ``spec`` is the model's vehicle.
    """
    x0, y0, psi0 = pose[:3]
    local, heading = dead_reckoning(states, spec)   # (..., H, 2 or 3) north, east[, down]
    cos_p, sin_p = math.cos(psi0), math.sin(psi0)
    north = x0 + cos_p * local[..., 0] - sin_p * local[..., 1]
    east = y0 + sin_p * local[..., 0] + cos_p * local[..., 1]
    down = pose[3] + local[..., 2] if spec.is_spatial else None
    return Track(north, east, psi0 + heading, down)


def bound_hit_fraction(hybrid: np.ndarray, physics: np.ndarray, bound: np.ndarray,
                       margin: float = 0.99) -> float:
    """Fraction of forecast values whose LSTM correction reaches ``margin`` x its bound."""
    finite = np.isfinite(bound)
    if not finite.any():
        return 0.0
    correction = np.abs(hybrid - physics)[..., finite]
    return float(np.mean(correction >= margin * bound[finite]))
