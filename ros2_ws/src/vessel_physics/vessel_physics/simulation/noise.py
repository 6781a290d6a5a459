"""
Gaussian sensor noise on the measured outputs, one random stream per run.

Noise is drawn in blocks per run from the run's own generator, so the sequence of a run
is the same whether it is simulated alone or in a batch.
"""

from __future__ import annotations

import numpy as np

BLOCK = 64  # samples drawn per run at a time


class SensorNoise:
    """
    Noise vectors (n_runs, channels) for successive samples.

    The channels are those of ``cfg.std`` in its order (``config.measured_channels``: the
    vessel's states, psi, x, y, its actuators, then wind_speed and wind_dir, the angle
    the wind comes from, perturbed before taking cos and sin).
    """

    def __init__(self, rngs: list[np.random.Generator], cfg):
        self._rngs = rngs
        self.enabled = cfg.enabled
        self.channels = tuple(cfg.std)
        self.sigma = np.array([cfg.std[c] for c in self.channels]) if cfg.enabled else None
        self._block = None
        self._index = BLOCK

    def next(self) -> np.ndarray:
        """Return the noise of the next sample (zeros when noise is disabled)."""
        width = len(self.channels)
        if not self.enabled:
            return np.zeros((len(self._rngs), width))
        if self._index == BLOCK:
            self._block = np.stack([rng.standard_normal((BLOCK, width))
                                    for rng in self._rngs], axis=1) * self.sigma
            self._index = 0
        out = self._block[self._index]
        self._index += 1
        return out
