"""
The family interface: what every physics family gives the simulator, the models and the diagnosis.

A family is one way of writing a vessel's equations of motion: the patrol boat's 4-DOF
terms (``vessel_physics.patrol``), the MMG standard model (``vessel_physics.mmg``), the
Fossen matrix model of small craft (``vessel_physics.fossen``), a multirotor in six
degrees of freedom (``vessel_physics.multirotor``). Each is one folder that reads top to
bottom: its parameters, its named terms, its mass matrix, and a ``Family`` that ties
them together. Everything else holds a ``Physics`` -- a family,
its parameter values, the terms in use and extra (discovered) terms -- and calls its
methods in the VESSEL's own vectors (the vessel file's states and controls): no module
outside a family names its states, coefficients or a vessel.

Vectors. A family's state vector starts with the body velocities its generalized forces
accelerate (``dofs``: ``M nu' = tau``), followed by states that follow from them
kinematically (the patrol boat's roll angle, phi' = p). Forces are generalized forces
about the family's reference point in FRD (N, N m). Terms are written against the
Python Array API, so one implementation runs on numpy (simulation, diagnosis), torch
(the hybrid, with autograd) and jax (the compiled forecaster).

Terms. One registry type, ``Term``, serves all three consumers:

- ``force``: part of the family's model, ``fn(z, c, params) -> tau`` (..., n_dof);
  the simulator sums all of them, a model may use a subset;
- ``candidate``: an effect the model lacks, named for the diagnosis; ``fn`` is the
  force of ONE unit of its coefficient, and a physics file adds ``coefficient * term``;
- ``feature``: a regressor of the family's hull model, ``fn(states) -> (...)`` on a
  mapping of state arrays by name (the hybrid's regression physics uses them).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
import dataclasses
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
import sys
from typing import Any

import numpy as np

from vessel_physics.arrays import constant, namespace, stack_last
from vessel_physics.errors import ConfigError

KINDS = ('force', 'candidate', 'feature')
# A family's candidate library for the diagnosis, in its folder (vessel_diagnosis.library).
CANDIDATES_FILE = 'diagnosis_candidates.yaml'
VELOCITIES = ('water', 'ground')   # which body velocity a force term takes


@dataclass(frozen=True)
class Term:
    """A named term of a family: its function, where it acts and what it models."""

    name: str
    fn: Callable
    dofs: tuple[str, ...]      # generalized forces it acts on (a feature: enters)
    category: str              # e.g. rigid_body, damping, propulsion, wind, static_bias
    description: str
    kind: str = 'force'        # force | candidate | feature (module docstring)
    velocity: str = 'water'    # force terms: u, v through the water or over ground
    unit: str = '1'            # unit of a coefficient multiplying it ('1': a fraction)
    # A force linear in some parameters: (features(z) -> (..., F), matrix(params) ->
    # (F, n_dof)) with fn = features @ matrix; the diagnosis differentiates it exactly.
    linear: tuple[Callable, Callable] | None = None


@dataclass(frozen=True)
class ExtraTerm:
    """``coefficient * term(z, c, params)`` on the DOFs ``dofs`` (a string like 'XYKN')."""

    term: str
    dofs: str
    coefficient: float
    info: Mapping[str, Any] = field(default_factory=dict, compare=False)

    def to_dict(self) -> dict:
        """Return the YAML mapping of this term."""
        return {'term': self.term, 'dofs': self.dofs, 'coefficient': float(self.coefficient),
                **dict(self.info)}


class Family(ABC):
    """
    One family of vessel physics. Subclasses set the class attributes and the methods.

    ``name`` is how physics files name it, ``parameters_format`` the format tag of its
    parameter files, ``states``/``dofs`` its vectors, ``terms`` its registry,
    ``model_terms`` the full model (what a parameter file alone stands for),
    ``term_sets`` named subsets (the paper's Min and Pro), ``environment`` the inputs it
    can feel ('wind', 'current', 'waves'). ``steady`` tells the simulator how to find a
    steady state (see ``SteadySpec``).
    """

    name: str
    title: str
    parameters_format: str
    states: tuple[str, ...]
    dofs: tuple[str, ...]
    terms: Mapping[str, Term]
    model_terms: tuple[str, ...]
    term_sets: Mapping[str, tuple[str, ...]] = {}
    environment: frozenset[str] = frozenset()
    steady: SteadySpec

    # -------------------------------------------------------------- parameters
    @abstractmethod
    def read_parameters(self, data: Mapping, source: str) -> Any:
        """Return validated parameters from a mapping (a parameter file's document)."""

    @abstractmethod
    def parameter_values(self, params: Any) -> dict:
        """Return the parameters as a mapping that ``read_parameters`` reads back exactly."""

    @property
    def diagnosis_candidates(self) -> Path:
        """Return the family's candidate library for the diagnosis (its folder's YAML)."""
        # Beside the family's terms: a term and the line that lets the diagnosis try it
        # are added in one folder (docs/extending.md).
        return Path(sys.modules[type(self).__module__].__file__).parent / CANDIDATES_FILE

    @property
    def features(self) -> tuple[str, ...]:
        """Return the names of the hull model's regressors (``feature`` terms), in order."""
        return tuple(n for n, t in self.terms.items() if t.kind == 'feature')

    def parameter_names(self) -> tuple[str, ...]:
        """Return the names of the numeric parameters (candidates of the diagnosis)."""
        return tuple(f.name for f in dataclasses.fields(self.params_type)
                     if f.type in ('float', float))

    params_type: type

    @abstractmethod
    def parameter_unit(self, name: str) -> str:
        """Return the unit of a parameter (e.g. 'N s^2 m^-2', '1')."""

    def parameter_dofs(self, name: str) -> str:
        """Return the DOFs a parameter acts on, as letters (default: all)."""
        return ''.join(self.dofs)

    def replace(self, params: Any, **changes) -> Any:
        """Return validated parameters with some values changed."""
        return self.read_parameters({**self.parameter_values(params), **changes},
                                    f'{self.name} parameters')

    # -------------------------------------------------------------- dynamics
    @abstractmethod
    def mass_matrix(self, params: Any) -> np.ndarray:
        """Return M (n_dof x n_dof, SI) with M nu' = tau."""

    def inverse_mass_matrix_t(self, params: Any) -> np.ndarray:
        """Return (M^-1)^T, so that ``tau @ result`` are the accelerations (read-only)."""
        return _inverse_mass_matrix_t(self, params)

    def kinematic_rates(self, z):
        """Return the rates of the states after the velocities, (..., n_state - n_dof)."""
        return None

    # -------------------------------------------------------------- a vessel's vectors
    @abstractmethod
    def controls_of(self, vessel, params: Any) -> tuple[int, ...] | None:
        """
        Return the vessel's control columns that make the family's control vector.

        None when the vessel's control vector is the family's. Raise ConfigError with
        one line when the vessel's states or actuators do not fit the family.
        """

    def check_states(self, vessel) -> None:
        """Raise ConfigError unless the vessel's state vector is the family's."""
        if tuple(vessel.state_names) != self.states:
            raise ConfigError(f'vessel {vessel.name!r} has states {list(vessel.state_names)}; '
                              f'the {self.title} takes {list(self.states)}')

    def check_scale(self, params: Any, vessel, source: str) -> None:  # noqa: B027
        """Raise ConfigError when the parameters (from ``source``) are for another size."""

    def actuator_dynamics(self, params: Any, vessel) -> dict | None:
        """
        Return the servo of each vessel actuator, or None when the parameters give none.

        ``{name: (low, high, time_constant_s, max_rate)}``: the set-point is clipped to
        [low, high], the actuator follows it at (set-point - state) / time_constant,
        at most ``max_rate`` per second.
        """
        return None

    def wave_hull(self, params: Any):
        """Return the box hull (``simulation.waves.BoxHull``) its wave forces act on."""
        raise ConfigError(f'the {self.title} feels no waves')

    @abstractmethod
    def probe(self) -> tuple[np.ndarray, np.ndarray]:
        """Return two probe states and controls in the family's vectors."""


@dataclass(frozen=True)
class SteadySpec:
    """
    How the simulator finds a steady state of a family (``simulation.steady``).

    ``unknowns``: states solved for (the others are zero; the first is u), ``steps`` their
    finite differences, ``limits`` the plausible |value| of each; the straight-ahead speed
    is bracketed in [0, ``max_speed``] m/s; a force balance within ``residual`` (N, N m)
    is steady.
    """

    unknowns: tuple[str, ...]
    steps: tuple[float, ...]
    limits: tuple[float, ...]
    max_speed: float
    residual: float


@dataclass(frozen=True)
class Physics:
    """
    A family, its parameter values, the terms in use and extra terms: one vessel's physics.

    ``controls`` (from ``for_vessel``) picks the vessel's control columns that make the
    family's control vector; None means they are the same. Every method takes and
    returns the vessel's vectors.
    """

    family: Family
    params: Any
    terms: tuple[str, ...]
    extra_terms: tuple[ExtraTerm, ...] = ()
    environment: Mapping[str, Any] = field(default_factory=dict, compare=False)
    parameters_file: str | None = None   # the parameter file, as a physics file names it
    source: str = field(default='<physics>', compare=False)
    controls: tuple[int, ...] | None = None

    def __post_init__(self):
        for name in self.terms:
            self.term(name)
        for extra in self.extra_terms:
            self.term(extra.term)

    # -------------------------------------------------------------- terms
    def term(self, name: str) -> Term:
        """Return a force or candidate term of the family; KeyError names the known ones."""
        term = self.family.terms.get(name)
        if term is None or term.kind == 'feature':
            known = sorted(n for n, t in self.family.terms.items() if t.kind != 'feature')
            raise KeyError(f'unknown term {name!r} of the {self.family.title}; known: '
                           f'{", ".join(known)}')
        return term

    def family_controls(self, c):
        """Return the family's control vector from the vessel's (the same array if equal)."""
        if self.controls is None:
            return c
        xp = namespace(c)
        return stack_last([c[..., j] for j in self.controls], xp)

    def term_force(self, name: str, z_water, c, z_ground=None, params=None):
        """One term's force (..., n_dof) in the vessel's vectors, at ``params`` if given."""
        term = self.term(name)
        z = z_ground if (term.velocity == 'ground' and z_ground is not None) else z_water
        return term.fn(z, self.family_controls(c), self.params if params is None else params)

    def _term_sum(self, z_water, c, z_ground, params):
        total = None
        for name in self.terms:
            term = self.family.terms[name]
            z = z_ground if (term.velocity == 'ground' and z_ground is not None) else z_water
            tau = term.fn(z, c, params)
            total = tau if total is None else total + tau
        if total is None:
            return namespace(z_water).zeros_like(z_water[..., :len(self.family.dofs)])
        return total

    def _extra(self, extra: ExtraTerm, z_water, c, z_ground, params):
        term = self.family.terms[extra.term]
        z = z_ground if (term.velocity == 'ground' and z_ground is not None) else z_water
        tau = term.fn(z, c, params)
        if extra.dofs != ''.join(self.family.dofs):
            xp = namespace(tau)
            mask = [1.0 if d in extra.dofs else 0.0 for d in self.family.dofs]
            tau = tau * xp.asarray(mask, dtype=tau.dtype)
        return extra.coefficient * tau

    # -------------------------------------------------------------- the equation of motion
    def force(self, z_water, c, z_ground=None):
        """
        Return the total generalized force about the reference point, FRD, (..., n_dof).

        ``z_water`` has u, v through the water, ``z_ground`` over ground (default the
        same; the wind terms take it).
        """
        tau = self._term_sum(z_water, self.family_controls(c), z_ground, self.params)
        if self.extra_terms:
            tau = tau + self.extra_force(z_water, c, z_ground)
        return tau

    def extra_force(self, z_water, c, z_ground=None):
        """Sum of the extra terms only (..., n_dof); zeros when there are none."""
        c = self.family_controls(c)
        total = None
        for extra in self.extra_terms:
            tau = self._extra(extra, z_water, c, z_ground, self.params)
            total = tau if total is None else total + tau
        if total is None:
            return namespace(z_water).zeros_like(z_water[..., :len(self.family.dofs)])
        return total

    def rates(self, tau, z_water, minv_t=None):
        """Return z' (..., n_state) under the total force ``tau``: [M^-1 tau, kinematics]."""
        xp = namespace(tau)
        if minv_t is None:
            minv_t = self.family.inverse_mass_matrix_t(self.params)
        accelerations = tau @ constant(minv_t, tau, xp)
        kinematic = self.family.kinematic_rates(z_water)
        if kinematic is None:
            return accelerations
        return xp.concat([accelerations, kinematic], axis=-1)

    def derivative(self, z_water, c, z_ground=None, extra_force=None):
        """
        Return z' (..., n_state): the vessel's equation of motion M nu' = tau, kinematics.

        ``extra_force`` (..., n_dof) adds forces no term holds (waves, a simulator hook).
        The simulator, the hybrid's first-principles part and the diagnosis integrate it.
        """
        tau = self.force(z_water, c, z_ground)
        if extra_force is not None:
            tau = tau + extra_force
        return self.rates(tau, z_water)

    def mass_matrix(self) -> np.ndarray:
        """Return M (n_dof x n_dof, SI)."""
        return self.family.mass_matrix(self.params)

    # -------------------------------------------------------------- changes
    def replace(self, **changes) -> Physics:
        """Return a copy with fields changed (``params``, ``terms``, ``extra_terms``, ...)."""
        return dataclasses.replace(self, **changes)

    def parameter(self, name: str) -> float:
        """Return the value of a parameter."""
        return float(getattr(self.params, name))

    def with_parameters(self, **changes) -> Physics:
        """Return a copy with some parameter values changed (validated)."""
        return self.replace(params=self.family.replace(self.params, **changes))

    def with_extra(self, term: str, dofs: str, coefficient: float, info=None) -> Physics:
        """Return a copy with ``coefficient`` added to the extra term ``term`` on ``dofs``."""
        extras = list(self.extra_terms)
        for i, extra in enumerate(extras):
            if extra.term == term and extra.dofs == dofs:
                extras[i] = ExtraTerm(term, dofs, extra.coefficient + float(coefficient),
                                      extra.info)
                break
        else:
            extras.append(ExtraTerm(term, dofs, float(coefficient), dict(info or {})))
        return self.replace(extra_terms=tuple(extras))

    def for_vessel(self, vessel) -> Physics:
        """Return this physics reading the vessel's vectors; ConfigError when they do not fit."""
        self.family.check_states(vessel)
        self.family.check_scale(self.params, vessel, self.parameters_file or self.source)
        return self.replace(controls=self.family.controls_of(vessel, self.params))

    def parameter_variant(self, name: str, step: float):
        """
        Return the change of force and mass matrix when parameter ``name`` grows by ``step``.

        Returns (extra_force(z_water, c, z_ground) -> (..., n_dof) or None,
        (M^-1)^T of the changed parameters or None when the mass matrix is unchanged).
        Only the terms that read the parameter (found on the family's probe states) are
        evaluated; a term linear in its parameters (``Term.linear``) is differentiated
        exactly.
        """
        params = self.params
        moved = self.family.replace(params, **{name: self.parameter(name) + step})
        z_probe, c_probe = self.family.probe()
        changed = [n for n in self.terms
                   if not np.array_equal(self.family.terms[n].fn(z_probe, c_probe, params),
                                         self.family.terms[n].fn(z_probe, c_probe, moved))]
        extras = [e for e in self.extra_terms
                  if not np.array_equal(self._extra(e, z_probe, c_probe, None, params),
                                        self._extra(e, z_probe, c_probe, None, moved))]
        minv_t = self.family.inverse_mass_matrix_t(moved)
        if np.array_equal(minv_t, self.family.inverse_mass_matrix_t(params)):
            minv_t = None
        linear = [self.family.terms[n].linear for n in changed]
        if len(changed) == 1 and not extras and linear[0] is not None:
            features, matrix = linear[0]
            delta = matrix(moved) - matrix(params)
            return (lambda zw, c, zg: features(zw) @ delta), minv_t

        def extra(zw, c, zg):
            c = self.family_controls(c)
            total = 0.0
            for n in changed:
                term = self.family.terms[n]
                z = zg if term.velocity == 'ground' else zw
                total = total + (term.fn(z, c, moved) - term.fn(z, c, params))
            for e in extras:
                total = total + (self._extra(e, zw, c, zg, moved)
                                 - self._extra(e, zw, c, zg, params))
            return total

        return (extra if (changed or extras) else None), minv_t


def term_registry(terms: Sequence[Term]) -> dict[str, Term]:
    """Return a registry (name -> term), refusing repeated names."""
    out = {}
    for term in terms:
        if term.kind not in KINDS or term.velocity not in VELOCITIES:
            raise ValueError(f'term {term.name}: kind {term.kind!r}, velocity {term.velocity!r}')
        if term.name in out:
            raise ValueError(f'term {term.name!r} is registered twice')
        out[term.name] = term
    return out


def one_dof(value, dof: int, n_dof: int):
    """Return (..., n_dof) with ``value`` in column ``dof`` and zeros elsewhere."""
    xp = namespace(value)
    zero = xp.zeros_like(value)
    return stack_last([value if j == dof else zero for j in range(n_dof)], xp)


def unit_force(z, dof: int, n_dof: int):
    """Return (..., n_dof) with 1 in column ``dof`` for each state of ``z``: a constant bias."""
    xp = namespace(z)
    return one_dof(xp.ones_like(z[..., 0]), dof, n_dof)


__all__ = ['ExtraTerm', 'Family', 'KINDS', 'Physics', 'SteadySpec', 'Term', 'VELOCITIES',
           'one_dof', 'term_registry', 'unit_force']


@lru_cache(maxsize=64)
def _inverse_mass_matrix_t(family: Family, params: Any) -> np.ndarray:
    # Cached per parameter set: the simulator and the diagnosis ask at every RK4 stage,
    # and inverting there was a twentieth of a diagnosis of the Otter.
    inverse = np.ascontiguousarray(np.linalg.inv(family.mass_matrix(params)).T)
    inverse.flags.writeable = False
    return inverse
