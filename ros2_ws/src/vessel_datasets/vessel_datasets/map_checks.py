"""
Checks that a recording map (topic or column map) gives the quantities it claims.

A map names a column or field per quantity with a unit and a frame; a wrong unit, frame
or sign still gives numbers that look fine on their own. These checks compare
quantities the data measures twice -- once directly, once as the derivative of another
-- on one run's dataset columns (model units and frames, after conversion):

* velocity: body u, v rotated to NED by psi (``vessel_physics.integrator.kinematics``)
  against d(x, y)/dt: least-squares slope through the origin and correlation, then the
  course (direction) difference, which catches earth-frame velocities mapped as body;
* drift: the angle between the bow and the velocity, which catches a wrong heading
  convention where velocities were rotated by that same heading;
* yaw rate against d(psi)/dt, roll rate against d(phi)/dt (where they were mapped,
  not differentiated);
* spikes: samples beyond the vessel's declared ranges (``limits`` for states,
  actuator ranges) and single-sample jumps of states far beyond their neighbours.

A slope far from 1 is matched against known unit slips (deg/rad, knots, km/h, rev,
per minute, ms) and the message names the map entry to fix. Each check gives a
:class:`Check`; its ``detail`` holds sums, so checks of many runs pool into one
(:func:`aggregate`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
import math
from typing import Any, TextIO

import numpy as np
import pandas as pd

from vessel_description import Vessel
from vessel_description.vessel import plain
from vessel_physics.integrator import kinematics

# A slope within this of 1 (and a correlation at least MIN_CORR) passes.
SLOPE_TOL = 0.1
MIN_CORR = 0.9
# A slope within this relative distance of a known factor is named as that slip (deg/rad
# and per minute are 4.7 % apart).
FACTOR_TOL = 0.03
MAX_COURSE_DEG = 2.0      # rms course difference of velocity vs d(position)/dt
MAX_DRIFT_DEG = 30.0      # rms drift angle of a ship under way (crabbing/astern exceed it)
MIN_SPEED = 0.05          # m/s; slower runs are too still to test the velocity map
MIN_RATE = math.radians(0.1)  # rad/s; steadier runs cannot test a rate map
MOVING = 0.25             # samples above this share of the 95th-percentile speed count
SMOOTH_S = 1.0            # both sides are averaged over this long against noise
# Out-of-range samples are spikes only while they are this rare; more means a unit or
# column is wrong, and they are kept so the other checks can say which.
MAX_SPIKE_SHARE = 0.05
JUMP_MADS = 10.0          # a jump beyond this many robust sigmas of its neighbours...
JUMP_SPAN = 0.1           # ...and beyond this share of the state's declared range

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

# Map entries named in messages: a column map's and a topic map's.
COLUMN_LABELS = {'velocity': 'columns.velocity', 'position': 'columns.position',
                 'heading': 'columns.heading', 'yaw_rate': 'columns.yaw_rate',
                 'roll_rate': 'columns.roll_rate', 'roll': 'columns.roll',
                 'time': 'columns.time', 'actuators': 'columns.actuators'}
TOPIC_LABELS = {'velocity': 'topics.body_velocity', 'position': 'topics.position',
                'heading': 'topics.attitude', 'yaw_rate': 'topics.body_velocity.yaw_rate',
                'roll_rate': 'topics.body_velocity.roll_rate', 'roll': 'topics.attitude',
                'time': 'stamps', 'actuators': 'topics.actuators'}
# Dataset column -> map quantity, for spike messages.
QUANTITY_OF = {'u': 'velocity', 'v': 'velocity', 'p': 'roll_rate', 'r': 'yaw_rate',
               'phi': 'roll'}


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


# ----------------------------------------------------------------- spikes
@dataclass
class Spikes:
    """Spike masks of one column and whether they may be dropped."""

    column: str
    samples: int
    out_of_range: np.ndarray
    jumps: np.ndarray
    bounds: tuple[float, float] | None

    @property
    def droppable(self) -> bool:
        """Whether the out-of-range samples are rare enough to be spikes."""
        return int(self.out_of_range.sum()) <= MAX_SPIKE_SHARE * max(self.samples, 1)

    @property
    def mask(self) -> np.ndarray:
        """Return the samples to drop: jumps always, out-of-range ones while rare."""
        return self.jumps | (self.out_of_range if self.droppable else False)

    def counts(self) -> dict[str, Any]:
        """Return counts for a report: samples, out of range, jumps, whether dropped."""
        return {'samples': int(self.samples), 'out_of_range': int(self.out_of_range.sum()),
                'jumps': int(self.jumps.sum()), 'dropped': bool(self.droppable),
                'bounds': list(self.bounds) if self.bounds else None}


def bounds_of(vessel: Vessel, column: str) -> tuple[float, float] | None:
    """Return the declared range of a state (``limits``) or actuator, if any."""
    if column in vessel.limits:
        return vessel.limits[column]
    if column in vessel.actuator_names:
        a = vessel.actuator(column)
        return (a.low, a.high)
    return None


def find_spikes(column: str, values: np.ndarray, vessel: Vessel) -> Spikes:
    """
    Find the spikes of one column (model units); NaN samples are never spikes.

    States are tested for range and single-sample jumps, actuators for range only
    (commands may step).
    """
    values = np.asarray(values, float)
    finite = np.isfinite(values)
    bounds = bounds_of(vessel, column)
    out = np.zeros(len(values), bool)
    if bounds is not None:
        out[finite] = (values[finite] < bounds[0]) | (values[finite] > bounds[1])
    jumps = np.zeros(len(values), bool)
    if column in vessel.states:
        keep = finite & ~out
        idx = np.nonzero(keep)[0]
        if len(idx) >= 5:
            x = values[idx]
            span = (bounds[1] - bounds[0]) if bounds else float(np.ptp(x))
            jumps[idx] = _jumps(x, span)
    return Spikes(column, int(finite.sum()), out, jumps, bounds)


def _jumps(x: np.ndarray, span: float) -> np.ndarray:
    """Flag samples far from the median of their two neighbours either side."""
    pad = np.pad(x, 2, mode='edge')
    neighbours = np.stack([pad[:-4], pad[1:-3], pad[3:-1], pad[4:]])
    d = x - np.median(neighbours, axis=0)
    sigma = 1.4826 * np.median(np.abs(d - np.median(d)))
    return (np.abs(d) > JUMP_MADS * sigma) & (np.abs(d) > JUMP_SPAN * span)


def spike_check(counts: Mapping[str, Mapping[str, Any]], refuse: bool,
                labels: Mapping[str, str]) -> Check:
    """Judge one run's spike counts (per column, from :meth:`Spikes.counts`)."""
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


