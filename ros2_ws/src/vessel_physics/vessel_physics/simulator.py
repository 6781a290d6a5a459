"""
Vectorized batch simulator of the 4-DOF patrol vessel in wind, waves and current.

``Simulator(config, n_runs, seed, run_offset)`` integrates ``n_runs`` independent runs at
once (numpy arrays shaped (n_runs, ...)) with RK4 at ``config.dt`` and samples them at
``config.output_rate_hz``. Run k draws all its randomness (sea state, wind, current,
initial heading, operator, sensor noise) from ``np.random.SeedSequence([seed,
run_offset + k])``, so a run is the same bit for bit whether it is simulated alone or in a
batch, and the ROS node (n_runs=1) reproduces the batch tool for the same seed.

Model. State nu_r = [u_r, v_r, p, r] (through the water, FRD), phi, psi (NED, unwrapped),
x, y (NED, from the run's first sample), and the actuator states n, delta_port,
delta_stbd. With the mass matrix M (``mass``) and the terms of ``terms``:

    M nu_r' = rigid_body_coriolis + restoring + hull_damping + propulsion   (nu_r)
              + wind (ground velocity) + waves + extra_forces hook

Kinematics (``integrator.kinematics``) plus the current give x', y', psi' = r cos phi,
phi' = p; actuators follow ``actuators``. Outputs are body velocities over ground.

Initial condition. Each run starts at a random heading in the steady state of its
operator's first orders (a Newton solve of the force balance under the wind at the start, p = 0),
then runs ``warmup_s`` of simulated time with those orders held so that wave, gust and
roll transients have died out; the first sample (t = 0, x = y = 0) follows.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from vessel_physics.actuators import rudder_rate, shaft_accel
from vessel_physics.augmented import ALL_DOFS, ExtraTerm, Physics
from vessel_physics.config import SimConfig, load_hook
from vessel_physics.current import CurrentField, draw_current
from vessel_physics.integrator import kinematics, rk4_step
from vessel_physics.noise import CHANNELS, SensorNoise
from vessel_physics.operator import Operator
from vessel_physics.terms import SIMULATOR_TERMS
from vessel_physics.waves import WaveField, draw_waves
from vessel_physics.wind import WindField, draw_wind

STATE = ('u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y', 'n', 'delta_port', 'delta_stbd')
I_U, I_V, I_P, I_R, I_PHI, I_PSI, I_X, I_Y, I_N, I_DP, I_DS = range(len(STATE))
TRUE_KEYS = ('u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y')
MEASURED_KEYS = ('t', 'u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y', 'n', 'delta_port',
                 'delta_stbd', 'wind_speed', 'wind_dir_cos', 'wind_dir_sin')
SAMPLE_KEYS = MEASURED_KEYS + tuple(k + '_true' for k in TRUE_KEYS)
COMMAND_KEYS = ('n', 'delta_port', 'delta_stbd')
# Random streams spawned from SeedSequence([seed, run]): their order is part of the
# reproducibility contract; add new ones at the end.
STREAMS = ('wind', 'waves', 'current', 'initial', 'operator', 'noise')

NEWTON_ITERATIONS = 30
NEWTON_STEP = np.array([1e-4, 1e-4, 1e-6, 1e-6])   # finite-difference steps for u, v, r, phi
STEADY_LIMITS = np.array([30.0, 5.0, 0.3, 0.5])      # plausible |u|, |v|, |r|, |phi| bounds
STEADY_RESIDUAL = 1.0  # N, N m: force balance accepted as steady
BISECTION_ITERATIONS = 60
MAX_SPEED = 30.0  # m/s, bracket for the straight-ahead speed


def _wrap(angle):
    """Wrap to (-pi, pi]."""
    return np.pi - np.mod(np.pi - angle, 2 * np.pi)


WATER_TERMS = tuple(t for t in SIMULATOR_TERMS if t != 'wind')   # wind: scaled, below


class Simulator:
    """Batch simulator; see the module docstring. All arrays are float64, SI units."""

    def __init__(self, config: SimConfig, n_runs: int = 1, seed: int = 0,
                 run_offset: int = 0):
        if int(n_runs) < 1:
            raise ValueError(f'n_runs must be >= 1, got {n_runs!r}')
        if int(run_offset) < 0 or int(seed) < 0:
            raise ValueError(f'seed and run_offset must be >= 0, got {seed!r}, {run_offset!r}')
        self.config = config
        self.params = config.vessel
        self.n_runs = int(n_runs)
        self.seed = int(seed)
        self.run_offset = int(run_offset)
        self._hook = load_hook(config.extra_forces) if config.extra_forces else None
        self.reset()

    # ------------------------------------------------------------------ set-up
    def reset(self, seed: int | None = None) -> None:
        """Start every run again (with a new seed if given): new environment, t = 0."""
        if seed is not None:
            if int(seed) < 0:
                raise ValueError(f'seed must be >= 0, got {seed!r}')
            self.seed = int(seed)
        cfg = self.config
        streams = [np.random.SeedSequence([self.seed, self.run_offset + k]).spawn(len(STREAMS))
                   for k in range(self.n_runs)]
        rngs = {name: [np.random.default_rng(s[i]) for s in streams]
                for i, name in enumerate(STREAMS)}
        self.wind = WindField([draw_wind(g, cfg.wind) for g in rngs['wind']])
        self.waves = WaveField([draw_waves(g, cfg.waves) for g in rngs['waves']],
                               self.params, cfg.waves)
        self.current = CurrentField([draw_current(g, cfg.current) for g in rngs['current']])
        psi0 = np.array([g.uniform(0.0, 2 * np.pi) for g in rngs['initial']])
        self.operator = Operator(rngs['operator'], cfg.operator)
        self.noise = SensorNoise(rngs['noise'], cfg.noise)
        self._wind_on = cfg.wind.enabled and cfg.wind.force_scale > 0
        # The vessel's force terms, the wind's at its configured scale (over ground).
        wind = (ExtraTerm('wind', ALL_DOFS, cfg.wind.force_scale),) if self._wind_on \
            else ()
        self.physics = Physics(self.params, terms=WATER_TERMS, extra_terms=wind)
        self._command = self.operator.setpoints(0.0)
        warmup_steps = int(round(cfg.warmup_s / cfg.dt))
        self._t = -warmup_steps * cfg.dt
        self._x = self._steady_state(psi0, self._t)
        for i in range(warmup_steps):
            self._step(self._t + i * cfg.dt)
        # Put the first sample at x = y = 0; shifting the wave phases keeps the sea in place.
        self.waves.shift_origin(self._x[:, I_X], self._x[:, I_Y])
        self._x[:, [I_X, I_Y]] = 0.0
        self._t = 0.0
        self._k = 0
        self._sample = None

    def _steady_state(self, psi0: np.ndarray, t: float) -> np.ndarray:
        """Return the initial state: steady motion under the first orders and wind at t."""
        n_sp, dp_sp, ds_sp = self._command
        x = np.zeros((self.n_runs, len(STATE)))
        x[:, I_PSI], x[:, I_N], x[:, I_DP], x[:, I_DS] = psi0, n_sp, dp_sp, ds_sp
        c = self._controls(t, x)

        def balance(q):
            z = np.zeros((self.n_runs, 5))
            z[:, 0], z[:, 1], z[:, 3], z[:, 4] = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
            return self.physics.force(z, c)

        # Straight-ahead speed by bisection (X is monotonic in u), then Newton on all DOFs.
        lo, hi = np.zeros(self.n_runs), np.full(self.n_runs, MAX_SPEED)
        q = np.zeros((self.n_runs, 4))
        for _ in range(BISECTION_ITERATIONS):
            q[:, 0] = 0.5 * (lo + hi)
            ahead = balance(q)[:, 0] > 0
            lo, hi = np.where(ahead, q[:, 0], lo), np.where(ahead, hi, q[:, 0])
        straight = q.copy()
        for _ in range(NEWTON_ITERATIONS):
            f = balance(q)
            jac = np.empty((self.n_runs, 4, 4))
            for j in range(4):
                dq = q.copy()
                dq[:, j] += NEWTON_STEP[j]
                jac[:, :, j] = (balance(dq) - f) / NEWTON_STEP[j]
            # pinv: a singular Jacobian (e.g. at rest, where |u| v has no slope) in one run
            # must not stop the others; such runs fall back to the straight solution.
            with np.errstate(invalid='ignore', over='ignore'):
                q = q - (np.linalg.pinv(jac) @ f[:, :, None])[:, :, 0]
                lost = ~np.all(np.isfinite(q) & (np.abs(q) < STEADY_LIMITS), axis=1)
            q[lost] = straight[lost]
        with np.errstate(invalid='ignore'):
            ok = (np.all(np.abs(q) < STEADY_LIMITS, axis=1)
                  & np.all(np.abs(balance(q)) < STEADY_RESIDUAL, axis=1))
        q = np.where(ok[:, None], q, straight)
        x[:, I_U], x[:, I_V], x[:, I_R], x[:, I_PHI] = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        return x

    # ------------------------------------------------------------------ dynamics
    def _controls(self, t: float, x: np.ndarray) -> np.ndarray:
        """Term input c = [n, delta_port, delta_stbd, wind speed, cos, sin of true wind dir]."""
        c = np.empty((self.n_runs, 6))
        c[:, 0:3] = x[:, I_N:I_DS + 1]
        if self._wind_on:
            speed, from_ned = self.wind.at(t)
            gamma = from_ned - x[:, I_PSI]
            c[:, 3], c[:, 4], c[:, 5] = speed, np.cos(gamma), np.sin(gamma)
        else:
            c[:, 3], c[:, 4], c[:, 5] = 0.0, 1.0, 0.0
        return c

    def _step(self, t: float) -> None:
        """One RK4 step of every run from time t (s)."""
        self._x = rk4_step(self._derivative, t, self._x, self.config.dt)

    def _derivative(self, t: float, x: np.ndarray) -> np.ndarray:
        """State derivative of every run at time t (s)."""
        u, v, r, phi, psi = x[:, I_U], x[:, I_V], x[:, I_R], x[:, I_PHI], x[:, I_PSI]
        z_water = x[:, :5]
        z_ground = z_water
        if self.current.active:
            u_c, v_c = self.current.body(t, psi)
            z_ground = z_water.copy()
            z_ground[:, 0] += u_c
            z_ground[:, 1] += v_c
        c = self._controls(t, x)
        extra = self.waves.forces(t, x[:, I_X], x[:, I_Y], psi) if self.waves.active else None
        if self._hook is not None:
            hook = self._call_hook(t, x, z_ground, c)
            extra = hook if extra is None else extra + hook
        dx = np.empty_like(x)
        dx[:, :I_PHI + 1] = self.physics.derivative(z_water, c, z_ground, extra)
        north, east, dx[:, I_PSI] = kinematics(u, v, r, phi, psi)
        if self.current.active:
            c_north, c_east = self.current.ned(t)
            north, east = north + c_north, east + c_east
        dx[:, I_X], dx[:, I_Y] = north, east
        n_cmd, dp_cmd, ds_cmd = self._command
        dx[:, I_N] = shaft_accel(n_cmd, x[:, I_N], self.params)
        dx[:, I_DP] = rudder_rate(dp_cmd, x[:, I_DP], self.params)
        dx[:, I_DS] = rudder_rate(ds_cmd, x[:, I_DS], self.params)
        return dx

    def _call_hook(self, t, x, z_ground, c) -> np.ndarray:
        c_north, c_east = self.current.ned(t)
        state = {'u': z_ground[:, 0].copy(), 'v': z_ground[:, 1].copy(),
                 'u_water': x[:, I_U].copy(), 'v_water': x[:, I_V].copy()}
        for key, i in (('p', I_P), ('r', I_R), ('phi', I_PHI), ('psi', I_PSI)):
            state[key] = x[:, i].copy()
        state['x'], state['y'] = x[:, I_X].copy(), x[:, I_Y].copy()
        controls = {'n': x[:, I_N].copy(), 'delta_port': x[:, I_DP].copy(),
                    'delta_stbd': x[:, I_DS].copy()}
        environment = {
            'wind_speed': c[:, 3].copy(), 'wind_dir': np.arctan2(c[:, 5], c[:, 4]),
            'current_north': np.broadcast_to(c_north, (self.n_runs,)).copy(),
            'current_east': np.broadcast_to(c_east, (self.n_runs,)).copy(),
            'wave_elevation': (self.waves.elevation(t, x[:, I_X], x[:, I_Y])
                               if self.waves.active else np.zeros(self.n_runs)),
        }
        extra = np.asarray(self._hook(t, state, controls, environment), dtype=float)
        if extra.shape != (self.n_runs, 4) or not np.all(np.isfinite(extra)):
            raise ValueError(f'extra_forces hook {self.config.extra_forces!r} must return '
                             f'finite [X, Y, K, N] of shape ({self.n_runs}, 4), got shape '
                             f'{extra.shape}')
        return extra

    # ------------------------------------------------------------------ public API
    @property
    def t(self) -> float:
        """Return the simulation time of the current sample (s)."""
        return self._t

    @property
    def state(self) -> dict[str, np.ndarray]:
        """Return the true state: ground velocities (FRD), pose (NED from start), actuators."""
        x = self._x
        out = {name: x[:, i].copy() for i, name in enumerate(STATE)}
        if self.current.active:
            u_c, v_c = self.current.body(self._t, x[:, I_PSI])
            out['u'], out['v'] = out['u'] + u_c, out['v'] + v_c
        return out

    def set_state(self, **values) -> None:
        """
        Overwrite parts of the true state (keys of ``STATE``; u, v through the water).

        Arrays broadcast to (n_runs,); x, y are NED positions like the outputs. Meant for
        manoeuvre tests and for resetting a vessel in the ROS node.
        """
        for key, value in values.items():
            if key not in STATE:
                raise KeyError(f'unknown state {key!r}; known: {", ".join(STATE)}')
            value = np.broadcast_to(np.asarray(value, dtype=float), (self.n_runs,))
            self._x[:, STATE.index(key)] = value
        self._sample = None

    def sample(self) -> dict[str, np.ndarray]:
        """Measured outputs (with noise) and truth at the current time, arrays (n_runs,)."""
        if self._sample is None:
            self._sample = self._measure()
        return {k: v.copy() for k, v in self._sample.items()}

    def _measure(self) -> dict[str, np.ndarray]:
        truth = self.state
        speed, from_ned = self.wind.at(self._t) if self.config.wind.enabled else (
            np.zeros(self.n_runs), self.wind.from_ned0)
        gamma = _wrap(from_ned - truth['psi'])
        noise = dict(zip(CHANNELS, self.noise.next().T, strict=True))
        out = {'t': np.full(self.n_runs, self._t)}
        for key in TRUE_KEYS + COMMAND_KEYS:
            out[key] = truth[key] + noise[key]
        out['wind_speed'] = np.maximum(speed + noise['wind_speed'], 0.0)
        measured_dir = gamma + noise['wind_dir']
        out['wind_dir_cos'], out['wind_dir_sin'] = np.cos(measured_dir), np.sin(measured_dir)
        for key in TRUE_KEYS:
            out[key + '_true'] = truth[key]
        return out

    def advance(self, command: Mapping[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        """
        Integrate one output period and return the new sample.

        ``command`` (optional) maps any of ``n`` (rad/s), ``delta_port``, ``delta_stbd``
        (rad) to set-points (scalars or arrays (n_runs,)) that override the operator's
        for this period. The operator's random stream advances either way.
        """
        orders = list(self.operator.setpoints(self._t))
        if command is not None:
            for key in command:
                if key not in COMMAND_KEYS:
                    raise KeyError(f'unknown command {key!r}; known: {", ".join(COMMAND_KEYS)}')
            for i, key in enumerate(COMMAND_KEYS):
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
        return {key: np.stack([row[key] for row in rows], axis=1) for key in SAMPLE_KEYS}
