"""
Physics files: a vessel, the registered terms it uses, and extra (discovered) terms.

A physics file says which physics a model or the diagnosis tool assumes. It is YAML::

    format: vessel-physics/1
    vessel: patrol_vessel.yaml     # parameter file: beside this file, then the package's
                                   # (or a mapping of the parameter values themselves)
    terms: [rigid_body_coriolis, restoring, hull_damping, propulsion, wind]
    extra_terms:                   # optional: coefficient * term, on the DOFs listed
      - {term: relative_wind_sway, dofs: Y, coefficient: 212.0}
      - {term: rudder_offset, dofs: XYKN, coefficient: 0.0087}
    environment: {}                # optional: what recordings said about the environment

``terms`` are names of ``vessel_physics.terms.TERMS``; an extra term names a term of
``vessel_physics.candidates.CANDIDATES`` or of ``TERMS`` (a registered term times a
coefficient, e.g. the Isherwood wind's side force scaled by 1.2), with ``dofs`` the
columns of [X, Y, K, N] it acts on. Extra keys of an extra term (category, ci95, ...)
are kept as information. A plain vessel parameter file is also accepted: it means that
vessel with every simulator term. ``diagnose`` writes augmented files in this format: the
corrected parameters go into a vessel file beside it, added effects into ``extra_terms``.

Consumers:

- models: ``load_physics(path).force(z_water, c, z_ground)`` is the total generalized
  force (numpy or torch, Array API), to use with ``mass.accelerations``;
- the simulator: set ``vessel:`` to the augmented vessel file and the hook
  ``extra_forces: vessel_physics.augmented:extra_forces_hook`` with the environment
  variable ``VESSEL_PHYSICS_EXTRA`` naming the physics file: the hook adds the extra
  terms (the simulator keeps its own registered terms).
"""

from __future__ import annotations

from collections.abc import Mapping
import dataclasses
from dataclasses import dataclass, field
import os
from pathlib import Path
from typing import Any

import yaml

from vessel_physics.arrays import namespace
from vessel_physics.candidates import CANDIDATES
from vessel_physics.errors import ConfigError, did_you_mean
from vessel_physics.files import read_yaml
from vessel_physics.mass import accelerations
from vessel_physics.params import VesselParams, config_dir, load_named_vessel, params_from_dict
from vessel_physics.terms import DOFS, SIMULATOR_TERMS, TERMS, Z_COLUMNS, total_force

FORMAT = 'vessel-physics/1'
ENV_VAR = 'VESSEL_PHYSICS_EXTRA'
_KEYS = ('format', 'description', 'vessel', 'terms', 'extra_terms', 'environment')
_TERM_KEYS = ('term', 'dofs', 'coefficient')


def term_function(name: str):
    """Return ``(fn, velocity)`` of a candidate or registered term, or raise KeyError."""
    if name in CANDIDATES:
        return CANDIDATES[name].fn, CANDIDATES[name].velocity
    if name in TERMS:
        return TERMS[name].fn, TERMS[name].velocity
    raise KeyError(name)


ROLL_RATE = Z_COLUMNS.index('p')
ALL_DOFS = ''.join(DOFS)   # an extra term acting on every DOF needs no mask


@dataclass(frozen=True)
class ExtraTerm:
    """``coefficient * term(z, c, params)`` on the DOFs ``dofs`` (a string like 'XYKN')."""

    term: str
    dofs: str
    coefficient: float
    info: Mapping[str, Any] = field(default_factory=dict, compare=False)

    def force(self, z_water, c, params: VesselParams, z_ground=None):
        """Return the generalized force of the term, shape (..., 4), FRD (N, N m)."""
        fn, velocity = term_function(self.term)
        z = z_ground if (velocity == 'ground' and z_ground is not None) else z_water
        tau = fn(z, c, params)
        if self.dofs != ALL_DOFS:
            xp = namespace(tau)
            mask = [1.0 if d in self.dofs else 0.0 for d in DOFS]
            tau = tau * xp.asarray(mask, dtype=tau.dtype)
        return self.coefficient * tau

    def to_dict(self) -> dict:
        """Return the YAML mapping of this term."""
        return {'term': self.term, 'dofs': self.dofs, 'coefficient': float(self.coefficient),
                **dict(self.info)}


