"""
Declare a node's parameters from a YAML spec, with descriptors.

A spec file maps each parameter name to its ``default``, a ``description`` and, for
numbers, an inclusive ``range: [low, high]``; ``read_only: true`` marks parameters that
only make sense at start-up. The type follows the default (bool, int, float, str).
A parameter that may stay unset has ``default: null`` and names its ``type`` (bool, int,
double, string): it is declared typed but without a value, so ``ros2 param get`` says
"not set" and the node reads None until a user gives one.
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

ALLOWED_KEYS = {'default', 'description', 'range', 'read_only', 'type'}
# The types an unset parameter (default: null) may name, and the value types they take.
UNSET_TYPES = {'bool': bool, 'int': int, 'double': float, 'string': str}


@dataclass(frozen=True)
class ParameterSpec:
    """One parameter: name, default (fixes the type), description, optional range."""

    name: str
    default: bool | int | float | str | None
    description: str
    value_range: tuple[float, float] | None = None
    read_only: bool = False
    unset_type: str | None = None   # for default None: the type it takes when set

    @property
    def value_type(self) -> type:
        """Return the Python type of the parameter's values."""
        return UNSET_TYPES[self.unset_type] if self.default is None else type(self.default)

    def descriptor(self) -> ParameterDescriptor:
        """Return the rclpy descriptor carrying description, range and read-only flag."""
        descriptor = ParameterDescriptor(description=self.description,
                                         read_only=self.read_only)
        if self.value_range is not None:
            low, high = self.value_range
            if self.value_type is int:
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
        unset_type = entry.get('type')
        if default is None and unset_type not in UNSET_TYPES:
            raise ValueError(f'{where}: default null needs a type, one of '
                             f'{sorted(UNSET_TYPES)}')
        if default is not None and (unset_type is not None or
                                    not isinstance(default, (bool, int, float, str))):
            raise ValueError(f'{where}: default must be a bool, number or string (its type '
                             f'is the type; give type only with default null)')
        value_range = entry.get('range')
        if value_range is not None:
            numeric = unset_type in ('int', 'double') if default is None else (
                isinstance(default, (int, float)) and not isinstance(default, bool))
            if (not numeric or len(value_range) != 2 or value_range[0] > value_range[1]
                    or (default is not None and
                        not value_range[0] <= default <= value_range[1])):
                raise ValueError(f'{where}: range {value_range} must be [low, high] around '
                                 f'the numeric default {default!r}')
            value_range = (value_range[0], value_range[1])
        specs.append(ParameterSpec(name=name, default=default,
                                   description=str(entry.get('description', '')).strip(),
                                   value_range=value_range,
                                   read_only=bool(entry.get('read_only', False)),
                                   unset_type=unset_type))
    return specs


def load_specs(path: str | Path) -> list[ParameterSpec]:
    """Load a spec file (see the module docstring)."""
    with open(path) as stream:
        return parse_specs(yaml.safe_load(stream), str(path))


def declare_from_specs(node, specs: list[ParameterSpec]) -> dict:
    """Declare every parameter on ``node``; return the values in force (with overrides)."""
    from rclpy.parameter import Parameter

    rclpy_types = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER,
                   float: Parameter.Type.DOUBLE, str: Parameter.Type.STRING}
    values = {}
    for spec in specs:
        value = spec.default if spec.default is not None else rclpy_types[spec.value_type]
        parameter = node.declare_parameter(spec.name, value, spec.descriptor())
        values[spec.name] = parameter.value
    return values


def package_config(package: str, filename: str) -> Path:
    """Return the installed path of ``config/<filename>`` in a package's share directory."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory(package)) / 'config' / filename
