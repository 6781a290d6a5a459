"""
Compiled forecasts of a trained hybrid model, fast enough for online use and MPC.

``Forecaster.from_checkpoint(path, relative_threshold=None)`` is how a trained hybrid
is served. It reads the checkpoint with safetensors' numpy reader and never imports
torch: the physical part is the framework-free ``hybrid_models.physical`` model of the
checkpoint's description, and every sample period is ``hybrid_models.hybrid_step``, the
very code training runs in torch. What this module adds is the execution: the
initialization window and the horizon as ``jax.lax.scan``, compiled once per batch size
with ``jax.jit``, batched over candidate control plans and sharded over the cores.

An ensemble checkpoint (``hybrid_models.ensemble``: K corrections on one physics) is
served by the same program: each step adds the mean of the members' bounded
corrections (``hybrid_step.ensemble_step``); a single hybrid is its one-member case.

The relative threshold is resolved once, here (meanings as in ``hybrid_models.bound``):
None serves the checkpoint's own bound (the threshold it was trained or deployed with,
``model.relative_threshold`` in its config); 0 serves the physics alone; T > 0 bounds
the correction to T R / 2 with the checkpoint's output range R.

XLA runs one program on one host core, and programs on the same device run one after
the other. So that a batch of what-if plans uses every core, the forecaster asks XLA for
one host device per core (``--xla_force_host_platform_device_count`` in ``XLA_FLAGS``,
unless the user set it or jax was imported first) and splits batches of
``MIN_SHARD`` plans or more across the devices; a single forecast stays on one device.
Each plan's forecast is the same computation wherever it runs. Compiled programs are
kept on disk (``compilation_cache_dir``), so a process that compiles what another
compiled before loads it instead.

``platform='gpu'`` runs the same program on the GPUs jax sees (its CUDA build,
``tools/setup.sh gpu``), batches split across them as across host devices; float32
matrix products there run at full precision, so forecasts agree with the CPU's to
float32 rounding (GPUs otherwise multiply in TF32). Asked for a GPU jax does not see,
the forecaster refuses in one line.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib
import os
from pathlib import Path
import sys
import time

import numpy as np

from hybrid_models import novelty
from hybrid_models.bands import Bands, BandsError
from hybrid_models.bound import half_width, is_constant, schedule_of, step_bounds
from hybrid_models.checkpoint_format import CheckpointError, read_model_arrays, vessel_of
from hybrid_models.hybrid_step import (
    ENSEMBLE_KIND as ENSEMBLE,
)
from hybrid_models.hybrid_step import correction_input, ensemble_step, step_weights
from hybrid_models.metrics import heading_rate
from hybrid_models.physical import PhysicalModel, build_physical
from hybrid_models.physical.base import part
from hybrid_models.recurrent import cell_of, layer_weights, map_state, stack_step, zeros
from vessel_description import Vessel
from vessel_description.vocabulary import ENVIRONMENT_DIRECTIONS


@dataclass(frozen=True)
class Forecast:
    """Forecasts of B plans: hybrid states and the physical part of every step."""

    hybrid: np.ndarray    # (B, H, n_state)
    physics: np.ndarray   # (B, H, n_state); hybrid - physics is the bounded correction
    # (B, H, 2): the wind direction's (cos, sin) each step used, a held one turned
    # (``Forecaster.forecast``'s ``hold_wind``); None when no plan held the wind.
    wind: np.ndarray | None = None
    # (B, H): the share of the bound each step had (``hybrid_models.novelty``; the
    # members' mean for an ensemble); None when the model is served without the fade.
    available: np.ndarray | None = None


def wind_direction_columns(spec: Vessel) -> tuple[int, int] | None:
    """Return the control indices of the wind's (cos, sin) relative to the bow, or None."""
    if 'wind' not in spec.environment:
        return None
    cos, sin = ENVIRONMENT_DIRECTIONS['wind']
    return spec.control_index(cos), spec.control_index(sin)


DEVICE_COUNT_FLAG = '--xla_force_host_platform_device_count'
PLATFORMS = ('cpu', 'gpu')   # where a forecaster may run (``platform_devices``)
MIN_SHARD = 8   # plans per device below which splitting a batch costs more than it gains


# Compiled programs kept on disk between processes (jax's persistent compilation cache):
# a predictor restarted on board forecasts in under a second instead of compiling again
# for seconds. jax's own variable names the directory; set empty, it turns the cache off.
CACHE_ENV = 'JAX_COMPILATION_CACHE_DIR'
CACHE_MAX_BYTES = 256 * 2 ** 20   # least recently used programs go beyond this
_cache_configured = False


