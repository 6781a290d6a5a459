"""
Batches, losses and validation for the recurrent models (LSTM baseline, hybrid).

Losses are mean squared errors of states divided by the training state std, so every
state weighs equally whatever its unit. ``teacher`` (phase 1 of 2P) feeds the TRUE
previous state to the physical model and trains the one-step residual; ``multistep``
feeds the model's own predictions back over ``sequence_length`` samples.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
from torch import nn

from hybrid_models.data import forecast_starts, gather_windows, tiling_starts, window_index
from hybrid_models.metrics import StepErrors
from hybrid_models.models import predict
from hybrid_models.nets import as_tensor
from hybrid_models.selection import PHYSICS_ALONE
from hybrid_models.training.distributed import Group, Shard
from hybrid_models.training.loop import Task

VAL_CHUNK = 1024  # validation windows evaluated at once (bounds memory, not results)


def gather_next(per_run: list, run_index: np.ndarray, t0: np.ndarray,
                length: int) -> np.ndarray:
    """Rows ``a[t0-1+k]`` (k < length) of per-run row sources aligned with one-step inputs."""
    out = None
    for i in np.unique(run_index):
        at = np.flatnonzero(run_index == i)
        part = per_run[i].rows(t0[at] - 1, length)
        if out is None:
            out = np.empty((len(t0),) + part.shape[1:], dtype=np.float32)
        out[at] = part
    return out


def batch_size(sequences: int, cfg: dict) -> int:
    """
    Return the batch size of an epoch of ``sequences`` training sequences.

    ``batch_size`` unless that leaves fewer than ``min_batches_per_epoch`` optimizer steps
    per epoch, as a few short recordings do; then smaller, down to ``min_batch_size``.
    """
    fit = sequences // max(int(cfg['min_batches_per_epoch']), 1)
    return int(min(cfg['batch_size'], max(fit, int(cfg['min_batch_size']))))


class RecurrentTask(Task):
    """
    Training data and objectives for LSTM and hybrid models.

    ``train`` / ``val``: runs with ``rows(first, count)`` (``run_store.RunFile`` on disk
    or ``RunArrays``); windows are cut a batch at a time, so memory holds batches only.
    ``z_phy_train`` / ``z_phy_val``: per run, row sources of the physical model's one-step
    output from the measured state, ``z_phy[t] = phy(z[t], c[t])`` (a prediction of
    z[t+1]); needed only for teacher forcing. Validation windows are shared out over the
    ranks of ``group`` and their error sums added up.
    """

    def __init__(self, spec, train: list, val: list, cfg: dict, state_std: np.ndarray,
                 z_phy_train=None, z_phy_val=None, group: Group | None = None):
        self.spec, self.train, self.val, self.cfg = spec, train, val, cfg
        self.group = group or Group()
        self.device = self.group.device
        self.state_std = as_tensor(state_std, self.device)
        self.state_std_np = np.asarray(state_std, dtype=np.float64)
        self.z_phy_train, self.z_phy_val = z_phy_train, z_phy_val
        v = cfg['validation']
        self.val_index = window_index([forecast_starts(r.length, cfg['window'], v['horizon'],
                                                       v['stride']) for r in val])
        if len(self.val_index[1]) == 0:
            raise ValueError(f"no validation run is long enough for window {cfg['window']} "
                             f"+ horizon {v['horizon']}")

    def _length(self, phase: dict) -> int:
        return int(phase.get('sequence_length') or self.cfg['sequence_length'])

    def batches(self, phase: dict, epoch: int, rng: np.random.Generator, shard: Shard):
        """Shuffled tiling sequences with a fresh offset each epoch; this rank's part."""
        length = self._length(phase)
        run_index, t0 = window_index(tiling_starts(self.train, self.cfg['window'], length,
                                                   int(rng.integers(0, length))))
        order = rng.permutation(len(t0))
        bs = batch_size(len(t0), self.cfg)
        for i in range(0, len(order), bs):
            dealt = shard.deal(order[i:i + bs])
            if dealt is None:
                continue
            idx, weight = dealt
            w = gather_windows(self.train, run_index[idx], t0[idx], self.cfg['window'],
                               length)
            z_phy = gather_next(self.z_phy_train, w.run_index, w.t0, length) \
                if phase['kind'] == 'teacher' else None
            yield (w, z_phy), weight

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

    def _my_chunks(self, run_index: np.ndarray, t0: np.ndarray):
        """Yield (run_index, t0) chunks of this rank's share of windows."""
        mine = np.arange(self.group.rank, len(t0), self.group.world)
        for i in range(0, len(mine), VAL_CHUNK):
            at = mine[i:i + VAL_CHUNK]
            yield run_index[at], t0[at]

    @torch.no_grad()
    def validation_errors(self, model: nn.Module) -> StepErrors:
        """Error sums per horizon step of the validation forecasts, over every rank."""
        horizon = self.cfg['validation']['horizon']
        errors = StepErrors(np.zeros((horizon, self.spec.n_state)), np.zeros(horizon), 0)
        for ri, t0 in self._my_chunks(*self.val_index):
            w = gather_windows(self.val, ri, t0, self.cfg['window'], horizon)
            errors = errors + StepErrors.of(predict(model, w), w.z_target, self.spec)
        return StepErrors.from_flat(self.group.sum(errors.flat()), horizon,
                                    self.spec.n_state)

    def alone(self) -> RecurrentTask:
        """Return this task for this process alone: every validation window, no rank sums."""
        alone = copy.copy(self)
        alone.group = Group(device=self.group.device)
        return alone

    @torch.no_grad()
    def validation_forecasts(self, model: nn.Module, stride: int | None = None
                             ) -> tuple[np.ndarray, ...]:
        """
        Return (forecasts, targets, run index) of this rank's validation windows.

        ``stride``: one forecast every this many samples of each run instead of the
        validation stride.
        """
        horizon = self.cfg['validation']['horizon']
        index = self.val_index if stride is None else window_index(
            [forecast_starts(r.length, self.cfg['window'], horizon, stride) for r in self.val])
        preds, targets, runs = [], [], []
        for ri, t0 in self._my_chunks(*index):
            w = gather_windows(self.val, ri, t0, self.cfg['window'], horizon)
            preds.append(predict(model, w))
            targets.append(w.z_target)
            runs.append(ri)
        return np.concatenate(preds), np.concatenate(targets), np.concatenate(runs)

    @torch.no_grad()
    def validation_forecasts_at(self, model: nn.Module, schedules: list
                                ) -> list[tuple[np.ndarray, ...]]:
        """
        Return ``validation_forecasts(model)`` as served at each of ``schedules`` (a list).

        A hybrid's windows are forecast at several thresholds in one batch, each copy of
        them with its own half-widths (``HybridModel.forecast``'s ``bounds``): a
        threshold selection's dozens of forecasts cost a few batches, not a run each.
        """
        horizon = self.cfg['validation']['horizon']
        out = [([], [], []) for _ in schedules]
        for ri, t0 in self._my_chunks(*self.val_index):
            w = gather_windows(self.val, ri, t0, self.cfg['window'], horizon)
            n = len(t0)
            per_batch = max(1, VAL_CHUNK // n)
            for first in range(0, len(schedules), per_batch):
                group = schedules[first:first + per_batch]
                bounds = torch.cat([model.bounds_at(s, horizon)[:, None].expand(-1, n, -1)
                                    for s in group], dim=1)
                pred = predict(model, w.tiled(len(group)), len(group) * n, bounds)
                for j, (preds, targets, runs) in enumerate(out[first:first + len(group)]):
                    preds.append(pred[j * n:(j + 1) * n])
                    targets.append(w.z_target)
                    runs.append(ri)
        return [tuple(np.concatenate(part) for part in forecasts) for forecasts in out]

    def validate(self, model: nn.Module, phase: dict) -> dict:
        """Multistep score (sum of per-state RMSE / std) and, in phase 1, teacher loss."""
        out = {'score': self.validation_errors(model).score(self.state_std_np)}
        if phase['kind'] == 'teacher':
            out['teacher'] = self._teacher_loss(model, phase)
        return out

    def reference(self, model: nn.Module) -> dict | None:
        """Return the physics alone's validation score (a hybrid served at threshold 0)."""
        if not hasattr(model, 'served_at'):
            return None
        with model.served_at(PHYSICS_ALONE):
            return {'score': self.validation_errors(model).score(self.state_std_np)}

    @torch.no_grad()
    def _teacher_loss(self, model, phase) -> float:
        length = self._length(phase)
        model.eval()
        total, count = 0.0, 0
        try:
            index = window_index(tiling_starts(self.val, self.cfg['window'], length, 0))
            for ri, t0 in self._my_chunks(*index):
                w = gather_windows(self.val, ri, t0, self.cfg['window'], length)
                zp = as_tensor(gather_next(self.z_phy_val, ri, t0, length), self.device)
                zw, cw, cf, target = (as_tensor(a, self.device) for a in (
                    w.z_window, w.c_window, w.c_future, w.z_target))
                pred = zp + model.teacher_forced(zw, cw, cf, zp)
                err = ((pred - target) / self.state_std) ** 2
                total += float(err.mean(dim=(1, 2)).double().sum())
                count += len(t0)
        finally:
            model.train()
        total, count = self.group.sum([total, count])
        return total / count
