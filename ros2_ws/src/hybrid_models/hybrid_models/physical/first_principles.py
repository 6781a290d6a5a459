"""
First-principles physical models: a vessel's physics of any family (``vessel_physics``).

Each integrates the family's equation of motion ``Physics.derivative`` (M nu' = tau and
its kinematics, in the vessel file's vectors) over one sample period with classical RK4
sub-steps, the control held constant (zero-order hold). The roll angle of the patrol
family integrates the roll RATE p; the authors' library used the roll acceleration
there, and stepped explicit Euler at dt = 1 s.

- ``physics``: the physics file a config names (``model.physical.physics``: any family's
  physics or parameter file, e.g. the augmented physics ``offline/diagnose.py`` writes);
- a named subset of the family's terms: a family's own name (``patrol``, ``mmg``,
  ``fossen``, ``multirotor``: its model terms, or the force terms ``terms`` lists) or a
  term set it names (the paper's Min and Pro of the patrol family, ``min``: rigid-body
  Coriolis and linearized restoring, ``pro``: Min plus the twin rudder-propellers), on
  the physics the vessel file names (``physics:``) or a given parameter file
  (``params``). Every name comes from the family (``vessel_physics.families``).

The checkpoint keeps the whole physics inline, so a model never needs the file again;
checkpoints written before the families stored the parameter values under ``vessel``
(Min, Pro) or ``mmg``, and are read as such. This module holds no physics of its own.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from hybrid_models.physical.integrated import IntegratedModel
from vessel_description import Vessel
from vessel_physics.errors import ConfigError
from vessel_physics.families import FAMILIES
from vessel_physics.family import Physics
from vessel_physics.physics_file import load_physics, physics_from_dict, physics_to_dict

PHYSICS_FILE_KIND = 'physics'
HINT = 'use a regression physics (lin, hyd, qua) or a physics file of a family that fits'



class FirstPrinciplesModel(IntegratedModel):
    """A family's equation of motion and RK4 sub-steps over one sample period."""

    def __init__(self, spec: Vessel, kind: str, physics: Physics, source: str,
                 substeps: int = 4):
        super().__init__(spec, substeps)
        try:
            self.physics = physics.for_vessel(spec)
        except ConfigError as exc:
            raise ValueError(f'{kind}: {exc}; {HINT}') from None
        self.kind, self.params_source = kind, source
        self.params = physics.params

    def derivative(self, z, c):
        """Return z' (the family's ``Physics.derivative``) in the vessel's vectors."""
        return self.physics.derivative(z, c)

    @property
    def params_yaml(self) -> dict:
        """Return the parameter values used (for the training report)."""
        return self.physics.family.parameter_values(self.params)

    def describe(self) -> dict:
        """Return the construction arguments, the whole physics inline."""
        return {'kind': self.kind, 'physics_source': self.params_source,
                'substeps': self.substeps,
                'physics': physics_to_dict(self.physics, inline=True)}


def _stored(cfg: Mapping) -> Physics | None:
    """Return the physics a checkpoint stored inline: today's mapping, or an older form."""
    source = str(cfg.get('physics_source') or cfg.get('params') or '<inline physics>')
    if isinstance(cfg.get('physics'), Mapping):
        return physics_from_dict(cfg['physics'], source=source)
    for key, family in (('vessel', 'patrol'), ('mmg', 'mmg')):
        if cfg.get(key):     # parameter values as checkpoints stored them before families
            f = FAMILIES[family]
            return Physics(f, f.read_parameters(dict(cfg[key]), source), f.model_terms,
                           source=source)
    return None


def _subset(kind: str, physics: Physics, terms: Sequence[str] | None) -> Physics:
    """Return the physics restricted to a named set of its family's terms."""
    family = physics.family
    if kind in FAMILIES:     # a family's name: its model terms, or some of its forces
        if family.name != kind:
            raise ValueError(f'{kind}: the physics ({physics.source}) is of the '
                             f'{family.title}, not the {kind} family; use kind physics')
        chosen = tuple(terms) if terms else family.model_terms
        forces = [n for n, t in family.terms.items() if t.kind == 'force']
        if not chosen or any(t not in forces for t in chosen):
            raise ValueError(f'{kind}: terms must be a non-empty subset of {forces}, got '
                             f'{list(chosen)}')
        return physics.replace(terms=chosen)
    if kind not in family.term_sets:
        raise ValueError(f'{kind}: the {family.title} has no term set {kind!r} (it has '
                         f'{sorted(family.term_sets) or "none"}); use kind physics')
    return physics.replace(terms=family.term_sets[kind])


def build_first_principles(kind: str, spec: Vessel, cfg: Mapping,
                           substeps: int = 4) -> FirstPrinciplesModel:
    """
    Build the model of ``kind`` for a vessel: 'physics' (a file), or a family's term set.

    ``cfg`` is the physical-model config (``build_physical``): ``physics`` (a path or a
    stored mapping), ``params`` (a parameter file), ``terms`` (a family's kind), or the
    values an older checkpoint stored.
    """
    stored = _stored(cfg)
    try:
        if kind == PHYSICS_FILE_KIND:
            if stored is None and cfg.get('physics') is None:
                raise ValueError("physical model 'physics' needs a physics file: set "
                                 "model.physical.physics to its path (e.g. the "
                                 'augmented_physics.yaml that offline/diagnose.py writes)')
            physics = stored if stored is not None else load_physics(cfg['physics'], spec)
            source = stored.source if stored is not None else str(cfg['physics'])
            # Per-run environment (e.g. each recording's current) does not carry to new runs.
            return FirstPrinciplesModel(spec, kind, physics.replace(environment={}), source,
                                        substeps)
        if isinstance(cfg.get('physics'), Mapping):    # stored with its terms: as it was
            return FirstPrinciplesModel(spec, kind, stored, stored.source, substeps)
        if stored is not None:
            physics, source = stored, stored.source
        else:
            source = cfg.get('params') or spec.physics
            if source is None:
                raise ValueError(f'physical model {kind!r} needs physics, and vessel '
                                 f'{spec.name!r} names none (key physics: in its vessel file); '
                                 f'use a regression physics (lin, hyd, qua) or give '
                                 f'model.physical.params')
            physics = load_physics(source, spec)
        physics = _subset(kind, physics, cfg.get('terms'))
    except ConfigError as exc:
        raise ValueError(f'{kind}: {exc}; {HINT}') from None
    return FirstPrinciplesModel(spec, kind, physics, str(source), substeps)
