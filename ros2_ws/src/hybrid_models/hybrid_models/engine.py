"""
Compiled forecasts of a trained hybrid model, fast enough for online use and MPC.

The training code runs the hybrid model step by step in PyTorch, which costs a few
hundred microseconds of dispatch per step: a 900-step forecast would take a good part
of a second. This engine takes the trained weights and runs the same computation as
one XLA program (``jax.lax.scan`` over the horizon, ``jax.jit`` compiled once per batch
size), batched over candidate control plans.

It does not restate the model: the physical part calls the very ``vessel_physics``
force terms, mass matrix and RK4 step the simulator and the torch model use (they are
written against the Array API), and the regression features come from the torch
model's own ``FeatureMap``. What is written here is the standard LSTM cell (gate order
i, f, g, o, as torch.nn.LSTM) and the data flow of ``HybridModel.step``; a test holds
it equal to the torch model's forecast.

XLA runs one program on one host core, and programs on the same device run one after
the other. So that a batch of what-if plans uses every core, the engine asks XLA for
one host device per core (``--xla_force_host_platform_device_count`` in ``XLA_FLAGS``,
unless the user set it or jax was imported first) and splits batches of
``MIN_SHARD`` plans or more across the devices; a single forecast stays on one device.
Each plan's forecast is the same computation wherever it runs.
"""

from __future__ import annotations

from dataclasses import dataclass
import hashlib
import os
from pathlib import Path
import sys

import numpy as np

from hybrid_models.nets import HybridModel


@dataclass(frozen=True)
class Forecast:
    """Forecasts of B plans: hybrid states and the physical part of every step."""

    hybrid: np.ndarray    # (B, H, n_state)
    physics: np.ndarray   # (B, H, n_state); hybrid - physics is the bounded correction


DEVICE_COUNT_FLAG = '--xla_force_host_platform_device_count'
MIN_SHARD = 8   # plans per device below which splitting a batch costs more than it gains


def _jax():
    if 'jax' not in sys.modules and DEVICE_COUNT_FLAG not in os.environ.get('XLA_FLAGS', ''):
        cores = len(os.sched_getaffinity(0)) if hasattr(os, 'sched_getaffinity') else (
            os.cpu_count() or 1)
        os.environ['XLA_FLAGS'] = (os.environ.get('XLA_FLAGS', '') +
                                   f' {DEVICE_COUNT_FLAG}={cores}').strip()
    import jax

    return jax


def _lstm_weights(lstm, dtype) -> list[tuple]:
    """Per layer (W_ih^T, W_hh^T, b_ih + b_hh) of a torch.nn.LSTM, as arrays."""
    layers = []
    for k in range(lstm.num_layers):
        w_ih = getattr(lstm, f'weight_ih_l{k}').detach().double().numpy().T
        w_hh = getattr(lstm, f'weight_hh_l{k}').detach().double().numpy().T
        bias = (getattr(lstm, f'bias_ih_l{k}') + getattr(lstm, f'bias_hh_l{k}'))
        layers.append(tuple(np.asarray(a, dtype) for a in (w_ih, w_hh,
                                                            bias.detach().double().numpy())))
    return layers


def _physical_step(physical, dtype):
    """Return f(z, c) -> z_phy for the model's physical part, in jax.numpy."""
    from hybrid_models.physical.composite import CompositeModel
    from hybrid_models.physical.regression import RegressionModel

    if isinstance(physical, CompositeModel):
        first = _physical_step(physical.first_principles, dtype)
        second = _physical_step(physical.regression, dtype)
        return lambda z, c: first(z, c) + second(z, c)
    if isinstance(physical, RegressionModel):
        weight = np.asarray(physical.weight.detach().double().numpy().T, dtype)
        bias = np.asarray(physical.bias.detach().double().numpy(), dtype)
        features = physical.features.array_features
        return lambda z, c: features(z, c) @ weight + bias
    from hybrid_models.physical.integrated import IntegratedModel

    if isinstance(physical, IntegratedModel):
        jax = _jax()

        def repeat(n, body, x):
            return jax.lax.fori_loop(0, n, lambda _i, state: body(state), x)

        return lambda z, c: physical.array_step(z, c, repeat)
    raise TypeError(f'no compiled form for physical model {type(physical).__name__}')


