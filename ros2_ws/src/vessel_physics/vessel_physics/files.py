"""Reading parameter and configuration files: YAML and numeric fields, one-line errors."""

from __future__ import annotations

from collections.abc import Iterable, Mapping
import math
from pathlib import Path
from typing import Any

from vessel_description import resources
from vessel_physics.errors import ConfigError, did_you_mean


def read_yaml(path: str | Path, what: str) -> Any:
    """Return the YAML document of ``path``; ConfigError names the file and the reason."""
    return resources.read_yaml(path, ConfigError, what)


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