def drop_spikes_on_grid(table: pd.DataFrame, vessel: Vessel) -> dict[str, dict[str, Any]]:
    """
    Drop the spikes of a resampled run table in place and refill them from neighbours.

    For tables already on the vessel's grid (bags): states are interpolated linearly
    over the dropped samples, actuators held from the previous sample -- what
    resampling would have given without them. Returns counts per column.
    """
    counts = {}
    t = table['t'].to_numpy(float)
    for col in vessel.states + vessel.actuator_names:
        values = table[col].to_numpy(float, copy=True)
        spikes = find_spikes(col, values, vessel)
        counts[col] = spikes.counts()
        mask = spikes.mask
        if not mask.any() or mask.all():
            continue
        good = np.nonzero(~mask)[0]
        if col in vessel.states:
            values[mask] = np.interp(t[mask], t[good], values[good])
        else:
            prev = np.maximum(np.searchsorted(good, np.nonzero(mask)[0]) - 1, 0)
            values[mask] = values[good[prev]]
        table[col] = values
    return counts


# ----------------------------------------------------------------- consistency
def consistency_checks(table: pd.DataFrame, vessel: Vessel, labels: Mapping[str, str],
                       derived: Sequence[str] = ()) -> list[Check]:
    """
    Compare one run's velocities and rates with the derivatives of its pose.

    ``table`` holds the vessel's dataset columns; ``derived`` names state columns the
    converter differentiated itself (their check would be circular and is skipped).
    """
    t = table['t'].to_numpy(float)
    col = {c: table[c].to_numpy(float) for c in table.columns}
    phi = col['phi'] if vessel.has_roll else np.zeros_like(t)
    width = max(1, int(round(SMOOTH_S * vessel.rate_hz))) | 1
    if len(t) < max(width, 3):
        return [Check('velocity vs d(position)/dt', None, '', True, None,
                      f'skipped: {len(t)} samples are too few')]
    north, east, _ = kinematics(col['u'], col['v'], col['r'], phi, col['psi'])
    a = np.stack([_smooth(north, width), _smooth(east, width)])
    b = np.stack([_smooth(np.gradient(col['x'], t), width),
                  _smooth(np.gradient(col['y'], t), width)])
    speed = np.hypot(*b)
    moving = speed > MOVING * np.percentile(speed, 95)
    checks = [_velocity(_sums(a[:, moving].ravel(), b[:, moving].ravel()), labels)]
    ang_a = np.arctan2(a[1], a[0])
    ang_b = np.arctan2(b[1], b[0])
    course = np.degrees(np.angle(np.exp(1j * (ang_a - ang_b))))[moving]
    checks.append(_course({'kind': 'course', 'n': int(moving.sum()),
                           'sum_sq': float(np.sum(course ** 2)),
                           'speed_sq': float(np.sum(speed[moving] ** 2))}, labels))
    # Folded about the beam (|u|): going astern is no drift, a heading 90 deg off is.
    drift = np.degrees(np.arctan2(_smooth(col['v'], width),
                                  np.abs(_smooth(col['u'], width))))[moving]
    checks.append(_drift({'kind': 'drift', 'n': int(moving.sum()),
                          'sum_sq': float(np.sum(drift ** 2)),
                          'speed_sq': float(np.sum(speed[moving] ** 2))}, labels))
    if 'r' in derived:
        checks.append(Check('yaw_rate vs d(heading)/dt', None, '', True, None,
                            'skipped: the yaw rate was differentiated from the heading'))
    else:
        # psi' = r cos(phi) (integrator.kinematics), so compare that with d(psi)/dt.
        checks.append(_rate('yaw_rate', 'heading', _sums(
            _smooth(col['r'] * np.cos(phi), width),
            _smooth(np.gradient(col['psi'], t), width)), labels))
    if vessel.has_roll:
        if 'p' in derived:
            checks.append(Check('roll_rate vs d(roll)/dt', None, '', True, None,
                                'skipped: the roll rate was differentiated from the roll'))
        else:
            checks.append(_rate('roll_rate', 'roll', _sums(
                _smooth(col['p'], width), _smooth(np.gradient(phi, t), width)), labels))
    return checks


