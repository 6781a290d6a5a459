"""
Optional ocean current: a steady NED velocity per run with a slow sinusoidal variation.

The current is horizontal and uniform; its speed varies slowly in time,
V_c(t) = V_c0 (1 + a sin(Omega t + zeta)), with a constant direction beta_c (the direction
it flows *to*, from north towards east). It enters physically in two places:

- hydrodynamics: hull, propeller and rigid-body terms see the velocity relative to the
  water. For a current that is constant in NED, M_RB nu' + C_RB(nu) nu equals
  M_RB nu_r' + C_RB(nu_r) nu_r (Fossen 2011, Property 10.1), so the simulator integrates
  nu_r directly; the slow variation's own inertia force is neglected;
- kinematics: position rate = R(psi) nu_r + V_c (NED).

The body-frame components (u_c, v_c) = V_c (cos(beta_c - psi), sin(beta_c - psi)) are in
the levelled frame (roll neglected for the current, < 0.2 % at 3 degrees of roll); measured
body velocities over ground are nu_r + (u_c, v_c).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from vessel_physics.frames import ned_to_body


@dataclass(frozen=True)
class CurrentDraw:
    """One run's current: speed (m/s), direction it flows to (rad, NED), variation."""

    speed: float
    direction: float
    variation: float       # relative amplitude a
    omega: float           # rad/s
    phase: float           # rad


def draw_current(rng: np.random.Generator, cfg) -> CurrentDraw:
    """Draw one run's current from ``cfg`` (config.CurrentConfig)."""
    speed = rng.uniform(*cfg.speed_mps)
    direction = rng.uniform(0.0, 2 * math.pi)
    phase = rng.uniform(0.0, 2 * math.pi)
    if not cfg.enabled:
        speed = 0.0
    return CurrentDraw(speed, direction, cfg.variation, 2 * math.pi / cfg.variation_period_s,
                       phase)


class CurrentField:
    """Current of a batch of runs (numpy arrays of shape (n_runs,))."""

    def __init__(self, draws: list[CurrentDraw]):
        self.speed0 = np.array([d.speed for d in draws])
        self.direction = np.array([d.direction for d in draws])
        self.variation = np.array([d.variation for d in draws])
        self.omega = np.array([d.omega for d in draws])
        self.phase = np.array([d.phase for d in draws])
        self.active = bool(np.any(self.speed0 > 0))

    def speed(self, t: float) -> np.ndarray:
        """Return the speed of the current (m/s) at time t (s)."""
        return self.speed0 * (1.0 + self.variation * np.sin(self.omega * t + self.phase))

    def ned(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Return the current velocity (north, east) in m/s."""
        s = self.speed(t)
        return s * np.cos(self.direction), s * np.sin(self.direction)

    def body(self, t: float, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Return the current in the levelled body frame (u_c, v_c) in m/s at heading psi."""
        return ned_to_body(*self.ned(t), psi)
