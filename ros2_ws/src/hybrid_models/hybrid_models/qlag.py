"""
Quadratic control lag model (QLag) of Punjani & Abbeel (2015), the physical baseline.

z_{t+1} - z_t = W f_t + b with the lagged features
f_t = [z_{t-L+1..t}, c_{t-L+1..t}, (c_{t-L+1..t})^2] (squares element-wise), fitted by
least squares on all one-step pairs of the training runs and run multistep by feeding
its own predictions back. Predicting the increment keeps a small ridge penalty from
pulling the model towards z_{t+1} = 0.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from hybrid_models.data import RunArrays
from hybrid_models.physical.regression import ridge_lstsq
from vessel_description import Vessel


class QLag(nn.Module):
    """Lagged linear model with quadratic control terms; ``fit`` then ``forecast``."""

    kind = 'qlag'

    def __init__(self, spec: Vessel, lag: int = 4, ridge: float = 1e-8):
        super().__init__()
        if lag < 1:
            raise ValueError(f'lag must be >= 1, got {lag}')
        self.spec, self.lag, self.ridge = spec, int(lag), float(ridge)
        n_feat = lag * (spec.n_state + 2 * spec.n_control)
        self.register_buffer('weight', torch.zeros(spec.n_state, n_feat))
        self.register_buffer('bias', torch.zeros(spec.n_state))

    @property
    def feature_names(self) -> list[str]:
        """Names of the lagged features (``x[t-k]``), in column order."""
        names = []
        for k in range(self.lag - 1, -1, -1):
            tag = f'[t-{k}]' if k else '[t]'
            names += [s + tag for s in self.spec.state_names]
            names += [c + tag for c in self.spec.control_names]
            names += [f'{c}^2' + tag for c in self.spec.control_names]
        return names

    @staticmethod
    def _features(z_hist, c_hist):
        """Features from histories (B, L, .) ordered oldest first."""
        lib = torch if isinstance(z_hist, torch.Tensor) else np
        cat = lib.cat if lib is torch else np.concatenate
        per_step = cat([z_hist, c_hist, c_hist * c_hist], -1)
        return per_step.reshape(per_step.shape[0], -1)

    def fit(self, runs: list[RunArrays]) -> QLag:
        """Least squares on every (history, next state) pair of the runs."""
        feats, targets = [], []
        for run in runs:
            t = np.arange(self.lag - 1, run.length - 1)
            idx = t[:, None] + np.arange(-self.lag + 1, 1)
            feats.append(self._features(run.z[idx].astype(np.float64),
                                        run.c[idx].astype(np.float64)))
            targets.append(run.z[t + 1].astype(np.float64) - run.z[t])
        x, y = np.concatenate(feats), np.concatenate(targets)
        w = np.zeros(self.weight.shape)
        b = np.zeros(self.bias.shape)
        for i in range(self.spec.n_state):
            w[i], b[i] = ridge_lstsq(x, y[:, i], self.ridge)
        self.weight.copy_(torch.as_tensor(w))
        self.bias.copy_(torch.as_tensor(b))
        return self

    def forecast(self, z_window: torch.Tensor, c_window: torch.Tensor,
                 c_future: torch.Tensor) -> torch.Tensor:
        """Multistep prediction; history is the window's tail, then its own output."""
        z_hist = z_window[:, -self.lag:]
        # c_window[:, -1] is c[t0-1] = c_future[:, 0]; controls are known ahead.
        c_all = torch.cat([c_window[:, :-1], c_future], dim=1)
        first = c_window.shape[1] - 1
        out = []
        for k in range(c_future.shape[1]):
            c_hist = c_all[:, first + k - self.lag + 1:first + k + 1]
            z_next = z_hist[:, -1] + self._features(z_hist, c_hist) @ self.weight.T + self.bias
            out.append(z_next)
            z_hist = torch.cat([z_hist[:, 1:], z_next.unsqueeze(1)], dim=1)
        return torch.stack(out, dim=1)

    def describe(self) -> dict:
        """Return the construction arguments."""
        return {'kind': self.kind, 'lag': self.lag, 'ridge': self.ridge}