def _smooth(x: np.ndarray, width: int) -> np.ndarray:
    """Centred moving average (edges: shorter windows); both sides get the same filter."""
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


def _velocity(stats: dict, labels: Mapping[str, str]) -> Check:
    name = 'velocity vs d(position)/dt'
    expected = f'slope 1 +- {SLOPE_TOL:g}, corr >= {MIN_CORR:g}'
    if not stats['n'] or math.sqrt(stats['sbb'] / stats['n']) < MIN_SPEED:
        return Check(name, None, expected, True, None,
                     f'skipped: the vessel moves slower than {MIN_SPEED:g} m/s', stats)
    slope, corr = _regression(stats)
    figures = f'slope {slope:.3f}, corr {corr:.3f}'
    if abs(slope - 1) <= SLOPE_TOL and corr >= MIN_CORR:
        return Check(name, slope, expected, True, None, f'{figures} -> ok', stats)
    suspect, why = _explain(slope, corr, 'velocity', 'speed', 'position', 'length', labels)
    if why is None:
        suspect = f'{labels["velocity"]}, {labels["position"]}'
        why = (f'velocity and position disagree: velocity frame or axes, position frame '
               f'(ned/enu) or heading wrong ({suspect}, {labels["heading"]})')
    return Check(name, slope, expected, False, suspect, f'{figures} -> {why}', stats)


