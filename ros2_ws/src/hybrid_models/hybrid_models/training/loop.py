"""
The fit loop: phases, early stopping on validation multistep error, resumable.

One epoch = one pass over tiling training sequences (``hybrid_models.data``), then a
validation forecast. After every epoch ``last.safetensors`` (model, optimizer and this
loop's state) is written atomically, and ``best.safetensors`` whenever the validation
multistep score improves, so a killed run resumes losing at most the epoch in flight.
Where the task has a reference (a hybrid's physics alone), it is epoch -1: the best
until an epoch forecasts the validation runs better.
Each epoch reseeds torch and numpy from (seed, epoch), which makes a resumed run
repeat exactly what the uninterrupted one would have done.

The same loop trains on several processes (``hybrid_models.training.distributed``):
every rank runs it, the model is wrapped in DistributedDataParallel, each rank trains
on its share of every global batch, the losses and validation figures are summed over
ranks (so every decision below is taken on the same numbers everywhere), and only
rank 0 writes checkpoints and the log or prints.
"""

from __future__ import annotations

from collections.abc import Callable
import copy
from dataclasses import asdict, dataclass
import json
import math
from pathlib import Path
import sys
import time

import numpy as np
import torch
from torch import nn
from tqdm import tqdm

from hybrid_models.checkpoint import load_checkpoint, restore_optimizer, save_checkpoint
from hybrid_models.training.distributed import Group, Shard

LAST, BEST, LOG = 'last.safetensors', 'best.safetensors', 'log.jsonl'
REFERENCE_EPOCH = -1   # the task's reference (a hybrid's physics alone) as an epoch
# Improvements smaller than this fraction do not reset the patience counter.
MIN_REL_IMPROVEMENT = 1e-3


@dataclass
class LoopState:
    """Where training stands; stored in ``last.safetensors``."""

    phase: int = 0
    phase_epoch: int = 0
    epoch: int = 0
    best_score: float = math.inf
    best_epoch: int = -1
    phase_best: float = math.inf
    bad_epochs: int = 0
    bad_steps: int = 0
    rollbacks: int = 0
    lr_scale: float = 1.0
    elapsed_s: float = 0.0
    finished: bool = False
    stop_reason: str = ''


class Task:
    """What the loop needs from a model family (see ``hybrid_models.training.train``)."""

    def batches(self, phase: dict, epoch: int, rng: np.random.Generator, shard: Shard):
        """
        Yield (batch, weight) for one epoch of ``phase``: this rank's part of each batch.

        ``rng`` is the same on every rank; ``shard.deal`` gives the part and its loss
        weight (1.0 on one process).
        """
        raise NotImplementedError

    def loss(self, model: nn.Module, phase: dict, batch) -> torch.Tensor:
        """Training loss of one batch."""
        raise NotImplementedError

    def validate(self, model: nn.Module, phase: dict) -> dict:
        """Return validation figures: ``score`` (multistep) and optionally ``teacher``."""
        raise NotImplementedError

    def reference(self, model: nn.Module) -> dict | None:
        """
        Return the validation ``score`` an epoch must beat to be the best (None: none).

        A hybrid's is its physics alone: epoch -1, which the untrained model is when
        its correction starts at zero.
        """
        return None


def _json_safe(x: float) -> float | None:
    return x if math.isfinite(x) else None


def seed_epoch(seed: int, epoch: int, rank: int = 0) -> np.random.Generator:
    """
    Seed torch for this epoch and return its numpy generator.

    The numpy generator (batch order) is the same on every rank; torch's (dropout)
    differs by rank so that ranks do not share dropout masks.
    """
    torch.manual_seed(seed * 1_000_003 + epoch + rank * 7_919)
    return np.random.default_rng([seed, epoch])


class _Objective(nn.Module):
    """The task's training loss as ``forward``: what DDP needs to synchronize gradients."""

    def __init__(self, model: nn.Module, task: Task):
        super().__init__()
        self.model, self.task = model, task

    def forward(self, phase: dict, batch) -> torch.Tensor:
        return self.task.loss(self.model, phase, batch)


