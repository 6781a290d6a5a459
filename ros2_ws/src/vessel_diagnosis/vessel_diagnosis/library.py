"""
The candidate library: named physical effects, how each changes a physics, its category.

A ``Candidate`` is one coefficient the recordings may ask for. Three kinds, all applied
to a ``vessel_physics.family.Physics`` of any family (so the simulator's and the models'
own term functions are reused, never copied):

- ``parameter``: a parameter of the family is off; the coefficient is its change (in its
  unit), applied with ``Physics.with_parameters`` (hull damping, restoring, added mass,
  wake fraction, rudder lift...);
- ``term``: a force term is missing or mis-scaled; the coefficient multiplies a force or
  candidate term of the family's registry on some of its DOFs;
- ``current``: a steady ocean current per run (north, east), which the predictor turns
  into the offset between velocity over ground and through the water.

Each family has its library (``Family.diagnosis_candidates``: the family folder's
diagnosis_candidates.yaml, whose comments document the keys); a user's
library (``--library``) is checked against the family of the physics it is used with.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vessel_description.resources import read_yaml
from vessel_diagnosis.predict import Variant
from vessel_physics.errors import did_you_mean
from vessel_physics.family import Family, Physics

KINDS = ('parameter', 'term', 'current')
CATEGORIES = {
    'resistance': 'surge resistance (hull fouling, added resistance)',
    'hull_damping': 'sway and yaw damping and cross-flow forces',
    'roll_damping': 'roll damping',
    'restoring': 'hydrostatic roll restoring (GM, GZ curve)',
    'added_mass': 'added mass and inertia (mass matrix)',
    'propulsion': 'propeller thrust (KT, diameter, wake, shaft speed reading)',
    'rudder': 'rudder forces (lift gradient, hull interaction)',
    'actuator_bias': 'rudder-angle offset, port/starboard thrust asymmetry',
    'static_bias': 'constant generalized force (list, asymmetric hull or appendage)',
    'wind': 'wind loads in the apparent wind',
    'current': 'steady ocean current (offset between ground and water velocity)',
    'rigid_body': 'mass and inertia of the rigid body (a payload, another battery)',
    'aerodynamics': "rotor drag, induced inflow, translational lift and the frame's drag",
}


# Froude's law: the power of the length ratio each base unit scales with (velocities
# with its square root, so times too); a library's absolute scales move with the vessel.
FROUDE_POWERS = {'N': 3.0, 'kg': 3.0, 'm': 1.0, 's': 0.5, 'rad': 0.0, '1': 0.0}


class LibraryError(ValueError):
    """A library file is invalid; the message is one line."""


def froude_power(unit: str) -> float:
    """Return the power of the length ratio a unit scales with, e.g. 'N s/m' -> 2.5."""
    power, sign = 0.0, 1.0
    for token in unit.split('(')[0].replace('/', ' / ').split():
        if token == '/':
            sign = -1.0
            continue
        base, _, exponent = token.partition('^')
        power += sign * FROUDE_POWERS[base] * (float(exponent) if exponent else 1.0)
    return power


@dataclass(frozen=True)
class Candidate:
    """One candidate coefficient; ``scale`` is its physically relevant size (its unit)."""

    name: str
    kind: str
    category: str
    target: str          # parameter name, term name, or 'current'
    dofs: str            # DOFs it acts on, e.g. 'X' or 'XYKN'
    unit: str
    scale: float
    description: str = ''
    requires: tuple[str, ...] = ()
    absolute_scale: float | None = None   # a parameter's, where its nominal value is zero


class Library:
    """An ordered set of candidates of one family; applies coefficients to its physics."""

    def __init__(self, candidates: Iterable[Candidate], family: str = '',
                 reference_length_m: float | None = None):
        self.family = family
        self.reference_length_m = reference_length_m
        self.candidates = tuple(candidates)
        self.by_name = {c.name: c for c in self.candidates}
        if len(self.by_name) != len(self.candidates):
            raise LibraryError('candidate names repeat')

    @property
    def global_candidates(self) -> tuple[Candidate, ...]:
        """Return the candidates with one coefficient for all runs (not per-run ones)."""
        return tuple(c for c in self.candidates if c.kind != 'current')

    @property
    def has_current(self) -> bool:
        """Return whether the library tries a per-run current."""
        return any(c.kind == 'current' for c in self.candidates)

    def apply(self, physics: Physics, values: Mapping[str, float]) -> Physics:
        """Return ``physics`` with the coefficients ``values`` (name -> value) added."""
        changes: dict[str, float] = {}
        for name, value in values.items():
            cand = self.by_name[name]
            if cand.kind == 'parameter':
                changes[cand.target] = changes.get(cand.target, physics.parameter(
                    cand.target)) + float(value)
            elif cand.kind == 'term':
                physics = physics.with_extra(cand.target, cand.dofs, float(value),
                                             {'candidate': cand.name,
                                              'category': cand.category})
            else:
                raise ValueError(f'{name}: a per-run candidate is not applied to the physics')
        return physics.with_parameters(**changes) if changes else physics

    def variant(self, cand: Candidate, physics: Physics, step: float) -> Variant:
        """
        Return the change ``step`` of a candidate's coefficient as a prediction variant.

        A term adds step * term; a parameter adds the difference of only the terms it
        enters and replaces the mass matrix if it enters that
        (``Physics.parameter_variant``); a current shifts the rows' current north (the
        east column is a separate variant).
        """
        if cand.kind == 'term':
            letters = ''.join(physics.family.dofs)
            weights = step * np.array([1.0 if d in cand.dofs else 0.0 for d in letters])
            return Variant(extra_force=lambda zw, c, zg: physics.term_force(
                cand.target, zw, c, zg) * weights)
        if cand.kind != 'parameter':
            raise ValueError(f'{cand.name}: per-run candidates have two components')
        extra, minv_t = physics.parameter_variant(cand.target, step)
        return Variant(extra_force=extra, minv_t=minv_t)

    def scaled_to(self, length_m: float) -> Library:
        """
        Return the library for a vessel ``length_m`` long.

        Absolute scales (terms, and parameters whose nominal value is zero) follow
        Froude's law from the length the file was written for (``reference_length_m``).
        """
        if not self.reference_length_m:
            return self
        ratio = length_m / self.reference_length_m

        def scaled(c: Candidate) -> Candidate:
            size = c.scale * ratio ** froude_power(c.unit)
            return dataclasses.replace(c, **({'absolute_scale': size} if c.kind == 'parameter'
                                             else {'scale': size}))

        return Library((scaled(c) for c in self.candidates), self.family, length_m)

    def absolute_scale(self, cand: Candidate, physics: Physics) -> float:
        """Return the relevant size of a coefficient in its unit (parameters: relative)."""
        if cand.kind == 'parameter':
            nominal = abs(physics.parameter(cand.target))
            return cand.scale * nominal if nominal > 0 else (cand.absolute_scale or cand.scale)
        return cand.scale


def _candidate(item: Mapping, index: int, source: str, family: Family) -> Candidate:
    where = f'{source}: candidates[{index}]'
    allowed = ('name', 'kind', 'category', 'parameter', 'term', 'dofs', 'scale', 'description',
               'requires')
    for key in item:
        if key not in allowed:
            raise LibraryError(f'{where}: unknown key {key!r}{did_you_mean(str(key), allowed)}')
    name, kind = str(item.get('name', '')), item.get('kind')
    if not name or kind not in KINDS:
        raise LibraryError(f'{where}: needs a name and kind in {KINDS}, got {name!r}, {kind!r}')
    category = item.get('category')
    if category not in CATEGORIES:
        raise LibraryError(f'{where} ({name}): category {category!r} is not one of '
                           f'{", ".join(CATEGORIES)}')
    scale = item.get('scale')
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
        raise LibraryError(f'{where} ({name}): scale must be a number > 0, got {scale!r}')
    requires = tuple(item.get('requires', ()))
    description = str(item.get('description', ''))
    letters = ''.join(family.dofs)
    if kind == 'parameter':
        target = str(item.get('parameter', ''))
        known = family.parameter_names()
        if target not in known:
            raise LibraryError(f'{where} ({name}): unknown parameter {target!r}'
                               f'{did_you_mean(target, known)} of the {family.title}')
        dofs = str(item.get('dofs', family.parameter_dofs(target)))
        unit = family.parameter_unit(target)
    elif kind == 'term':
        target = str(item.get('term', ''))
        known = sorted(n for n, t in family.terms.items() if t.kind != 'feature')
        if target not in known:
            raise LibraryError(f'{where} ({name}): unknown term {target!r}'
                               f'{did_you_mean(target, known)} of the {family.title}')
        term = family.terms[target]
        dofs = str(item.get('dofs', ''))
        unit = term.unit if term.kind == 'candidate' else '1 (fraction of the term)'
        description = description or term.description
    else:
        target, dofs, unit = 'current', letters, 'm/s'
    if not dofs or any(d not in letters for d in dofs):
        raise LibraryError(f'{where} ({name}): dofs must be letters of {letters}, got '
                           f'{dofs!r}')
    return Candidate(name, kind, category, target, dofs, unit, float(scale), description,
                     requires)


def load_library(path: str | Path | None, family: Family) -> Library:
    """Read a library YAML file of ``family`` (default: the family's packaged one)."""
    path = Path(path) if path else family.diagnosis_candidates
    data = read_yaml(path, LibraryError, 'the library') or {}
    items = data.get('candidates') if isinstance(data, Mapping) else None
    if not isinstance(items, list) or not items:
        raise LibraryError(f'{path}: expected a non-empty list under candidates:')
    reference = data.get('reference_length_m')
    if reference is not None and (isinstance(reference, bool) or not isinstance(
            reference, (int, float)) or not reference > 0):
        raise LibraryError(f'{path}: reference_length_m must be a length > 0 (m), got '
                           f'{reference!r}')
    return Library((_candidate(item, i, str(path), family) for i, item in enumerate(items)),
                   family.name, reference)
