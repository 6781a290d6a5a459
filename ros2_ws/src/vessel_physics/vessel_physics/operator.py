"""
Open-loop "human operator": shaft-speed and rudder set-points like routine operation.

Each run has its own random stream, so a run's set-points do not depend on which batch it
is simulated in. Orders are held for a random time and then replaced (Baier et al.:
control inputs "mimic a human operator" in routine operation):

- shaft speed: a new order drawn uniformly in ``shaft_speed_rpm`` (paper: 366-980 rpm),
  held ``shaft_hold_s`` (minutes);
- rudder: mostly small routine corrections, uniform in +-``rudder_routine_rad`` (paper:
  about +-0.05 rad) held ``rudder_hold_s`` (tens of seconds); with probability
  ``turn_probability`` a deliberate turn of ``rudder_turn_rad`` to either side held
  ``turn_hold_s``. Both rudders get the same order plus a small normal difference.

Orders change only at output instants (the operator acts at the output rate); the
servo and shaft dynamics in ``actuators`` smooth the steps.
"""

from __future__ import annotations

import math

import numpy as np

RPM = 2 * math.pi / 60.0  # rad/s per rpm
EVENT_TOLERANCE = 1e-9    # s, so that an order due at t is given at t despite rounding


class Operator:
    """Set-points for a batch of runs (arrays of shape (n_runs,), rad/s and rad)."""

    def __init__(self, rngs: list[np.random.Generator], cfg, t0: float = 0.0):
        self.cfg = cfg
        self._rngs = rngs
        n_runs = len(rngs)
        self.shaft = np.empty(n_runs)
        self.rudder_port = np.empty(n_runs)
        self.rudder_stbd = np.empty(n_runs)
        self._next_shaft = np.empty(n_runs)
        self._next_rudder = np.empty(n_runs)
        for k in range(n_runs):
            self._order_shaft(k, t0)
            self._order_rudder(k, t0, allow_turn=False)

    def _order_shaft(self, k: int, t: float) -> None:
        rng, cfg = self._rngs[k], self.cfg
        self.shaft[k] = rng.uniform(*cfg.shaft_speed_rpm) * RPM
        self._next_shaft[k] = t + rng.uniform(*cfg.shaft_hold_s)

    def _order_rudder(self, k: int, t: float, allow_turn: bool = True) -> None:
        rng, cfg = self._rngs[k], self.cfg
        turn = rng.random() < cfg.turn_probability
        if turn and allow_turn:
            angle = rng.uniform(*cfg.rudder_turn_rad) * (1.0 if rng.random() < 0.5 else -1.0)
            hold = rng.uniform(*cfg.turn_hold_s)
        else:
            angle = rng.uniform(-cfg.rudder_routine_rad, cfg.rudder_routine_rad)
            hold = rng.uniform(*cfg.rudder_hold_s)
        difference = cfg.rudder_difference_rad * rng.standard_normal()
        self.rudder_port[k] = angle + 0.5 * difference
        self.rudder_stbd[k] = angle - 0.5 * difference
        self._next_rudder[k] = t + hold

    def setpoints(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Give the orders due by time t (s); return (n, delta_port, delta_stbd) copies."""
        if self.cfg.enabled:
            for k in np.flatnonzero(self._next_shaft <= t + EVENT_TOLERANCE):
                self._order_shaft(int(k), t)
            for k in np.flatnonzero(self._next_rudder <= t + EVENT_TOLERANCE):
                self._order_rudder(int(k), t)
        return self.shaft.copy(), self.rudder_port.copy(), self.rudder_stbd.copy()
