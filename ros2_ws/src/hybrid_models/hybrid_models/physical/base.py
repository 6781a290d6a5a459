"""The physical-model interface shared by first-principles and regression components."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from hybrid_models.vehicle import VehicleSpec


class PhysicalModel(nn.Module):
    """
    One sample period of a physical model: z_phy_{t+1} = f(z_t, c_t).

    ``forward`` takes the state ``z`` (B, n_state) and the control ``c`` (B, n_control),
    held constant over the period, in the vehicle's units, and returns the state one
    sample period later (B, n_state). Everything a fitted model learned lives in
    buffers, so ``state_dict`` plus ``describe()`` rebuild it exactly.
    """

    kind = 'abstract'

    def __init__(self, spec: VehicleSpec):
        super().__init__()
        self.spec = spec

    def forward(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """Predict the next state."""
        raise NotImplementedError

    def fit(self, z: np.ndarray, c: np.ndarray, z_next: np.ndarray) -> PhysicalModel:
        """Fit learnable parts on one-step pairs (N rows each); a no-op for pure physics."""
        return self

    def describe(self) -> dict:
        """JSON-ready construction arguments (``build_physical`` input)."""
        return {'kind': self.kind}

    @torch.no_grad()
    def predict(self, z: np.ndarray, c: np.ndarray, batch: int = 65536) -> np.ndarray:
        """Numpy convenience: one-step predictions for N rows, in chunks."""
        floats = [b.dtype for b in self.buffers() if b.is_floating_point()]
        dtype = floats[0] if floats else torch.float64
        out = []
        for i in range(0, len(z), batch):
            zi = torch.tensor(np.asarray(z[i:i + batch]), dtype=dtype)
            ci = torch.tensor(np.asarray(c[i:i + batch]), dtype=dtype)
            out.append(self(zi, ci).numpy())
        return np.concatenate(out) if out else np.zeros((0, self.spec.n_state))
