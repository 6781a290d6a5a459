"""
First-principles models Min and Pro, built from ``vessel_physics`` force terms.

Both integrate M [u, v, p, r]' = sum of named terms (z, c), phi' = p over one sample
period with classical RK4 sub-steps (``vessel_physics.integrator.rk4_step``), the
control held constant (zero-order hold). The roll angle integrates the roll RATE p;
the authors' library used the roll acceleration there, and stepped explicit Euler
at dt = 1 s.

- Min (Baier et al.): rigid-body Coriolis and linearized restoring -G eta with the mass
  matrix including added mass; no damping, no control forces.
- Pro: Min plus the twin rudder-propeller thrust.

The terms are written against the Array API, so this module holds no physics of its
own: it picks terms, sub-steps and parameters (default: the nominal vessel).
"""

from __future__ import annotations

from dataclasses import asdict

import torch

from hybrid_models.physical.base import PhysicalModel
from hybrid_models.vehicle import VehicleSpec
from vessel_physics.arrays import namespace
from vessel_physics.integrator import rk4_step
from vessel_physics.mass import accelerations
from vessel_physics.params import VesselParams, load_named_vessel, params_from_dict
from vessel_physics.terms import MIN_TERMS, PRO_TERMS, total_force

TERM_SETS = {'min': MIN_TERMS, 'pro': PRO_TERMS}
DEFAULT_PARAMS = 'nominal_vessel'
ROLL_RATE, ROLL_ANGLE = 2, 4   # columns of z = [u, v, p, r, phi]


class FirstPrinciplesModel(PhysicalModel):
    """Named force terms, the mass matrix and RK4 sub-steps over one sample period."""

    def __init__(self, spec: VehicleSpec, kind: str, params: VesselParams,
                 params_source: str = DEFAULT_PARAMS, substeps: int = 4):
        super().__init__(spec)
        if spec.state_names != ('u', 'v', 'p', 'r', 'phi'):
            raise ValueError(f'{kind}: the vessel terms need z = [u, v, p, r, phi], '
                             f'got {spec.state_names}')
        if substeps < 1:
            raise ValueError(f'substeps must be >= 1, got {substeps}')
        self.kind, self.terms = kind, TERM_SETS[kind]
        self.params, self.params_source = params, params_source
        self.substeps = int(substeps)

    def derivative(self, z, c):
        """Z' = [M^-1 tau(z, c), p] (FRD; m/s^2, rad/s^2, rad/s), on Array API arrays."""
        xp = namespace(z, c)
        acc = accelerations(total_force(self.terms, z, c, self.params), self.params)
        return xp.concat([acc, z[..., ROLL_RATE:ROLL_RATE + 1]], axis=-1)

    def array_step(self, z, c, repeat=None):
        """
        Return the state one sample period later, on any Array API arrays.

        The same code serves the torch model (with autograd) and the compiled forecast
        engine (jax). ``repeat(n, body, x)`` applies ``body`` n times; the default is a
        Python loop, the engine passes a compiled loop.
        """
        h = self.spec.dt / self.substeps

        def body(x):
            return rk4_step(lambda _t, s: self.derivative(s, c), 0.0, x, h)

        if repeat is not None:
            return repeat(self.substeps, body, z)
        for _ in range(self.substeps):
            z = body(z)
        return z

    def forward(self, z: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        """State one sample period later."""
        return self.array_step(z, c)

    @property
    def params_yaml(self) -> dict:
        """Return the parameter values used (stored in checkpoints)."""
        return asdict(self.params)

    def describe(self) -> dict:
        """Return the construction arguments, including every parameter value."""
        return {'kind': self.kind, 'params': self.params_source, 'substeps': self.substeps,
                'vessel': asdict(self.params)}


def build_first_principles(kind: str, spec: VehicleSpec, params: str | None = None,
                           substeps: int = 4, vessel: dict | None = None
                           ) -> FirstPrinciplesModel:
    """Min or Pro with parameters from ``vessel`` values, a YAML name/path, or nominal."""
    source = params or DEFAULT_PARAMS
    values = params_from_dict(vessel, source) if vessel else load_named_vessel(source)
    return FirstPrinciplesModel(spec, kind, values, source, substeps)