def compilation_cache_dir(environ=os.environ) -> Path | None:
    """Return where compiled programs are kept (None: not kept); ``$XDG_CACHE_HOME``-based."""
    if CACHE_ENV in environ:
        return Path(environ[CACHE_ENV]).expanduser() if environ[CACHE_ENV] else None
    base = environ.get('XDG_CACHE_HOME') or Path.home() / '.cache'
    return Path(base) / 'hybrid_models' / 'jax'


def _use_compilation_cache(jax) -> None:
    global _cache_configured
    if _cache_configured:
        return
    _cache_configured = True
    cache = compilation_cache_dir()
    if cache is None:
        return
    if jax.config.jax_compilation_cache_dir:   # set in code before: the user's own
        cache = Path(jax.config.jax_compilation_cache_dir)
    try:
        cache.mkdir(parents=True, exist_ok=True)
    except OSError as exc:   # a read-only home: compile every time, as before
        print(f'hybrid_models: compiled programs not kept ({cache}: {exc.strerror})',
              file=sys.stderr)
        return
    jax.config.update('jax_compilation_cache_dir', str(cache))
    # Every program, however quick to compile (jax keeps those over 1 s by default):
    # the predictor compiles one per batch size, each under a second.
    for option, value in (('jax_persistent_cache_min_compile_time_secs', 0.0),
                          ('jax_compilation_cache_max_size', CACHE_MAX_BYTES)):
        if option.upper() not in os.environ:
            jax.config.update(option, value)


def jax_module():
    """Return jax, asking XLA for a host device per core and keeping compiled programs."""
    if 'jax' not in sys.modules and DEVICE_COUNT_FLAG not in os.environ.get('XLA_FLAGS', ''):
        cores = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else (
            os.cpu_count() or 1)
        os.environ['XLA_FLAGS'] = (os.environ.get('XLA_FLAGS', '') +
                                   f' {DEVICE_COUNT_FLAG}={cores}').strip()
    import jax

    _use_compilation_cache(jax)
    return jax


def platform_devices(platform: str) -> list:
    """Return jax's devices of ``platform`` ('cpu' or 'gpu'); ValueError in one line if none."""
    if platform not in PLATFORMS:
        raise ValueError(f'unknown compute platform {platform!r}; known: {", ".join(PLATFORMS)}')
    jax = jax_module()
    try:
        return jax.devices(platform)
    except RuntimeError:
        raise ValueError(f'compute platform {platform!r}: jax {jax.__version__} sees no GPU '
                         f'here (its CUDA build: tools/setup.sh gpu, on a machine with an '
                         f'NVIDIA driver); use cpu') from None


def compiled_repeat(n, body, x):
    """Apply ``body`` n times as one compiled loop (the physics' RK4 sub-steps)."""
    return jax_module().lax.fori_loop(0, n, lambda _i, state: body(state), x)


def served_bound(state: dict, model_config: dict,
                 relative_threshold: float | None) -> tuple:
    """
    Return (threshold, half-widths b) to serve: None keeps the checkpoint's own.

    The checkpoint's own may be a schedule (``hybrid_models.bound``); b is then its last
    entry's, and ``Forecaster.step_bounds`` gives every step's.
    """
    out_range = np.asarray(state['output_range'], np.float64)
    if relative_threshold is None:
        threshold = model_config.get('relative_threshold')
        if is_constant(threshold):
            return threshold, np.asarray(state['bound'], np.float64).copy()
        return threshold, half_width(schedule_of(threshold)[-1][1], out_range)
    return float(relative_threshold), half_width(relative_threshold, out_range)


def served_bands(config: dict, spec, relative_threshold) -> tuple[Bands | None, str]:
    """
    Return (bands, note): the checkpoint's calibrated bands, or None and why not.

    Bands (``hybrid_models.bands``) are served only at the threshold they were computed at.
    """
    stored = config.get('bands')
    if not stored:
        return None, ('the checkpoint has no calibrated bands (train it again, or give it '
                      'bands with set_bands)')
    try:
        bands = Bands.from_dict(stored, spec.state_names)
    except BandsError as exc:
        return None, str(exc)
    if not bands.serves(relative_threshold):
        return None, (f'the calibrated bands hold at relative threshold '
                      f'{bands.relative_threshold}, not at the served {relative_threshold}')
    return bands, f'bands at levels {list(bands.levels)} from {bands.origin}'


