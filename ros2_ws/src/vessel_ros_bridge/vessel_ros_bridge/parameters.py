"""
Declare a node's parameters from a YAML spec, with descriptors.

A spec file maps each parameter name to its ``default``, a ``description`` and, for
numbers, an inclusive ``range: [low, high]``; ``read_only: true`` marks parameters that
only make sense at start-up. The type follows the default (bool, int, float, str).
Keeping the spec in the package's ``config/`` puts every default and limit in one
reviewed file, and ``ros2 param describe`` shows the same text a reader sees there.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
)
import yaml

ALLOWED_KEYS = {'default', 'description', 'range', 'read_only'}


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter: name, default (fixes the type), description, optional range."""

    name: str
    default: bool | int | float | str
    description: str
    value_range: tuple[float, float] | None = None
    read_only: bool = False

    def descriptor(self) -> ParameterDescriptor:
        """Return the rclpy descriptor carrying description, range and read-only flag."""
        descriptor = ParameterDescriptor(description=self.description,
                                         read_only=self.read_only)
        if self.value_range is not None:
            low, high = self.value_range
            if isinstance(self.default, int):
                descriptor.integer_range = [IntegerRange(from_value=int(low),
                                                         to_value=int(high), step=0)]
            else:
                descriptor.floating_point_range = [FloatingPointRange(
                    from_value=float(low), to_value=float(high), step=0.0)]
        return descriptor


def parse_specs(data: dict, source: str) -> list[ParameterSpec]:
    """Check and convert a loaded spec mapping; errors name the source and parameter."""
    if not isinstance(data, dict) or not data:
        raise ValueError(f'{source}: expected a mapping of parameter names to specs')
    specs = []
    for name, entry in data.items():
        where = f'{source}: parameter {name!r}'
        if not isinstance(entry, dict) or 'default' not in entry:
            raise ValueError(f'{where}: needs a mapping with at least a default')
        unknown = set(entry) - ALLOWED_KEYS
        if unknown:
            raise ValueError(f'{where}: unknown keys {sorted(unknown)}; '
                             f'allowed {sorted(ALLOWED_KEYS)}')
        default = entry['default']
        if not isinstance(default, (bool, int, float, str)):
            raise ValueError(f'{where}: default must be a bool, number or string')
        value_range = entry.get('range')
        if value_range is not None:
            if (isinstance(default, (bool, str)) or len(value_range) != 2
                    or not value_range[0] <= default <= value_range[1]):
                raise ValueError(f'{where}: range {value_range} must be [low, high] around '
                                 f'the numeric default {default!r}')
            value_range = (value_range[0], value_range[1])
        specs.append(ParameterSpec(name=name, default=default,
                                   description=str(entry.get('description', '')).strip(),
                                   value_range=value_range,
                                   read_only=bool(entry.get('read_only', False))))
    return specs


def load_specs(path: str | Path) -> list[ParameterSpec]:
    """Load a spec file (see the module docstring)."""
    with open(path) as stream:
        return parse_specs(yaml.safe_load(stream), str(path))


def declare_from_specs(node, specs: list[ParameterSpec]) -> dict:
    """Declare every parameter on ``node``; return the values in force (with overrides)."""
    values = {}
    for spec in specs:
        parameter = node.declare_parameter(spec.name, spec.default, spec.descriptor())
        values[spec.name] = parameter.value
    return values


def package_config(package: str, filename: str) -> Path:
    """Return the installed path of ``config/<filename>`` in a package's share directory."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory(package)) / 'config' / filename