@dataclass(frozen=True)
class Physics:
    """A vessel, the registered terms it uses and extra terms: the model of its forces."""

    params: VesselParams
    terms: tuple[str, ...] = SIMULATOR_TERMS
    extra_terms: tuple[ExtraTerm, ...] = ()
    environment: Mapping[str, Any] = field(default_factory=dict, compare=False)
    vessel_file: str | None = None
    source: str = field(default='<physics>', compare=False)

    def force(self, z_water, c, z_ground=None):
        """
        Total generalized force [X, Y, K, N] (..., 4) about CO, FRD (N, N m).

        ``z_water`` has u, v through the water, ``z_ground`` over ground (default the
        same); the wind terms use the ground velocity.
        """
        tau = total_force(self.terms, z_water, c, self.params, z_ground)
        if self.extra_terms:
            tau = tau + self.extra_force(z_water, c, z_ground)
        return tau

    def derivative(self, z_water, c, z_ground=None, extra_force=None):
        """
        Return z' (..., 5) for z = [u, v, p, r, phi]: the vessel's equation of motion.

        M nu' = tau(z, c) (+ ``extra_force``, forces no term holds: waves, a hook), so
        [u', v', p', r'] = M^-1 tau in FRD (m/s^2, rad/s^2), and phi' = p (rad/s). The one
        equation of motion of the 4-DOF vessel: the simulator, the first-principles
        models and the diagnosis integrate it.
        """
        tau = self.force(z_water, c, z_ground)
        if extra_force is not None:
            tau = tau + extra_force
        return self.rates(tau, z_water)

    def rates(self, tau, z_water):
        """Return z' (..., 5) under the total force ``tau`` (..., 4): [M^-1 tau, p]."""
        xp = namespace(z_water)
        return xp.concat([accelerations(tau, self.params),
                          z_water[..., ROLL_RATE:ROLL_RATE + 1]], axis=-1)

    def extra_force(self, z_water, c, z_ground=None):
        """Sum of the extra terms only (..., 4); zeros when there are none."""
        total = None
        for term in self.extra_terms:
            tau = term.force(z_water, c, self.params, z_ground)
            total = tau if total is None else total + tau
        if total is None:
            xp = namespace(z_water)
            return xp.zeros_like(z_water[..., :4])
        return total

    def replace(self, **changes) -> Physics:
        """Return a copy with fields changed (``params``, ``terms``, ``extra_terms``, ...)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self, vessel_file: str | None = None, inline_vessel: bool = False) -> dict:
        """
        Return the YAML mapping of this physics.

        ``vessel_file`` names the vessel; with ``inline_vessel`` the parameter values
        themselves stand there instead (self-contained, as checkpoints keep it).
        """
        vessel = (dataclasses.asdict(self.params) if inline_vessel
                  else vessel_file or self.vessel_file or self.params.name)
        out = {'format': FORMAT, 'vessel': vessel, 'terms': list(self.terms)}
        if self.extra_terms:
            out['extra_terms'] = [t.to_dict() for t in self.extra_terms]
        if self.environment:
            out['environment'] = _plain(self.environment)
        return out


def _plain(value):
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, 'item'):
        return value.item()
    return value


def _parse_extra(item: Any, index: int, source: str) -> ExtraTerm:
    where = f'{source}: extra_terms[{index}]'
    if not isinstance(item, Mapping):
        raise ConfigError(f'{where}: expected a mapping with {", ".join(_TERM_KEYS)}, got '
                          f'{type(item).__name__}')
    missing = [k for k in _TERM_KEYS if k not in item]
    if missing:
        raise ConfigError(f'{where}: missing {", ".join(missing)}')
    name = str(item['term'])
    try:
        term_function(name)
    except KeyError:
        known = sorted(CANDIDATES) + sorted(TERMS)
        raise ConfigError(f'{where}: unknown term {name!r}{did_you_mean(name, known)}; known: '
                          f'{", ".join(known)}') from None
    dofs = str(item['dofs'])
    if not dofs or any(d not in DOFS for d in dofs) or len(set(dofs)) != len(dofs):
        raise ConfigError(f'{where}: dofs: expected letters of {"".join(DOFS)} (e.g. Y or '
                          f'XYKN), got {dofs!r}')
    value = item['coefficient']
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{where}: coefficient: expected a number, got {value!r}')
    info = {k: v for k, v in item.items() if k not in _TERM_KEYS}
    return ExtraTerm(name, dofs, float(value), info)


def physics_from_dict(data: Mapping, base: Path | None = None,
                      source: str = '<physics>') -> Physics:
    """Build a Physics from a physics mapping (see the module docstring) or vessel mapping."""
    if not isinstance(data, Mapping):
        raise ConfigError(f'{source}: expected a mapping, got {type(data).__name__}')
    if 'format' not in data:
        params = params_from_dict(dict(data), source)
        return Physics(params, SIMULATOR_TERMS, source=source)
    if data['format'] != FORMAT:
        raise ConfigError(f'{source}: format: expected {FORMAT!r}, got {data["format"]!r}')
    for key in data:
        if key not in _KEYS:
            raise ConfigError(f'{source}: unknown key {key!r}{did_you_mean(str(key), _KEYS)}; '
                              f'allowed keys: {", ".join(_KEYS)}')
    if 'vessel' not in data:
        raise ConfigError(f'{source}: vessel: missing (a vessel parameter file name or path, '
                          f'or the parameter values)')
    if isinstance(data['vessel'], Mapping):
        # Inline values: what checkpoints store, so that a model never needs the file.
        vessel, params = None, params_from_dict(dict(data['vessel']), f'{source}: vessel')
    else:
        vessel = str(data['vessel'])
        params = load_named_vessel(vessel, base)
    terms = data.get('terms', list(SIMULATOR_TERMS))
    if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
        raise ConfigError(f'{source}: terms: expected a list of term names, got {terms!r}')
    for name in terms:
        if name not in TERMS:
            raise ConfigError(f'{source}: terms: unknown term {name!r}'
                              f'{did_you_mean(name, TERMS)}; known: {", ".join(TERMS)}')
    extras = data.get('extra_terms') or []
    if not isinstance(extras, list):
        raise ConfigError(f'{source}: extra_terms: expected a list, got {extras!r}')
    environment = data.get('environment') or {}
    if not isinstance(environment, Mapping):
        raise ConfigError(f'{source}: environment: expected a mapping, got {environment!r}')
    return Physics(params, tuple(terms),
                   tuple(_parse_extra(item, i, source) for i, item in enumerate(extras)),
                   dict(environment), vessel, source)


def load_physics(path: str | Path) -> Physics:
    """Load a physics file or a plain vessel parameter file (name or path); see module doc."""
    path = Path(path)
    if not path.suffix:
        path = path.with_suffix('.yaml')
    if not path.is_file() and not path.is_absolute() and (config_dir() / path).is_file():
        path = config_dir() / path
    data = read_yaml(path, 'physics file')
    return physics_from_dict(data, path.resolve().parent, str(path))


def write_vessel(params: VesselParams, path: str | Path, header: str = '') -> Path:
    """Write a vessel parameter file that ``load_vessel`` reads back exactly."""
    path = Path(path)
    lines = [f'# {line}' if line else '#' for line in header.splitlines()]
    values = dataclasses.asdict(params)
    body = yaml.safe_dump(values, sort_keys=False, default_flow_style=False)
    path.write_text('\n'.join(lines + [body]))
    return path


def write_physics(physics: Physics, path: str | Path, vessel_file: str,
                  header: str = '') -> Path:
    """Write a physics file naming ``vessel_file`` (relative to the file's directory)."""
    path = Path(path)
    lines = [f'# {line}' if line else '#' for line in header.splitlines()]
    body = yaml.safe_dump(physics.to_dict(vessel_file), sort_keys=False,
                          default_flow_style=None, width=99)
    path.write_text('\n'.join(lines + [body]))
    return path


_HOOK_CACHE: dict[str, Physics] = {}


def extra_forces_hook(t, state, controls, environment):
    """
    Return the extra terms' forces of the physics file named by VESSEL_PHYSICS_EXTRA.

    A simulator hook (``extra_forces: vessel_physics.augmented:extra_forces_hook``).
    Signature and units as ``vessel_physics.config`` documents for ``extra_forces``; the
    file is read once per process.
    """
    import numpy as np

    path = os.environ.get(ENV_VAR)
    if not path:
        raise ConfigError(f'extra_forces_hook: set {ENV_VAR} to the physics file whose '
                          f'extra terms the simulator should add')
    if path not in _HOOK_CACHE:
        _HOOK_CACHE[path] = load_physics(path)
    physics = _HOOK_CACHE[path]
    zeros = np.zeros_like(state['u'])
    z_water = np.stack([state['u_water'], state['v_water'], state['p'], state['r'],
                        state['phi']], axis=-1)
    z_ground = np.stack([state['u'], state['v'], state['p'], state['r'], state['phi']],
                        axis=-1)
    wind_dir = environment['wind_dir']
    c = np.stack([controls['n'], controls['delta_port'], controls['delta_stbd'],
                  environment.get('wind_speed', zeros), np.cos(wind_dir), np.sin(wind_dir)],
                 axis=-1)
    return physics.extra_force(z_water, c, z_ground)


__all__ = ['ENV_VAR', 'FORMAT', 'ExtraTerm', 'Physics', 'extra_forces_hook', 'load_physics',
           'physics_from_dict', 'term_function', 'write_physics', 'write_vessel']
