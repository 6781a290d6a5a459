"""
Physics files: which family, its parameters, the terms in use and extra (discovered) terms.

``load_physics(name, vessel)`` is the one way to get a ``Physics`` from a file. A physics
file is YAML::

    format: vessel-physics/2
    family: patrol                  # patrol | mmg | fossen | multirotor (families)
    parameters: patrol_vessel.yaml  # the family's parameter file: beside this file, then
                                    # the package's (or a mapping of the values themselves)
    terms: [rigid_body_coriolis, restoring, hull_damping, propulsion, wind]
    extra_terms:                    # optional: coefficient * term, on the DOFs listed
      - {term: relative_wind_sway, dofs: Y, coefficient: 212.0}
    environment: {}                 # optional: what recordings said about the environment

``terms`` are force terms of the family's registry (default: its whole model); an extra
term names a force or candidate term, with ``dofs`` the letters of the family's
generalized forces it acts on. Extra keys of an extra term (category, ci95, ...) are kept
as information. A family's parameter file alone is a physics file too (its whole model):
``format: mmg-params/1``, ``fossen-params/1``, ``multirotor-params/1``, ``patrol-params/1``
(patrol parameter files older than that tag have no format key). Files of the first
version (``vessel-physics/1``) are the patrol family's and name the parameter file
``vessel:``.

Where a file is found (``vessel_physics.files.find_file``): a path as given; a name beside
the vessel file that names it (``vessel.physics``), beside the physics file that names a
parameter file, in the working directory, then among the packaged files. With a vessel,
the physics is bound to the vessel's vectors (``Physics.for_vessel``): a family that
does not fit the vessel's states, actuators or size is refused in one line.
"""

from __future__ import annotations

from collections.abc import Mapping
import os
from pathlib import Path
from typing import Any

import yaml

from vessel_physics.errors import ConfigError, did_you_mean
from vessel_physics.families import FAMILIES, family_of_format
from vessel_physics.family import ExtraTerm, Physics
from vessel_physics.files import config_dir, find_file, read_document

FORMAT = 'vessel-physics/2'
FORMAT_V1 = 'vessel-physics/1'    # the patrol family's files before there were families
_KEYS = ('format', 'description', 'family', 'parameters', 'terms', 'extra_terms',
         'environment')
_KEYS_V1 = ('format', 'description', 'vessel', 'terms', 'extra_terms', 'environment')
_TERM_KEYS = ('term', 'dofs', 'coefficient')


def _parse_extra(physics_family, item: Any, index: int, source: str) -> ExtraTerm:
    where = f'{source}: extra_terms[{index}]'
    if not isinstance(item, Mapping):
        raise ConfigError(f'{where}: expected a mapping with {", ".join(_TERM_KEYS)}, got '
                          f'{type(item).__name__}')
    missing = [k for k in _TERM_KEYS if k not in item]
    if missing:
        raise ConfigError(f'{where}: missing {", ".join(missing)}')
    name = str(item['term'])
    known = sorted(n for n, t in physics_family.terms.items() if t.kind != 'feature')
    if name not in known:
        raise ConfigError(f'{where}: unknown term {name!r}{did_you_mean(name, known)}; known '
                          f'terms of the {physics_family.title}: {", ".join(known)}')
    dofs = str(item['dofs'])
    letters = ''.join(physics_family.dofs)
    if not dofs or any(d not in letters for d in dofs) or len(set(dofs)) != len(dofs):
        raise ConfigError(f'{where}: dofs: expected letters of {letters} (e.g. Y or '
                          f'{letters}), got {dofs!r}')
    value = item['coefficient']
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f'{where}: coefficient: expected a number, got {value!r}')
    info = {k: v for k, v in item.items() if k not in _TERM_KEYS}
    return ExtraTerm(name, dofs, float(value), info)


def _check_keys(data: Mapping, keys, source: str) -> None:
    for key in data:
        if key not in keys:
            raise ConfigError(f'{source}: unknown key {key!r}{did_you_mean(str(key), keys)}; '
                              f'allowed keys: {", ".join(keys)}')


