"""
Recurrent forecasters: the LSTM baseline and the hybrid residual model.

Both are stacks of one recurrent cell (``hybrid_models.recurrent``: the paper's LSTM by
default, or a GRU), trained by torch's fused module, with an initializer stack after
Mohajerin & Waslander (2019): it reads the initialization window of normalized states
and controls, and its final state of every layer is the predictor stack's initial state
(same cell, layers and hidden size, so no mapping is needed). The hybrid's fed-back
steps run ``hybrid_models.hybrid_step`` on the same weights, the one step the compiled
forecaster serves; teacher forcing keeps the fused call. The predictor stack is the
module ``lstm`` whatever its cell, so that checkpoints keep the paper's names.

Normalization (buffers, fitted on training data): x_n = (x - mean) / std for states
and controls; the network's output y becomes a state (LSTM) or a residual (hybrid) as
y * std, with the state std or the std of the physical model's one-step residual.

Every model offers ``forecast(z_window, c_window, c_future)`` with the indexing of
``hybrid_models.data``: windows (B, W, .), controls c[t0-1:t0-1+H] (B, H, n_control),
returning the states z[t0:t0+H] (B, H, n_state) in physical units.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torch import nn

from hybrid_models.bound import (
    ServedThreshold,
    half_width,
    is_constant,
    schedule_of,
    step_bounds,
)
from hybrid_models.compiled_physics import CompiledStep, compile_step
from hybrid_models.hybrid_step import bounded_residual, hybrid_step, step_weights
from hybrid_models.normalization import Normalizer
from hybrid_models.novelty import Novelty
from hybrid_models.physical import PhysicalModel
from hybrid_models.recurrent import cell_of, from_torch, torch_stack
from vessel_description import Vessel

CORRECTION_INITS = ('zero', 'random')


class _Normalized(nn.Module):
    """Holds the normalization buffers shared by the recurrent models."""

    def __init__(self, spec: Vessel):
        super().__init__()
        self.spec = spec
        for name, dim in (('state', spec.n_state), ('control', spec.n_control)):
            self.register_buffer(f'{name}_mean', torch.zeros(dim))
            self.register_buffer(f'{name}_std', torch.ones(dim))

    def set_normalization(self, state: Normalizer, control: Normalizer) -> None:
        """Copy fitted statistics into the buffers."""
        for name, norm in (('state', state), ('control', control)):
            getattr(self, f'{name}_mean').copy_(torch.as_tensor(norm.mean))
            getattr(self, f'{name}_std').copy_(torch.as_tensor(norm.std))

    def nz(self, z: torch.Tensor) -> torch.Tensor:
        """Normalize a state."""
        return (z - self.state_mean) / self.state_std

    def nc(self, c: torch.Tensor) -> torch.Tensor:
        """Normalize a control."""
        return (c - self.control_mean) / self.control_std

    def initial_state(self, init: nn.Module, z_window: torch.Tensor, c_window: torch.Tensor):
        """Return the initializer's final state after the window (torch's form)."""
        _, final = init(torch.cat([self.nz(z_window), self.nc(c_window)], dim=-1))
        return final


class PhysicalModule(nn.Module):
    """
    A physical model inside a torch model: its learned values as buffers.

    The model itself is framework-free (``hybrid_models.physical``); this module keeps
    its arrays as buffers named like them (``weight``, ``regression.weight``), so they
    move with ``.to()``/``.double()`` and live in the hybrid's state dict, and runs the
    model's one ``step`` on them.
    """

    def __init__(self, model: PhysicalModel):
        super().__init__()
        self.model = model
        for name, value in model.arrays().items():
            owner = self
            *path, leaf = name.split('.')
            for child in path:
                if not hasattr(owner, child):
                    owner.add_module(child, nn.Module())
                owner = getattr(owner, child)
            tensor = torch.as_tensor(value)
            owner.register_buffer(leaf, tensor.float() if tensor.is_floating_point()
                                  else tensor)
        self.spec, self.kind = model.spec, model.kind
        self.compiled = None

    def compile(self) -> None:
        """
        Run the step as one compiled program with its Jacobian (``compiled_physics``).

        For training on a CPU once the model is fitted: its values are constants of the
        program, so ``fit`` or a new state dict afterwards needs another ``compile``.
        """
        self.compiled = compile_step(self.numpy_model())

    def forward(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """Predict the next state with the buffers' values."""
        if self.compiled is not None:
            return CompiledStep.apply(z, c, self.compiled)
        return self.model.step(z, c, dict(self.named_buffers()))

    def fit(self, z: np.ndarray, c: np.ndarray, z_next: np.ndarray) -> PhysicalModule:
        """Fit the model (numpy, float64) and copy what it learned into the buffers."""
        self.model.fit(z, c, z_next)
        buffers = dict(self.named_buffers())
        with torch.no_grad():
            for name, value in self.model.arrays().items():
                buffers[name].copy_(torch.as_tensor(value))
        return self

    def numpy_model(self) -> PhysicalModel:
        """Return the framework-free model holding the buffers' current values."""
        return self.model.load_arrays({k: v.detach().cpu().numpy()
                                       for k, v in self.named_buffers()})

    def describe(self) -> dict:
        """Return the model's construction arguments."""
        return self.model.describe()


