"""Finding and checking parameter files: where they are, their numeric fields, one-line errors."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math
import os
from pathlib import Path
from typing import Any

from vessel_description.resources import data_dir, read_yaml
from vessel_physics.errors import ConfigError, did_you_mean

# How reports name a packaged file: vessel_physics/config/<its path in config_dir()>.
PACKAGED = ('vessel_physics', 'config')


def config_dir() -> Path:
    """Directory of the packaged physics and simulation files (source tree or install)."""
    return data_dir('vessel_physics', __file__, 'config')


def find_file(name: str | os.PathLike, beside: Iterable[Path | None] = (),
              what: str = 'physics file') -> Path:
    """
    Return the file ``name`` names: a path, else beside one of ``beside``, else packaged.

    A name without a suffix gets ``.yaml``. Relative names are looked up in the folders
    ``beside`` (e.g. the folder of the vessel file or physics file that names it), then
    the working directory, then this package's config folder; the error lists them all.
    A packaged file's ``display_name`` (``vessel_physics/config/...``, as reports and
    findings.json name it) finds that file.
    """
    path = Path(name)
    if not path.suffix:
        path = path.with_suffix('.yaml')
    if path.parts[:2] == PACKAGED and (config_dir() / Path(*path.parts[2:])).is_file():
        return config_dir() / Path(*path.parts[2:])
    if path.is_absolute():
        if path.is_file():
            return path
        raise ConfigError(f'{what} {str(path)!r}: no such file')
    folders = [Path(b) for b in beside if b is not None] + [Path('.'), config_dir()]
    for folder in folders:
        if (folder / path).is_file():
            return folder / path
    raise ConfigError(f'no {what} {str(path)!r} (looked in '
                      f'{", ".join(str(f) for f in dict.fromkeys(folders))})')


def read_document(path: str | os.PathLike, what: str) -> Any:
    """Return a YAML file's document; ConfigError (one line) names the file and the reason."""
    return read_yaml(path, ConfigError, what)


def parameter_mapping(data: Any, fmt: str, source: str, what: str = 'parameters') -> dict:
    """
    Return a parameter file's mapping without what it says of itself, its format checked.

    ``data`` is the parsed YAML; ``format`` (``fmt`` where absent), ``description`` and
    ``sources`` are left out. ConfigError (one line) when it is no mapping or of another
    format.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f'{source}: expected a mapping of {what}, got {type(data).__name__}')
    found = data.get('format', fmt)
    if found != fmt:
        raise ConfigError(f'{source}: format: expected {fmt!r}, got {found!r}')
    return {k: v for k, v in data.items() if k not in ('format', 'description', 'sources')}


def numeric_fields(data: Any, known: Iterable[str], numbers: Iterable[str], source: str,
                   what: str) -> dict[str, float]:
    """
    Check that ``data`` has exactly the keys ``known``; return its ``numbers`` as floats.

    Raises ConfigError with one line naming the first unknown, missing or non-numeric key.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f'{source}: expected a mapping of {what}, got {type(data).__name__}')
    known = set(known)
    for key in data:
        if key not in known:
            raise ConfigError(f'{source}: unknown {what[:-1] if what.endswith("s") else what}'
                              f' {key!r}{did_you_mean(str(key), known)}')
    missing = sorted(known - set(data))
    if missing:
        raise ConfigError(f'{source}: missing {what} {missing}')
    values = {}
    for key in numbers:
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            hint = ' (YAML reads 1e6 as text: write 1.0e+6)' if isinstance(value, str) else ''
            raise ConfigError(f'{source}: {key}: must be a number, got {value!r}{hint}')
        values[key] = float(value)
    return values


def check_ranges(params: Any, finite: Iterable[str], positive: Iterable[str] = (),
                 fractions: Iterable[str] = (), source: str = 'parameters') -> None:
    """Raise ConfigError (one line) unless the named attributes are finite, > 0, in [0, 1)."""
    for key in finite:
        if not math.isfinite(getattr(params, key)):
            raise ConfigError(f'{source}: {key}: must be a finite number, got '
                              f'{getattr(params, key)!r}')
    for key in positive:
        if getattr(params, key) <= 0:
            raise ConfigError(f'{source}: {key}: must be > 0, got {getattr(params, key)!r}')
    for key in fractions:
        if not 0 <= getattr(params, key) < 1:
            raise ConfigError(f'{source}: {key}: must be in [0, 1), got '
                              f'{getattr(params, key)!r}')


def display_name(path: str | os.PathLike) -> str:
    """Name a file for a report: packaged ones by package (vessel_physics/config/...)."""
    path = Path(path)
    try:
        return '/'.join([*PACKAGED, str(path.resolve().relative_to(config_dir().resolve()))])
    except ValueError:
        return str(path)
