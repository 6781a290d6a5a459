"""
Reference trajectories of a multirotor's flights: the nano-drone benchmark's kinds.

Each run flies one kind, drawn from its own random stream (``simulation.simulator``:
the ``operator`` stream), so a run's flight does not depend on the batch it is in:

- ``square``: the corners of a square (side ``side_m``, a random orientation and
  sense), each reached in a rest-to-rest hop of ``move_s`` and held ``hold_s``; after
  each lap a vertical hop of ``climb_m``, alternately up and down (the benchmark's
  square flights: two layers 1 m apart).
- ``random``: random waypoints in a box of half-extents ``box_m`` about the start,
  joined by smooth segments flown at a speed drawn in ``speed_mps`` (at least
  ``min_segment_s`` each); the velocity at a waypoint is the Catmull-Rom tangent of its
  neighbours, so the motion flows through them.
- ``multisine``: on each axis a sum of ``components`` sines (amplitudes
  ``horizontal_amplitude_m``, ``vertical_amplitude_m``, random phases) whose frequency
  sweeps smoothly up and down across ``frequency_hz`` every ``sweep_s`` (the benchmark's
  chirp-like multisine: 0.1 to 0.5 Hz over a minute).
- ``melon``: great circles of radius ``radius_m`` about a point, laps at a frequency
  that sweeps across ``lap_hz`` every ``sweep_s``, in a plane through a horizontal axis
  that turns about that axis once every ``turn_period_s``: the lobes of a melon.
- ``aggressive``: a mix, waypoints like ``random`` but faster, with a share
  ``hop_share`` of them reached in a rest-to-rest hop at a mean speed in
  ``hop_speed_mps`` (stops and starts), and wider yaw swings.

Every kind also swings its heading about the initial one, A sin(2 pi t / P + phase)
(A in ``yaw_amplitude_rad``, P in ``yaw_period_s``). All start at rest at the
run's start point (x = y = z = 0) at t = 0 with zero velocity and acceleration; the
closed-form kinds and the yaw come in over ``ramp_s`` (a C2 smoothstep), so the
reference is twice continuously differentiable. Before t = 0 (the warm-up) the
reference is hover at the start. Positions are NED (m), yaw rad (unwrapped).

Segments: ``quintic`` (Hermite, from position and velocity to position and velocity,
zero acceleration at both ends) and ``cycloid`` (rest to rest along a line, acceleration
one period of a sine: at most 2 pi D/T^2 with a jerk of at most 4 pi^2 D/T^3, where a
quintic needs 60 D/T^3 for 5.77 D/T^2; a quadrotor's tilt follows the acceleration and
its body rates the jerk, about jerk / g).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
import math

import numpy as np

KINDS = ('square', 'random', 'multisine', 'melon', 'aggressive')
DOWN = np.array([0.0, 0.0, 1.0])
TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class Reference:
    """Reference of every run at one time: arrays (n_runs, 3) NED and (n_runs,)."""

    position: np.ndarray       # m
    velocity: np.ndarray       # m/s
    acceleration: np.ndarray   # m/s^2
    yaw: np.ndarray            # rad
    yaw_rate: np.ndarray       # rad/s


def smoothstep(t: float, duration: float) -> tuple[float, float, float]:
    """Return the C2 smoothstep 6s^5 - 15s^4 + 10s^3 (s = t / duration) and its derivatives."""
    if duration <= 0.0 or t >= duration:
        return 1.0, 0.0, 0.0
    if t <= 0.0:
        return 0.0, 0.0, 0.0
    s = t / duration
    return (s ** 3 * (10.0 - 15.0 * s + 6.0 * s * s),
            30.0 * s * s * (1.0 - s) ** 2 / duration,
            60.0 * s * (1.0 - s) * (1.0 - 2.0 * s) / duration ** 2)


def sweep_phase(t: float, f_lo: float, f_hi: float, period: float
                ) -> tuple[float, float, float]:
    """
    Return the phase (rad) of a sine whose frequency sweeps f_lo -> f_hi -> f_lo, and rates.

    f(t) = f_mid - f_amp cos(pi t / period): f_lo at t = 0, f_hi at ``period``, smooth.
    """
    mid, amp = 0.5 * (f_lo + f_hi), 0.5 * (f_hi - f_lo)
    w = math.pi / period
    phase = TWO_PI * (mid * t - amp * math.sin(w * t) / w)
    return phase, TWO_PI * (mid - amp * math.cos(w * t)), TWO_PI * amp * w * math.sin(w * t)


def _uniform(rng: np.random.Generator, interval: Sequence[float]) -> float:
    return float(rng.uniform(interval[0], interval[1]))


# ---------------------------------------------------------------- segments
@dataclass(frozen=True)
class Segment:
    """A piece of path from t0 for T seconds: quintic Hermite or cycloidal hop."""

    t0: float
    duration: float
    p0: np.ndarray
    p1: np.ndarray
    v0: np.ndarray
    v1: np.ndarray
    shape: str = 'quintic'

    @property
    def end(self) -> float:
        """Return the time the segment ends (s)."""
        return self.t0 + self.duration

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return position, velocity and acceleration at time t (inside the segment)."""
        T = self.duration
        s = min(max((t - self.t0) / T, 0.0), 1.0)
        d = self.p1 - self.p0
        if self.shape == 'cycloid':
            w = TWO_PI * s
            return (self.p0 + d * (s - math.sin(w) / TWO_PI), d * (1.0 - math.cos(w)) / T,
                    d * TWO_PI * math.sin(w) / T ** 2)
        s2, s3 = s * s, s * s * s
        # Quintic Hermite basis with zero end accelerations (position, and its s-rates).
        h01 = s3 * (10.0 - 15.0 * s + 6.0 * s2)
        h10 = s - s3 * (6.0 - 8.0 * s + 3.0 * s2)
        h11 = -s3 * (4.0 - 7.0 * s + 3.0 * s2)
        d01 = 30.0 * s2 * (1.0 - s) ** 2
        d10 = 1.0 - s2 * (18.0 - 32.0 * s + 15.0 * s2)
        d11 = -s2 * (12.0 - 28.0 * s + 15.0 * s2)
        a01 = 60.0 * s * (1.0 - s) * (1.0 - 2.0 * s)
        a10 = -s * (36.0 - 96.0 * s + 60.0 * s2)
        a11 = -s * (24.0 - 84.0 * s + 60.0 * s2)
        tv0, tv1 = T * self.v0, T * self.v1
        return (self.p0 + h01 * d + h10 * tv0 + h11 * tv1,
                (d01 * d + d10 * tv0 + d11 * tv1) / T,
                (a01 * d + a10 * tv0 + a11 * tv1) / T ** 2)


