"""
Checks that a recording map (topic, column or log map) gives the quantities it claims.

A map names a field or column per quantity with a unit, a frame and a delay; a wrong
unit, frame, sign or delay still gives numbers that look fine on their own. These
checks compare quantities the data measures twice -- once directly, once as the
derivative of another -- on one run's dataset columns (model units and frames, after
conversion):

* velocity: body u, v rotated to NED by psi (``vessel_physics.integrator.kinematics``)
  against d(x, y)/dt: least-squares slope through the origin and correlation, then the
  course (direction) difference, which catches earth-frame velocities mapped as body;
* timing: the lags of position, heading and yaw rate behind the velocity
  (``timing``), judged over all runs and printed as the ``delay_s`` entries that would
  remove them;
* heading against the track: the heading's rate against the course's rate (a mirrored
  heading convention or an angle unit turns it), and the drift angle while running
  straight (a heading offset);
* yaw rate against d(psi)/dt, roll rate against d(phi)/dt (where they were mapped,
  not differentiated); speed over ground against the track's speed, where mapped;
* spikes (``spikes``): samples beyond the vessel's declared ranges and single-sample
  jumps, dropped before resampling and counted here.

A 6-DOF vehicle (``spatial_checks``) is checked in space: its body velocity turned by
the whole attitude (``integrator.body_to_ned``) against d(x, y, z)/dt, all three
components and the vertical one alone (a flipped down axis hides among larger horizontal
motions), the course over ground of the two (horizontal, as for vessels: a frame or
axis slip turns it by tens of degrees, while a scale error of the horizontal velocity
within the velocity check's tolerance would tilt a 3-D direction by degrees), the lags
of position and yaw rate, and each body rate against the rate of its Euler angle
(``integrator.attitude_rates``: roll, pitch and heading). Its heading need not follow
its track (a multirotor flies sideways), so the heading-rate and drift checks, which
hold for hulls, are skipped with that reason. Its rate checks are judged over all runs,
as the timing is: a flight that holds its heading turns a few degrees a second, where a
MEMS gyro's bias and the estimator's heading corrections weigh as much as the motion
(the nanodrone's square flights: yaw-rate correlation 0.75-0.86 alone, 0.93 pooled),
while a wrong column, unit or sign is wrong in every flight.

Both sides of every comparison are averaged over the same time, at least ``SMOOTH_S``
and longer where a quantity is coarse (``resolution``): quantisation then stays below a
twentieth of the change compared, while a wrong unit, sign or frame does not average
out. Velocities derived from the track are not compared with it (circular); the
heading checks still test them. A slope far from 1 is matched against known unit slips
(deg/rad, knots, km/h, rev, per minute, ms) and the message names the map entry to fix.
Each check gives a :class:`Check`; its ``detail`` holds sums, so checks of many runs
pool into one (:func:`aggregate`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import dataclasses
from dataclasses import asdict, dataclass, field
import math
from typing import Any, TextIO

import numpy as np
import pandas as pd

from vessel_description.vessel import plain
from vessel_physics.integrator import attitude_rates, body_to_ned, kinematics

from . import timing
from .topic_map import TopicMap

# A slope within this of 1 (and a correlation at least MIN_CORR) passes.
SLOPE_TOL = 0.1
MIN_CORR = 0.9
# Heading rate against course rate: in a steady turn the course turns as the heading
# does (slope 1); in a zig-zag the drift angle swings against the heading and the course
# turns less (KVLCC2: 0.45, the snuboat's free runs about 0.6). A mirrored heading gives
# a negative slope, an angle unit a factor of 57 or 2 pi.
TURN_RATIO = 3.0          # slope within [1/3, 3]...
TURN_MIN_CORR = 0.5       # ...and at least this correlation
# A slope within this relative distance of a known factor is named as that slip (deg/rad
# and per minute are 4.7 % apart).
FACTOR_TOL = 0.03
MAX_COURSE_DEG = 2.0      # typical (median) course difference, velocity vs d(position)/dt
MAX_DRIFT_DEG = 15.0      # typical (median) drift angle while running straight
# Angles are judged by their median, pooled through a histogram (deg): a few samples of a
# tracking glitch do not fail a right map; a wrong one is off almost everywhere.
ANGLE_BINS = np.concatenate([np.arange(0.0, 10.0, 0.05), np.arange(10.0, 181.0, 1.0)])
TURN_LENGTHS = 5.0        # heading and course turns are compared over this many lengths
POOLED = ('timing', 'turn', 'spatial_rate')  # kinds of check judged over all runs only
STRAIGHT = 0.1            # running straight: |r| L / U below this (turning radius > 10 L)
MIN_STRAIGHT_S = 5.0      # fewer straight-running seconds leave the drift unjudged
MIN_SPEED = 0.05          # m/s; slower runs are too still to test the velocity map
MIN_RATE = math.radians(0.1)  # rad/s; steadier runs cannot test a rate map
MOVING = 0.25             # samples above this share of the 95th-percentile speed count
SMOOTH_S = 1.0            # both sides are averaged over at least this long against noise

KNOT = 1852.0 / 3600.0
DEG = 180.0 / math.pi
# ratio (mapped value / true value) -> what was confused, per kind of quantity.
UNIT_SLIPS: dict[str, dict[float, str]] = {
    'speed': {1 / KNOT: 'knots given as m/s', KNOT: 'm/s given as knots',
              3.6: 'km/h given as m/s', 1 / 3.6: 'm/s given as km/h'},
    'rate': {DEG: 'deg/s given as rad/s', 1 / DEG: 'rad/s given as deg/s',
             2 * math.pi: 'rev/s given as rad/s', 1 / (2 * math.pi): 'rad/s given as rev/s',
             60.0: 'per-minute values given per second',
             1 / 60.0: 'per-second values given per minute'},
    'angle': {DEG: 'deg given as rad', 1 / DEG: 'rad given as deg',
              2 * math.pi: 'rev given as rad', 1 / (2 * math.pi): 'rad given as rev'},
    'length': {1000.0: 'mm given as m', 0.001: 'km given as m'},
    'time': {1000.0: 'ms given as s', 0.001: 's given as ms', 1 / 60.0: 'min given as s'},
}

# Map entries named in messages, per section of the vessel file the map comes from.
LABELS = {
    'columns': {'velocity': 'columns.velocity', 'position': 'columns.position',
                'heading': 'columns.heading', 'yaw_rate': 'columns.yaw_rate',
                'roll_rate': 'columns.roll_rate', 'roll': 'columns.roll',
                'pitch_rate': 'columns.pitch_rate', 'pitch': 'columns.pitch',
                'time': 'columns.time', 'actuators': 'columns.actuators',
                'speed_over_ground': 'columns.speed_over_ground'},
    'topics': {'velocity': 'topics.body_velocity', 'position': 'topics.position',
               'heading': 'topics.attitude', 'yaw_rate': 'topics.body_velocity.yaw_rate',
               'roll_rate': 'topics.body_velocity.roll_rate', 'roll': 'topics.attitude',
               'pitch_rate': 'topics.body_velocity.pitch_rate', 'pitch': 'topics.attitude',
               'time': 'stamps', 'actuators': 'topics.actuators',
               'speed_over_ground': 'topics.speed_over_ground'},
}
LABELS['logs'] = {k: v.replace('topics.', 'logs.') for k, v in LABELS['topics'].items()}
# Dataset column -> map quantity, for spike messages.
QUANTITY_OF = {'u': 'velocity', 'v': 'velocity', 'w': 'velocity', 'p': 'roll_rate',
               'q': 'pitch_rate', 'r': 'yaw_rate', 'phi': 'roll', 'theta': 'pitch'}
# Quantities whose coarseness sets the averaging time of each comparison.
SCALES_OF = {'velocity': ('velocity', 'position'), 'heading': ('velocity', 'position',
                                                                'heading'),
             'yaw_rate': ('yaw_rate', 'heading'), 'roll_rate': ('roll_rate', 'roll'),
             'pitch_rate': ('pitch_rate', 'pitch')}
HULL_ONLY = 'skipped: a 6-DOF vehicle need not point where it flies'


@dataclass(frozen=True)
class Check:
    """
    One check of one run (or of all runs pooled).

    ``figure`` is the number judged (a slope, degrees, a count; None when skipped),
    ``expected`` what passes, ``suspect`` the map entry to look at when it fails.
    """

    name: str
    figure: float | None
    expected: str
    ok: bool
    suspect: str | None
    message: str
    detail: dict[str, Any] = field(default_factory=dict, compare=False)

    def line(self) -> str:
        """Return the check as one printable line."""
        return f'check {self.name}: {self.message}'

    def to_dict(self) -> dict[str, Any]:
        """Return the check as JSON-ready data (for the manifest)."""
        return asdict(self)


@dataclass(frozen=True)
class Context:
    """What a map and its conversion tell the checks about one run."""

    labels: Mapping[str, str]
    derived: tuple[str, ...] = ()      # 'r', 'p', 'track': differentiated by the converter
    entries: Mapping[str, Sequence[tuple[str, float]]] = field(default_factory=dict)
    scales: Mapping[str, float] = field(default_factory=dict)   # quantity -> s
    length_m: float = 1.0
    extras: Mapping[str, np.ndarray] = field(default_factory=dict)  # 'sog' on the grid
    interval_s: float = 0.0            # the recording's longest typical sample interval


def context_for(topic_map: TopicMap, scales: Mapping[str, float] | None = None,
                extras: Mapping[str, np.ndarray] | None = None, interval_s: float = 0.0
                ) -> Context:
    """Return the checks' context of a map: labels, what was derived, entries to delay."""
    leaves = topic_map.leaves()
    channels = {leaf.channel for leaf in leaves}
    derived = () if 'yaw_rate' in channels else ('r',)
    if topic_map.vessel.has_roll and 'roll_rate' not in channels:
        derived += ('p',)
    if not channels & {'surge', 'vel_north'}:
        derived += ('track',)
    section = topic_map.section
    quantity = {'surge': 'velocity', 'sway': 'velocity', 'heave': 'velocity',
                'vel_north': 'velocity', 'vel_east': 'velocity', 'vel_down': 'velocity',
                'yaw_rate': 'yaw_rate', 'heading': 'heading', 'qx': 'heading'}
    entries: dict[str, list[tuple[str, float]]] = {}
    for e in topic_map.entries:
        q = 'position' if e.group == 'position' else quantity.get(
            e.name if e.name != 'quaternion' else 'qx')
        if q is None:
            continue
        if section == 'columns':  # a column map names quantities, not groups
            label = LABELS['columns'][q]
        else:
            label = f'{section}.{e.group}' if q == 'position' else f'{section}.{e.label}'
        if (label, e.delay_s) not in entries.setdefault(q, []):
            entries[q].append((label, e.delay_s))
    return Context(LABELS[section], derived, entries, dict(scales or {}),
                   topic_map.vessel.length_m, dict(extras or {}), interval_s)


