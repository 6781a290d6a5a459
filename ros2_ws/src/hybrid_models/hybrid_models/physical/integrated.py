"""
Physical models that integrate an equation of motion over one sample period.

A subclass gives ``derivative(z, c)`` (the state's time derivative on Array API arrays);
this base integrates it over one sample period with ``vessel_physics.integrator.
held_period`` (classical RK4 sub-steps, the control held), the integration the MMG
simulation uses too. It serves the torch model (with autograd) and the compiled
forecaster (jax).
"""

from __future__ import annotations

from abc import ABCMeta, abstractmethod
from collections.abc import Mapping

from hybrid_models.physical.base import PhysicalModel
from vessel_description import Vessel
from vessel_physics.integrator import held_period


class IntegratedModel(PhysicalModel, metaclass=ABCMeta):
    """An equation of motion z' = f(z, c), integrated with ``substeps`` RK4 steps."""

    def __init__(self, spec: Vessel, substeps: int = 4):
        super().__init__(spec)
        if substeps < 1:
            raise ValueError(f'substeps must be >= 1, got {substeps}')
        self.substeps = int(substeps)

    @abstractmethod
    def derivative(self, z, c):
        """Return z' (..., n_state) in the vehicle's units per second."""

    def step(self, z, c, arrays: Mapping | None = None, repeat=None):
        """Return the state one sample period later (nothing learned: ``arrays`` is empty)."""
        return held_period(self.derivative, z, c, self.spec.dt, self.substeps, repeat)
