"""First-principles model plus a regression fitted on its one-step residual."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from hybrid_models.physical.base import PhysicalModel, part
from hybrid_models.physical.regression import RegressionModel


class CompositeModel(PhysicalModel):
    """
    z_phy = FirstPrinciples(z, c) + Regression(z, c) (Baier et al., eq. 1).

    The regression is fitted in closed form on the first-principles ONE-STEP residual
    z_{t+1} - FirstPrinciples(z_t, c_t) (their eq. 5).
    """

    PARTS = ('first_principles', 'regression')   # attribute names, prefixes of arrays()

    def __init__(self, first_principles: PhysicalModel, regression: RegressionModel):
        super().__init__(first_principles.spec)
        self.first_principles = first_principles
        self.regression = regression
        self.kind = f'{first_principles.kind}+{regression.kind}'

    def step(self, z, c, arrays: Mapping, repeat=None):
        """Sum of both components."""
        return (self.first_principles.step(z, c, part(arrays, 'first_principles'), repeat) +
                self.regression.step(z, c, part(arrays, 'regression'), repeat))

    def arrays(self) -> dict:
        """Return both parts' learned values, named ``<part>.<name>``."""
        return {f'{name}.{k}': v for name in self.PARTS
                for k, v in getattr(self, name).arrays().items()}

    def load_arrays(self, arrays: Mapping) -> CompositeModel:
        """Set both parts' learned values (names as ``arrays()``)."""
        unknown = [k for k in arrays if k.split('.', 1)[0] not in self.PARTS]
        if unknown:
            raise ValueError(f'{self.kind}: unknown learned values {unknown}')
        for name in self.PARTS:
            getattr(self, name).load_arrays(part(arrays, name))
        return self

    def fit(self, z: np.ndarray, c: np.ndarray, z_next: np.ndarray) -> CompositeModel:
        """Fit the regression on the first-principles residual."""
        self.first_principles.fit(z, c, z_next)
        residual = z_next - self.first_principles.predict(z, c)
        self.regression.fit(z, c, residual)
        return self

    def describe(self) -> dict:
        """Return the construction arguments of both parts."""
        fp = self.first_principles.describe()
        reg = self.regression.describe()
        return {**fp, **{k: v for k, v in reg.items() if k != 'kind'}, 'kind': self.kind}
