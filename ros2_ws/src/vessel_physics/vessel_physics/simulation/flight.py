"""
A multirotor's operator: a geometric tracking controller flying reference trajectories.

The ships have an open-loop operator (``simulation.operator``); a multirotor cannot fly
open loop, so its operator closes the loop on the TRUE state (the simulator's, before
sensor noise: a flight does not change when the noise settings do). Once per output
period it reads the state and the run's reference (``simulation.trajectories``) and
commands the rotor speeds, which reach the rotors through their motor lag (the family's
``actuator_dynamics``). The controller is Lee, Leok & McClamroch (2010) as Mellinger &
Kumar (2011) and rotorpy's ``SE3Control`` write it, in NED/FRD:

1. position and velocity errors -> the force the rotors must give (NED), with the
   reference's acceleration fed forward and gravity cancelled:
   F = m (a_ref - K_p e_p - K_v e_v - g e_down), its tilt from the vertical limited to
   ``max_tilt_rad`` and its upward part to at least ``min_thrust_share`` of the weight;
2. the attitude that points the thrust (-b3, body z is down) along F with the reference
   heading: b3 = -F/|F|, b2 = b3 x (cos psi, sin psi, 0) normalised, b1 = b2 x b3;
   the collective thrust T = F . (-b3) of the body's present axis;
3. body moments from the attitude error e_R = vee(R_d^T R - R^T R_d) / 2 and the rate
   error e_w = w - (0, 0, psi_ref'): M = I (-K_R e_R - K_w e_w) + w x I w;
4. rotor speeds through the inverse of the allocation [T, K, M, N] = A f, computed from
   the parameter file's rotors: thrust f_i = k_eta n_i^2 along -z at (x_i, y_i) gives
   K = -y_i f_i, M = x_i f_i, and N = s_i (k_m / k_eta) f_i by its spin (s = +1 ccw);
   n_i = sqrt(max(f_i, 0) / k_eta), clipped to the rotor's range.

Gains (per axis: north, east, down; roll, pitch, yaw) are the scenario's ``flight``
section (``config.FlightConfig``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from vessel_physics.errors import ConfigError
from vessel_physics.multirotor.params import SPIN_SIGN, MultirotorParams
from vessel_physics.simulation.trajectories import Reference, Trajectories


def rotation_body_to_ned(phi, theta, psi) -> np.ndarray:
    """Return R (n, 3, 3) with R @ v_body = v_ned (Euler ZYX; integrator.body_to_ned)."""
    cf, sf, ct, st = np.cos(phi), np.sin(phi), np.cos(theta), np.sin(theta)
    cp, sp = np.cos(psi), np.sin(psi)
    return np.stack([
        np.stack([cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf], axis=-1),
        np.stack([sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf], axis=-1),
        np.stack([-st, ct * sf, ct * cf], axis=-1)], axis=-2)


def allocation_matrix(params: MultirotorParams) -> np.ndarray:
    """Return A (4, n_rotors): [T, K, M, N] = A f for rotor thrusts f (N), FRD."""
    ratio = params.k_m / params.k_eta
    return np.array([[1.0] * len(params.rotors),
                     [-r.y for r in params.rotors],
                     [r.x for r in params.rotors],
                     [SPIN_SIGN[r.spin] * ratio for r in params.rotors]])


def _normalise(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


class FlightController:
    """
    The operator of a batch of multirotor runs (module docstring).

    ``setpoints(t, state)`` returns one array (n_runs,) of rotor speed set-points (rad/s)
    per vessel actuator, from the true ``state`` (arrays by name: the vessel's states and
    psi, x, y, z) and the reference at t.
    """

    def __init__(self, rngs: Sequence[np.random.Generator], cfg, physics, vessel,
                 run_indices: Sequence[int], psi0: np.ndarray):
        params = physics.params
        if not isinstance(params, MultirotorParams):
            raise ConfigError(f'vessel {vessel.name!r}: the flight controller flies a '
                              f'multirotor; the physics is the {physics.family.title}')
        self.cfg = cfg
        self.params = params
        self.trajectories = Trajectories(rngs, cfg, run_indices, psi0)
        gains = cfg.controller
        self.kp, self.kv = np.array(gains.position_gain), np.array(gains.velocity_gain)
        self.kr, self.kw = np.array(gains.attitude_gain), np.array(gains.rate_gain)
        self.tan_tilt = float(np.tan(gains.max_tilt_rad))
        self.min_lift = gains.min_thrust_share * params.m * params.g
        self.inertia = params.inertia
        self.allocate = np.linalg.pinv(allocation_matrix(params))     # (n_rotors, 4)
        ranges = [vessel.actuator(r.actuator) for r in params.rotors]
        self.low = np.array([a.low for a in ranges])
        self.high = np.array([a.high for a in ranges])
        order = [r.actuator for r in params.rotors]
        self.columns = [order.index(name) for name in vessel.actuator_names]
        self.last: Reference | None = None

    @property
    def kinds(self) -> tuple[str, ...]:
        """Return the trajectory kind of each run."""
        return self.trajectories.kinds

    def thrust_force(self, state: Mapping[str, np.ndarray], ref: Reference) -> np.ndarray:
        """Return the force (n, 3) NED the rotors must give to track ``ref`` (step 1)."""
        p = self.params
        position = np.stack([state['x'], state['y'], state['z']], axis=-1)
        body = np.stack([state['u'], state['v'], state['w']], axis=-1)
        rotation = rotation_body_to_ned(state['phi'], state['theta'], state['psi'])
        velocity = (rotation @ body[..., None])[..., 0]
        acceleration = (ref.acceleration - self.kp * (position - ref.position)
                        - self.kv * (velocity - ref.velocity))
        force = p.m * acceleration
        force[:, 2] -= p.m * p.g
        # Keep the thrust pointing up, and its tilt inside the limit.
        force[:, 2] = np.minimum(force[:, 2], -self.min_lift)
        horizontal = np.hypot(force[:, 0], force[:, 1])
        limit = self.tan_tilt * -force[:, 2]
        scale = np.where(horizontal > limit, limit / np.maximum(horizontal, 1e-12), 1.0)
        force[:, :2] *= scale[:, None]
        return force

    def wrench(self, state: Mapping[str, np.ndarray], ref: Reference) -> np.ndarray:
        """Return the commanded collective thrust and body moments (n, 4): T, K, M, N."""
        force = self.thrust_force(state, ref)
        rotation = rotation_body_to_ned(state['phi'], state['theta'], state['psi'])
        b3 = -_normalise(force)
        heading = np.stack([np.cos(ref.yaw), np.sin(ref.yaw), np.zeros_like(ref.yaw)], -1)
        b2 = _normalise(np.cross(b3, heading))
        b1 = np.cross(b2, b3)
        desired = np.stack([b1, b2, b3], axis=-1)                   # columns b1 b2 b3
        thrust = -np.einsum('ni,ni->n', force, rotation[:, :, 2])
        error = 0.5 * (np.swapaxes(desired, 1, 2) @ rotation
                       - np.swapaxes(rotation, 1, 2) @ desired)
        e_r = np.stack([error[:, 2, 1], error[:, 0, 2], error[:, 1, 0]], axis=-1)
        rates = np.stack([state['p'], state['q'], state['r']], axis=-1)
        e_w = rates.copy()
        e_w[:, 2] -= ref.yaw_rate
        momentum = rates @ self.inertia
        moment = ((-self.kr * e_r - self.kw * e_w) @ self.inertia
                  + np.cross(rates, momentum))
        return np.column_stack([thrust, moment])

    def rotor_speeds(self, wrench: np.ndarray) -> np.ndarray:
        """Return the rotor speeds (n, n_rotors) that give ``wrench`` (T, K, M, N)."""
        thrusts = wrench @ self.allocate.T
        speeds = np.sqrt(np.maximum(thrusts, 0.0) / self.params.k_eta)
        return np.clip(speeds, self.low, self.high)

    def setpoints(self, t: float, state: Mapping[str, np.ndarray]) -> tuple[np.ndarray, ...]:
        """Give the rotor speed set-points at time t (s) for the true ``state``."""
        ref = self.trajectories.at(t)
        self.last = ref
        speeds = self.rotor_speeds(self.wrench(state, ref))
        return tuple(speeds[:, j].copy() for j in self.columns)
