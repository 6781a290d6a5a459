"""
A dataset carries its vessel's own physics file, so that nothing it names is left behind.

A vessel file may name a physics file of its own beside it (``physics: my_mmg.yaml``).
A dataset keeps the vessel description in its manifest, not the vessel file's folder,
so every later step (training, the diagnosis, the workflow's fold views) would look
for that file beside the manifest and not find it. ``carry`` writes the physics into
the dataset as one self-contained file (its parameter values inline) and returns the
vessel naming that file; ``carry_into_view`` gives a view of the dataset the same file.
Packaged physics files stay named as they are: every installation has them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
import shutil

import yaml

from vessel_description import Vessel
from vessel_physics.errors import ConfigError
from vessel_physics.files import config_dir, find_file
from vessel_physics.physics_file import load_physics, physics_to_dict

PREFIX = 'physics_'   # the carried file: physics_<its own name>.yaml in the dataset root


def carry(vessel: Vessel, out: Path) -> Vessel:
    """Write the vessel's own physics file into ``out``; return the vessel naming it."""
    if vessel.physics is None or not Path(vessel.source).is_file():
        return vessel
    try:
        path = find_file(vessel.physics, [Path(vessel.source).resolve().parent]).resolve()
    except ConfigError:
        return vessel   # whoever needs the physics refuses it, with this same one line
    if path.is_relative_to(config_dir().resolve()):
        return vessel
    name = f'{PREFIX}{path.stem}.yaml'
    try:
        document = physics_to_dict(load_physics(path), inline=True)
    except ConfigError:
        return vessel   # not a physics file (e.g. the vessel file itself): refused where used
    document['description'] = f'{path.name} as the dataset was made (parameters inline)'
    (out / name).write_text(yaml.safe_dump(document, sort_keys=False))
    return replace(vessel, physics=name)


def carry_into_view(vessel: Vessel, root: Path, view: Path) -> None:
    """Give a view of the dataset at ``root`` the physics file the dataset carries."""
    if vessel.physics and (root / vessel.physics).is_file() and root != view:
        shutil.copyfile(root / vessel.physics, view / vessel.physics)
