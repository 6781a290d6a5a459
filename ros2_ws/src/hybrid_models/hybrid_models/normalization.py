"""
Per-channel affine normalization, x_n = (x - mean) / std, fitted on training data.

The statistics live in the model as buffers (so they travel with the weights into a
checkpoint and any exported inference engine) and in the JSON config for humans.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# A channel that never moves in the training data (e.g. wind switched off) would
# otherwise divide by zero; its normalized value is then simply x - mean.
MIN_STD = 1e-6


@dataclass
class Normalizer:
    """Mean and standard deviation of each channel (units of the channel)."""

    mean: np.ndarray
    std: np.ndarray

    @classmethod
    def fit(cls, x: np.ndarray) -> Normalizer:
        """Statistics of ``x`` (N, D) over its rows."""
        x = np.asarray(x, dtype=np.float64)
        return cls(mean=x.mean(axis=0), std=np.maximum(x.std(axis=0), MIN_STD))

    @classmethod
    def identity(cls, dim: int) -> Normalizer:
        """Mean 0, std 1 (placeholder until fitted)."""
        return cls(mean=np.zeros(dim), std=np.ones(dim))

    def to_dict(self) -> dict:
        """JSON-ready form."""
        return {'mean': self.mean.tolist(), 'std': self.std.tolist()}

    @classmethod
    def from_dict(cls, d: dict) -> Normalizer:
        """Inverse of ``to_dict``."""
        return cls(mean=np.asarray(d['mean'], float), std=np.asarray(d['std'], float))
