"""
First-principles models Min, Pro and a physics file, built from ``vessel_physics`` terms.

Each integrates M [u, v, p, r]' = sum of named terms (z, c), phi' = p over one sample
period with classical RK4 sub-steps (``vessel_physics.integrator.rk4_step``), the
control held constant (zero-order hold). The roll angle integrates the roll RATE p;
the authors' library used the roll acceleration there, and stepped explicit Euler
at dt = 1 s.

- Min (Baier et al.): rigid-body Coriolis and linearized restoring -G eta with the mass
  matrix including added mass; no damping, no control forces.
- Pro: Min plus the twin rudder-propeller thrust.
- Physics: the terms and discovered extra terms of a physics file
  (``vessel_physics.augmented``), e.g. the nominal physics or the augmented physics that
  ``offline/diagnose.py`` writes; the checkpoint keeps the whole file inline.

The terms are written against the Array API, so this module holds no physics of its
own: it picks terms, sub-steps and parameters (default: those the vessel file names
under ``physics``; a vessel without them is refused).
"""

from __future__ import annotations

from dataclasses import asdict

from hybrid_models.physical.integrated import IntegratedModel
from hybrid_models.vehicle import VehicleSpec, load_vessel
from vessel_physics.augmented import Physics, load_physics, physics_from_dict
from vessel_physics.params import load_named_vessel, params_from_dict
from vessel_physics.terms import MIN_TERMS, PRO_TERMS

TERM_SETS = {'min': MIN_TERMS, 'pro': PRO_TERMS}
PHYSICS_FILE_KIND = 'physics'
# The vessel file whose vectors the 4-DOF terms of vessel_physics are written for.
PHYSICS_FAMILY_VESSEL = 'patrol_boat'


class FirstPrinciplesModel(IntegratedModel):
    """Named force terms, the mass matrix and RK4 sub-steps over one sample period."""

    def __init__(self, spec: VehicleSpec, kind: str, physics: Physics,
                 params_source: str, substeps: int = 4):
        super().__init__(spec, substeps)
        family = load_vessel(PHYSICS_FAMILY_VESSEL)
        if (spec.state_names, spec.control_names) != (family.state_names,
                                                      family.control_names):
            raise ValueError(f'{kind}: the 4-DOF vessel terms take z = {family.state_names} '
                             f'and c = {family.control_names}; vessel {spec.name!r} has '
                             f'{spec.state_names} and {spec.control_names}: use a '
                             f'regression physics (lin, hyd, qua)')
        self.kind, self.physics = kind, physics
        self.params, self.params_source = physics.params, params_source

    def derivative(self, z, c):
        """Z' = [M^-1 tau(z, c), p] (FRD; m/s^2, rad/s^2, rad/s): ``Physics.derivative``."""
        return self.physics.derivative(z, c)

    @property
    def params_yaml(self) -> dict:
        """Return the parameter values used (stored in checkpoints)."""
        return asdict(self.params)

    def describe(self) -> dict:
        """Return the construction arguments, including every parameter value."""
        if self.kind == PHYSICS_FILE_KIND:
            return {'kind': self.kind, 'physics_source': self.params_source,
                    'substeps': self.substeps,
                    'physics': self.physics.to_dict(inline_vessel=True)}
        return {'kind': self.kind, 'params': self.params_source, 'substeps': self.substeps,
                'vessel': asdict(self.params)}


def build_first_principles(kind: str, spec: VehicleSpec, params: str | None = None,
                           substeps: int = 4, vessel: dict | None = None,
                           physics: str | dict | None = None,
                           physics_source: str | None = None) -> FirstPrinciplesModel:
    """
    Min or Pro, or the physics of a physics file.

    Min and Pro take their parameters from ``vessel`` values, a YAML name/path
    (``params``), or the hull parameters the vessel file names (``physics``). Kind
    'physics' needs ``physics``: a physics file's path, or its mapping (as ``describe``
    stores it, with ``physics_source`` naming where it came from).
    """
    if kind == PHYSICS_FILE_KIND:
        if physics is None:
            raise ValueError("physical model 'physics' needs a physics file: set "
                             "model.physical.physics to its path (e.g. the "
                             'augmented_physics.yaml that offline/diagnose.py writes)')
        if isinstance(physics, dict):
            source = physics_source or '<inline physics>'
            loaded = physics_from_dict(physics, source=source)
        else:
            source, loaded = str(physics), load_physics(physics)
        # Per-run environment (e.g. each recording's current) does not carry to new runs.
        return FirstPrinciplesModel(spec, kind, loaded.replace(environment={}), source,
                                    substeps)
    if kind not in TERM_SETS:
        raise ValueError(f'unknown first-principles model {kind!r}; use '
                         f'{sorted(TERM_SETS) + [PHYSICS_FILE_KIND]}')
    source = params or spec.physics
    if source is None and not vessel:
        raise ValueError(f'physical model {kind!r} needs hull parameters, and vessel '
                         f'{spec.name!r} names none (key physics: in its vessel file); use a '
                         f'regression physics (lin, hyd, qua) or give model.physical.params')
    values = params_from_dict(vessel, source) if vessel else load_named_vessel(source)
    return FirstPrinciplesModel(spec, kind, Physics(values, TERM_SETS[kind], source=source),
                                source, substeps)
