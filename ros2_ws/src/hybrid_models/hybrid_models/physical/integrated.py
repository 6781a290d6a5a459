"""
Physical models that integrate an equation of motion over one sample period.

A subclass gives ``derivative(z, c)`` (the state's time derivative on Array API arrays);
this base integrates it with classical RK4 sub-steps (``vessel_physics.integrator``),
the control held over the period (zero-order hold). One integration serves the torch
model (with autograd) and the compiled forecaster (jax).
"""

from __future__ import annotations

from abc import ABCMeta, abstractmethod
from collections.abc import Mapping

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.vehicle import VehicleSpec
from vessel_physics.integrator import rk4_step


class IntegratedModel(PhysicalModel, metaclass=ABCMeta):
    """An equation of motion z' = f(z, c), integrated with ``substeps`` RK4 steps."""

    def __init__(self, spec: VehicleSpec, substeps: int = 4):
        super().__init__(spec)
        if substeps < 1:
            raise ValueError(f'substeps must be >= 1, got {substeps}')
        self.substeps = int(substeps)

    @abstractmethod
    def derivative(self, z, c):
        """Return z' (..., n_state) in the vehicle's units per second."""

    def step(self, z, c, arrays: Mapping | None = None, repeat=None):
        """Return the state one sample period later (nothing learned: ``arrays`` is empty)."""
        h = self.spec.dt / self.substeps

        def body(x):
            return rk4_step(lambda _t, s: self.derivative(s, c), 0.0, x, h)

        if repeat is not None:
            return repeat(self.substeps, body, z)
        for _ in range(self.substeps):
            z = body(z)
        return z
