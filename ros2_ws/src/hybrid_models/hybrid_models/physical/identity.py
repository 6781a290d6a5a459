"""
Which physics a hybrid corrects: a fingerprint and a name for its physical part.

Studies put each distinct physics in a row of its own and an ensemble accepts only
members on one physics; both ask the same question, answered here once from the part's
description and learned values, never from the paths its files were read from.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

SOURCE_KEYS = ('physics_source', 'params')   # where a physical part's file was read from


def without_sources(described):
    """Return a physical part's description without the paths of the files it read."""
    if isinstance(described, dict):
        return {k: without_sources(v) for k, v in described.items()
                if not (k in SOURCE_KEYS and isinstance(v, str))}
    if isinstance(described, list):
        return [without_sources(v) for v in described]
    return described


def physics_identity(physical) -> tuple[str, str]:
    """
    Return (fingerprint, name) of a hybrid's physical part (a ``nets.PhysicalModule``).

    Equal fingerprints mean equal forecasts: the description and every learned value
    agree, wherever the files were read from (a study copied to another folder keeps its
    physics). The name says the kind and the file it came from, e.g. 'mmg physics
    (augmented_mmg)'; a regression's is its kind alone ('hyd physics').
    """
    described = physical.describe()
    digest = hashlib.sha256(json.dumps(without_sources(described), sort_keys=True,
                                       default=str).encode())
    for key, value in sorted(physical.numpy_model().arrays().items()):
        digest.update(key.encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    parts = [described] if 'first_principles' not in described else [
        described['first_principles']]
    sources = [str(p.get('params') or p.get('physics_source') or '') for p in parts]
    stems = [Path(s).stem for s in sources if s and not s.startswith('<')]
    kind = described['kind']
    name = (kind if kind.startswith('physics') else f'{kind} physics') + (
        f' ({", ".join(stems)})' if stems else '')
    return digest.hexdigest()[:16], name


def physics_label(name: str, fingerprint: str, owner: str, taken: set[str]) -> str:
    """
    Label a physics row distinctly from the ``taken`` labels.

    Two physics of one name (a regression fitted on other data) are told apart by the
    model whose physics it is (``owner``), and by fingerprint only if that is not enough.
    """
    for label in (name, f'{name} (of {owner})'):
        if label not in taken:
            return label
    return f'{name} (of {owner}) [{fingerprint[:6]}]'
