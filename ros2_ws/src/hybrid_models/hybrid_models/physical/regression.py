"""Regression components fitted in closed form: z_{t+1} (or a residual) = W f(z, c) + b."""

from __future__ import annotations

import numpy as np
import torch

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.physical.features import FeatureMap
from hybrid_models.vehicle import VehicleSpec


def ridge_lstsq(x: np.ndarray, y: np.ndarray, ridge: float) -> tuple[np.ndarray, float]:
    """
    Least squares y ~ x w + b on standardized columns; return (w, b) in raw units.

    ``ridge`` is relative: the penalty is ridge * N * |w_std|^2 on the standardized
    weights, so its meaning does not change with the amount of data or feature scales.
    """
    mean, std = x.mean(axis=0), x.std(axis=0)
    std = np.where(std > 0, std, 1.0)
    xs = (x - mean) / std
    y_mean = y.mean()
    if ridge > 0:
        n, k = xs.shape
        xs = np.vstack([xs, np.sqrt(ridge * n) * np.eye(k)])
        yc = np.concatenate([y - y_mean, np.zeros(k)])
    else:
        yc = y - y_mean
    w_std = np.linalg.lstsq(xs, yc, rcond=None)[0]
    w = w_std / std
    return w, float(y_mean - mean @ w)


class RegressionModel(PhysicalModel):
    """Linear-in-parameters model over a named feature map, one row per state."""

    def __init__(self, spec: VehicleSpec, features: str = 'lin', ridge: float = 1e-8,
                 masks: str = 'coupled'):
        super().__init__(spec)
        self.kind = features
        self.ridge = float(ridge)
        self.features = FeatureMap(spec, features, masks)
        n_feat = len(self.features.names)
        self.register_buffer('weight', torch.zeros(spec.n_state, n_feat))
        self.register_buffer('bias', torch.zeros(spec.n_state))
        self.register_buffer('fitted', torch.zeros((), dtype=torch.bool))

    def forward(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """W f(z, c) + b."""
        return self.features(z, c) @ self.weight.T + self.bias

    def fit(self, z: np.ndarray, c: np.ndarray, target: np.ndarray) -> RegressionModel:
        """Least squares on rows (z, c) -> target (N, n_state), each state on its mask."""
        with torch.no_grad():
            phi = self.features(torch.as_tensor(z, dtype=torch.float64),
                                torch.as_tensor(c, dtype=torch.float64)).numpy()
        mask = self.features.mask_matrix().numpy()
        weight = np.zeros(self.weight.shape)
        bias = np.zeros(self.bias.shape)
        for i in range(self.spec.n_state):
            cols = np.flatnonzero(mask[i])
            weight[i, cols], bias[i] = ridge_lstsq(phi[:, cols], target[:, i], self.ridge)
        self.weight.copy_(torch.as_tensor(weight, dtype=self.weight.dtype))
        self.bias.copy_(torch.as_tensor(bias, dtype=self.bias.dtype))
        self.fitted.fill_(True)
        return self

    def coefficients(self) -> dict[str, dict[str, float]]:
        """Fitted coefficients by state and feature name (masked-out terms omitted)."""
        mask = self.features.mask_matrix()
        out = {}
        for i, state in enumerate(self.spec.state_names):
            row = {n: float(self.weight[i, j]) for j, n in enumerate(self.features.names)
                   if mask[i, j]}
            row['1'] = float(self.bias[i])
            out[state] = row
        return out

    def describe(self) -> dict:
        """Return the construction arguments."""
        return {'kind': self.kind, 'ridge': self.ridge, 'masks': self.features.mask_mode}