# ----------------------------------------------------------------- spikes
def spike_check(counts: Mapping[str, Mapping[str, Any]], refuse: bool,
                labels: Mapping[str, str]) -> Check:
    """Judge one run's spike counts (per column, from ``spikes.Spikes.counts``)."""
    parts, failed, suspects = [], False, []
    total = 0
    for col, c in counts.items():
        n_out, n_jump = c['out_of_range'], c['jumps']
        if not n_out and not n_jump:
            continue
        lo, hi = c['bounds'] or (None, None)
        if n_out and not c['dropped']:
            failed = True
            suspects.append(_label_of(col, labels))
            share = 100.0 * n_out / max(c['samples'], 1)
            parts.append(f'{col}: {n_out} of {c["samples"]} samples ({share:.0f} %) outside '
                         f'[{lo:g}, {hi:g}], too many for spikes: unit or column wrong? '
                         f'({_label_of(col, labels)})')
            n_out = 0
        bits = ([f'{n_out} outside [{lo:g}, {hi:g}]'] if n_out else []) + (
            [f'{n_jump} jumps'] if n_jump else [])
        if bits:
            parts.append(f'{col}: {", ".join(bits)}')
            total += n_out + n_jump
    if not parts:
        return Check('spikes', 0, 'none', True, None, 'none',
                     {'kind': 'spikes', 'columns': plain(counts)})
    if total and refuse:
        failed = True
    verdict = ('refused (--refuse-spikes)' if refuse and total else 'dropped') if total else ''
    message = '; '.join(parts) + (f' -> {total} samples {verdict}' if total else '')
    return Check('spikes', float(total), 'none', not failed,
                 ', '.join(dict.fromkeys(suspects)) or None, message,
                 {'kind': 'spikes', 'refuse': refuse, 'columns': plain(counts)})


