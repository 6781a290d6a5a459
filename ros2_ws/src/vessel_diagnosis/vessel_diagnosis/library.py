"""
The candidate library: named physical effects, how each changes a physics, its category.

A ``Candidate`` is one coefficient the recordings may ask for. Three kinds, all applied
to a ``vessel_physics.augmented.Physics`` (so the simulator's and the models' own term
functions are reused, never copied):

- ``parameter``: a vessel parameter is off; the coefficient is its change (SI), applied
  with ``VesselParams.replace`` (hull damping, restoring, added mass, wake fraction);
- ``term``: a force term is missing or mis-scaled; the coefficient multiplies a term of
  ``vessel_physics.candidates`` or ``vessel_physics.terms`` on some DOFs;
- ``current``: a steady ocean current per run (north, east), which the predictor turns
  into the offset between velocity over ground and through the water.

The library is read from YAML (config/library.yaml documents the keys).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
import re

import numpy as np

from vessel_description.resources import read_yaml
from vessel_diagnosis.predict import Variant
from vessel_diagnosis.settings import config_dir
from vessel_physics.augmented import ExtraTerm, Physics, term_function
from vessel_physics.candidates import CANDIDATES
from vessel_physics.errors import did_you_mean
from vessel_physics.mass import inverse_mass_matrix_T
from vessel_physics.params import VesselParams
from vessel_physics.terms import DOFS, TERMS, hull_damping_features, hull_damping_matrix

KINDS = ('parameter', 'term', 'current')
CATEGORIES = {
    'resistance': 'surge resistance (hull fouling, added resistance)',
    'hull_damping': 'sway and yaw damping and cross-flow forces',
    'roll_damping': 'roll damping',
    'restoring': 'hydrostatic roll restoring (GM, GZ curve)',
    'added_mass': 'added mass and inertia (mass matrix)',
    'propulsion': 'propeller thrust (KT, diameter, wake, shaft speed reading)',
    'actuator_bias': 'rudder-angle offset, port/starboard thrust asymmetry',
    'static_bias': 'constant generalized force (list, asymmetric hull or appendage)',
    'wind': 'wind loads in the apparent wind',
    'current': 'steady ocean current (offset between ground and water velocity)',
}
_MASS_UNITS = {'Xudot': 'kg', 'Yvdot': 'kg', 'Ypdot': 'kg m', 'Yrdot': 'kg m', 'Kvdot': 'kg m',
               'Kpdot': 'kg m^2', 'Krdot': 'kg m^2', 'Nvdot': 'kg m', 'Npdot': 'kg m^2',
               'Nrdot': 'kg m^2'}
_OTHER_UNITS = {'GM': 'm', 'wake_fraction': '1', 'Ixx': 'kg m^2', 'Izz': 'kg m^2'}
_OTHER_DOFS = {'GM': 'K', 'wake_fraction': 'XYKN', 'Ixx': 'K', 'Izz': 'N'}
# Probe states and controls that tell which terms a parameter enters (any that differ).
_PROBE_Z = np.array([[6.0, 0.2, 0.01, 0.02, 0.01], [3.0, -0.3, -0.02, -0.01, -0.02]])
_PROBE_C = np.array([[80.0, 0.05, 0.04, 5.0, 0.6, 0.8], [50.0, -0.1, -0.12, 9.0, -0.8, -0.6]])


class LibraryError(ValueError):
    """A library file is invalid; the message is one line."""


def parameter_unit(name: str) -> str:
    """Return the SI unit of a textbook coefficient name (e.g. Xauu -> 'N s^2 m^-2')."""
    if name in _MASS_UNITS:
        return _MASS_UNITS[name]
    if name in _OTHER_UNITS:
        return _OTHER_UNITS[name]
    dof, rest = name[0], name[1:]
    metres, seconds, radians = (1 if dof in 'KN' else 0), 0, 0
    for token in re.findall(r'phi|a?[uvpr]', rest):
        q = token[-1]
        if token == 'phi':
            radians -= 1
        elif q in 'uv':
            metres, seconds = metres - 1, seconds + 1
        else:
            radians, seconds = radians - 1, seconds + 1
    parts = ['N'] + [f'{u}^{e}' if e != 1 else u for u, e in
                     (('m', metres), ('s', seconds), ('rad', radians)) if e]
    return ' '.join(parts)


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


class Library:
    """An ordered set of candidates; applies coefficients to a physics."""

    def __init__(self, candidates: Iterable[Candidate]):
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
        extras = list(physics.extra_terms)
        for name, value in values.items():
            cand = self.by_name[name]
            if cand.kind == 'parameter':
                changes[cand.target] = changes.get(cand.target, getattr(
                    physics.params, cand.target)) + float(value)
            elif cand.kind == 'term':
                for i, term in enumerate(extras):
                    if term.term == cand.target and term.dofs == cand.dofs:
                        extras[i] = ExtraTerm(term.term, term.dofs,
                                              term.coefficient + float(value), term.info)
                        break
                else:
                    extras.append(ExtraTerm(cand.target, cand.dofs, float(value),
                                            {'candidate': cand.name, 'category': cand.category}))
            else:
                raise ValueError(f'{name}: a per-run candidate is not applied to the physics')
        params = physics.params.replace(**changes) if changes else physics.params
        return physics.replace(params=params, extra_terms=tuple(extras))

    def variant(self, cand: Candidate, physics: Physics, step: float) -> Variant:
        """
        Return the change ``step`` of a candidate's coefficient as a prediction variant.

        A term adds step * term; a parameter adds the difference of only the terms it
        enters (found on probe states), and replaces the mass matrix if it enters that;
        a current shifts the rows' current north (the east column is a separate variant).
        """
        if cand.kind == 'term':
            fn, velocity = term_function(cand.target)
            weights = step * np.array([1.0 if d in cand.dofs else 0.0 for d in DOFS])
            params = physics.params
            if velocity == 'ground':
                return Variant(extra_force=lambda zw, c, zg: fn(zg, c, params) * weights)
            return Variant(extra_force=lambda zw, c, zg: fn(zw, c, params) * weights)
        if cand.kind != 'parameter':
            raise ValueError(f'{cand.name}: per-run candidates have two components')
        params = physics.params
        moved = params.replace(**{cand.target: getattr(params, cand.target) + step})
        terms = [name for name in physics.terms
                 if not np.array_equal(term_function(name)[0](_PROBE_Z, _PROBE_C, params),
                                       term_function(name)[0](_PROBE_Z, _PROBE_C, moved))]
        extras = [t for t in physics.extra_terms
                  if not np.array_equal(t.force(_PROBE_Z, _PROBE_C, params),
                                        t.force(_PROBE_Z, _PROBE_C, moved))]
        minv_t = inverse_mass_matrix_T(moved)
        minv_t = None if np.array_equal(minv_t, inverse_mass_matrix_T(params)) else minv_t
        if terms == ['hull_damping'] and not extras:
            # Hull damping is linear in its coefficients: features times the change.
            delta = hull_damping_matrix(moved) - hull_damping_matrix(params)
            return Variant(extra_force=lambda zw, c, zg: hull_damping_features(zw) @ delta,
                           minv_t=minv_t)

        def extra(zw, c, zg):
            total = np.zeros((len(zw), 4))
            for name in terms:
                fn, velocity = term_function(name)
                z = zg if velocity == 'ground' else zw
                total += fn(z, c, moved) - fn(z, c, params)
            for term in extras:
                total += term.force(zw, c, moved, zg) - term.force(zw, c, params, zg)
            return total

        return Variant(extra_force=extra if (terms or extras) else None, minv_t=minv_t)

    def absolute_scale(self, cand: Candidate, params: VesselParams) -> float:
        """Return the relevant size of a coefficient in its unit (parameters: relative)."""
        if cand.kind == 'parameter':
            nominal = abs(getattr(params, cand.target))
            return cand.scale * nominal if nominal > 0 else cand.scale
        return cand.scale


def _candidate(item: Mapping, index: int, source: str) -> Candidate:
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
    if kind == 'parameter':
        target = str(item.get('parameter', ''))
        known = [f.name for f in fields(VesselParams) if f.name != 'name']
        if target not in known:
            raise LibraryError(f'{where} ({name}): unknown parameter {target!r}'
                               f'{did_you_mean(target, known)}')
        dofs = str(item.get('dofs', _OTHER_DOFS.get(target, target[0])))
        unit = parameter_unit(target)
    elif kind == 'term':
        target = str(item.get('term', ''))
        try:
            term_function(target)
        except KeyError:
            known = sorted(CANDIDATES) + sorted(TERMS)
            raise LibraryError(f'{where} ({name}): unknown term {target!r}'
                               f'{did_you_mean(target, known)}') from None
        dofs = str(item.get('dofs', ''))
        unit = CANDIDATES[target].unit if target in CANDIDATES else '1 (fraction of the term)'
        description = description or (CANDIDATES[target].description if target in CANDIDATES
                                      else TERMS[target].description)
    else:
        target, dofs, unit = 'current', 'XYKN', 'm/s'
    if not dofs or any(d not in DOFS for d in dofs):
        raise LibraryError(f'{where} ({name}): dofs must be letters of XYKN, got {dofs!r}')
    return Candidate(name, kind, category, target, dofs, unit, float(scale), description,
                     requires)


def load_library(path: str | Path | None = None) -> Library:
    """Read a library YAML file (default: the package's config/library.yaml)."""
    path = Path(path) if path else config_dir() / 'library.yaml'
    data = read_yaml(path, LibraryError, 'the library') or {}
    items = data.get('candidates') if isinstance(data, Mapping) else None
    if not isinstance(items, list) or not items:
        raise LibraryError(f'{path}: expected a non-empty list under candidates:')
    return Library(_candidate(item, i, str(path)) for i, item in enumerate(items))