class ForecastEngine:
    """
    Batched, compiled forecasts of a trained ``HybridModel``.

    ``forecast(z_window, c_window, c_future)`` takes one initialization window
    (W, n_state) and (W, n_control) and B plans of future controls (B, H, n_control),
    indexed as in ``hybrid_models.data``: c_future[:, 0] is the control at the last
    window sample. Computation runs in ``dtype`` (float32 by default, as trained).
    """

    def __init__(self, model: HybridModel, dtype=np.float32, model_id: str = '',
                 config: dict | None = None):
        if not isinstance(model, HybridModel):
            raise TypeError(f'the engine runs hybrid models, got {type(model).__name__}')
        jax = _jax()
        if dtype == np.float64:
            jax.config.update('jax_enable_x64', True)
        self.model = model.eval()
        self.spec = model.spec
        self.dtype = dtype
        self.model_id = model_id
        self.config = dict(config or {})
        self.bound = model.bound.detach().double().numpy().copy()

        def buffer(name):
            return np.asarray(getattr(model, name).detach().double().numpy(), dtype)

        self._params = {
            'state_mean': buffer('state_mean'), 'state_std': buffer('state_std'),
            'control_mean': buffer('control_mean'), 'control_std': buffer('control_std'),
            'residual_std': buffer('residual_std'),
            'bound': np.asarray(np.where(np.isfinite(self.bound), self.bound, 0.0), dtype),
            'head_w': np.asarray(model.head.weight.detach().double().numpy().T, dtype),
            'head_b': np.asarray(model.head.bias.detach().double().numpy(), dtype),
            'init': _lstm_weights(model.init, dtype),
            'lstm': _lstm_weights(model.lstm, dtype),
        }
        self._bounded = bool(np.isfinite(self.bound).any())
        self._finite_bound = np.isfinite(self.bound)
        self._mode = model.bound_mode
        self._physical = _physical_step(model.physical, dtype)
        self._compiled = jax.jit(self._forecast)
        self.devices = jax.devices('cpu')
        self._device_params = [jax.device_put(self._params, d) for d in self.devices]

    @classmethod
    def from_checkpoint(cls, path: str | Path, dtype=np.float32) -> ForecastEngine:
        """Load a hybrid checkpoint (never unpickles) and build its engine."""
        from hybrid_models.checkpoint import load_model

        model, config = load_model(path)
        digest = hashlib.sha256(Path(path).read_bytes()).hexdigest()[:12]
        return cls(model, dtype, model_id=f'{Path(path).stem}@{digest}', config=config)

    @property
    def window(self) -> int:
        """Return the initialization window the model was trained with (samples)."""
        run_config = self.config.get('training', {})   # the training run's whole config
        return int(run_config['training']['window'])

    # ------------------------------------------------------------------ the program
    @staticmethod
    def _cell(x, h, c, weights):
        jnp = _jax().numpy
        w_ih, w_hh, bias = weights
        gates = x @ w_ih + h @ w_hh + bias
        i, f, g, o = jnp.split(gates, 4, axis=-1)
        sig = _jax().nn.sigmoid
        c = sig(f) * c + sig(i) * jnp.tanh(g)
        return sig(o) * jnp.tanh(c), c

    def _stack(self, x, hs, cs, layers):
        new_h, new_c = [], []
        for k, weights in enumerate(layers):
            h, c = self._cell(x, hs[k], cs[k], weights)
            new_h.append(h)
            new_c.append(c)
            x = h
        return x, tuple(new_h), tuple(new_c)

    def _bound(self, res, p):
        jnp = _jax().numpy
        if not self._bounded:
            return res
        b = jnp.where(self._finite_bound, p['bound'], 1.0)
        if self._mode == 'tanh':
            limited = b * jnp.tanh(res / b)
        else:
            limited = jnp.clip(res, -b, b)
        return jnp.where(self._finite_bound, limited, res)

    def _forecast(self, p, z_window, c_window, c_future):
        jax = _jax()
        jnp = jax.numpy
        batch = c_future.shape[0]
        nz = lambda z: (z - p['state_mean']) / p['state_std']  # noqa: E731
        nc = lambda c: (c - p['control_mean']) / p['control_std']  # noqa: E731
        hidden = p['init'][0][1].shape[0]
        zeros = tuple(jnp.zeros((1, hidden), self.dtype) for _ in p['init'])

        def init_step(carry, x):
            _, hs, cs = self._stack(x[None, :], carry[0], carry[1], p['init'])
            return (hs, cs), None

        window_in = jnp.concatenate([nz(z_window), nc(c_window)], axis=-1)
        (hs, cs), _ = jax.lax.scan(init_step, (zeros, zeros), window_in)
        hs = tuple(jnp.broadcast_to(h, (batch, hidden)) for h in hs)
        cs = tuple(jnp.broadcast_to(c, (batch, hidden)) for c in cs)
        z0 = jnp.broadcast_to(z_window[-1], (batch, z_window.shape[-1]))

        def step(carry, c_t):
            z, hs, cs = carry
            z_phy = self._physical(z, c_t)
            y, hs, cs = self._stack(jnp.concatenate([nc(c_t), nz(z_phy)], axis=-1), hs, cs,
                                    p['lstm'])
            res = self._bound((y @ p['head_w'] + p['head_b']) * p['residual_std'], p)
            z_next = z_phy + res
            return (z_next, hs, cs), (z_next, z_phy)

        _, (hybrid, physics) = jax.lax.scan(step, (z0, hs, cs), jnp.swapaxes(c_future, 0, 1))
        return jnp.swapaxes(hybrid, 0, 1), jnp.swapaxes(physics, 0, 1)

    # ------------------------------------------------------------------ public API
    def forecast(self, z_window: np.ndarray, c_window: np.ndarray,
                 c_future: np.ndarray) -> Forecast:
        """Forecast every plan from one window; arrays in physical units (see class doc)."""
        z_window = np.asarray(z_window, self.dtype)
        c_window = np.asarray(c_window, self.dtype)
        c_future = np.asarray(c_future, self.dtype)
        if c_future.ndim == 2:
            c_future = c_future[None]
        batch = c_future.shape[0]
        # Each batch size is its own compiled program: pad to the next of a few sizes
        # so that serving never waits for a compile (warm_up compiles them up front).
        padded = next((b for b in self.batch_buckets if b >= batch), batch)
        if padded > batch:
            pad = np.repeat(c_future[-1:], padded - batch, axis=0)
            c_future = np.concatenate([c_future, pad], axis=0)
        shards = self._shards(padded)
        size = padded // shards
        jax = _jax()
        # Dispatch is asynchronous: every shard is running before the first is read.
        running = [self._compiled(self._device_params[k], *jax.device_put(
            (z_window, c_window, c_future[k * size:(k + 1) * size]), self.devices[k]))
            for k in range(shards)]
        hybrid = np.concatenate([np.asarray(h, np.float64) for h, _ in running])
        physics = np.concatenate([np.asarray(p, np.float64) for _, p in running])
        return Forecast(hybrid[:batch], physics[:batch])

    def _shards(self, padded: int) -> int:
        """Return how many devices a padded batch is split across (it divides evenly)."""
        shards = min(len(self.devices), padded // MIN_SHARD)
        while shards > 1 and padded % shards:
            shards -= 1
        return max(shards, 1)

    batch_buckets = (1, 4, 16, 64, 256)

    def warm_up(self, horizon: int, window: int = 60, max_batch: int = 256) -> None:
        """Compile every batch bucket up to ``max_batch`` now, so no forecast waits later."""
        z = np.zeros((window, self.spec.n_state))
        c = np.zeros((window, self.spec.n_control))
        for batch in self.batch_buckets:
            if batch <= max(max_batch, 1):
                self.forecast(z, c, np.zeros((batch, horizon, self.spec.n_control)))