def _label_of(column: str, labels: Mapping[str, str]) -> str:
    quantity = QUANTITY_OF.get(column)
    if quantity is None:
        return f'{labels.get("actuators", "actuators")}.{column}'
    return labels.get(quantity, quantity)


# ----------------------------------------------------------------- consistency
def consistency_checks(table: pd.DataFrame, topic_map: TopicMap, ctx: Context
                       ) -> list[Check]:
    """Compare one run's velocities, heading and rates with the derivatives of its pose."""
    vessel = topic_map.vessel
    if vessel.is_spatial:
        return spatial_checks(table, topic_map, ctx)
    labels = ctx.labels
    t = table['t'].to_numpy(float)
    col = {c: table[c].to_numpy(float) for c in table.columns}
    phi = col['phi'] if vessel.has_roll else np.zeros_like(t)
    width = _widths(ctx, vessel.rate_hz)
    w_vel, w_head = width('velocity'), width('heading')
    if len(t) < max(w_head, 3):
        return [Check('velocity vs d(position)/dt', None, '', True, None,
                      f'skipped: {len(t)} samples are too few')]
    track = 'track' in ctx.derived
    north, east, _ = kinematics(col['u'], col['v'], col['r'], phi, col['psi'])

    def earth(w: int):
        """Velocity rotated to NED and d(position)/dt, smoothed; speed; moving samples."""
        a = np.stack([_smooth(north, w), _smooth(east, w)])
        b = np.stack([_smooth(np.gradient(col['x'], t), w),
                      _smooth(np.gradient(col['y'], t), w)])
        speed = np.hypot(*b)
        return a, b, speed, speed > MOVING * np.percentile(speed, 95)

    checks = []
    if not track:
        a, b, _, moving = earth(w_vel)
        checks.append(_velocity(_sums(a[:, moving].ravel(), b[:, moving].ravel()), labels))
    a, b, speed, moving = earth(w_head)
    course = np.degrees(np.angle(np.exp(1j * (np.arctan2(a[1], a[0])
                                              - np.arctan2(b[1], b[0])))))[moving]
    course_stats = _angles('course', course, speed[moving])
    lags = _lags(t, col, phi, ctx, (w_vel, w_head, width('yaw_rate')), b, moving,
                 vessel.rate_hz)
    # A lag shorter than a sample period (the grid's or the recording's) is no lag.
    lags['tolerance_s'] = max(1.0 / vessel.rate_hz, ctx.interval_s)
    checks.append(_timing(lags, ctx, vessel.rate_hz))
    if track:
        checks.append(Check('course of velocity vs of d(position)/dt', None, '', True, None,
                            'skipped: the velocities come from the track'))
    else:
        checks.append(_course(course_stats, labels))
    mean_speed = float(speed[moving].mean()) if moving.any() else 0.0
    w_turn = max(w_head, int(round(TURN_LENGTHS * ctx.length_m / max(mean_speed, MIN_SPEED)
                                   * vessel.rate_hz)) | 1)
    checks.append(_turn(t, col, earth(w_turn)[1], moving, w_turn, labels))
    checks.append(_drift(t, col, speed, moving, w_head, ctx))
    if 'r' in ctx.derived:
        checks.append(Check('yaw_rate vs d(heading)/dt', None, '', True, None,
                            'skipped: the yaw rate was differentiated from the heading'))
    else:
        w = width('yaw_rate')
        # psi' = r cos(phi) (integrator.kinematics), so compare that with d(psi)/dt.
        checks.append(_rate('yaw_rate', 'heading', _sums(
            _smooth(col['r'] * np.cos(phi), w), _smooth(np.gradient(col['psi'], t), w)),
            labels))
    if vessel.has_roll:
        if 'p' in ctx.derived:
            checks.append(Check('roll_rate vs d(roll)/dt', None, '', True, None,
                                'skipped: the roll rate was differentiated from the roll'))
        else:
            w = width('roll_rate')
            checks.append(_rate('roll_rate', 'roll', _sums(
                _smooth(col['p'], w), _smooth(np.gradient(phi, t), w)), labels))
    if 'sog' in ctx.extras:
        sog = _smooth(np.asarray(ctx.extras['sog'], float), w_vel)
        track_speed = np.hypot(_smooth(np.gradient(col['x'], t), w_vel),
                               _smooth(np.gradient(col['y'], t), w_vel))
        checks.append(_speed_over_ground(_sums(sog, track_speed), labels))
    return checks


