"""
Batches, losses and validation for the recurrent models (LSTM baseline, hybrid).

Losses are mean squared errors of states divided by the training state std, so every
state weighs equally whatever its unit. ``teacher`` (phase 1 of 2P) feeds the TRUE
previous state to the physical model and trains the one-step residual; ``multistep``
feeds the model's own predictions back over ``sequence_length`` samples.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import nn

from hybrid_models.data import RunArrays, Windows, forecast_windows, tiling_windows
from hybrid_models.metrics import normalized_rmse_sum
from hybrid_models.models import predict
from hybrid_models.nets import as_tensor
from hybrid_models.training.distributed import Shard
from hybrid_models.training.loop import Task


def gather_next(per_run: list[np.ndarray], windows: Windows, length: int) -> np.ndarray:
    """Rows ``a[t0-1+k]`` (k < length) of per-run arrays aligned with one-step inputs."""
    out = np.empty((len(windows), length, per_run[0].shape[1]), dtype=np.float32)
    steps = np.arange(length) - 1
    for i, arr in enumerate(per_run):
        rows = windows.run_index == i
        if rows.any():
            out[rows] = arr[windows.t0[rows, None] + steps]
    return out


class RecurrentTask(Task):
    """
    Training data and objectives for LSTM and hybrid models.

    ``z_phy_train`` / ``z_phy_val``: per run, the physical model's one-step output
    from the measured state, ``z_phy[t] = phy(z[t], c[t])`` (a prediction of z[t+1]);
    needed only for teacher forcing.
    """

    def __init__(self, train: list[RunArrays], val: list[RunArrays], cfg: dict,
                 state_std: np.ndarray, z_phy_train=None, z_phy_val=None,
                 device: torch.device | None = None):
        self.train, self.val, self.cfg = train, val, cfg
        self.device = device or torch.device('cpu')
        self.state_std = as_tensor(state_std, self.device)
        self.state_std_np = np.asarray(state_std, dtype=np.float64)
        self.z_phy_train, self.z_phy_val = z_phy_train, z_phy_val
        v = cfg['validation']
        self.val_windows = forecast_windows(val, cfg['window'], v['horizon'], v['stride'])
        self._val_teacher = None

    def _length(self, phase: dict) -> int:
        return int(phase.get('sequence_length') or self.cfg['sequence_length'])

    def batches(self, phase: dict, epoch: int, rng: np.random.Generator, shard: Shard):
        """Shuffled tiling sequences with a fresh offset each epoch; this rank's part."""
        length = self._length(phase)
        w = tiling_windows(self.train, self.cfg['window'], length,
                           int(rng.integers(0, length)))
        z_phy = gather_next(self.z_phy_train, w, length) if phase['kind'] == 'teacher' \
            else None
        order = rng.permutation(len(w))
        bs = self.cfg['batch_size']
        for i in range(0, len(order), bs):
            dealt = shard.deal(order[i:i + bs])
            if dealt is None:
                continue
            idx, weight = dealt
            yield (w.subset(idx), None if z_phy is None else z_phy[idx]), weight

    def loss(self, model: nn.Module, phase: dict, batch) -> torch.Tensor:
        """Return the normalized MSE of the predicted states."""
        w, z_phy = batch
        zw, cw, cf, target = (as_tensor(a, self.device)
                              for a in (w.z_window, w.c_window, w.c_future, w.z_target))
        if phase['kind'] == 'teacher':
            z_phy = as_tensor(z_phy, self.device)
            pred = z_phy + model.teacher_forced(zw, cw, cf, z_phy)
        else:
            pred = model.forecast(zw, cw, cf)
        return (((pred - target) / self.state_std) ** 2).mean()

    @torch.no_grad()
    def validate(self, model: nn.Module, phase: dict) -> dict:
        """Multistep score (sum of per-state RMSE / std) and, in phase 1, teacher loss."""
        pred = predict(model, self.val_windows)
        out = {'score': normalized_rmse_sum(pred, self.val_windows.z_target,
                                            self.state_std_np)}
        if phase['kind'] == 'teacher':
            out['teacher'] = self._teacher_loss(model, phase)
        return out

    def _teacher_loss(self, model, phase) -> float:
        length = self._length(phase)
        if self._val_teacher is None:
            w = tiling_windows(self.val, self.cfg['window'], length, 0)
            self._val_teacher = (w, gather_next(self.z_phy_val, w, length))
        w, z_phy = self._val_teacher
        model.eval()
        try:
            losses = []
            for i in range(0, len(w), 1024):
                sub = w.subset(slice(i, i + 1024))
                zp = as_tensor(z_phy[i:i + 1024], self.device)
                zw, cw, cf, target = (as_tensor(a, self.device) for a in (
                    sub.z_window, sub.c_window, sub.c_future, sub.z_target))
                pred = zp + model.teacher_forced(zw, cw, cf, zp)
                err = ((pred - target) / self.state_std) ** 2
                losses.append(err.mean(dim=(1, 2)))
            return float(torch.cat(losses).mean())
        finally:
            model.train()