def fit(model: nn.Module, task: Task, cfg: dict, out_dir: Path,
        checkpoint_config: Callable[[], dict], resume: bool = False,
        group: Group | None = None) -> LoopState:
    """
    Train ``model`` through ``cfg['phases']``; returns the final loop state.

    ``checkpoint_config()`` gives the JSON config stored in every checkpoint (model
    description, normalization, dataset hash, ...); the loop adds its own state.
    ``group``: this process's place in a torchrun job (None: one process).
    """
    group = group or Group()
    out_dir = Path(out_dir)
    if group.main:
        out_dir.mkdir(parents=True, exist_ok=True)
    objective = group.wrap(_Objective(model, task))
    phases = cfg['phases']
    state = LoopState()
    optimizer = None
    if resume and (out_dir / LAST).exists():
        ckpt = load_checkpoint(out_dir / LAST)
        model.load_state_dict(ckpt.model_state)
        state = LoopState(**ckpt.config['loop'])
        if not state.finished and ckpt.optim_state and ckpt.config.get('optimizer_phase') \
                == state.phase:
            optimizer = _optimizer(model, phases[state.phase], cfg, state)
            restore_optimizer(optimizer, ckpt)
        if group.main:
            _truncate_log(out_dir / LOG, state.epoch)
            print(f'resuming at epoch {state.epoch} (phase {state.phase})', file=sys.stderr)
    else:
        if group.main:
            # A fresh run must not inherit a previous run's log or best model.
            for stale in (LOG, BEST):
                (out_dir / stale).unlink(missing_ok=True)
        _start_from_reference(model, task, state, out_dir, checkpoint_config, group)
    limit = cfg.get('time_limit_minutes')
    while not state.finished and state.phase < len(phases):
        phase = phases[state.phase]
        if optimizer is None:
            optimizer = _optimizer(model, phase, cfg, state)
        start = time.monotonic()
        snapshot = (copy.deepcopy(model.state_dict()), copy.deepcopy(optimizer.state_dict()))
        rng = seed_epoch(cfg['seed'], state.epoch, group.rank)
        train_loss, n_bad, n_steps = _train_epoch(objective, task, phase, optimizer, cfg,
                                                  state, rng, group)
        val = _agreed(task.validate(model, phase), group)
        criterion = val['teacher'] if phase['kind'] == 'teacher' else val['score']
        rolled_back = not math.isfinite(criterion) or n_bad > cfg['max_bad_step_fraction'] * \
            max(n_steps, 1)
        state.bad_steps += n_bad
        if rolled_back:
            # Diverged: return to the epoch's start and halve the step size.
            model.load_state_dict(snapshot[0])
            optimizer.load_state_dict(snapshot[1])
            state.rollbacks += 1
            state.lr_scale *= 0.5
            for param_group in optimizer.param_groups:
                param_group['lr'] = phase['lr'] * state.lr_scale
            state.bad_epochs += 1
        else:
            if val['score'] < state.best_score:
                state.best_score, state.best_epoch = val['score'], state.epoch
                if group.main:
                    save_checkpoint(out_dir / BEST, model, {**checkpoint_config(),
                                                            'val': val, 'epoch': state.epoch})
            if criterion < state.phase_best * (1 - MIN_REL_IMPROVEMENT):
                state.phase_best, state.bad_epochs = criterion, 0
            else:
                state.bad_epochs += 1
        record = {'epoch': state.epoch, 'phase': state.phase, 'phase_kind': phase['kind'],
                  'train_loss': _json_safe(train_loss), 'val_score': _json_safe(val['score']),
                  'val_teacher': _json_safe(val.get('teacher', math.nan)),
                  'lr': optimizer.param_groups[0]['lr'], 'bad_steps': n_bad,
                  'rolled_back': rolled_back, 'best_score': _json_safe(state.best_score),
                  'seconds': round(time.monotonic() - start, 2)}
        state.epoch += 1
        state.phase_epoch += 1
        # The slowest rank's time, so that every rank meets the time limit together.
        state.elapsed_s += group.max(time.monotonic() - start)
        stop_loss = phase.get('stop_loss')
        if state.phase_epoch >= phase['max_epochs'] or state.bad_epochs >= phase['patience'] \
                or (stop_loss is not None and criterion <= stop_loss):
            state.phase += 1
            state.phase_epoch, state.bad_epochs = 0, 0
            state.phase_best, state.lr_scale = math.inf, 1.0
            optimizer = None
        if limit is not None and state.elapsed_s > 60 * limit:
            state.finished, state.stop_reason = True, f'time limit {limit} min'
        if state.phase >= len(phases):
            state.finished = True
            state.stop_reason = state.stop_reason or 'all phases done'
        if not group.main:
            continue
        # The log line first: a kill between the two writes leaves the log one epoch
        # ahead, which a resume truncates and redoes; the other order lost the line.
        with open(out_dir / LOG, 'a') as f:
            f.write(json.dumps(record) + '\n')
        _save_last(out_dir, model, optimizer, state, checkpoint_config())
        print(f"epoch {record['epoch']:3d} {phase['kind']:9s} loss {train_loss:.4g} "
              f"val {val['score']:.4g} best {state.best_score:.4g}"
              + (' (rolled back)' if rolled_back else ''), file=sys.stderr)
    return state