def _widths(ctx: Context, rate_hz: float):
    """Return width(what): the odd number of samples a comparison of ``what`` averages."""
    def width(what: str) -> int:
        seconds = max([SMOOTH_S] + [ctx.scales.get(q, 0.0) for q in SCALES_OF[what]])
        return max(1, int(round(seconds * rate_hz))) | 1
    return width


def spatial_checks(table: pd.DataFrame, topic_map: TopicMap, ctx: Context) -> list[Check]:
    """``consistency_checks`` of a 6-DOF vehicle (module docstring): checks in space."""
    vessel, labels = topic_map.vessel, ctx.labels
    t = table['t'].to_numpy(float)
    col = {c: table[c].to_numpy(float) for c in table.columns}
    width = _widths(ctx, vessel.rate_hz)
    w_vel = width('velocity')
    if len(t) < max(w_vel, 3):
        return [Check('velocity vs d(position)/dt', None, '', True, None,
                      f'skipped: {len(t)} samples are too few')]
    angles = (col['phi'], col['theta'], col['psi'])
    velocity = np.stack([_smooth(a, w_vel) for a in body_to_ned(col['u'], col['v'], col['w'],
                                                                  *angles)])
    track = np.stack([_smooth(np.gradient(col[c], t), w_vel) for c in ('x', 'y', 'z')])
    speed = np.linalg.norm(track, axis=0)
    moving = speed > MOVING * np.percentile(speed, 95)
    checks = [_velocity(_sums(velocity[:, moving].ravel(), track[:, moving].ravel()), labels),
              _vertical(_sums(velocity[2], track[2]), labels)]
    euler = attitude_rates(col['p'], col['q'], col['r'], *angles[:2])
    w_rate = width('yaw_rate')
    lags: dict[str, Any] = {}
    coarse = [q for q, w in (('position', w_vel), ('yaw_rate', w_rate))
              if w / vessel.rate_hz > timing.MAX_TIMED_SCALE_S]
    if coarse:
        lags['coarse'] = coarse
    ks = timing.shifts(vessel.rate_hz)
    speed_v = np.linalg.norm(velocity, axis=0)
    if _rms(speed_v) >= MIN_SPEED and 'position' not in coarse:
        lags['position'] = timing.cost_curve(speed_v, speed, ks)
    heading_rate = _smooth(np.gradient(col['psi'], t), w_rate)
    if _rms(heading_rate) >= MIN_RATE and 'yaw_rate' not in coarse:
        lags['yaw_rate'] = timing.cost_curve(heading_rate, _smooth(euler[2], w_rate), ks)
    lags['tolerance_s'] = max(1.0 / vessel.rate_hz, ctx.interval_s)
    checks.append(_timing(lags, ctx, vessel.rate_hz))
    ground = np.hypot(track[0], track[1])
    over_ground = ground > MOVING * np.percentile(ground, 95)
    course = np.degrees(np.angle(np.exp(1j * (np.arctan2(velocity[1], velocity[0])
                                              - np.arctan2(track[1], track[0])))))
    checks.append(_course(_angles('course', course[over_ground], ground[over_ground]),
                          labels))
    checks.append(Check('heading rate vs course rate', None, '', True, None, HULL_ONLY))
    checks.append(Check('drift angle atan2(v, |u|) running straight', None, '', True, None,
                        HULL_ONLY))
    for rate, angle, column, euler_rate in (('yaw_rate', 'heading', 'psi', euler[2]),
                                            ('roll_rate', 'roll', 'phi', euler[0]),
                                            ('pitch_rate', 'pitch', 'theta', euler[1])):
        w = width(rate)
        stats = {**_sums(_smooth(euler_rate, w), _smooth(np.gradient(col[column], t), w)),
                 'kind': 'spatial_rate'}
        check = _rate(rate, angle, stats, labels)
        if not check.ok:
            figures = check.message.split(' -> ')[0]
            check = dataclasses.replace(check, ok=True, suspect=None,
                                        message=f'{figures} -> judged over all runs')
        checks.append(check)
    return checks


