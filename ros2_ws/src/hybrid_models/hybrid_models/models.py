"""Build any forecaster from its JSON description, and run it on windows."""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from hybrid_models.data import Windows
from hybrid_models.ensemble import KIND as ENSEMBLE
from hybrid_models.ensemble import EnsembleHybrid
from hybrid_models.nets import HybridModel, LSTMBaseline, as_tensor, module_device
from hybrid_models.physical import build_physical
from hybrid_models.qlag import QLag
from vessel_description import Vessel

MODEL_KINDS = ('qlag', 'lstm', 'hybrid', 'hybrid_ensemble')


def build_model(cfg: dict, spec: Vessel) -> nn.Module:
    """Build an untrained model of the described kind and architecture."""
    kind = cfg.get('kind')
    if kind == 'qlag':
        return QLag(spec, lag=int(cfg.get('lag', 4)), ridge=float(cfg.get('ridge', 1e-8)))
    # Checkpoints older than the key 'cell' were LSTMs.
    if kind == 'lstm':
        return LSTMBaseline(spec, int(cfg.get('hidden', 64)), int(cfg.get('layers', 2)),
                            float(cfg.get('dropout', 0.25)), cfg.get('cell', 'lstm'))
    if kind == 'hybrid':
        model = HybridModel(spec, build_physical(cfg['physical'], spec),
                            int(cfg.get('hidden', 64)), int(cfg.get('layers', 2)),
                            float(cfg.get('dropout', 0.25)), cfg.get('bound_mode', 'tanh'),
                            bool(cfg.get('bound_in_training', False)),
                            # Checkpoints older than the key were trained from torch's init.
                            cfg.get('correction_init', 'random'), cfg.get('cell', 'lstm'),
                            bool(cfg.get('novelty_fade', False)))
        model.relative_threshold = cfg.get('relative_threshold')
        return model
    if kind == ENSEMBLE:
        model = EnsembleHybrid([build_model(cfg['member'], spec)
                                for _ in range(int(cfg['members']))])
        model.relative_threshold = cfg.get('relative_threshold')
        return model
    raise ValueError(f'unknown model kind {kind!r}; use one of {MODEL_KINDS}')


@torch.no_grad()
def predict(model: nn.Module, windows: Windows, batch_size: int = 1024,
            bounds: torch.Tensor | None = None) -> np.ndarray:
    """
    Forecasts (B, H, n_state) for every window, in evaluation mode.

    ``bounds`` (H, B, n_state): a hybrid's half-widths per step and window instead of
    its served threshold's (``HybridModel.forecast``).
    """
    was_training = model.training
    model.eval()
    out = []
    device = module_device(model)
    try:
        for i in range(0, len(windows), batch_size):
            w = windows.subset(slice(i, i + batch_size))
            rows = {} if bounds is None else {'bounds': bounds[:, i:i + batch_size]}
            out.append(model.forecast(as_tensor(w.z_window, device),
                                      as_tensor(w.c_window, device),
                                      as_tensor(w.c_future, device), **rows).cpu().numpy())
    finally:
        model.train(was_training)
    return np.concatenate(out)
