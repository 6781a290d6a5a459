"""Regression components fitted in closed form: z_{t+1} (or a residual) = W f(z, c) + b."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.physical.features import FeatureMap
from hybrid_models.physical.stability import constrained_ridge, envelope_points, feature_slopes
from vessel_description import Vessel


def ridge_lstsq(x: np.ndarray, y: np.ndarray, ridge: float,
                slopes: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """
    Least squares y ~ x w + b on standardized columns; return (w, b) in raw units.

    ``ridge`` is relative: the penalty is ridge * N * |w_std|^2 on the standardized
    weights, so its meaning does not change with the amount of data or feature scales.
    ``slopes`` (P, k), raw units: constrain slopes w <= 1 (``stability.constrained_ridge``).
    """
    mean, std = x.mean(axis=0), x.std(axis=0)
    std = np.where(std > 0, std, 1.0)
    xs = (x - mean) / std
    y_mean = y.mean()
    n, k = xs.shape
    if ridge > 0:
        augmented = np.vstack([xs, np.sqrt(ridge * n) * np.eye(k)])
        yc = np.concatenate([y - y_mean, np.zeros(k)])
    else:
        augmented, yc = xs, y - y_mean
    w_std = np.linalg.lstsq(augmented, yc, rcond=None)[0]
    if slopes is not None:
        w_std = constrained_ridge(xs, y - y_mean, ridge, slopes / std, w_std)
    w = w_std / std
    return w, float(y_mean - mean @ w)


class RegressionModel(PhysicalModel):
    """Linear-in-parameters model over a named feature map, one row per state."""

    def __init__(self, spec: Vessel, features: str = 'lin', ridge: float = 1e-8,
                 masks: str = 'coupled', damped: bool = False):
        super().__init__(spec)
        self.kind = features
        self.ridge = float(ridge)
        self.damped = bool(damped)
        self.features = FeatureMap(spec, features, masks)
        n_feat = len(self.features.names)
        self._arrays = {'weight': np.zeros((spec.n_state, n_feat)),
                        'bias': np.zeros(spec.n_state), 'fitted': np.zeros((), bool)}

    def step(self, z, c, arrays: Mapping, repeat=None):
        """W f(z, c) + b."""
        return self.features.array_features(z, c) @ arrays['weight'].T + arrays['bias']

    def fit(self, z: np.ndarray, c: np.ndarray, target: np.ndarray) -> RegressionModel:
        """
        Least squares on rows (z, c) -> target (N, n_state), each state on its mask.

        Damped (``damped``; the target must be the next state): each state's own one-step
        gain is kept <= 1 over the vessel's envelope (``physical.stability``).
        """
        z, c = np.asarray(z, np.float64), np.asarray(c, np.float64)
        phi = self.features.array_features(z, c)
        mask = self.features.mask_matrix()
        weight = np.zeros_like(self._arrays['weight'])
        bias = np.zeros_like(self._arrays['bias'])
        points = envelope_points(z, self.spec.limits, self.spec.state_names) \
            if self.damped else None
        for i in range(self.spec.n_state):
            cols = np.flatnonzero(mask[i])
            slopes = None
            if points is not None:
                slopes = feature_slopes(self.features.array_features, points,
                                        np.zeros((len(points), c.shape[1])), i)[:, cols]
            weight[i, cols], bias[i] = ridge_lstsq(phi[:, cols], target[:, i], self.ridge,
                                                   slopes)
        self._arrays.update(weight=weight, bias=bias, fitted=np.ones((), bool))
        return self

    def coefficients(self) -> dict[str, dict[str, float]]:
        """Fitted coefficients by state and feature name (masked-out terms omitted)."""
        mask = self.features.mask_matrix()
        weight, bias = self._arrays['weight'], self._arrays['bias']
        out = {}
        for i, state in enumerate(self.spec.state_names):
            row = {n: float(weight[i, j]) for j, n in enumerate(self.features.names)
                   if mask[i, j]}
            row['1'] = float(bias[i])
            out[state] = row
        return out

    def describe(self) -> dict:
        """Return the construction arguments."""
        return {'kind': self.kind, 'ridge': self.ridge, 'masks': self.features.mask_mode,
                'damped': self.damped}
