"""Train what a config asks for: one model, or an ensemble of ``training.members`` hybrids."""

from __future__ import annotations

from pathlib import Path

from hybrid_models.training.ensemble import train_ensemble
from hybrid_models.training.train import train_model


def train(cfg: dict, out_dir: str | Path, resume: bool = False, device: str = 'auto') -> dict:
    """
    Train the configured model or ensemble; return the final checkpoint's config.

    ``training.members`` 1: ``train.train_model``; more: ``ensemble.train_ensemble``, which
    trains each member with ``train_model`` and serves them as one.
    """
    if cfg['training']['members'] > 1:
        return train_ensemble(cfg, Path(out_dir), resume, device)
    return train_model(cfg, out_dir, resume, device)
