"""
Vectorized batch simulator of any vessel of any family, in wind, waves and current.

``Simulator(config, n_runs, seed, run_offset)`` integrates ``n_runs`` independent runs at
once (numpy arrays shaped (n_runs, ...)) with RK4 at ``config.dt`` and samples them at
``config.output_rate_hz``. Run k draws all its randomness (sea state, wind, current,
initial heading, operator, sensor noise) from ``np.random.SeedSequence([seed,
run_offset + k])``, so a run is the same bit for bit whether it is simulated alone or in a
batch, and the ROS node (n_runs=1) reproduces the batch tool for the same seed.

Model. The state is the vessel file's: its states z through the water (FRD), then its
pose psi (NED, unwrapped), x, y (NED, from the run's first sample) and, for a 6-DOF
vehicle, z (down), then one state per actuator. With the physics of the configuration
(``config.physics``, any family):

    z' = physics.derivative(z_water, c, z_ground, waves + extra_forces hook)

where the wind terms of the family feel the ground velocity and are scaled by
``wind.force_scale``. Kinematics (``integrator.kinematics``) plus the current give x',
y', psi' = r cos phi; a 6-DOF vehicle's position follows R(phi, theta, psi) (u, v, w)
(``integrator.body_to_ned``) and its heading ``integrator.attitude_rates`` (roll and
pitch are states: the family's ``kinematic_rates``). Actuators follow their servos
(``actuators``). Outputs are body velocities over ground, pose, actuators and, where the
vessel measures it, the wind.

Operator. A vessel's orders come from the open-loop ``operator``; a vehicle with rotors
is flown by ``flight.FlightController``, which reads the true state at every output
instant (warm-up included) and tracks the run's reference trajectory.

Initial condition. Each run starts at a random heading in the steady state of its
operator's first orders (a Newton solve of the force balance under the wind at the start,
``Family.steady``), then runs ``warmup_s`` of simulated time with those orders held so
that wave, gust and roll transients have died out; the first sample (t = 0, x = y = 0)
follows. A family without a steady state (``steady`` None: the multirotor) starts at
rest, level, at hover with its actuators at the operator's first orders (the flight
controller's: hover), and warms up under its operator.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from vessel_physics.family import ExtraTerm
from vessel_physics.integrator import attitude_rates, body_to_ned, kinematics, rk4_step
from vessel_physics.simulation.actuators import servo_rate
from vessel_physics.simulation.config import SimConfig, load_hook
from vessel_physics.simulation.current import CurrentField, draw_current
from vessel_physics.simulation.flight import FlightController
from vessel_physics.simulation.noise import SensorNoise
from vessel_physics.simulation.operator import Operator
from vessel_physics.simulation.waves import WaveField, draw_waves
from vessel_physics.simulation.wind import WindField, draw_wind

POSE = ('psi', 'x', 'y')      # a vessel's; a 6-DOF vehicle adds z (Vessel.pose_names)
# Random streams spawned from SeedSequence([seed, run]): their order is part of the
# reproducibility contract; add new ones at the end.
STREAMS = ('wind', 'waves', 'current', 'initial', 'operator', 'noise')
NEWTON_ITERATIONS = 30
BISECTION_ITERATIONS = 60


def _wrap(angle):
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2 * np.pi)


def onset_weight(t: float, from_s: float | None, ramp_s: float) -> float:
    """
    Return the share (0..1) of the extra_forces hook at simulation time t (s).

    1 throughout when ``from_s`` is None; otherwise a smoothstep from 0 at ``from_s`` to 1
    ``ramp_s`` later: continuous with its slope, as RK4 wants of a force.
    """
    if from_s is None:
        return 1.0
    s = min(max((t - from_s) / ramp_s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


class Simulator:
    """Batch simulator; see the module docstring. All arrays are float64, SI units."""

    def __init__(self, config: SimConfig, n_runs: int = 1, seed: int = 0,
                 run_offset: int = 0):
        if int(n_runs) < 1:
            raise ValueError(f'n_runs must be >= 1, got {n_runs!r}')
        if int(run_offset) < 0 or int(seed) < 0:
            raise ValueError(f'seed and run_offset must be >= 0, got {seed!r}, {run_offset!r}')
        self.config = config
        self.vessel = config.vessel
        self.n_runs = int(n_runs)
        self.seed = int(seed)
        self.run_offset = int(run_offset)
        self._hook = load_hook(config.extra_forces) if config.extra_forces else None
        vessel = self.vessel
        self.states = tuple(vessel.state_names)
        self.actuators = tuple(vessel.actuator_names)
        self.spatial = vessel.is_spatial
        self.pose = tuple(vessel.pose_names)
        self.state_names = self.states + self.pose + self.actuators
        self.true_keys = self.states + self.pose
        self.flies = config.flight is not None
        self.has_wind = 'wind' in vessel.environment
        wind = ('wind_speed', 'wind_dir_cos', 'wind_dir_sin') if self.has_wind else ()
        self.measured_keys = ('t',) + self.true_keys + self.actuators + wind
        self.sample_keys = self.measured_keys + tuple(k + '_true' for k in self.true_keys)
        n = len(self.states)
        self._u, self._v, self._r = (self.states.index(s) for s in ('u', 'v', 'r'))
        self._phi = self.states.index('phi') if 'phi' in self.states else None
        self._psi, self._xpos, self._y = n, n + 1, n + 2
        if self.spatial:
            self._w, self._p, self._q, self._theta = (self.states.index(s)
                                                      for s in ('w', 'p', 'q', 'theta'))
            self._zpos = n + 3
        self._act = slice(n + len(self.pose), n + len(self.pose) + len(self.actuators))
        self._servos = [config.actuators[a] for a in self.actuators]
        self.reset()

    # ------------------------------------------------------------------ set-up
    def reset(self, seed: int | None = None) -> None:
        """Start every run again (with a new seed if given): new environment, t = 0."""
        if seed is not None:
            if int(seed) < 0:
                raise ValueError(f'seed must be >= 0, got {seed!r}')
            self.seed = int(seed)
        cfg = self.config
        physics = cfg.physics
        streams = [np.random.SeedSequence([self.seed, self.run_offset + k]).spawn(len(STREAMS))
                   for k in range(self.n_runs)]
        rngs = {name: [np.random.default_rng(s[i]) for s in streams]
                for i, name in enumerate(STREAMS)}
        self.wind = WindField([draw_wind(g, cfg.wind) for g in rngs['wind']])
        hull = physics.family.wave_hull(physics.params) if cfg.waves.enabled else None
        self.waves = WaveField([draw_waves(g, cfg.waves) for g in rngs['waves']], hull,
                               cfg.waves)
        self.current = CurrentField([draw_current(g, cfg.current) for g in rngs['current']])
        psi0 = np.array([g.uniform(0.0, 2 * np.pi) for g in rngs['initial']])
        if self.flies:
            self.operator = FlightController(
                rngs['operator'], cfg.flight, physics, self.vessel,
                range(self.run_offset, self.run_offset + self.n_runs), psi0)
        else:
            self.operator = Operator(rngs['operator'], cfg.operator, self.vessel)
        self.noise = SensorNoise(rngs['noise'], cfg.noise)
        self._wind_on = self.has_wind and cfg.wind.enabled and cfg.wind.force_scale > 0
        # The vessel's force terms; its wind loads at the configured scale (over ground).
        family = physics.family
        wind_terms = tuple(t for t in physics.terms if family.terms[t].category == 'wind')
        water = tuple(t for t in physics.terms if t not in wind_terms)
        extra = tuple(ExtraTerm(t, ''.join(family.dofs), cfg.wind.force_scale)
                      for t in wind_terms) if self._wind_on else ()
        self.physics = physics.replace(terms=water,
                                       extra_terms=extra + tuple(physics.extra_terms))
        warmup_steps = int(round(cfg.warmup_s / cfg.dt))
        self._t = -warmup_steps * cfg.dt
        if family.steady is None:
            self._x = self._at_rest(psi0, min(self._t, 0.0))
        else:
            self._command = self.operator.setpoints(min(self._t, 0.0))
            self._x = self._steady_state(psi0, self._t)
        steps = cfg.steps_per_sample
        for i in range(warmup_steps):
            if self.flies and i and i % steps == 0:      # a closed loop acts in warm-up too
                self._command = self._orders(self._t + i * cfg.dt)
            self._step(self._t + i * cfg.dt)
        # Put the first sample at x = y = 0; shifting the wave phases keeps the sea in place.
        self.waves.shift_origin(self._x[:, self._xpos], self._x[:, self._y])
        self._x[:, [self._xpos, self._y]] = 0.0
        if self.spatial:
            self._x[:, self._zpos] = 0.0
        self._t = 0.0
        self._k = 0
        self._sample = None

    def _at_rest(self, psi0: np.ndarray, t: float) -> np.ndarray:
        """Return the initial state at rest, level, at heading psi0, actuators at the orders."""
        x = np.zeros((self.n_runs, len(self.state_names)))
        x[:, self._psi] = psi0
        self._x = x
        self._command = self._orders(t)
        x[:, self._act] = np.stack(self._command, axis=-1)
        return x

    def _orders(self, t: float) -> tuple[np.ndarray, ...]:
        """Return the operator's orders at time t (a flight controller reads the true state)."""
        if self.flies:
            return self.operator.setpoints(t, self.state)
        return self.operator.setpoints(t, self._x[:, self._psi])

    def _steady_state(self, psi0: np.ndarray, t: float) -> np.ndarray:
        """Return the initial state: steady motion under the first orders and wind at t."""
        spec = self.config.physics.family.steady
        unknown = [self.states.index(s) for s in spec.unknowns]
        steps, limits = np.array(spec.steps), np.array(spec.limits)
        x = np.zeros((self.n_runs, len(self.state_names)))
        x[:, self._psi] = psi0
        x[:, self._act] = np.stack(self._command, axis=-1)
        c = self._controls(t, x)

        def balance(q):
            z = np.zeros((self.n_runs, len(self.states)))
            z[:, unknown] = q
            return self.physics.force(z, c)

        # Straight-ahead speed by bisection (X is monotonic in u), then Newton on all DOFs.
        lo, hi = np.zeros(self.n_runs), np.full(self.n_runs, spec.max_speed)
        q = np.zeros((self.n_runs, len(unknown)))
        for _ in range(BISECTION_ITERATIONS):
            q[:, 0] = 0.5 * (lo + hi)
            ahead = balance(q)[:, 0] > 0
            lo, hi = np.where(ahead, q[:, 0], lo), np.where(ahead, hi, q[:, 0])
        straight = q.copy()
        for _ in range(NEWTON_ITERATIONS):
            f = balance(q)
            jac = np.empty((self.n_runs, len(unknown), len(unknown)))
            for j in range(len(unknown)):
                dq = q.copy()
                dq[:, j] += steps[j]
                jac[:, :, j] = (balance(dq) - f) / steps[j]
            # pinv: a singular Jacobian (e.g. at rest, where |u| v has no slope) in one run
            # must not stop the others; such runs fall back to the straight solution.
            with np.errstate(invalid='ignore', over='ignore'):
                q = q - (np.linalg.pinv(jac) @ f[:, :, None])[:, :, 0]
                lost = ~np.all(np.isfinite(q) & (np.abs(q) < limits), axis=1)
            q[lost] = straight[lost]
        with np.errstate(invalid='ignore'):
            ok = (np.all(np.abs(q) < limits, axis=1)
                  & np.all(np.abs(balance(q)) < spec.residual, axis=1))
        q = np.where(ok[:, None], q, straight)
        x[:, unknown] = q
        return x

    # ------------------------------------------------------------------ dynamics
    def _controls(self, t: float, x: np.ndarray) -> np.ndarray:
        """Control vector c: the actuator states, then the true wind (speed, cos, sin)."""
        c = np.empty((self.n_runs, self.vessel.n_control))
        n_act = len(self.actuators)
        c[:, :n_act] = x[:, self._act]
        if not self.has_wind:
            return c
        if self._wind_on:
            speed, from_ned = self.wind.at(t)
            gamma = from_ned - x[:, self._psi]
            c[:, n_act], c[:, n_act + 1], c[:, n_act + 2] = speed, np.cos(gamma), np.sin(gamma)
        else:
            c[:, n_act], c[:, n_act + 1], c[:, n_act + 2] = 0.0, 1.0, 0.0
        return c

    def _step(self, t: float) -> None:
        """One RK4 step of every run from time t (s)."""
        self._x = rk4_step(self._derivative, t, self._x, self.config.dt)

    def _derivative(self, t: float, x: np.ndarray) -> np.ndarray:
        """State derivative of every run at time t (s)."""
        n = len(self.states)
        u, v, r, psi = x[:, self._u], x[:, self._v], x[:, self._r], x[:, self._psi]
        phi = x[:, self._phi] if self._phi is not None else 0.0
        z_water = x[:, :n]
        z_ground = z_water
        if self.current.active:
            u_c, v_c = self.current.body(t, psi)
            z_ground = z_water.copy()
            z_ground[:, self._u] += u_c
            z_ground[:, self._v] += v_c
        c = self._controls(t, x)
        extra = self.waves.forces(t, x[:, self._xpos], x[:, self._y], psi) \
            if self.waves.active else None
        if self._hook is not None:
            hook = self._call_hook(t, x, z_ground, c)
            extra = hook if extra is None else extra + hook
        dx = np.empty_like(x)
        dx[:, :n] = self.physics.derivative(z_water, c, z_ground, extra)
        if self.spatial:
            w, theta = x[:, self._w], x[:, self._theta]
            north, east, dx[:, self._zpos] = body_to_ned(u, v, w, phi, theta, psi)
            dx[:, self._psi] = attitude_rates(x[:, self._p], x[:, self._q], r, phi, theta)[2]
        else:
            north, east, dx[:, self._psi] = kinematics(u, v, r, phi, psi)
        if self.current.active:
            c_north, c_east = self.current.ned(t)
            north, east = north + c_north, east + c_east
        dx[:, self._xpos], dx[:, self._y] = north, east
        for j, (command, servo) in enumerate(zip(self._command, self._servos, strict=True)):
            i = self._act.start + j
            dx[:, i] = servo_rate(command, x[:, i], *servo)
        return dx

    def _call_hook(self, t, x, z_ground, c) -> np.ndarray:
        dofs = len(self.physics.family.dofs)
        weight = onset_weight(t, self.config.extra_forces_from_s,
                              self.config.extra_forces_ramp_s)
        if weight == 0.0:
            return np.zeros((self.n_runs, dofs))
        c_north, c_east = self.current.ned(t)
        state = {name: z_ground[:, i].copy() for i, name in enumerate(self.states)}
        state['u_water'], state['v_water'] = x[:, self._u].copy(), x[:, self._v].copy()
        for key in self.pose:
            state[key] = x[:, self.state_names.index(key)].copy()
        controls = {name: x[:, self._act.start + j].copy()
                    for j, name in enumerate(self.actuators)}
        n_act = len(self.actuators)
        wind_speed = c[:, n_act] if self.has_wind else np.zeros(self.n_runs)
        wind_dir = np.arctan2(c[:, n_act + 2], c[:, n_act + 1]) if self.has_wind else \
            np.zeros(self.n_runs)
        environment = {
            'wind_speed': wind_speed.copy(), 'wind_dir': wind_dir,
            'current_north': np.broadcast_to(c_north, (self.n_runs,)).copy(),
            'current_east': np.broadcast_to(c_east, (self.n_runs,)).copy(),
            'wave_elevation': (self.waves.elevation(t, x[:, self._xpos], x[:, self._y])
                               if self.waves.active else np.zeros(self.n_runs)),
        }
        extra = np.asarray(self._hook(t, state, controls, environment), dtype=float)
        if extra.shape != (self.n_runs, dofs) or not np.all(np.isfinite(extra)):
            raise ValueError(f'extra_forces hook {self.config.extra_forces!r} must return '
                             f'finite forces of shape ({self.n_runs}, {dofs}), got shape '
                             f'{extra.shape}')
        return weight * extra

    # ------------------------------------------------------------------ public API
    @property
    def command(self) -> dict[str, np.ndarray]:
        """Return the set-points in force since the last sample, by actuator (arrays)."""
        return {name: np.array(c, dtype=float) for name, c in
                zip(self.actuators, self._command, strict=True)}

    @property
    def t(self) -> float:
        """Return the simulation time of the current sample (s)."""
        return self._t

    @property
    def state(self) -> dict[str, np.ndarray]:
        """Return the true state: ground velocities (FRD), pose (NED from start), actuators."""
        x = self._x
        out = {name: x[:, i].copy() for i, name in enumerate(self.state_names)}
        if self.current.active:
            u_c, v_c = self.current.body(self._t, x[:, self._psi])
            out['u'], out['v'] = out['u'] + u_c, out['v'] + v_c
        return out

    def set_state(self, **values) -> None:
        """
        Overwrite parts of the true state (keys of ``state_names``; u, v through the water).

        Arrays broadcast to (n_runs,); x, y are NED positions like the outputs. Meant for
        manoeuvre tests and for resetting a vessel in the ROS node.
        """
        for key, value in values.items():
            if key not in self.state_names:
                raise KeyError(f'unknown state {key!r}; known: {", ".join(self.state_names)}')
            value = np.broadcast_to(np.asarray(value, dtype=float), (self.n_runs,))
            self._x[:, self.state_names.index(key)] = value
        self._sample = None

    def sample(self) -> dict[str, np.ndarray]:
        """Measured outputs (with noise) and truth at the current time, arrays (n_runs,)."""
        if self._sample is None:
            self._sample = self._measure()
        return {k: v.copy() for k, v in self._sample.items()}

    def _measure(self) -> dict[str, np.ndarray]:
        truth = self.state
        noise = dict(zip(self.noise.channels, self.noise.next().T, strict=True))
        out = {'t': np.full(self.n_runs, self._t)}
        for key in self.true_keys + self.actuators:
            out[key] = truth[key] + noise[key]
        if self.has_wind:
            speed, from_ned = self.wind.at(self._t) if self.config.wind.enabled else (
                np.zeros(self.n_runs), self.wind.from_ned0)
            gamma = _wrap(from_ned - truth['psi'])
            out['wind_speed'] = np.maximum(speed + noise['wind_speed'], 0.0)
            measured_dir = gamma + noise['wind_dir']
            out['wind_dir_cos'], out['wind_dir_sin'] = np.cos(measured_dir), np.sin(
                measured_dir)
        for key in self.true_keys:
            out[key + '_true'] = truth[key]
        return out

    def advance(self, command: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """
        Integrate one output period and return the new sample.

        ``command`` (optional) maps actuator names to set-points (scalars or arrays
        (n_runs,), the vessel file's units) that override the operator's for this
        period. The operator's random stream advances either way (a flight controller
        computes its orders either way).
        """
        orders = list(self._orders(self._t))
        if command is not None:
            for key in command:
                if key not in self.actuators:
                    raise KeyError(f'unknown command {key!r}; known: '
                                   f'{", ".join(self.actuators)}')
            for i, key in enumerate(self.actuators):
                if key in command:
                    value = np.broadcast_to(np.asarray(command[key], dtype=float),
                                            (self.n_runs,)).copy()
                    if not np.all(np.isfinite(value)):
                        raise ValueError(f'command {key!r} must be finite, got {value}')
                    orders[i] = value
        self._command = tuple(orders)
        cfg = self.config
        steps = cfg.steps_per_sample
        t0 = self._k / cfg.output_rate_hz
        for i in range(steps):
            self._step(t0 + i * cfg.dt)
        self._k += 1
        self._t = self._k / cfg.output_rate_hz
        self._sample = None
        return self.sample()

    def run(self, seconds: float, progress=None) -> dict[str, np.ndarray]:
        """
        Return the current sample and those of the next ``seconds`` (n_runs, n_samples).

        ``progress`` (optional) is called with 1 after each output period.
        """
        n = int(round(seconds * self.config.output_rate_hz))
        rows = [self.sample()]
        for _ in range(n):
            rows.append(self.advance())
            if progress is not None:
                progress(1)
        return {key: np.stack([row[key] for row in rows], axis=1) for key in self.sample_keys}
