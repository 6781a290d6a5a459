"""
The checkpoint file format, read without torch: header and tensors as numpy arrays.

A checkpoint is one safetensors file: tensors ``model/<state_dict key>`` (and
``optim/...`` in resumable training files), and header metadata ``format`` and
``config`` (JSON). Writing and rebuilding torch models is ``hybrid_models.checkpoint``;
this module is what serving needs, so that the predictor never imports torch.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import struct

import numpy as np
from safetensors import SafetensorError
from safetensors.numpy import load_file, save_file

from vessel_description import Vessel, VesselError

FORMAT = 'hybrid-models-checkpoint/1'
# A header larger than this is not one of ours (ours are a few hundred kB at most).
MAX_HEADER_BYTES = 64 * 1024 * 1024
MODEL_PREFIX = 'model/'


class CheckpointError(ValueError):
    """A file is not a readable hybrid_models checkpoint."""


def read_header(path: str | Path) -> dict:
    """Read the checkpoint's JSON config from the header alone; refuse foreign files."""
    path = Path(path)
    not_ours = f'{path}: not a hybrid_models checkpoint'
    try:
        with open(path, 'rb') as f:
            raw_len = f.read(8)
            if len(raw_len) < 8:
                raise CheckpointError(f'{not_ours} (too short)')
            (n,) = struct.unpack('<Q', raw_len)
            if n > min(MAX_HEADER_BYTES, path.stat().st_size - 8):
                raise CheckpointError(f'{not_ours} (no safetensors header)')
            header = json.loads(f.read(n).decode('utf-8'))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f'{not_ours} ({type(exc).__name__})') from None
    meta = header.get('__metadata__') if isinstance(header, dict) else None
    if not isinstance(meta, dict) or meta.get('format') != FORMAT:
        raise CheckpointError(f'{not_ours} (format is not {FORMAT})')
    try:
        return json.loads(meta['config'])
    except (KeyError, TypeError, json.JSONDecodeError):
        raise CheckpointError(f'{path}: damaged hybrid_models checkpoint (config)') from None


def read_model_arrays(path: str | Path) -> tuple[dict, dict[str, np.ndarray]]:
    """Return (config, the model's state dict as numpy arrays) of a checkpoint."""
    config = read_header(path)
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError) as exc:
        raise CheckpointError(f'{path}: damaged hybrid_models checkpoint ({exc})') from None
    return config, {k[len(MODEL_PREFIX):]: v for k, v in tensors.items()
                    if k.startswith(MODEL_PREFIX)}


def json_default(value):
    """Turn the values a config may hold (arrays, paths, tuples) into JSON types."""
    if hasattr(value, 'tolist'):
        return value.tolist()
    if isinstance(value, (Path, tuple)):
        return str(value) if isinstance(value, Path) else list(value)
    raise TypeError(f'cannot store {type(value).__name__} in a checkpoint config')


def write_file(path: str | Path, tensors: dict, config: dict, save=save_file) -> Path:
    """
    Write tensors and config as a checkpoint, atomically (temporary file, then rename).

    ``save`` is safetensors' writer of the tensors' framework (numpy here; torch in
    ``hybrid_models.checkpoint``), so a kill never leaves half a file.
    """
    path = Path(path)
    meta = {'format': FORMAT, 'config': json.dumps(config, default=json_default)}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + '.tmp')
    save(tensors, str(tmp), metadata=meta)
    os.replace(tmp, path)
    return path


def rewrite_config(path: str | Path, config: dict, out: str | Path | None = None) -> Path:
    """Write ``path``'s tensors, bit for bit, with a new config to ``out`` (default: in place)."""
    read_header(path)
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError) as exc:
        raise CheckpointError(f'{path}: damaged hybrid_models checkpoint ({exc})') from None
    return write_file(out or path, tensors, config)


def vessel_of(config: dict, path: str | Path) -> Vessel:
    """Return the vessel description a checkpoint's config carries; refuse old files."""
    stored = config.get('vehicle') or {}
    if 'format' not in stored:
        raise CheckpointError(f'{path}: made before vessel files (no vessel description); '
                              f'give it one with hybrid_models.checkpoint.upgrade_checkpoint')
    try:
        return Vessel.from_dict(stored)
    except (KeyError, TypeError, ValueError, VesselError) as exc:
        raise CheckpointError(f'{path}: damaged vessel description ({exc})') from None