def _course(stats: dict, labels: Mapping[str, str]) -> Check:
    return _angle_rms(
        stats, 'course of velocity vs of d(position)/dt', MAX_COURSE_DEG, 'rms difference',
        2, labels['velocity'],
        f'the velocity points elsewhere than the track: earth-frame velocities mapped as '
        f'body (surge/sway), swapped or sign-flipped components ({labels["velocity"]}), or '
        f'a wrong heading or position frame ({labels["heading"]}, {labels["position"]})')


def _drift(stats: dict, labels: Mapping[str, str]) -> Check:
    return _angle_rms(
        stats, 'drift angle atan2(v, |u|)', MAX_DRIFT_DEG, 'rms', 1, labels['heading'],
        f'the bow points far from the track: heading convention or unit wrong '
        f'({labels["heading"]}), or surge/sway swapped ({labels["velocity"]}); legitimate '
        f'only for a vessel moving sideways (then --accept-checks)',
        expected_suffix=' under way')


def _angle_rms(stats: dict, name: str, limit_deg: float, label: str, digits: int,
               suspect: str, why: str, expected_suffix: str = '') -> Check:
    """Pass when the rms of an angle (deg) over moving samples stays under ``limit_deg``."""
    expected = f'rms < {limit_deg:g} deg{expected_suffix}'
    if not _moving(stats):
        return Check(name, None, expected, True, None,
                     f'skipped: the vessel moves slower than {MIN_SPEED:g} m/s', stats)
    rms = math.sqrt(stats['sum_sq'] / stats['n'])
    figures = f'{label} {rms:.{digits}f} deg'
    if rms < limit_deg:
        return Check(name, rms, expected, True, None, f'{figures} -> ok', stats)
    return Check(name, rms, expected, False, suspect, f'{figures} -> {why}', stats)


def _moving(stats: Mapping[str, float]) -> bool:
    return bool(stats['n']) and math.sqrt(stats['speed_sq'] / stats['n']) >= MIN_SPEED


def _rate(rate: str, angle: str, stats: dict, labels: Mapping[str, str]) -> Check:
    name = f'{rate} vs d({angle})/dt'
    stats = {**stats, 'rate': rate, 'angle': angle}
    expected = f'slope 1 +- {SLOPE_TOL:g}, corr >= {MIN_CORR:g}'
    if not stats['n'] or math.sqrt(stats['sbb'] / stats['n']) < MIN_RATE:
        return Check(name, None, expected, True, None,
                     f'skipped: the {angle} changes slower than '
                     f'{math.degrees(MIN_RATE):g} deg/s', stats)
    slope, corr = _regression(stats)
    figures = f'slope {slope:.3f}, corr {corr:.3f}'
    if abs(slope - 1) <= SLOPE_TOL and corr >= MIN_CORR:
        return Check(name, slope, expected, True, None, f'{figures} -> ok', stats)
    suspect, why = _explain(slope, corr, rate, 'rate', angle, 'angle', labels)
    if why is None:
        suspect = labels[rate]
        why = (f'{rate} does not follow the {angle}: wrong column for {rate} or {angle} '
               f'({labels[rate]}, {labels[angle]})')
    return Check(name, slope, expected, False, suspect, f'{figures} -> {why}', stats)


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
def check_run(table: pd.DataFrame, vessel: Vessel, labels: Mapping[str, str],
              spikes: Mapping[str, Mapping[str, Any]], derived: Sequence[str] = (),
              refuse_spikes: bool = False) -> list[Check]:
    """Return every check of one run: consistency, then spikes (counted by the caller)."""
    return consistency_checks(table, vessel, labels, derived) + [
        spike_check(spikes, refuse_spikes, labels)]


