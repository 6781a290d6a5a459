"""
Open-loop "human operator": shaft-speed and steering set-points like routine operation.

Each run has its own random stream, so a run's set-points do not depend on which batch it
is simulated in. Orders are held for a random time and then replaced (Baier et al.:
control inputs "mimic a human operator" in routine operation):

- shaft speed: a new order drawn uniformly in ``shaft_speed_rpm`` (paper: 366-980 rpm),
  held ``shaft_hold_s`` (minutes); every propeller gets it;
- steering: mostly small routine corrections, uniform in +-``rudder_routine_rad`` (paper:
  about +-0.05 rad) held ``rudder_hold_s`` (tens of seconds); with probability
  ``turn_probability`` a deliberate turn of ``rudder_turn_rad`` to either side held
  ``turn_hold_s``, plus a small normal difference between two steering actuators.

How the orders reach a vessel's actuators follows their kinds: rudders and azimuths get
the steering order (two of them: plus and minus half the difference); a craft without
them is steered by differential thrust, its first propeller at shaft (1 + g s) and its
second at shaft (1 - g s), s the steering order (rad of a virtual helm) and g
``differential_per_rad``.

``mode: zigzag`` is the IMO zig-zag instead: each run holds one shaft speed, goes
straight during the warm-up (t < 0), then puts the steering to +-A (A uniform in
``zigzag_rudder_rad``), reversing it whenever the heading has left the course of t = 0
by the check angle (A times a share uniform in ``zigzag_check_share``) on the side it
is turning to.

Orders change only at output instants (the operator acts at the output rate); the
servo dynamics of ``actuators`` smooth the steps.
"""

from __future__ import annotations

import math

import numpy as np

from vessel_physics.errors import ConfigError

RPM = 2 * math.pi / 60.0  # rad/s per rpm
EVENT_TOLERANCE = 1e-9    # s, so that an order due at t is given at t despite rounding
STEERING_KINDS = ('rudder', 'azimuth')


class Operator:
    """Set-points for a batch of runs: one array (n_runs,) per vessel actuator."""

    def __init__(self, rngs: list[np.random.Generator], cfg, vessel, t0: float = 0.0):
        self.cfg = cfg
        self._rngs = rngs
        kinds = [a.kind for a in vessel.actuators]
        other = [a.name for a in vessel.actuators
                 if a.kind not in STEERING_KINDS + ('propeller',)]
        self.propellers = [i for i, k in enumerate(kinds) if k == 'propeller']
        self.steering = [i for i, k in enumerate(kinds) if k in STEERING_KINDS]
        if other or not self.propellers or (not self.steering and len(self.propellers) < 2):
            actuators = dict(zip(vessel.actuator_names, kinds, strict=True))
            raise ConfigError(f'vessel {vessel.name!r}: the simulated operator drives '
                              f'propellers with rudders or azimuths, or two propellers by '
                              f'differential thrust; actuators {actuators}')
        n_runs = len(rngs)
        self.n_actuators = len(kinds)
        self.shaft = np.empty(n_runs)
        self.angle = np.empty(n_runs)
        self.difference = np.empty(n_runs)
        self._next_shaft = np.empty(n_runs)
        self._next_rudder = np.empty(n_runs)
        self.zigzag = cfg.mode == 'zigzag'
        if self.zigzag:
            self._check = np.empty(n_runs)
            self._course = np.full(n_runs, np.nan)
            self._side = np.zeros(n_runs)
        for k in range(n_runs):
            self._order_shaft(k, t0)
            if self.zigzag:
                self._order_zigzag(k)
            else:
                self._order_rudder(k, t0, allow_turn=False)

    def _order_shaft(self, k: int, t: float) -> None:
        rng, cfg = self._rngs[k], self.cfg
        self.shaft[k] = rng.uniform(*cfg.shaft_speed_rpm) * RPM
        self._next_shaft[k] = math.inf if self.zigzag else t + rng.uniform(*cfg.shaft_hold_s)

    def _order_rudder(self, k: int, t: float, allow_turn: bool = True) -> None:
        rng, cfg = self._rngs[k], self.cfg
        turn = rng.random() < cfg.turn_probability
        if turn and allow_turn:
            angle = rng.uniform(*cfg.rudder_turn_rad) * (1.0 if rng.random() < 0.5 else -1.0)
            hold = rng.uniform(*cfg.turn_hold_s)
        else:
            angle = rng.uniform(-cfg.rudder_routine_rad, cfg.rudder_routine_rad)
            hold = rng.uniform(*cfg.rudder_hold_s)
        self.difference[k] = cfg.rudder_difference_rad * rng.standard_normal()
        self.angle[k] = angle
        self._next_rudder[k] = t + hold

    def _order_zigzag(self, k: int) -> None:
        rng, cfg = self._rngs[k], self.cfg
        self.angle[k] = rng.uniform(*cfg.zigzag_rudder_rad)
        self._check[k] = self.angle[k] * rng.uniform(*cfg.zigzag_check_share)
        self.difference[k] = 0.0
        self._next_rudder[k] = math.inf

    def _reverse(self, psi: np.ndarray) -> None:
        """Zig-zag: reverse where the heading passed the check angle on the new side."""
        start = np.isnan(self._course)
        self._course[start] = psi[start]
        deviation = psi - self._course
        passed = (np.abs(deviation) > self._check) & (np.sign(deviation) != self._side)
        self.angle[passed] = -self.angle[passed]
        self._side[passed] = np.sign(deviation[passed])

    def setpoints(self, t: float, psi: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Give the orders due by time t (s), at headings ``psi`` (rad); one copy per actuator."""
        if self.cfg.enabled:
            for k in np.flatnonzero(self._next_shaft <= t + EVENT_TOLERANCE):
                self._order_shaft(int(k), t)
            for k in np.flatnonzero(self._next_rudder <= t + EVENT_TOLERANCE):
                self._order_rudder(int(k), t)
            if self.zigzag and psi is not None:
                self._reverse(np.asarray(psi, float))
        out = [None] * self.n_actuators
        angle = self.angle if not (self.zigzag and t < 0) else 0.0 * self.angle
        if self.steering:
            for i in self.propellers:
                out[i] = self.shaft.copy()
            half = 0.5 * self.difference
            signs = [1.0, -1.0] if len(self.steering) == 2 else [0.0] * len(self.steering)
            for i, sign in zip(self.steering, signs, strict=True):
                out[i] = angle + half if sign > 0 else (
                    angle - half if sign < 0 else angle.copy())
        else:
            share = self.cfg.differential_per_rad * angle
            for j, i in enumerate(self.propellers):
                sign = (1.0, -1.0)[j] if j < 2 else 0.0
                out[i] = self.shaft * (1.0 + sign * share)
        return tuple(out)
