"""
Statistics of data seen a chunk at a time, in memory that does not grow with the data.

``Moments``: exact per-channel mean and standard deviation (Chan et al.'s pairwise
update in float64), equal to ``Normalizer.fit`` on the concatenated rows up to float
rounding. ``RowSample``: a uniform sample of at most ``capacity`` rows without
replacement (bottom-k of seeded random keys); while the data has no more rows than
that, it holds ALL of them in their original order, so anything computed from it
(physics fit, percentiles) is exactly what the whole data gives.
"""

from __future__ import annotations

import numpy as np

from hybrid_models.normalization import MIN_STD, Normalizer


class Moments:
    """Running count, mean and sum of squared deviations of each channel."""

    def __init__(self, dim: int):
        self.n = 0
        self.mean = np.zeros(dim)
        self.m2 = np.zeros(dim)

    def add(self, x: np.ndarray) -> None:
        """Take in rows ``x`` (N, dim)."""
        x = np.asarray(x, dtype=np.float64)
        if len(x) == 0:
            return
        n, mean = len(x), x.mean(axis=0)
        m2 = ((x - mean) ** 2).sum(axis=0)
        total = self.n + n
        delta = mean - self.mean
        self.mean = self.mean + delta * (n / total)
        self.m2 = self.m2 + m2 + delta ** 2 * (self.n * n / total)
        self.n = total

    def normalizer(self) -> Normalizer:
        """Mean and (population) std of everything added, as ``Normalizer.fit`` gives."""
        if self.n == 0:
            raise ValueError('no rows to compute statistics from')
        return Normalizer(mean=self.mean.copy(),
                          std=np.maximum(np.sqrt(self.m2 / self.n), MIN_STD))


class RowSample:
    """A uniform sample of at most ``capacity`` rows, all of them while they fit."""

    def __init__(self, capacity: int, seed: int = 0):
        if capacity < 1:
            raise ValueError(f'a row sample needs a capacity >= 1, got {capacity}')
        self.capacity = int(capacity)
        self.rng = np.random.default_rng(seed)
        self.seen = 0
        self._keys = np.zeros(0)
        self._order = np.zeros(0, dtype=np.int64)
        self._rows: np.ndarray | None = None

    def add(self, rows: np.ndarray) -> None:
        """Offer rows (N, D); keeps those with the ``capacity`` smallest random keys."""
        keys = self.rng.random(len(rows))
        order = np.arange(self.seen, self.seen + len(rows))
        self.seen += len(rows)
        if self._rows is None:
            self._rows = np.zeros((0,) + rows.shape[1:], dtype=rows.dtype)
        keys = np.concatenate([self._keys, keys])
        order = np.concatenate([self._order, order])
        kept = np.concatenate([self._rows, rows])
        if len(keys) > self.capacity:
            pick = np.argpartition(keys, self.capacity - 1)[:self.capacity]
            keys, order, kept = keys[pick], order[pick], kept[pick]
        self._keys, self._order, self._rows = keys, order, kept

    @property
    def complete(self) -> bool:
        """Return True while the sample holds every row offered."""
        return self.seen <= self.capacity

    def rows(self) -> np.ndarray:
        """Return the sampled rows in the order they were offered."""
        if self._rows is None:
            raise ValueError('no rows were offered')
        return self._rows[np.argsort(self._order, kind='stable')]