def check_runs(runs: Mapping[str, pd.DataFrame], vessel: Vessel,
               labels: Mapping[str, str] = TOPIC_LABELS,
               refuse_spikes: bool = False) -> dict[str, list[Check]]:
    """
    Check resampled run tables (bags): drop their spikes in place, then check each.

    Returns the checks per run id; :func:`aggregate` pools them.
    """
    out = {}
    for run_id, table in runs.items():
        counts = drop_spikes_on_grid(table, vessel)
        out[run_id] = check_run(table, vessel, labels, counts, refuse_spikes=refuse_spikes)
    return out


def aggregate(per_run: Mapping[str, Sequence[Check]], labels: Mapping[str, str]
              ) -> list[Check]:
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
                if isinstance(v, (int, float)) and not isinstance(v, bool):
                    acc[k] = acc.get(k, 0) + v
                else:
                    acc[k] = v
    out = []
    for name, stats in pooled.items():
        kind = stats['kind']
        if kind == 'spikes':
            out.append(spike_check(stats['columns'], refuse, labels))
        elif kind == 'course':
            out.append(_course(stats, labels))
        elif kind == 'drift':
            out.append(_drift(stats, labels))
        elif name.startswith('velocity'):
            out.append(_velocity(stats, labels))
        else:
            out.append(_rate(stats['rate'], stats['angle'], stats, labels))
    return out


def report(per_run: Mapping[str, Sequence[Check]], labels: Mapping[str, str],
           stream: TextIO) -> tuple[bool, dict[str, Any]]:
    """
    Print one line per check and run, then the pooled lines; return (all ok, manifest data).

    A run fails when any of its checks fails; the pooled lines only summarise.
    """
    ok = True
    for run_id, checks in per_run.items():
        for c in checks:
            print(f'{run_id}: {c.line()}', file=stream)
            ok = ok and c.ok
    pooled = aggregate(per_run, labels)
    if len(per_run) > 1:
        for c in pooled:
            print(f'all runs: {c.line()}', file=stream)
    failed = sorted({c.name for checks in per_run.values() for c in checks if not c.ok})
    data = {'ok': ok, 'failed': failed,
            'runs': {r: [c.to_dict() for c in checks] for r, checks in per_run.items()},
            'all': [c.to_dict() for c in pooled]}
    return ok, data


def gate(per_run: Mapping[str, Sequence[Check]], labels: Mapping[str, str], accept: bool,
         refuse_spikes: bool, stream: TextIO) -> tuple[bool, dict[str, Any]]:
    """
    Print the checks and decide whether to write: (go on, manifest data).

    Failed checks stop the conversion unless ``accept``; spikes under ``refuse_spikes``
    stop it regardless.
    """
    ok, data = report(per_run, labels, stream)
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


def check_bag_results(results: Sequence[Any], vessel: Vessel, accept: bool,
                      refuse_spikes: bool, stream: TextIO) -> bool:
    """
    Check the runs of ``convert.BagResult`` objects before they are written.

    Drops spikes in the run tables, prints the checks, stores each bag's in its report
    (so in the manifest) and returns whether to write.
    """
    runs = {run_id: table for r in results for run_id, table in r.runs.items()}
    go_on, data = gate(check_runs(runs, vessel, TOPIC_LABELS, refuse_spikes), TOPIC_LABELS,
                       accept, refuse_spikes, stream)
    for r in results:
        r.report['checks'] = {run_id: data['runs'][run_id] for run_id in r.runs}
    return go_on
