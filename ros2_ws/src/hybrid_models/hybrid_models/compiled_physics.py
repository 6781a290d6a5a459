"""
A hybrid's physical part compiled with JAX for torch training: step and Jacobian at once.

During training the physical part learns nothing (a regression is fitted in closed form
before, first principles keep their parameters), so back-propagation through it needs
only the Jacobian of one sample period with respect to the state, dz_next/dz. Torch's
autograd records some hundreds of small operations per step of a first-principles model
and their backward dominates multistep training on a CPU; XLA runs the step and its
per-sample Jacobian (``jax.jacfwd``) as one compiled program instead, and torch gets
J^T g as the step's backward. The step is the model's one ``step`` (Array API), the
program the compiled forecaster (``hybrid_models.engine``) serves.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from hybrid_models.engine import compiled_repeat, jax_module
from hybrid_models.physical import PhysicalModel


def compile_step(model: PhysicalModel) -> Callable:
    """
    Return f(z, c) -> (z_next, dz_next/dz) of ``model`` (numpy in, numpy out), compiled.

    z (B, n_state), c (B, n_control); the Jacobian is (B, n_state, n_state). The learned
    values the model holds now are constants of the program.
    """
    jax = jax_module()
    arrays = {k: v if v.dtype == bool else jax.numpy.asarray(v, np.float32)
              for k, v in model.arrays().items()}

    def step(z, c):
        return model.step(z, c, arrays, compiled_repeat)

    def one(z1, c1):
        return step(z1[None], c1[None])[0]

    compiled = jax.jit(lambda z, c: (step(z, c), jax.vmap(jax.jacfwd(one))(z, c)))

    def call(z: np.ndarray, c: np.ndarray):
        z_next, jacobian = compiled(np.asarray(z, np.float32), np.asarray(c, np.float32))
        return np.array(z_next), np.array(jacobian)   # writable copies for torch
    return call


class CompiledStep(torch.autograd.Function):
    """One sample period of a compiled physical model; gradients flow to the state only."""

    @staticmethod
    def forward(ctx, z: torch.Tensor, c: torch.Tensor, step: Callable) -> torch.Tensor:
        """Return the next state; keep the Jacobian for the backward pass."""
        z_next, jacobian = step(z.detach().cpu().numpy(), c.detach().cpu().numpy())
        ctx.save_for_backward(torch.as_tensor(jacobian, dtype=z.dtype, device=z.device))
        return torch.as_tensor(z_next, dtype=z.dtype, device=z.device)

    @staticmethod
    def backward(ctx, grad: torch.Tensor):
        """Return J^T grad for the state; the controls and the step take none."""
        (jacobian,) = ctx.saved_tensors
        return torch.einsum('bi,bij->bj', grad, jacobian), None, None
