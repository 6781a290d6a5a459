"""
Gaussian sensor noise on the measured outputs, one random stream per run.

Noise is drawn in blocks per run from the run's own generator, so the sequence of a run
is the same whether it is simulated alone or in a batch.
"""

from __future__ import annotations

import numpy as np

# Measured channels in the order of the noise vector. wind_dir is the angle the wind
# comes from relative to the bow (rad), perturbed before taking cos and sin.
CHANNELS = ('u', 'v', 'p', 'r', 'phi', 'psi', 'x', 'y', 'n', 'delta_port', 'delta_stbd',
            'wind_speed', 'wind_dir')
BLOCK = 64  # samples drawn per run at a time


class SensorNoise:
    """Noise vectors (n_runs, len(CHANNELS)) for successive samples."""

    def __init__(self, rngs: list[np.random.Generator], cfg):
        self._rngs = rngs
        self.enabled = cfg.enabled
        self.sigma = np.array([cfg.std[c] for c in CHANNELS]) if cfg.enabled else None
        self._block = None
        self._index = BLOCK

    def next(self) -> np.ndarray:
        """Return the noise of the next sample (zeros when noise is disabled)."""
        if not self.enabled:
            return np.zeros((len(self._rngs), len(CHANNELS)))
        if self._index == BLOCK:
            self._block = np.stack([rng.standard_normal((BLOCK, len(CHANNELS)))
                                    for rng in self._rngs], axis=1) * self.sigma
            self._index = 0
        out = self._block[self._index]
        self._index += 1
        return out