def _start_from_reference(model, task, state, out_dir, checkpoint_config, group) -> None:
    """Make the task's reference (a hybrid's physics alone) epoch -1, the best so far."""
    reference = task.reference(model)
    if reference is None:
        return
    state.best_score, state.best_epoch = reference['score'], REFERENCE_EPOCH
    if not group.main:
        return
    save_checkpoint(out_dir / BEST, model, {**checkpoint_config(), 'val': reference,
                                            'epoch': REFERENCE_EPOCH})
    with open(out_dir / LOG, 'a') as f:
        f.write(json.dumps({'epoch': REFERENCE_EPOCH, 'phase_kind': 'reference',
                            'val_score': _json_safe(reference['score'])}) + '\n')
    print(f"epoch {REFERENCE_EPOCH:3d} reference val {reference['score']:.4g} "
          f"(the physics alone)", file=sys.stderr)


def _optimizer(model: nn.Module, phase: dict, cfg: dict, state: LoopState):
    return torch.optim.Adam([p for p in model.parameters() if p.requires_grad],
                            lr=phase['lr'] * state.lr_scale,
                            weight_decay=cfg.get('weight_decay', 0.0))


def _agreed(val: dict, group: Group) -> dict:
    """Average validation figures over ranks: equal everywhere, so decisions agree."""
    keys = sorted(val)
    sums = group.sum([float(val[k]) for k in keys])
    return {k: s / group.world for k, s in zip(keys, sums, strict=True)}


def _train_epoch(objective, task, phase, optimizer, cfg, state, rng, group):
    objective.train()
    params = [p for p in objective.parameters() if p.requires_grad]
    total, n_good, n_bad = 0.0, 0, 0
    bar = tqdm(task.batches(phase, state.epoch, rng, group.shard),
               desc=f'epoch {state.epoch}', file=sys.stderr,
               disable=not (cfg.get('progress', True) and group.main), leave=False,
               mininterval=2.0)
    for batch, weight in bar:
        optimizer.zero_grad(set_to_none=True)
        loss = objective(phase, batch) * weight if weight != 1.0 else objective(phase, batch)
        # The global batch's loss; NaN on any rank makes every rank skip this step.
        (global_loss,) = group.sum([float(loss.detach()) / group.world])
        if not math.isfinite(global_loss):
            n_bad += 1
            continue
        loss.backward()
        norm = nn.utils.clip_grad_norm_(params, cfg['grad_clip'])
        if not torch.isfinite(norm):
            # NaN guard: a non-finite gradient would poison the weights; skip the step.
            n_bad += 1
            optimizer.zero_grad(set_to_none=True)
            continue
        optimizer.step()
        total += global_loss
        n_good += 1
        bar.set_postfix(loss=f'{total / n_good:.4g}', refresh=False)
    return (total / n_good if n_good else math.nan), n_bad, n_good + n_bad


def _save_last(out_dir, model, optimizer, state, config):
    config = {**config, 'loop': asdict(state),
              'optimizer_phase': state.phase if optimizer is not None else None}
    save_checkpoint(out_dir / LAST, model, config, optimizer)


def _truncate_log(path: Path, epochs_done: int) -> None:
    """Drop log lines of epochs that the resumed run will redo."""
    if not path.exists():
        return
    keep = [line for line in path.read_text().splitlines()
            if line.strip() and json.loads(line)['epoch'] < epochs_done]
    path.write_text(''.join(line + '\n' for line in keep))