class LSTMBaseline(_Normalized):
    """
    Stacked LSTM (or ``cell``) with an initializer (Mohajerin & Waslander 2019).

    The predictor sees only the controls; its output is the normalized state.
    """

    kind = 'lstm'

    def __init__(self, spec: Vessel, hidden: int = 64, layers: int = 2,
                 dropout: float = 0.25, cell: str = 'lstm'):
        super().__init__(spec)
        self.hidden, self.layers, self.dropout = hidden, layers, dropout
        self.cell = cell_of(cell)
        self.init = torch_stack(self.cell, spec.n_state + spec.n_control, hidden, layers,
                                dropout)
        self.lstm = torch_stack(self.cell, spec.n_control, hidden, layers, dropout)
        self.head = nn.Linear(hidden, spec.n_state)

    def forecast(self, z_window: torch.Tensor, c_window: torch.Tensor,
                 c_future: torch.Tensor) -> torch.Tensor:
        """States over the horizon; no feedback, so one fused call."""
        y, _ = self.lstm(self.nc(c_future), self.initial_state(self.init, z_window, c_window))
        return self.head(y) * self.state_std + self.state_mean

    def describe(self) -> dict:
        """Architecture (``build_model`` input)."""
        return {'kind': self.kind, 'cell': self.cell.name, 'hidden': self.hidden,
                'layers': self.layers, 'dropout': self.dropout}


def roll_out(step, z: torch.Tensor, c_future: torch.Tensor, recurrent,
             bounds: torch.Tensor | None, return_parts: bool = False):
    """
    Feed ``step`` its own output over the horizon: the hybrids' multistep forecast.

    ``step(z, c, recurrent, bound)`` returns (z_next, z_phy, residual, recurrent), as
    ``hybrid_step`` does; z (B, n_state) is the last measured state, c_future
    (B, H, n_control), bounds (H, ...) one row a step or None for the served ones. Returns
    the states (B, H, n_state) and, with ``return_parts``, z_phy and the residuals too.
    """
    zs, phys, ress = [], [], []
    for k in range(c_future.shape[1]):
        z, z_phy, res, recurrent = step(z, c_future[:, k], recurrent,
                                        None if bounds is None else bounds[k])
        zs.append(z)
        phys.append(z_phy)
        ress.append(res)
    out = torch.stack(zs, dim=1)
    if return_parts:
        return out, torch.stack(phys, dim=1), torch.stack(ress, dim=1)
    return out


