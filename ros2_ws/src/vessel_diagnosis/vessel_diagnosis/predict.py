"""
Batch predictions of a physics of any family (numpy): one step, and multistep.

The model integrates the family's equation of motion in the vessel's vectors
(``Physics.derivative``: M nu_r' = physics.force(nu_r, c, nu_ground) and its kinematic
states, e.g. phi' = p) and psi' = r cos phi (Fossen 2011; the simulator's kinematics;
cos phi = 1 without roll; a 6-DOF vehicle's psi' = (q sin phi + r cos phi) / cos theta,
``integrator.attitude_rates``) with classical RK4 sub-steps over each sample period. States
and outputs are body velocities OVER GROUND, as measured; with a current (north, east
in m/s, constant over a prediction) the model integrates the velocity through the water
nu_r = nu_ground - (u_c, v_c), where (u_c, v_c) = V_c rotated into the levelled body
frame at the heading psi (Fossen 2011, Property 10.1: for a current constant in NED the
rigid-body and hydrodynamic terms can be written in nu_r).

Controls between samples are interpolated linearly (first-order hold) from c_k to
c_{k+1}: the actuators move during a period (rudder servo 0.2 s, shaft 1 s), and a
zero-order hold would leave a systematic error at every order change that the diagnosis
would then try to explain.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from vessel_physics.family import Physics
from vessel_physics.frames import ned_to_body
from vessel_physics.integrator import attitude_rates, rk4_step


def body_current(current: np.ndarray | None, psi: np.ndarray):
    """Return (u_c, v_c) of a NED current (..., 2) at heading psi (rad); zeros if None."""
    if current is None:
        return 0.0, 0.0
    return ned_to_body(current[..., 0], current[..., 1], psi)


@dataclass(frozen=True)
class Variant:
    """
    A change of the physics for one block of a batched prediction (see simulate_variants).

    ``extra_force(z_water, c, z_ground) -> (n, n_dof)`` is added to the physics' force,
    ``minv_t`` replaces its (M^-1)^T, ``current_shift`` (north, east, m/s) is added to
    the rows' current.
    """

    extra_force: Callable | None = None
    minv_t: np.ndarray | None = None
    current_shift: tuple[float, float] | None = None


class Predictor:
    """Predictions of one physics; ``substeps`` RK4 steps per sample period ``dt`` (s)."""

    def __init__(self, physics: Physics, dt: float = 1.0, substeps: int = 4):
        if substeps < 1 or not dt > 0:
            raise ValueError(f'need dt > 0 and substeps >= 1, got {dt}, {substeps}')
        self.physics = physics
        self.dt = float(dt)
        self.substeps = int(substeps)
        self._blocks: list[tuple[slice, Variant]] = []
        states = physics.family.states
        self.n_state, self.n_dof = len(states), len(physics.family.dofs)
        self.u, self.v, self.r = (states.index(s) for s in ('u', 'v', 'r'))
        self.phi = states.index('phi') if 'phi' in states else None
        # A 6-DOF vehicle's heading follows its pitch and roll rates too.
        self.spatial = (tuple(states.index(s) for s in ('p', 'q', 'theta'))
                        if 'theta' in states else None)
        self.psi = self.n_state     # x = [z (over ground or through the water), psi]

    def derivative(self, x: np.ndarray, c: np.ndarray, current: np.ndarray | None):
        """Return x' for x = [z_water, psi] (n, n_state + 1) under controls c (n, n_control)."""
        z_water = x[:, :self.n_state]
        z_ground = z_water
        if current is not None:
            u_c, v_c = body_current(current, x[:, self.psi])
            z_ground = z_water.copy()
            z_ground[:, self.u] += u_c
            z_ground[:, self.v] += v_c
        tau = self.physics.force(z_water, c, z_ground)
        for rows, variant in self._blocks:
            if variant.extra_force is not None:
                tau[rows] += variant.extra_force(z_water[rows], c[rows], z_ground[rows])
        dx = np.empty_like(x)
        dx[:, :self.n_state] = self.physics.rates(tau, z_water)
        for rows, variant in self._blocks:
            if variant.minv_t is not None:   # a candidate that changes the mass matrix
                dx[rows, :self.n_dof] = tau[rows] @ variant.minv_t
        if self.spatial is not None:
            p, q, theta = self.spatial
            dx[:, self.psi] = attitude_rates(x[:, p], x[:, q], x[:, self.r], x[:, self.phi],
                                             x[:, theta])[2]
        else:
            roll = np.cos(x[:, self.phi]) if self.phi is not None else 1.0
            dx[:, self.psi] = x[:, self.r] * roll
        return dx

    def _advance(self, x, c0, c1, current):
        """One sample period from x with controls going linearly from c0 to c1."""
        h = self.dt / self.substeps
        slope = (c1 - c0) / self.dt
        for k in range(self.substeps):
            t0 = k * h

            def f(t, s, t0=t0):
                return self.derivative(s, c0 + slope * (t0 + t), current)

            x = rk4_step(f, 0.0, x, h)
        return x

    def _to_water(self, z, psi, current):
        x = np.empty((len(z), self.n_state + 1))
        x[:, :self.n_state] = z
        x[:, self.psi] = psi
        u_c, v_c = body_current(current, psi)
        x[:, self.u] -= u_c
        x[:, self.v] -= v_c
        return x

    def _to_ground(self, x, current):
        z = x[:, :self.n_state].copy()
        u_c, v_c = body_current(current, x[:, self.psi])
        z[:, self.u] += u_c
        z[:, self.v] += v_c
        return z

    def one_step(self, z: np.ndarray, psi: np.ndarray, c0: np.ndarray, c1: np.ndarray,
                 current: np.ndarray | None = None) -> np.ndarray:
        """
        Predict z one period ahead for every row (n, n_state).

        ``z`` (n, n_state) measured states over ground, ``psi`` (n,) heading, ``c0``,
        ``c1`` (n, n_control) the controls at the start and end of the period,
        ``current`` (n, 2) NED current per row or None.
        """
        x = self._to_water(np.asarray(z, float), np.asarray(psi, float), current)
        return self._to_ground(self._advance(x, c0, c1, current), current)

    def simulate(self, z0: np.ndarray, psi0: np.ndarray, c: np.ndarray,
                 current: np.ndarray | None = None, hold: bool = False) -> np.ndarray:
        """
        Free-run predictions from measured initial states: (n, H, n_state) for c (n, H + 1, m).

        Row i starts from ``z0[i]``, ``psi0[i]`` at the time of ``c[i, 0]``; step k of the
        output is the state at the time of ``c[i, k + 1]``. ``hold``: each sample's
        controls held over its period (zero-order) instead of the linear course.
        """
        c = np.asarray(c, float)
        horizon = c.shape[1] - 1
        x = self._to_water(np.asarray(z0, float), np.asarray(psi0, float), current)
        out = np.empty((len(x), horizon, self.n_state))
        for k in range(horizon):
            x = self._advance(x, c[:, k], c[:, k] if hold else c[:, k + 1], current)
            out[:, k] = self._to_ground(x, current)
        return out

    def simulate_variants(self, z0: np.ndarray, psi0: np.ndarray, c: np.ndarray,
                          current: np.ndarray | None, variants: Sequence[Variant]
                          ) -> np.ndarray:
        """
        Free runs of the physics and of each variant at once: (1 + V, n, H, n_state).

        Block 0 is the physics itself, block i + 1 variant i; all blocks start from the
        same states. One vectorized integration evaluates the shared force terms once for
        every block, which is what makes a design of 40 candidates affordable.
        """
        n, copies = len(z0), len(variants) + 1
        tiled = [np.concatenate([np.asarray(a, float)] * copies) for a in (z0, psi0, c)]
        base = np.zeros((n, 2)) if current is None else np.asarray(current, float)
        cur = np.concatenate([base] * copies)
        shifted = current is not None
        for i, variant in enumerate(variants):
            if variant.current_shift is not None:
                cur[(i + 1) * n:(i + 2) * n] += np.asarray(variant.current_shift, float)
                shifted = True
        self._blocks = [(slice((i + 1) * n, (i + 2) * n), v) for i, v in enumerate(variants)
                        if v.extra_force is not None or v.minv_t is not None]
        try:
            out = self.simulate(*tiled, cur if shifted else None)
        finally:
            self._blocks = []
        return out.reshape(copies, n, out.shape[1], self.n_state)