def served_novelty(member_config: dict, config: dict, members: int, cast) -> list:
    """
    Return each member's ``Novelty.weights`` when served with the fade, else Nones.

    A model configured with the fade whose checkpoint holds no calibration is refused.
    """
    if not member_config.get('novelty_fade', False):
        return [None] * members
    stored = config.get('novelty') or [None] * members
    if len(stored) != members or any(entry is None for entry in stored):
        raise CheckpointError('the model is served with the novelty fade but holds no novelty '
                              'calibration for every member (train it again)')
    return [novelty.Novelty.from_dict(entry).weights(cast) for entry in stored]


def members_of(state: dict, model_config: dict) -> list[dict]:
    """Return the state dict of each member: one for a hybrid, K for an ensemble."""
    if model_config.get('kind') != ENSEMBLE:
        return [state]
    return [part(state, f'members.{k}') for k in range(int(model_config['members']))]


class Forecaster:
    """
    Batched, compiled forecasts of a trained hybrid model.

    ``forecast(z_window, c_window, c_future)`` takes one initialization window
    (W, n_state) and (W, n_control) and B plans of future controls (B, H, n_control),
    indexed as in ``hybrid_models.data``: c_future[:, 0] is the control at the last
    window sample. Computation runs in ``dtype`` (float32 by default, as trained), on
    ``platform`` ('cpu' by default, or 'gpu'; see the module docstring). Build one with
    ``from_checkpoint`` (serving) or ``from_model`` (a torch model).
    """

    def __init__(self, spec: Vessel, model_config: dict, physical: PhysicalModel,
                 state: dict, relative_threshold: float | None = None, dtype=np.float32,
                 model_id: str = '', config: dict | None = None, platform: str = 'cpu'):
        jax = jax_module()
        self.devices = platform_devices(platform)
        self.platform = platform
        if dtype == np.float64:
            jax.config.update('jax_enable_x64', True)
        self.spec, self.physical, self.dtype = spec, physical, dtype
        self.model_id, self.config = model_id, dict(config or {})
        self._wind = wind_direction_columns(spec)
        member_config = model_config.get('member', model_config)
        first = members_of(state, model_config)[0]
        self.bound_mode = member_config.get('bound_mode', 'tanh')
        self.relative_threshold, self.bound = served_bound(first, model_config,
                                                           relative_threshold)
        self._output_range = np.asarray(first['output_range'], np.float64)
        self.bands, self.bands_note = served_bands(self.config, spec, self.relative_threshold)
        layers = int(member_config['layers'])
        # Checkpoints older than the key 'cell' were LSTMs.
        self.cell = cell = cell_of(member_config.get('cell', 'lstm'))

        def cast(a):
            a = np.asarray(a)
            return a.astype(dtype) if np.issubdtype(a.dtype, np.floating) else a

        arrays = {k: cast(v) for k, v in state.items()}
        self.members = len(members_of(arrays, model_config))
        fades = served_novelty(member_config, self.config, self.members, cast)
        self.novelty_fade = fades[0] is not None
        self._params = tuple({**step_weights(cell, m | {'bound': cast(self.bound)}, layers,
                                             fade),
                              'init': layer_weights(cell, m, 'init', layers)}
                             for m, fade in zip(members_of(arrays, model_config), fades,
                                                strict=True))
        # The physical model's learned values enter the program as constants: XLA folds
        # them into its feature products (measured: 5.9 -> 4.6 ms per 900-step forecast).
        self._physical_arrays = {k: cast(v) for k, v in physical.arrays().items()}
        # Two programs for a vessel with wind: turning a held wind costs a tenth more per
        # step, which forecasts that hold none do not pay.
        program = self._forecast if platform == 'cpu' else self._full_precision
        self._compiled = jax.jit(program, static_argnames='turning')
        self._device_params = [jax.device_put(self._params, d) for d in self.devices]

    @classmethod
    def from_checkpoint(cls, path: str | Path, relative_threshold: float | None = None,
                        dtype=np.float32, platform: str = 'cpu') -> Forecaster:
        """Serve a hybrid checkpoint (read without torch, never unpickled)."""
        config, state = read_model_arrays(path)
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
        try:
            return cls._build(vessel_of(config, path), config.get('model') or {}, state,
                              relative_threshold, dtype, f'{Path(path).stem}@{digest}',
                              config, platform)
        except (KeyError, TypeError) as exc:
            raise CheckpointError(f'{path}: checkpoint does not match its model '
                                  f'({type(exc).__name__}: {exc})') from None

    @classmethod
    def from_model(cls, model, relative_threshold: float | None = None, dtype=np.float32,
                   model_id: str = '', config: dict | None = None,
                   platform: str = 'cpu') -> Forecaster:
        """Serve a trained torch ``HybridModel`` (its weights are copied to numpy)."""
        state = {k: v.detach().cpu().numpy() for k, v in model.state_dict().items()}
        calibrations = novelty.stored(model)
        if calibrations is not None:
            config = {**(config or {}), 'novelty': calibrations}
        return cls._build(model.spec, model.describe(), state, relative_threshold, dtype,
                          model_id, config, platform)

    @classmethod
    def _build(cls, spec, model_config: dict, state: dict, relative_threshold, dtype,
               model_id: str, config: dict | None, platform: str = 'cpu') -> Forecaster:
        kind = model_config.get('kind')
        if kind not in ('hybrid', ENSEMBLE):
            raise CheckpointError(f'the forecaster serves hybrid models and ensembles of '
                                  f'them, not kind {kind!r}')
        # An ensemble's members share one physics: the first member's is served.
        first = members_of(state, model_config)[0]
        member_config = model_config['member'] if kind == ENSEMBLE else model_config
        physical = build_physical(member_config['physical'], spec)
        physical.load_arrays(part(first, 'physical'))
        return cls(spec, model_config, physical, state, relative_threshold, dtype, model_id,
                   config, platform)

    @property
    def window(self) -> int:
        """Return the initialization window the model was trained with (samples)."""
        run_config = self.config.get('training', {})   # the training run's whole config
        return int(run_config['training']['window'])

    def step_bounds(self, horizon: int) -> np.ndarray:
        """Return the served half-widths of forecast steps 1..horizon (horizon, n_state)."""
        if is_constant(self.relative_threshold):
            return np.broadcast_to(self.bound, (horizon, len(self.bound))).copy()
        return step_bounds(self.relative_threshold, self._output_range, self.spec.dt, horizon)

    # ------------------------------------------------------------------ the program
    def _full_precision(self, *args, turning: bool):
        with jax_module().default_matmul_precision('highest'):
            return self._forecast(*args, turning=turning)

    def _forecast(self, members, z_window, c_window, c_future, hold_wind, turning: bool):
        jax = jax_module()
        jnp = jax.numpy
        batch = c_future.shape[0]

        def start(p):
            """One member's recurrent state after the window, for every plan."""
            norm = jnp.concatenate([(z_window - p['state_mean']) / p['state_std'],
                                    (c_window - p['control_mean']) / p['control_std']],
                                   axis=-1)

            def init_step(recurrent, x):
                return stack_step(self.cell, x[None, :], recurrent, p['init'])[1], None

            start, _ = jax.lax.scan(init_step, zeros(self.cell, jnp, 1, p['init'], self.dtype),
                                    norm)
            return map_state(lambda a: jnp.broadcast_to(a, (batch, a.shape[-1])), start)

        recurrents = tuple(start(p) for p in members)
        z0 = jnp.broadcast_to(z_window[-1], (batch, z_window.shape[-1]))

        def physical(z, c):
            return self.physical.step(z, c, self._physical_arrays, compiled_repeat)

        wind = self._wind if turning else None
        if wind is not None:
            # A held wind stays put over the earth (hybrid_predictor.held_wind): its angle
            # from the bow is the first step's, turned against the forecast's own heading
            # change psi, which the dead reckoning's heading_rate integrates as it goes.
            gamma0 = jnp.arctan2(c_future[:, 0, wind[1]], c_future[:, 0, wind[0]])
            dt = self.dtype(self.spec.dt)

        def step(carry, inputs):
            (z, psi, recurrents), (c_t, bound) = carry, inputs
            if wind is not None:
                turned = (jnp.cos(gamma0 - psi), jnp.sin(gamma0 - psi))
                for column, value in zip(wind, turned, strict=True):
                    c_t = c_t.at[:, column].set(jnp.where(hold_wind, value, c_t[:, column]))
            z_next, z_phy, _, recurrents = ensemble_step(self.cell, members, physical, z, c_t,
                                                         recurrents, self.bound_mode, bound)
            out = {'hybrid': z_next, 'physics': z_phy}
            if self.novelty_fade:
                out['available'] = sum(novelty.available(correction_input(p, z_phy, c_t),
                                                         p['novelty'])[:, 0]
                                       for p in members) / len(members)
            if wind is not None:
                psi = psi + dt * heading_rate(z_next, self.spec)
                out['wind'] = c_t[:, list(wind)]
            return (z_next, psi, recurrents), out

        # The horizon is a static shape: each step's bound is a constant of the program.
        bounds = self.step_bounds(c_future.shape[1]).astype(self.dtype)
        psi0 = jnp.zeros((batch,), self.dtype)
        _, outputs = jax.lax.scan(step, (z0, psi0, recurrents),
                                  (jnp.swapaxes(c_future, 0, 1), bounds))
        return {name: jnp.swapaxes(out, 0, 1) for name, out in outputs.items()}

    # ------------------------------------------------------------------ public API
    def forecast(self, z_window: np.ndarray, c_window: np.ndarray,
                 c_future: np.ndarray, hold_wind=None) -> Forecast:
        """
        Forecast every plan from one window; arrays in physical units (see class doc).

        ``hold_wind`` (B,) bools marks the plans whose wind is held over the earth: the
        direction of their first step is turned against the forecast's own heading
        change at every later step, in the same pass (``hybrid_predictor.held_wind``).
        Other plans, and vessels without wind, are forecast with the controls as given.
        """
        z_window = np.asarray(z_window, self.dtype)
        c_window = np.asarray(c_window, self.dtype)
        c_future = np.asarray(c_future, self.dtype)
        if c_future.ndim == 2:
            c_future = c_future[None]
        batch = c_future.shape[0]
        held = np.zeros(batch, bool) if hold_wind is None else np.asarray(hold_wind, bool)
        if held.shape != (batch,):
            raise ValueError(f'hold_wind must give one flag per plan ({batch}), got shape '
                             f'{held.shape}')
        # Each batch size is its own compiled program: pad to the next of a few sizes
        # so that serving never waits for a compile (warm_up compiles them up front).
        padded = next((b for b in self.batch_buckets if b >= batch), batch)
        if padded > batch:
            pad = np.repeat(c_future[-1:], padded - batch, axis=0)
            c_future = np.concatenate([c_future, pad], axis=0)
            held = np.concatenate([held, np.zeros(padded - batch, bool)])
        shards = self._shards(padded)
        size = padded // shards
        # Dispatch is asynchronous: every shard is running before the first is read. Each
        # runs on its parameters' device, where jax moves the NumPy inputs itself (an
        # explicit device_put cost a single forecast 0.2 of its 0.8 ms).
        turning = self._wind is not None and bool(held.any())
        running = [self._compiled(self._device_params[k], z_window, c_window,
                                  c_future[k * size:(k + 1) * size],
                                  held[k * size:(k + 1) * size], turning=turning)
                   for k in range(shards)]
        return Forecast(**{name: np.concatenate([np.asarray(part[name], np.float64)
                                                 for part in running])[:batch]
                           for name in running[0]})

    def forecast_each(self, z_window: np.ndarray, c_window: np.ndarray, c_future: np.ndarray,
                      progress=iter, seconds: list | None = None) -> Forecast:
        """
        Forecast B problems, each from its own window (a ``data.Windows``' arrays).

        Shapes (B, W, n_state), (B, W, n_control), (B, H, n_control); ``progress`` wraps
        the loop over problems (e.g. tqdm); ``seconds`` collects each forecast's time.
        """
        hybrid = np.empty(c_future.shape[:2] + (self.spec.n_state,))
        physics = np.empty_like(hybrid)
        available = np.empty(c_future.shape[:2]) if self.novelty_fade else None
        for i in progress(range(len(c_future))):
            started = time.perf_counter()
            out = self.forecast(z_window[i], c_window[i], c_future[i])
            if seconds is not None:
                seconds.append(time.perf_counter() - started)
            hybrid[i], physics[i] = out.hybrid[0], out.physics[0]
            if available is not None:
                available[i] = out.available[0]
        return Forecast(hybrid, physics, available=available)

    def _shards(self, padded: int) -> int:
        """Return how many devices a padded batch is split across (it divides evenly)."""
        shards = min(len(self.devices), padded // MIN_SHARD)
        while shards > 1 and padded % shards:
            shards -= 1
        return max(shards, 1)

    batch_buckets = (1, 4, 16, 64, 256)

    def warm_up(self, horizon: int, window: int = 60, max_batch: int = 256) -> None:
        """
        Compile every batch bucket up to ``max_batch`` now, so no forecast waits later.

        For a vessel with wind, both programs: plans as given, and plans holding the wind.
        """
        z = np.zeros((window, self.spec.n_state))
        c = np.zeros((window, self.spec.n_control))
        holds = (False,) if self._wind is None else (False, True)
        for batch in self.batch_buckets:
            if batch <= max(max_batch, 1):
                for held in holds:
                    self.forecast(z, c, np.zeros((batch, horizon, self.spec.n_control)),
                                  np.full(batch, held))