class HybridModel(_Normalized, ServedThreshold):
    """
    Residual hybrid of Baier et al.: z_{t+1} = z_phy_{t+1} + bound(LSTM residual).

    Per step: z_phy = physical(z_t, c_t); the predictor stack reads the normalized
    (c_t, z_phy) and its linear head gives the residual; the residual is limited to
    [-b, b] per state (``hybrid_models.bound``) and added. During multistep
    prediction the sum is fed back as the next z_t.

    ``correction_init`` 'zero' (the default) starts the head at exactly zero, so an
    untrained hybrid forecasts what its physics does and training moves away from the
    physics only as far as the data asks; 'random' keeps torch's initialization.
    """

    kind = 'hybrid'

    def __init__(self, spec: Vessel, physical: PhysicalModel, hidden: int = 64,
                 layers: int = 2, dropout: float = 0.25, bound_mode: str = 'tanh',
                 bound_in_training: bool = False, correction_init: str = 'zero',
                 cell: str = 'lstm', novelty_fade: bool = False):
        super().__init__(spec)
        if correction_init not in CORRECTION_INITS:
            raise ValueError(f'correction_init must be one of {CORRECTION_INITS}, got '
                             f'{correction_init!r}')
        self.physical = PhysicalModule(physical)
        self.hidden, self.layers, self.dropout = hidden, layers, dropout
        self.bound_mode, self.bound_in_training = bound_mode, bool(bound_in_training)
        self.cell = cell_of(cell)
        self.init = torch_stack(self.cell, spec.n_state + spec.n_control, hidden, layers,
                                dropout)
        self.lstm = torch_stack(self.cell, spec.n_control + spec.n_state, hidden, layers,
                                dropout)
        self.head = nn.Linear(hidden, spec.n_state)
        self.correction_init = correction_init
        if correction_init == 'zero':
            nn.init.zeros_(self.head.weight)
            nn.init.zeros_(self.head.bias)
        self.register_buffer('residual_std', torch.ones(spec.n_state))
        # The physical model's 95 % output range R_i and the bound b_i = T R_i / 2.
        self.register_buffer('output_range', torch.full((spec.n_state,), math.nan))
        self.register_buffer('bound', torch.full((spec.n_state,), math.inf))
        self.relative_threshold = None   # T, None or a schedule (hybrid_models.bound)
        # Where the correction was trained (hybrid_models.novelty): the calibration,
        # stored in the checkpoint's config, and whether the served bound fades by it.
        self.novelty: Novelty | None = None
        self.novelty_fade = bool(novelty_fade)

    def set_threshold(self, relative_threshold) -> None:
        """
        Constrain the residual to T R / 2 per state (None: unconstrained; 0: physics).

        A schedule [[0, T1], [start_s, T2], ...] changes T along the forecast
        (``bound.step_bounds``); the ``bound`` buffer then holds its last entry's.
        """
        last = schedule_of(relative_threshold)[-1][1]
        b = half_width(last, self.output_range.double().numpy())
        self.bound.copy_(torch.as_tensor(b, dtype=self.bound.dtype))
        self.relative_threshold = relative_threshold

    def step_bounds(self, horizon: int) -> torch.Tensor | None:
        """Half-widths (horizon, n_state) of the served threshold; None when constant."""
        if is_constant(self.relative_threshold):
            return None
        return self.bounds_at(self.relative_threshold, horizon)

    def bounds_at(self, relative_threshold, horizon: int) -> torch.Tensor:
        """Half-widths (horizon, n_state) of any threshold or schedule (inf: unbounded)."""
        b = step_bounds(relative_threshold, self.output_range.double().numpy(),
                        self.spec.dt, horizon)
        return torch.as_tensor(b, dtype=self.bound.dtype, device=self.bound.device)

    def _bound_mode(self) -> str | None:
        """Return the bound to apply now (None while training unconstrained)."""
        return None if self.training and not self.bound_in_training else self.bound_mode

    def start(self, z_window: torch.Tensor, c_window: torch.Tensor) -> tuple:
        """Return the predictor's recurrent state after the window (``recurrent``'s form)."""
        return from_torch(self.cell, self.initial_state(self.init, z_window, c_window))

    def step(self, z: torch.Tensor, c: torch.Tensor, recurrent: tuple,
             weights: dict | None = None, bound: torch.Tensor | None = None):
        """One sample period (``hybrid_models.hybrid_step``): (z_next, z_phy, res, state)."""
        weights = weights if weights is not None else self.step_weights()
        return hybrid_step(self.cell, weights, self.physical, z, c, recurrent,
                           self._bound_mode(), self._between_layers(), bound)

    def step_weights(self) -> dict:
        """Return the step's weights as views of the parameters (gradients flow)."""
        return step_weights(self.cell,
                            dict(self.named_parameters()) | dict(self.named_buffers()),
                            self.layers, self.served_novelty())

    def served_novelty(self) -> dict | None:
        """Return the fade's ``Novelty.weights`` as tensors when it is served, else None."""
        if not self.novelty_fade:
            return None
        if self.novelty is None:
            raise ValueError('the novelty fade is on but the model has no novelty calibration '
                             '(train it again)')
        return self.novelty.weights(lambda a: torch.as_tensor(
            a, dtype=self.bound.dtype, device=self.bound.device))

    def _between_layers(self):
        # The fused module's dropout between stacked layers, which teacher forcing applies.
        if not self.training or self.layers < 2 or self.lstm.dropout == 0:
            return None
        return lambda x: nn.functional.dropout(x, self.lstm.dropout, training=True)

    def forecast(self, z_window: torch.Tensor, c_window: torch.Tensor,
                 c_future: torch.Tensor, return_parts: bool = False,
                 bounds: torch.Tensor | None = None):
        """
        Multistep prediction with feedback; ``return_parts`` adds (z_phy, residual).

        ``bounds``: half-widths per step (H, n_state) or per step and row (H, B, n_state)
        instead of the served threshold's (``bounds_at``), e.g. to forecast the same
        windows at several thresholds in one batch.
        """
        recurrent = self.start(z_window, c_window)
        weights = self.step_weights()
        if bounds is None:
            bounds = self.step_bounds(c_future.shape[1])
        return roll_out(lambda z, c, state, bound: self.step(z, c, state, weights, bound),
                        z_window[:, -1], c_future, recurrent, bounds, return_parts)

    def teacher_forced(self, z_window: torch.Tensor, c_window: torch.Tensor,
                       c_future: torch.Tensor, z_phy: torch.Tensor) -> torch.Tensor:
        """
        Residuals (B, L, n_state) given the physical one-step outputs from TRUE states.

        Phase 1 of the two-phase training: z_phy does not depend on the network, so
        the whole sequence is one fused call.
        """
        y, _ = self.lstm(torch.cat([self.nc(c_future), self.nz(z_phy)], dim=-1),
                         self.initial_state(self.init, z_window, c_window))
        return bounded_residual(y, self.step_weights(), self._bound_mode())

    def describe(self) -> dict:
        """Architecture and constraint (``build_model`` input)."""
        return {'kind': self.kind, 'cell': self.cell.name, 'hidden': self.hidden,
                'layers': self.layers, 'dropout': self.dropout,
                'physical': self.physical.describe(),
                'bound_mode': self.bound_mode, 'bound_in_training': self.bound_in_training,
                'correction_init': self.correction_init,
                'relative_threshold': self.relative_threshold,
                'novelty_fade': self.novelty_fade}


def count_parameters(model: nn.Module) -> int:
    """Trainable parameters."""
    return int(sum(p.numel() for p in model.parameters() if p.requires_grad))


def as_tensor(x: np.ndarray | torch.Tensor, device: torch.device | None = None
              ) -> torch.Tensor:
    """float32 tensor of an array on ``device`` (a view when on the CPU already)."""
    return torch.as_tensor(x, dtype=torch.float32, device=device)


def module_device(module: nn.Module) -> torch.device:
    """Return the device of a module's first parameter or buffer (the CPU if none)."""
    for tensor in (*module.parameters(), *module.buffers()):
        return tensor.device
    return torch.device('cpu')
