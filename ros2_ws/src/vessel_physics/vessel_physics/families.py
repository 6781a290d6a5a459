"""The families this package knows: the one place that lists them (``family.Family``)."""

from __future__ import annotations

from vessel_physics.errors import ConfigError
from vessel_physics.family import Family
from vessel_physics.fossen import FAMILY as FOSSEN
from vessel_physics.mmg import FAMILY as MMG
from vessel_physics.multirotor import FAMILY as MULTIROTOR
from vessel_physics.patrol import FAMILY as PATROL

FAMILIES: dict[str, Family] = {f.name: f for f in (PATROL, MMG, FOSSEN, MULTIROTOR)}


def family_of_format(fmt, source: str) -> Family:
    """
    Return the family whose parameter files carry the format tag ``fmt``.

    Patrol parameter files written before the tag existed have none (``fmt`` None).
    """
    if fmt is None:
        return PATROL
    for family in FAMILIES.values():
        if family.parameters_format == fmt:
            return family
    known = ', '.join(['vessel-physics/2'] + [f.parameters_format for f in FAMILIES.values()])
    raise ConfigError(f'{source}: format: {fmt!r} is no physics or parameter file format '
                      f'(known: {known})')
