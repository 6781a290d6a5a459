"""
Where the correction was trained: a bound that fades outside its training inputs.

Each step the correction reads x = [(c - c_mean) / c_std, (z_phy - z_mean) / z_std]
(``hybrid_step.correction_input``). Its novelty is the RMS Mahalanobis distance

    d(x) = sqrt((x - m)^T S^-1 (x - m) / n),     n = len(x),

with m and S the mean and covariance (plus ``RIDGE`` I) of the training runs' inputs,
teacher-forced from measured states (mirror images included where training used them).
The radius r is the largest d over the training and the validation runs' inputs. A
model served with the fade (``model.novelty_fade``) scales its bound at every step by

    a(x) = min(1, r / d(x)),

the share of the bound available: the plain bound wherever the inputs lie within what
training and validation covered (every training input), half of it at twice the radius.
Training calibrates every hybrid (the checkpoint's ``novelty``); ``set_novelty`` turns
the fade on or off. Written against the Array API: training (torch) and serving (jax)
run this one code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vessel_physics.arrays import namespace

# On the normalised inputs (unit variance each): keeps S invertible where two inputs
# move together or one never moved in training (a control held constant), without
# changing distances along the directions that did vary.
RIDGE = 1.0e-3


@dataclass(frozen=True)
class Novelty:
    """The correction inputs' mean m (n,), whitening W (n, n) with W W^T = S^-1, radius r."""

    mean: np.ndarray
    whiten: np.ndarray
    radius: float
    source: str = ''

    def to_dict(self) -> dict:
        """Return the checkpoint's ``novelty`` entry (plain JSON)."""
        return {'mean': self.mean.tolist(), 'whiten': self.whiten.tolist(),
                'radius': self.radius, 'source': self.source,
                'definition': 'bound x min(1, radius / d), d the RMS Mahalanobis distance '
                              'of the correction input from the training inputs'}

    @classmethod
    def from_dict(cls, stored: dict) -> Novelty:
        """Read a checkpoint's ``novelty`` entry."""
        return cls(np.asarray(stored['mean'], np.float64),
                   np.asarray(stored['whiten'], np.float64), float(stored['radius']),
                   stored.get('source', ''))

    def weights(self, cast=np.asarray) -> dict:
        """Return what ``available`` reads, each array through ``cast``."""
        return {'mean': cast(self.mean), 'whiten': cast(self.whiten),
                'radius': cast(np.asarray(self.radius))}


def hybrids_of(model) -> list:
    """Return the hybrids a model serves, each with its own calibration: its members, or it."""
    return list(getattr(model, 'members', [model]))


def stored(model) -> list | None:
    """Return a model's calibrations as its checkpoint keeps them: one per member, or None."""
    entries = [m.novelty.to_dict() if getattr(m, 'novelty', None) is not None else None
               for m in hybrids_of(model)]
    return entries if any(e is not None for e in entries) else None


def distance(x, weights: dict):
    """Return d(x) (..., 1) of correction inputs x (..., n) (see module doc)."""
    xp = namespace(x)
    w = (x - weights['mean']) @ weights['whiten']
    return xp.sqrt(xp.sum(w * w, axis=-1, keepdims=True) / x.shape[-1])


def available(x, weights: dict):
    """Return the share of the bound available, min(1, r / d(x)), (..., 1)."""
    xp = namespace(x)
    d = distance(x, weights)
    radius = weights['radius']
    # At d = 0 the ratio is inf (share 1); the floor only keeps it from being a nan.
    return xp.minimum(xp.ones_like(d), radius / xp.maximum(d, xp.zeros_like(d) + 1e-30))


def calibrate(train_inputs: np.ndarray, val_inputs: np.ndarray, source: str = '') -> Novelty:
    """Fit m, W on the training inputs (N, n) and the radius on both (see module doc)."""
    train = np.asarray(train_inputs, np.float64)
    if len(train) < 2 or not np.isfinite(train).all():
        raise ValueError(f'novelty needs two or more finite training inputs, got {len(train)}')
    n = train.shape[1]
    cov = np.atleast_2d(np.cov(train, rowvar=False)) + RIDGE * np.eye(n)
    weights = {'mean': train.mean(axis=0), 'whiten': np.linalg.cholesky(np.linalg.inv(cov))}
    rows = np.concatenate([train, np.asarray(val_inputs, np.float64).reshape(-1, n)])
    radius = float(np.nanmax(distance(rows, weights)))
    return Novelty(weights['mean'], weights['whiten'], radius, source)