def _lags(t, col, phi, ctx: Context, widths: tuple[int, int, int], b_head, moving,
          rate_hz: float) -> dict[str, Any]:
    """
    Cost curves of the three lags (``timing``); a lag is left out where not measurable.

    Under the floors of the other checks (a vessel slower than ``MIN_SPEED``, a heading
    turning slower than ``MIN_RATE``) the curves would match noise against noise: a
    still vessel's lag is not measured rather than found by chance. Nor is a lag whose
    comparison must be smoothed over more than ``timing.MAX_TIMED_SCALE_S`` for the
    resolution of its columns (``widths``: samples of the position, heading and yaw-rate
    comparisons); those are listed under 'coarse'.
    """
    ks = timing.shifts(rate_hz)
    out: dict[str, Any] = {}
    w_vel, w_head, w_rate = widths
    coarse = [q for q, w in zip(timing.QUANTITIES, widths, strict=True)
              if w / rate_hz > timing.MAX_TIMED_SCALE_S]
    if coarse:
        out['coarse'] = coarse
    speed_v = _smooth(np.hypot(col['u'], col['v'] * np.cos(phi)), w_vel)
    if 'track' not in ctx.derived and _rms(speed_v) >= MIN_SPEED and 'position' not in coarse:
        speed_p = _smooth(np.hypot(np.gradient(col['x'], t), np.gradient(col['y'], t)),
                          w_vel)
        out['position'] = timing.cost_curve(speed_v, speed_p, ks)
    if _rms(np.hypot(*b_head)[moving]) >= MIN_SPEED and 'heading' not in coarse:
        # The heading the velocity implies: the track's course less the body drift angle.
        implied = np.arctan2(b_head[1], b_head[0]) - np.arctan2(_smooth(col['v'], w_head),
                                                                _smooth(col['u'], w_head))
        implied = np.where(moving, implied, np.nan)
        out['heading'] = timing.cost_curve(implied, col['psi'], ks, angle=True)
    heading_rate = _smooth(np.gradient(col['psi'], t), w_rate)
    if 'r' not in ctx.derived and _rms(heading_rate) >= MIN_RATE and 'yaw_rate' not in coarse:
        out['yaw_rate'] = timing.cost_curve(heading_rate,
                                            _smooth(col['r'] * np.cos(phi), w_rate), ks)
    return out


def _rms(x: np.ndarray) -> float:
    """Return the root mean square of the finite values (0 for none)."""
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x * x))) if len(x) else 0.0


def _timing(curves: Mapping[str, Any], ctx: Context, rate_hz: float,
            judge: bool = False) -> Check:
    """
    Report the lags; judge them only over all runs (``judge``: a short run is noisy).

    Fails when a lag exceeds a sample period (``tolerance_s``); the message gives the
    map entries with the ``delay_s`` that would remove it.
    """
    name = 'timing of position, heading, yaw_rate vs velocity'
    tol = curves['tolerance_s']
    expected = f'lags within {tol:.3g} s'
    lags = {q: timing.best_shift(curves[q], rate_hz) for q in timing.QUANTITIES
            if q in curves}
    detail = {'kind': 'timing', 'rate_hz': rate_hz, **curves}
    found = {q: v for q, v in lags.items() if v is not None}
    too_coarse = curves.get('coarse', [])
    coarse = f'; too coarse to time: {", ".join(too_coarse)}' if too_coarse else ''
    if not found:
        why = ('' if len(too_coarse) == len(timing.QUANTITIES) else
               'too little turning or speed change') + coarse
        return Check(name, None, expected, True, None,
                     f'skipped: no lag is measurable ({why.lstrip("; ")})', detail)
    text = ', '.join(f'{q} {v:+.2f} s' for q, v in found.items()) + coarse
    worst = max(abs(v) for v in found.values())
    if worst <= tol or not judge:
        verdict = 'ok' if worst <= tol else 'judged over all runs'
        return Check(name, worst, expected, True, None, f'{text} -> {verdict}', detail)
    delays = timing.delays(lags)
    suggest = []
    for q in ('velocity', 'position', 'heading', 'yaw_rate'):
        for label, current in ctx.entries.get(q, ()):
            new = round(current + delays[q], 2)
            if abs(new - current) > 0.5 * tol:
                suggest.append(f'{label}: delay_s: {new:g}')
    suspects = ', '.join(s.split(':')[0] for s in suggest) or None
    return Check(name, worst, expected, False, suspects,
                 f'{text} (position and heading behind the velocity, yaw rate behind the '
                 f'heading) -> the stamps are late; suggested map entries: '
                 f'{"; ".join(suggest)}', detail)


