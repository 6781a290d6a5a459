"""The physical-model interface shared by first-principles and regression components."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from vessel_description import Vessel
from vessel_physics.arrays import constant, namespace


class PhysicalModel:
    """
    One sample period of a physical model: z_phy_{t+1} = f(z_t, c_t).

    ``step(z, c, arrays)`` is the model, written against the Array API: the state ``z``
    (..., n_state) and the control ``c`` (..., n_control), held constant over the period,
    in the vehicle's units, give the state one sample period later. Everything a fitted
    model learned is in ``arrays()`` (named arrays, float64), so the description plus
    these arrays rebuild it exactly, and no framework is needed to run it: numpy for
    fitting and diagnosis, torch inside the hybrid during training, jax when serving.
    """

    kind = 'abstract'

    def __init__(self, spec: Vessel):
        self.spec = spec
        self._arrays: dict[str, np.ndarray] = {}

    def step(self, z, c, arrays: Mapping, repeat=None):
        """
        Return the state one sample period later, on any Array API arrays.

        ``arrays`` holds the learned values (``arrays()``' names) in the namespace of z;
        ``repeat(n, body, x)`` applies ``body`` n times (the default is a Python loop; the
        forecaster passes a compiled loop).
        """
        raise NotImplementedError

    def arrays(self) -> dict[str, np.ndarray]:
        """Return the learned values by name (empty for pure physics)."""
        return dict(self._arrays)

    def load_arrays(self, arrays: Mapping) -> PhysicalModel:
        """Set the learned values (same names and shapes as ``arrays()``)."""
        own = self.arrays()
        if set(arrays) != set(own):
            raise ValueError(f'{self.kind}: learned values {sorted(arrays)} are not '
                             f'{sorted(own)}')
        for name, value in arrays.items():
            value = np.asarray(value)
            if value.shape != own[name].shape:
                raise ValueError(f'{self.kind}: {name} has shape {value.shape}, expected '
                                 f'{own[name].shape}')
            self._arrays[name] = value.astype(own[name].dtype)
        return self

    def __call__(self, z, c):
        """Predict the next state with the model's own learned values."""
        xp = namespace(z, c)
        own = {k: v if v.dtype == bool else constant(v, z, xp)
               for k, v in self.arrays().items()}
        return self.step(z, c, own)

    def fit(self, z: np.ndarray, c: np.ndarray, z_next: np.ndarray) -> PhysicalModel:
        """Fit learnable parts on one-step pairs (N rows each); a no-op for pure physics."""
        return self

    def describe(self) -> dict:
        """JSON-ready construction arguments (``build_physical`` input)."""
        return {'kind': self.kind}

    def predict(self, z: np.ndarray, c: np.ndarray, batch: int = 65536) -> np.ndarray:
        """Numpy convenience: one-step predictions for N rows (float64), in chunks."""
        out = [self(np.asarray(z[i:i + batch], np.float64),
                    np.asarray(c[i:i + batch], np.float64)) for i in range(0, len(z), batch)]
        return np.concatenate(out) if out else np.zeros((0, self.spec.n_state))


def part(arrays: Mapping, prefix: str) -> dict:
    """Return the arrays under ``prefix.`` with the prefix removed."""
    lead = f'{prefix}.'
    return {k[len(lead):]: v for k, v in arrays.items() if k.startswith(lead)}