class SegmentPath:
    """A path of segments drawn as time goes on (``_more`` appends the next ones)."""

    def __init__(self, rng: np.random.Generator, cfg: Mapping):
        self.rng, self.cfg = rng, cfg
        self.segments: list[Segment] = []
        self._index = 0

    def _more(self) -> None:
        raise NotImplementedError

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return position, velocity and acceleration (3,) at time t >= 0."""
        while not self.segments or self.segments[-1].end <= t:
            self._more()
        if self.segments[self._index].t0 > t:      # asked for an earlier time
            self._index = 0
        while self.segments[self._index].end <= t:
            self._index += 1
        return self.segments[self._index].at(t)

    def _append(self, duration: float, p1, v1=None, shape: str = 'quintic') -> None:
        last = self.segments[-1] if self.segments else None
        t0, p0, v0 = (last.end, last.p1, last.v1) if last else (0.0, np.zeros(3), np.zeros(3))
        self.segments.append(Segment(t0, duration, p0, np.asarray(p1, float), v0,
                                     np.zeros(3) if v1 is None else np.asarray(v1, float),
                                     shape))

    def describe(self) -> dict:
        """Return what was drawn for the run (for a dataset's manifest)."""
        return {}


class SquarePath(SegmentPath):
    """Corners of a square, rest to rest, with a climb or descent after each lap."""

    def __init__(self, rng, cfg):
        super().__init__(rng, cfg)
        self.side = _uniform(rng, cfg['side_m'])
        self.bearing = float(rng.uniform(0.0, TWO_PI))
        self.sense = 1.0 if rng.random() < 0.5 else -1.0
        self.climb = -1.0        # the first change of layer goes up (NED z < 0)
        a = np.array([math.cos(self.bearing), math.sin(self.bearing), 0.0])
        b = self.sense * np.array([-a[1], a[0], 0.0])
        self.corners = [np.zeros(3), self.side * a, self.side * (a + b), self.side * b]
        self._corner, self._height = 0, 0.0

    def _hop(self, target) -> None:
        self._append(_uniform(self.rng, self.cfg['move_s']), target, shape='cycloid')
        self._append(_uniform(self.rng, self.cfg['hold_s']), target)

    def _more(self) -> None:
        self._corner = (self._corner + 1) % 4
        if self._corner == 0:
            here = self.corners[0] + self._height * DOWN
            self._hop(here)
            self._height += self.climb * _uniform(self.rng, self.cfg['climb_m'])
            self.climb = -self.climb
        self._hop(self.corners[self._corner] + self._height * DOWN)

    def describe(self):
        """Return what was drawn for the run."""
        return {'side_m': self.side, 'bearing_rad': self.bearing, 'sense': self.sense}


class WaypointPath(SegmentPath):
    """Random waypoints in a box, flown through with Catmull-Rom velocities (and hops)."""

    def __init__(self, rng, cfg, hops: bool = False):
        super().__init__(rng, cfg)
        self.box = np.asarray(cfg['box_m'], float)
        self.hops = hops
        self._points = [np.zeros(3), self._point()]
        self._durations = [self._duration(self._points[0], self._points[1])]
        self._stops = [True, self._stop()]       # the start is at rest

    def _point(self) -> np.ndarray:
        return self.rng.uniform(-self.box, self.box)

    def _stop(self) -> bool:
        return bool(self.hops and self.rng.random() < self.cfg['hop_share'])

    def _duration(self, a, b) -> float:
        speed = _uniform(self.rng, self.cfg['speed_mps'])
        return max(self.cfg['min_segment_s'], float(np.linalg.norm(b - a)) / speed)

    def _more(self) -> None:
        # Draw one waypoint ahead: the velocity at the next one is its neighbours' chord,
        # or zero where it is a stop (a hop: rest to rest where it starts at rest too).
        self._points.append(self._point())
        self._durations.append(self._duration(self._points[-2], self._points[-1]))
        self._stops.append(self._stop())
        prev, here, ahead = self._points[-3:]
        t_in, t_out = self._durations[-2:]
        if self._stops[-2]:
            distance = float(np.linalg.norm(here - prev))
            duration = max(self.cfg['min_segment_s'],
                           distance / _uniform(self.rng, self.cfg['hop_speed_mps']))
            at_rest = not self.segments or not self.segments[-1].v1.any()
            self._append(duration, here, shape='cycloid' if at_rest else 'quintic')
        else:
            self._append(t_in, here, (ahead - prev) / (t_in + t_out))

    def describe(self):
        """Return what was drawn for the run."""
        return {'box_m': self.box.tolist()}


class ClosedForm:
    """A path given by a formula s(t), flown as e(t) (s(t) - s(0)) (ramp e over ramp_s)."""

    def __init__(self, ramp_s: float):
        self.ramp_s = ramp_s
        self._origin = self.shape(0.0)[0]

    def shape(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the formula's position, velocity and acceleration (3,) at time t."""
        raise NotImplementedError

    def describe(self) -> dict:
        """Return what was drawn for the run (for a dataset's manifest)."""
        return {}

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return position, velocity and acceleration (3,) at time t >= 0."""
        e, de, dde = smoothstep(t, self.ramp_s)
        s, ds, dds = self.shape(t)
        s = s - self._origin
        return e * s, de * s + e * ds, dde * s + 2.0 * de * ds + e * dds


class MultisinePath(ClosedForm):
    """On each axis a sum of sines whose frequencies sweep the band, each at its own pace."""

    def __init__(self, rng, cfg, ramp_s):
        n = int(cfg['components'])
        amplitude = np.array([_uniform(rng, cfg['horizontal_amplitude_m']),
                              _uniform(rng, cfg['horizontal_amplitude_m']),
                              _uniform(rng, cfg['vertical_amplitude_m'])])
        weights = rng.uniform(0.5, 1.0, (3, n))
        self.amplitude = amplitude[:, None] * weights / weights.sum(axis=1, keepdims=True)
        self.phase = rng.uniform(0.0, TWO_PI, (3, n))
        self.band = tuple(cfg['frequency_hz'])
        self.periods = [_uniform(rng, cfg['sweep_s']) for _ in range(n)]
        super().__init__(ramp_s)

    def shape(self, t):
        """Return the formula's position, velocity and acceleration (3,) at time t."""
        pos, vel, acc = np.zeros(3), np.zeros(3), np.zeros(3)
        for j, period in enumerate(self.periods):
            phi, dphi, ddphi = sweep_phase(t, *self.band, period)
            arg = phi + self.phase[:, j]
            a, sin, cos = self.amplitude[:, j], np.sin(arg), np.cos(arg)
            pos += a * sin
            vel += a * cos * dphi
            acc += a * (cos * ddphi - sin * dphi * dphi)
        return pos, vel, acc

    def describe(self):
        """Return what was drawn for the run."""
        return {'amplitude_m': self.amplitude.sum(axis=1).tolist(), 'sweep_s': self.periods}


class MelonPath(ClosedForm):
    """Great circles whose plane turns about a horizontal axis: the lobes of a melon."""

    def __init__(self, rng, cfg, ramp_s):
        self.radius = _uniform(rng, cfg['radius_m'])
        self.band = tuple(cfg['lap_hz'])
        self.period = _uniform(rng, cfg['sweep_s'])
        self.turn = TWO_PI / _uniform(rng, cfg['turn_period_s']) * (
            1.0 if rng.random() < 0.5 else -1.0)
        self.bearing = float(rng.uniform(0.0, TWO_PI))
        self.tilt0 = float(rng.uniform(0.0, math.pi))
        a = np.array([math.cos(self.bearing), math.sin(self.bearing), 0.0])
        self.axes = (a, np.array([-a[1], a[0], 0.0]), -DOWN)   # axis, across, up
        super().__init__(ramp_s)

    def shape(self, t):
        """Return the formula's position, velocity and acceleration (3,) at time t."""
        th, dth, ddth = sweep_phase(t, *self.band, self.period)
        al, dal = self.tilt0 + self.turn * t, self.turn
        c, s, ca, sa = math.cos(th), math.sin(th), math.cos(al), math.sin(al)
        R = self.radius
        a, b, up = self.axes
        pos = R * (c * a + s * ca * b + s * sa * up)
        vel = R * (-s * dth * a + (c * dth * ca - s * sa * dal) * b
                   + (c * dth * sa + s * ca * dal) * up)
        acc = R * ((-c * dth ** 2 - s * ddth) * a
                   + (-s * dth ** 2 * ca + c * ddth * ca - 2 * c * dth * sa * dal
                      - s * ca * dal ** 2) * b
                   + (-s * dth ** 2 * sa + c * ddth * sa + 2 * c * dth * ca * dal
                      - s * sa * dal ** 2) * up)
        return pos, vel, acc

    def describe(self):
        """Return what was drawn for the run."""
        return {'radius_m': self.radius, 'sweep_s': self.period,
                'turn_rad_s': self.turn, 'bearing_rad': self.bearing}


def draw_path(kind: str, rng: np.random.Generator, cfg) -> SegmentPath | ClosedForm:
    """Return the path of one run of ``kind`` (settings ``cfg``: config.FlightConfig)."""
    settings = getattr(cfg, kind)
    if kind == 'square':
        return SquarePath(rng, settings)
    if kind in ('random', 'aggressive'):
        return WaypointPath(rng, settings, hops=kind == 'aggressive')
    if kind == 'multisine':
        return MultisinePath(rng, settings, cfg.ramp_s)
    if kind == 'melon':
        return MelonPath(rng, settings, cfg.ramp_s)
    raise ValueError(f'unknown trajectory kind {kind!r}; known: {", ".join(KINDS)}')


class YawSwing:
    """Heading reference psi0 + e(t) A sin(2 pi t / P + phase) (e: the ramp)."""

    def __init__(self, rng, settings: Mapping, psi0: float, ramp_s: float):
        self.psi0, self.ramp_s = psi0, ramp_s
        self.amplitude = _uniform(rng, settings['yaw_amplitude_rad'])
        self.omega = TWO_PI / _uniform(rng, settings['yaw_period_s'])
        self.phase = float(rng.uniform(0.0, TWO_PI))

    def at(self, t: float) -> tuple[float, float]:
        """Return the heading (rad) and its rate (rad/s) at time t >= 0."""
        e, de, _ = smoothstep(t, self.ramp_s)
        arg = self.omega * t + self.phase
        return (self.psi0 + e * self.amplitude * math.sin(arg),
                self.amplitude * (de * math.sin(arg) + e * self.omega * math.cos(arg)))


class Trajectories:
    """
    The reference of every run of a batch (module docstring).

    ``run_indices`` are the runs' numbers in the data set: run i flies the kind
    ``cfg.kinds[i % len(cfg.kinds)]`` (the scenario's cycle of kinds, so any that many
    consecutive runs hold its shares exactly); ``psi0`` are their initial headings.
    Drawing happens here and, for the waypoint kinds, as time goes on, always from the
    run's own stream.
    """

    def __init__(self, rngs: Sequence[np.random.Generator], cfg, run_indices: Sequence[int],
                 psi0: np.ndarray):
        cycle = cfg.kinds
        self.enabled = cfg.enabled
        self.kinds = tuple(cycle[i % len(cycle)] for i in run_indices)
        self.yaw = [YawSwing(rng, getattr(cfg, kind), float(p), cfg.ramp_s)
                    for rng, kind, p in zip(rngs, self.kinds, psi0, strict=True)]
        self.paths = [draw_path(kind, rng, cfg)
                      for rng, kind in zip(rngs, self.kinds, strict=True)]
        self.psi0 = np.asarray(psi0, float).copy()

    def at(self, t: float) -> Reference:
        """Return the reference of every run at time t (s; hover at the start before 0)."""
        n = len(self.paths)
        if t <= 0.0 or not self.enabled:
            zero = np.zeros((n, 3))
            return Reference(zero, zero.copy(), zero.copy(), self.psi0.copy(), np.zeros(n))
        rows = np.array([path.at(t) for path in self.paths])        # (n, 3, 3)
        yaw = np.array([swing.at(t) for swing in self.yaw])         # (n, 2)
        return Reference(rows[:, 0], rows[:, 1], rows[:, 2], yaw[:, 0], yaw[:, 1])

    def describe(self, k: int) -> dict:
        """Return what run k flies (kind and drawn settings) for a dataset's manifest."""
        swing = self.yaw[k]
        return {'kind': self.kinds[k], **self.paths[k].describe(),
                'yaw_amplitude_rad': swing.amplitude,
                'yaw_period_s': TWO_PI / swing.omega}