def _smooth(x: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average (edges: shorter windows); both sides get the same filter."""
    width = min(width, len(x) - 1 + len(x) % 2)  # odd, and no longer than the signal
    if width <= 1:
        return np.asarray(x, float)
    kernel = np.ones(width)
    num = np.convolve(x, kernel, mode='same')
    den = np.convolve(np.ones(len(x)), kernel, mode='same')
    return num / den


def _sums(a: np.ndarray, b: np.ndarray) -> dict[str, float]:
    ok = np.isfinite(a) & np.isfinite(b)
    a, b = a[ok], b[ok]
    return {'kind': 'regression', 'n': int(len(a)), 'saa': float(a @ a),
            'sab': float(a @ b), 'sbb': float(b @ b)}


def _regression(stats: Mapping[str, float]) -> tuple[float, float]:
    slope = stats['sab'] / stats['sbb']
    corr = stats['sab'] / math.sqrt(stats['saa'] * stats['sbb']) if stats['saa'] else 0.0
    return slope, corr


def _judge_slope(name: str, stats: dict, floor: float, floor_text: str, explain
                 ) -> Check:
    """
    Judge a regression through the origin: slope 1 +- SLOPE_TOL, corr >= MIN_CORR.

    Skipped when the reference's rms is under ``floor`` (``floor_text`` says what); a
    failure asks ``explain(slope, corr)`` for (suspect, why).
    """
    expected = f'slope 1 +- {SLOPE_TOL:g}, corr >= {MIN_CORR:g}'
    if not stats['n'] or math.sqrt(stats['sbb'] / stats['n']) < floor:
        return Check(name, None, expected, True, None, f'skipped: {floor_text}', stats)
    slope, corr = _regression(stats)
    figures = f'slope {slope:.3f}, corr {corr:.3f}'
    if abs(slope - 1) <= SLOPE_TOL and corr >= MIN_CORR:
        return Check(name, slope, expected, True, None, f'{figures} -> ok', stats)
    suspect, why = explain(slope, corr)
    return Check(name, slope, expected, False, suspect, f'{figures} -> {why}', stats)


def _velocity(stats: dict, labels: Mapping[str, str]) -> Check:
    def explain(slope, corr):
        suspect, why = _explain(slope, corr, 'velocity', 'speed', 'position', 'length',
                                labels)
        if why is None:
            suspect = f'{labels["velocity"]}, {labels["position"]}'
            why = (f'velocity and position disagree: velocity frame or axes, position '
                   f'frame (ned/enu) or heading wrong ({suspect}, {labels["heading"]})')
        return suspect, why

    return _judge_slope('velocity vs d(position)/dt', stats, MIN_SPEED,
                        f'the vessel moves slower than {MIN_SPEED:g} m/s', explain)


def _vertical(stats: dict, labels: Mapping[str, str]) -> Check:
    def explain(slope, corr):
        suspect, why = _explain(slope, corr, 'velocity', 'speed', 'position', 'length',
                                labels)
        if why is None:
            suspect = f'{labels["velocity"]}, {labels["position"]}'
            why = (f'the vertical velocity and the height disagree: down or z sign, frame '
                   f'(ned/enu) or column wrong ({suspect})')
        return suspect, why

    return _judge_slope('vertical velocity vs d(z)/dt', {**stats, 'vertical': True},
                        MIN_SPEED, f'the vehicle climbs and sinks slower than '
                        f'{MIN_SPEED:g} m/s', explain)


def _speed_over_ground(stats: dict, labels: Mapping[str, str]) -> Check:
    label = labels['speed_over_ground']

    def explain(slope, corr):
        # The track's speed is noisier than a receiver's: name a slip within 10 %.
        found = [what for ratio, what in UNIT_SLIPS['speed'].items()
                 if abs(slope / ratio - 1) <= 0.1]
        return label, (f'speed over ground looks like {" or ".join(found)} (map entry '
                       f'{label})' if found else
                       f'speed over ground does not follow the track ({label})')

    return _judge_slope('speed over ground vs the track', stats, MIN_SPEED,
                        f'the vessel moves slower than {MIN_SPEED:g} m/s', explain)


def _course(stats: dict, labels: Mapping[str, str]) -> Check:
    return _angle_median(
        stats, 'course of velocity vs of d(position)/dt', MAX_COURSE_DEG, 'median difference',
        2, labels['velocity'],
        f'the velocity points elsewhere than the track: earth-frame velocities mapped as '
        f'body (surge/sway), swapped or sign-flipped components ({labels["velocity"]}), a '
        f'wrong heading or position frame ({labels["heading"]}, {labels["position"]}), or '
        f'a lag (the timing check over all runs says which)')


def _turn(t, col, b, moving, w: int, labels: Mapping[str, str]) -> Check:
    """Check that the heading turns with the track: course rate against d(psi)/dt."""
    # The course's rate from the track's velocity and acceleration (no unwrapping), the
    # noisy side: regressed on the heading rate; both zero where the vessel is still.
    speed_sq = np.maximum(b[0] ** 2 + b[1] ** 2, 1e-12)
    course_rate = (b[0] * np.gradient(b[1], t) - b[1] * np.gradient(b[0], t)) / speed_sq
    a = _smooth(np.where(moving, course_rate, 0.0), w)
    heading_rate = _smooth(np.where(moving, np.gradient(col['psi'], t), 0.0), w)
    return _judge_turn({**_sums(a, heading_rate), 'kind': 'turn'}, labels)


def _judge_turn(stats: dict, labels: Mapping[str, str], judge: bool = False) -> Check:
    """
    Judge the turn over all runs only (``judge``): a zig-zag's drift swings widely.

    Skipped where the heading turns too little (each run, and all runs pooled: every run
    of a still vessel skipped leaves nothing to regress).
    """
    name = 'heading rate vs course rate'
    expected = f'slope {1 / TURN_RATIO:.2g}..{TURN_RATIO:g}, corr >= {TURN_MIN_CORR:g}'
    if not stats['n'] or math.sqrt(stats['sbb'] / stats['n']) < MIN_RATE:
        return Check(name, None, expected, True, None,
                     f'skipped: the heading turns slower than {math.degrees(MIN_RATE):g} '
                     f'deg/s', stats)
    slope, corr = _regression(stats)
    figures = f'slope {slope:.3f}, corr {corr:.3f}'
    if 1 / TURN_RATIO <= slope <= TURN_RATIO and corr >= TURN_MIN_CORR:
        return Check(name, slope, expected, True, None, f'{figures} -> ok', stats)
    if not judge:
        return Check(name, slope, expected, True, None, f'{figures} -> judged over all runs',
                     stats)
    label = labels['heading']
    # A heading r times the truth turns the slope (course per heading) into 1/r.
    found = [what for ratio, what in UNIT_SLIPS['angle'].items()
             if slope and _near(1 / abs(slope), ratio)]
    if slope < 0:
        why = (f'the heading turns against the track: heading convention (north_clockwise '
               f'vs east_counterclockwise) or sign ({label})')
    elif found:
        why = f'heading looks like {" or ".join(found)} (map entry {label})'
    else:
        why = f'the heading does not turn with the track: wrong column or unit ({label})'
    return Check(name, slope, expected, False, label, f'{figures} -> {why}', stats)


def _drift(t, col, speed, moving, w: int, ctx: Context) -> Check:
    """Drift angle while running straight (turning radius over 10 lengths)."""
    u, v, r = (_smooth(col[c], w) for c in ('u', 'v', 'r'))
    straight = moving & (np.abs(r) * ctx.length_m < STRAIGHT * np.maximum(speed, 1e-9))
    # Folded about the beam (|u|): going astern is no drift, a heading 90 deg off is.
    drift = np.degrees(np.arctan2(v, np.abs(u)))[straight]
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
    stats = {**_angles('drift', drift, speed[straight]), 'seconds': dt * straight.sum()}
    return _judge_drift(stats, ctx.labels)


def _angles(kind: str, degrees: np.ndarray, speed: np.ndarray) -> dict[str, Any]:
    """Return sums of an angle for pooling: |angle| histogram, count, speed squares."""
    counts, _ = np.histogram(np.minimum(np.abs(degrees), ANGLE_BINS[-1]), ANGLE_BINS)
    return {'kind': kind, 'n': int(len(degrees)), 'hist': counts.tolist(),
            'speed_sq': float(np.sum(speed ** 2))}


def _judge_drift(stats: dict, labels: Mapping[str, str]) -> Check:
    name = 'drift angle atan2(v, |u|) running straight'
    if stats['seconds'] < MIN_STRAIGHT_S:
        return Check(name, None, f'median < {MAX_DRIFT_DEG:g} deg', True, None,
                     f'skipped: {stats["seconds"]:.1f} s of straight running (radius over '
                     f'{1 / STRAIGHT:g} lengths) are too few', stats)
    return _angle_median(
        stats, name, MAX_DRIFT_DEG, 'median', 1, labels['heading'],
        f'the bow points far from the track while running straight: heading convention, '
        f'offset or unit wrong ({labels["heading"]}), or surge/sway swapped '
        f'({labels["velocity"]}); legitimate only for a vessel moving sideways (then '
        f'--accept-checks)')


def _angle_median(stats: dict, name: str, limit_deg: float, label: str, digits: int,
                  suspect: str, why: str) -> Check:
    """Pass when the median |angle| (deg) over moving samples stays under ``limit_deg``."""
    expected = f'median < {limit_deg:g} deg'
    if not _moving(stats):
        return Check(name, None, expected, True, None,
                     f'skipped: the vessel moves slower than {MIN_SPEED:g} m/s', stats)
    cum = np.cumsum(stats['hist'])
    i = int(np.searchsorted(cum, 0.5 * cum[-1]))
    median = float(ANGLE_BINS[i + 1])  # the bin's upper edge: never flatters
    p95 = float(ANGLE_BINS[int(np.searchsorted(cum, 0.95 * cum[-1])) + 1])
    figures = f'{label} {median:.{digits}f} deg (95 % below {p95:.{digits}f})'
    if median < limit_deg:
        return Check(name, median, expected, True, None, f'{figures} -> ok', stats)
    return Check(name, median, expected, False, suspect, f'{figures} -> {why}', stats)


def _moving(stats: Mapping[str, float]) -> bool:
    return bool(stats['n']) and math.sqrt(stats['speed_sq'] / stats['n']) >= MIN_SPEED


def _rate(rate: str, angle: str, stats: dict, labels: Mapping[str, str]) -> Check:
    def explain(slope, corr):
        suspect, why = _explain(slope, corr, rate, 'rate', angle, 'angle', labels)
        if why is None:
            suspect = labels[rate]
            why = (f'{rate} does not follow the {angle}: wrong column for {rate} or '
                   f'{angle} ({labels[rate]}, {labels[angle]})')
        return suspect, why

    return _judge_slope(f'{rate} vs d({angle})/dt', {**stats, 'rate': rate, 'angle': angle},
                        MIN_RATE, f'the {angle} changes slower than '
                        f'{math.degrees(MIN_RATE):g} deg/s', explain)


def _explain(slope: float, corr: float, a: str, a_kind: str, b: str, b_kind: str,
             labels: Mapping[str, str]) -> tuple[str | None, str | None]:
    """Name the unit slips or sign flip a slope points to, if any (else None, None)."""
    if corr < MIN_CORR and abs(abs(corr) - 1) > 0.1:
        return None, None
    if abs(slope + 1) <= SLOPE_TOL:
        return labels[a], (f'sign flip: {a} sign or {b} convention/sign '
                           f'({labels[a]}, {labels[b]})')
    sign = 'sign-flipped and ' if slope < 0 else ''
    # A mapped value r times the truth gives slope r; a reference r times gives 1/r;
    # time values r times the truth make every derivative 1/r and the slope r.
    found = [(labels[a], f'{a} looks like {sign}{what} (map entry {labels[a]})')
             for ratio, what in UNIT_SLIPS[a_kind].items() if _near(abs(slope), ratio)]
    found += [(labels[b], f'{b} looks like {sign}{what} (map entry {labels[b]})')
              for ratio, what in UNIT_SLIPS[b_kind].items() if _near(abs(slope), 1 / ratio)]
    found += [(labels['time'], f'time looks like {sign}{what} (map entry {labels["time"]})')
              for ratio, what in UNIT_SLIPS['time'].items() if _near(abs(slope), ratio)]
    if not found:
        return None, None
    return found[0][0], ', or '.join(why for _, why in found)


def _near(value: float, ratio: float) -> bool:
    return abs(value / ratio - 1) <= FACTOR_TOL


# ----------------------------------------------------------------- runs and pooling
def check_run(table: pd.DataFrame, topic_map: TopicMap, ctx: Context,
              spikes: Mapping[str, Mapping[str, Any]], refuse_spikes: bool = False
              ) -> list[Check]:
    """Return every check of one run: consistency, then spikes (counted by the converter)."""
    return consistency_checks(table, topic_map, ctx) + [
        spike_check(spikes, refuse_spikes, ctx.labels)]


def aggregate(per_run: Mapping[str, Sequence[Check]], ctx: Context) -> list[Check]:
    """Pool the checks of many runs into one per check name (sums, not averages)."""
    pooled: dict[str, dict] = {}
    refuse = False
    for checks in per_run.values():
        for c in checks:
            kind = c.detail.get('kind')
            if kind is None:
                continue
            acc = pooled.setdefault(c.name, {'kind': kind})
            if kind == 'spikes':
                refuse = refuse or c.detail.get('refuse', False)
                cols = acc.setdefault('columns', {})
                for col, n in c.detail['columns'].items():
                    have = cols.setdefault(col, {'samples': 0, 'out_of_range': 0,
                                                 'jumps': 0, 'dropped': True,
                                                 'bounds': n['bounds']})
                    for k in ('samples', 'out_of_range', 'jumps'):
                        have[k] += n[k]
                    have['dropped'] = have['dropped'] and n['dropped']
                continue
            for k, v in c.detail.items():
                if k == 'hist':
                    acc[k] = [x + y for x, y in zip(acc.get(k, [0] * len(v)), v, strict=True)]
                elif isinstance(v, Mapping) and 'sum_sq' in v:  # a timing cost curve
                    cur = acc.setdefault(k, {'sum_sq': [0.0] * len(v['sum_sq']),
                                             'n': [0] * len(v['n'])})
                    cur['sum_sq'] = [x + y for x, y in zip(cur['sum_sq'], v['sum_sq'],
                                                           strict=True)]
                    cur['n'] = [x + y for x, y in zip(cur['n'], v['n'], strict=True)]
                elif k == 'tolerance_s':
                    acc[k] = max(acc.get(k, 0.0), v)
                elif k == 'coarse':   # quantities too coarse to time in some run
                    acc[k] = sorted(set(acc.get(k, ())) | set(v), key=timing.QUANTITIES.index)
                elif isinstance(v, (int, float)) and not isinstance(v, bool) and \
                        k != 'rate_hz':
                    acc[k] = acc.get(k, 0) + v
                else:
                    acc[k] = v
    out = []
    for name, stats in pooled.items():
        out.append(_judge(name, stats, refuse, ctx))
    return out


def _judge(name: str, stats: dict, refuse: bool, ctx: Context) -> Check:
    kind = stats['kind']
    labels = ctx.labels
    if kind == 'spikes':
        return spike_check(stats['columns'], refuse, labels)
    if kind == 'course':
        return _course(stats, labels)
    if kind == 'drift':
        return _judge_drift(stats, labels)
    if kind == 'timing':
        return _timing(stats, ctx, stats['rate_hz'], judge=True)
    if kind == 'turn':
        return _judge_turn(stats, labels, judge=True)
    if kind == 'spatial_rate':
        return _rate(stats['rate'], stats['angle'], stats, labels)
    if name.startswith('velocity'):
        return _velocity(stats, labels)
    if name.startswith('vertical'):
        return _vertical(stats, labels)
    if name.startswith('speed over ground'):
        return _speed_over_ground(stats, labels)
    return _rate(stats['rate'], stats['angle'], stats, labels)


def report(per_run: Mapping[str, Sequence[Check]], ctx: Context,
           stream: TextIO) -> tuple[bool, dict[str, Any]]:
    """
    Print one line per check and run, then the pooled lines; return (all ok, manifest data).

    A run fails when any of its checks fails; timing and the turn are judged over all
    runs only (``POOLED``: one run is too short or too oscillatory), so their pooled
    lines can fail the whole conversion.
    """
    ok = True
    for run_id, checks in per_run.items():
        for c in checks:
            print(f'{run_id}: {c.line()}', file=stream)
            ok = ok and c.ok
    pooled = aggregate(per_run, ctx)
    for c in pooled:
        if len(per_run) > 1 or c.detail.get('kind') in POOLED:
            print(f'all runs: {c.line()}', file=stream)
    failed = sorted({c.name for checks in per_run.values() for c in checks if not c.ok}
                    | {c.name for c in pooled if not c.ok and c.detail.get('kind') in POOLED})
    ok = not failed
    data = {'ok': ok, 'failed': failed,
            'runs': {r: [c.to_dict() for c in checks] for r, checks in per_run.items()},
            'all': [c.to_dict() for c in pooled]}
    return ok, data


def gate(per_run: Mapping[str, Sequence[Check]], ctx: Context, accept: bool,
         refuse_spikes: bool, stream: TextIO) -> tuple[bool, dict[str, Any]]:
    """
    Print the checks and decide whether to write: (go on, manifest data).

    Failed checks stop the conversion unless ``accept``; spikes under ``refuse_spikes``
    stop it regardless.
    """
    ok, data = report(per_run, ctx, stream)
    if ok:
        return True, data
    failed = ', '.join(data['failed'])
    if not accept or (refuse_spikes and 'spikes' in data['failed']):
        print(f'error: map checks failed ({failed}); fix the map, or give --accept-checks '
              f'if the data are right', file=stream)
        return False, data
    print(f'warning: map checks failed ({failed}); writing anyway (--accept-checks)',
          file=stream)
    return True, data