def physics_from_dict(data: Mapping, base: Path | None = None,
                      source: str = '<physics>') -> Physics:
    """Build a Physics from a physics file's mapping or a parameter file's (module doc)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f'{source}: expected a mapping, got {type(data).__name__}')
    fmt = data.get('format')
    if fmt not in (FORMAT, FORMAT_V1):
        family = family_of_format(fmt, source)
        params = family.read_parameters(dict(data), source)
        return Physics(family, params, family.model_terms, parameters_file=reference(source),
                       source=source)
    if fmt == FORMAT_V1:
        _check_keys(data, _KEYS_V1, source)
        family, parameters = FAMILIES['patrol'], data.get('vessel')
        if parameters is None:
            raise ConfigError(f'{source}: vessel: missing (the patrol parameter file, or '
                              f'its values)')
    else:
        _check_keys(data, _KEYS, source)
        name = data.get('family')
        if name not in FAMILIES:
            raise ConfigError(f'{source}: family: expected one of {", ".join(FAMILIES)}, got '
                              f'{name!r}')
        family, parameters = FAMILIES[name], data.get('parameters')
        if parameters is None:
            raise ConfigError(f'{source}: parameters: missing (a parameter file name or '
                              f'path of the {family.title}, or its values)')
    if isinstance(parameters, Mapping):
        # Inline values: what checkpoints store, so that a model never needs the file.
        file, params = None, family.read_parameters(dict(parameters), f'{source}: parameters')
    else:
        file = str(parameters)
        path = find_file(file, [base], f'{family.name} parameter file')
        document = read_document(path, f'{family.name} parameter file')
        if not isinstance(document, Mapping):
            raise ConfigError(f'{path}: expected a mapping of parameters')
        if family_of_format(document.get('format'), str(path)) is not family:
            raise ConfigError(f'{path}: not a parameter file of the {family.title} '
                              f'(format {document.get("format")!r})')
        params = family.read_parameters(dict(document), str(path))
    terms = data.get('terms', list(family.model_terms))
    if not isinstance(terms, list) or not all(isinstance(t, str) for t in terms):
        raise ConfigError(f'{source}: terms: expected a list of term names, got {terms!r}')
    forces = [n for n, t in family.terms.items() if t.kind == 'force']
    for name in terms:
        if name not in forces:
            raise ConfigError(f'{source}: terms: unknown term {name!r}'
                              f'{did_you_mean(name, forces)}; force terms of the '
                              f'{family.title}: {", ".join(forces)}')
    extras = data.get('extra_terms') or []
    if not isinstance(extras, list):
        raise ConfigError(f'{source}: extra_terms: expected a list, got {extras!r}')
    environment = data.get('environment') or {}
    if not isinstance(environment, Mapping):
        raise ConfigError(f'{source}: environment: expected a mapping, got {environment!r}')
    return Physics(family, params, tuple(terms),
                   tuple(_parse_extra(family, item, i, source) for i, item in
                         enumerate(extras)), dict(environment), file, source)


def reference(source: str | os.PathLike) -> str | None:
    """Return how a physics file names a parameter file: packaged by name, others by path."""
    path = Path(source)
    if not path.is_file():
        return None
    try:
        return str(path.resolve().relative_to(config_dir().resolve()))
    except ValueError:
        return str(path.resolve())


def load_physics(name: str | os.PathLike, vessel=None) -> Physics:
    """
    Load a physics file or a family's parameter file (a path, or a name; module doc).

    With ``vessel`` (a ``vessel_description.Vessel``) a relative name is looked up beside
    the vessel's file first, and the physics is bound to the vessel's vectors.
    """
    beside = [Path(vessel.source).resolve().parent] if vessel is not None and \
        Path(vessel.source).is_file() else []
    path = find_file(name, beside)
    physics = physics_from_dict(read_document(path, 'physics file'), path.resolve().parent,
                                str(path))
    return physics if vessel is None else physics.for_vessel(vessel)


def vessel_physics(vessel) -> Physics:
    """Return the physics a vessel file names (``physics:``), bound to it; one line if none."""
    if vessel.physics is None:
        raise ConfigError(f'vessel {vessel.name!r} ({vessel.source}) names no physics file '
                          f'(key physics: in its vessel file)')
    return load_physics(vessel.physics, vessel)


def physics_to_dict(physics: Physics, parameters_file: str | None = None,
                    inline: bool = False) -> dict:
    """
    Return the YAML mapping of a physics (``format: vessel-physics/2``).

    ``parameters_file`` names the parameter file; with ``inline`` the parameter values
    themselves stand there instead (self-contained, as checkpoints keep it).
    """
    family = physics.family
    parameters = (family.parameter_values(physics.params) if inline else
                  parameters_file or physics.parameters_file or physics.params.name)
    out = {'format': FORMAT, 'family': family.name, 'parameters': parameters,
           'terms': list(physics.terms)}
    if physics.extra_terms:
        out['extra_terms'] = [_plain(t.to_dict()) for t in physics.extra_terms]
    if physics.environment:
        out['environment'] = _plain(physics.environment)
    return out


def _plain(value):
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if hasattr(value, 'item'):
        return value.item()
    return value


def _header(text: str) -> list[str]:
    return [f'# {line}' if line else '#' for line in text.splitlines()]


def write_parameters(physics: Physics, path: str | os.PathLike, header: str = '') -> Path:
    """Write the family's parameter file of a physics; ``load_physics`` reads it back."""
    path = Path(path)
    values = physics.family.parameter_values(physics.params)
    values.setdefault('format', physics.family.parameters_format)
    body = yaml.safe_dump({'format': values.pop('format'), **values}, sort_keys=False,
                          default_flow_style=False)
    path.write_text('\n'.join(_header(header) + [body]))
    return path


def write_physics(physics: Physics, path: str | os.PathLike, parameters_file: str,
                  header: str = '') -> Path:
    """Write a physics file naming ``parameters_file`` (relative to the file's folder)."""
    path = Path(path)
    body = yaml.safe_dump(physics_to_dict(physics, parameters_file), sort_keys=False,
                          default_flow_style=None, width=99)
    path.write_text('\n'.join(_header(header) + [body]))
    return path


__all__ = ['FORMAT', 'FORMAT_V1', 'load_physics', 'physics_from_dict', 'physics_to_dict',
           'vessel_physics', 'write_parameters', 'write_physics']
