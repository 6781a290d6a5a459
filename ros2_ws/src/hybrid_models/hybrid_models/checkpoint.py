"""
Checkpoints: one safetensors file holding the weights and a JSON description.

Layout: tensors ``model/<state_dict key>`` (and, for resumable training files,
``optim/<param index>/<key>``); the safetensors header metadata carries
``format = hybrid-models-checkpoint/1`` and ``config``, a JSON document with the model
kind and architecture, normalization, output range and bound, physics description
and parameter YAML, dataset hash, training config and metrics. The header is plain
JSON after an 8-byte length, so other languages read it directly; serving reads it
without torch (``hybrid_models.checkpoint_format``).

Loading never unpickles: the header is parsed and checked before any tensor is
read, and anything that is not our format is refused with one ``CheckpointError``
line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from safetensors import SafetensorError
from safetensors.torch import load_file, save_file
import torch
from torch import nn

from hybrid_models import novelty
from hybrid_models.checkpoint_format import (
    FORMAT,
    CheckpointError,
    read_header,
    rewrite_config,
    vessel_of,
    write_file,
)
from hybrid_models.ensemble import is_hybrid
from hybrid_models.models import build_model
from vessel_description import Vessel

__all__ = ['FORMAT', 'Checkpoint', 'CheckpointError', 'load_checkpoint', 'load_model',
           'read_header', 'restore_optimizer', 'save_checkpoint', 'upgrade_checkpoint']

@dataclass
class Checkpoint:
    """The parts of a checkpoint file."""

    config: dict
    model_state: dict[str, torch.Tensor]
    optim_state: dict[str, torch.Tensor] = field(default_factory=dict)


def save_checkpoint(path: str | Path, model: nn.Module, config: dict,
                    optimizer: torch.optim.Optimizer | None = None) -> Path:
    """Write atomically (temporary file, then rename), so a kill never leaves half a file."""
    path = Path(path)
    calibrations = novelty.stored(model)
    if calibrations is not None:
        config = {**config, 'novelty': calibrations}
    # Stored from the CPU, so a checkpoint written on a GPU loads anywhere.
    tensors = {f'model/{k}': v.detach().cpu().contiguous().clone()
               for k, v in model.state_dict().items()}
    config = dict(config)
    if optimizer is not None:
        opt = optimizer.state_dict()
        scalars = {}
        for idx, state in opt['state'].items():
            for key, value in state.items():
                if isinstance(value, torch.Tensor):
                    tensors[f'optim/{idx}/{key}'] = value.detach().cpu().contiguous().clone()
                else:
                    scalars[f'{idx}/{key}'] = value
        config['optimizer'] = {'param_groups': opt['param_groups'], 'scalars': scalars}
    return write_file(path, tensors, config, save_file)


def load_checkpoint(path: str | Path) -> Checkpoint:
    """Read config and tensors of a checkpoint."""
    config = read_header(path)
    try:
        tensors = load_file(str(path))
    except (SafetensorError, OSError) as exc:
        raise CheckpointError(f'{path}: damaged hybrid_models checkpoint ({exc})') from None
    model_state = {k[6:]: v for k, v in tensors.items() if k.startswith('model/')}
    optim_state = {k[6:]: v for k, v in tensors.items() if k.startswith('optim/')}
    return Checkpoint(config, model_state, optim_state)


def restore_optimizer(optimizer: torch.optim.Optimizer, ckpt: Checkpoint) -> None:
    """Load the optimizer state saved by ``save_checkpoint``."""
    saved = ckpt.config.get('optimizer')
    if saved is None:
        raise CheckpointError('checkpoint holds no optimizer state')
    state: dict[int, dict] = {}
    for key, value in ckpt.optim_state.items():
        idx, name = key.split('/', 1)
        state.setdefault(int(idx), {})[name] = value
    for key, value in saved['scalars'].items():
        idx, name = key.split('/', 1)
        state.setdefault(int(idx), {})[name] = value
    optimizer.load_state_dict({'state': state, 'param_groups': saved['param_groups']})


def upgrade_checkpoint(path: str | Path, vessel: Vessel) -> None:
    """
    Give a checkpoint made before vessel files the description of ``vessel``.

    Only the header changes, and only when the stored vectors and rate are the vessel's;
    weights are kept bit for bit.
    """
    config = read_header(path)
    old = config.get('vehicle') or {}
    if 'format' in old:
        return  # already a vessel description
    stored = (tuple(old.get('state_names', ())), tuple(old.get('control_names', ())),
              old.get('rate_hz'))
    if stored != (vessel.state_names, vessel.control_names, vessel.rate_hz):
        raise CheckpointError(f'{path}: stored vectors and rate {stored} are not those of '
                              f'vessel {vessel.name!r}')
    rewrite_config(path, {**config, 'vehicle': vessel.to_dict()})


def load_model(path: str | Path) -> tuple[nn.Module, dict]:
    """Rebuild a trained model from its checkpoint; returns (model in eval mode, config)."""
    ckpt = load_checkpoint(path)
    spec = vessel_of(ckpt.config, path)
    try:
        model = build_model(ckpt.config['model'], spec)
        model.load_state_dict(ckpt.model_state)
    except (KeyError, TypeError, ValueError, RuntimeError) as exc:
        raise CheckpointError(f'{path}: checkpoint does not match its model '
                              f'({type(exc).__name__}: {exc})'.splitlines()[0]) from None
    _restore_novelty(model, ckpt.config.get('novelty'), path)
    model.eval()
    return model, ckpt.config


def load_hybrid(path: str | Path, having: str) -> tuple[nn.Module, dict]:
    """Load a hybrid or an ensemble of them; refuse another model, naming what it lacks."""
    model, config = load_model(path)
    if not is_hybrid(model):
        raise CheckpointError(f'{path}: only hybrid models (and ensembles of them) have '
                              f'{having} (this is '
                              f'{getattr(model, "kind", type(model).__name__)!r})')
    return model, config


def _restore_novelty(model: nn.Module, stored: list | None, path) -> None:
    """Give each member its calibration (``hybrid_models.novelty``) from the config."""
    members = novelty.hybrids_of(model)
    for m, entry in zip(members, stored or [None] * len(members), strict=False):
        if entry is not None:
            m.novelty = novelty.Novelty.from_dict(entry)
        if getattr(m, 'novelty_fade', False) and m.novelty is None:
            raise CheckpointError(f'{path}: the model is served with the novelty fade but '
                                  f'holds no novelty calibration (train it again)')
