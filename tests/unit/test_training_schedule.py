"""The fit loop's phase schedule (1P/2P), early stopping, NaN guard and rollback."""

import json
import math

import numpy as np
import pytest
import torch
from torch import nn

from hybrid_models.training.loop import BEST, LAST, LOG, Task, fit


class Scripted(Task):
    """Two batches per epoch; validation numbers come from a script."""

    def __init__(self, teacher=(), score=(), nan_batches=()):
        self.teacher, self.score = list(teacher), list(score)
        self.nan_batches = set(nan_batches)
        self.calls = 0

    def batches(self, phase, epoch, rng, shard):
        yield from ((0, 1.0), (1, 1.0))

    def loss(self, model, phase, batch):
        self.calls += 1
        out = model(torch.ones(1, 2)).pow(2).mean()
        return out * math.nan if self.calls in self.nan_batches else out

    def validate(self, model, phase):
        val = {'score': self.score.pop(0) if self.score else 1.0}
        if phase['kind'] == 'teacher':
            val['teacher'] = self.teacher.pop(0) if self.teacher else 1.0
        return val


def cfg(*phases, **kw):
    return {'seed': 0, 'grad_clip': 1.0, 'max_bad_step_fraction': 0.5, 'progress': False,
            'phases': list(phases), **kw}


def run(tmp_path, task, config):
    model = nn.Linear(2, 1)
    state = fit(model, task, config, tmp_path, lambda: {'model': {'kind': 'test'}})
    log = [json.loads(line) for line in (tmp_path / LOG).read_text().splitlines()]
    return state, log, model


TEACHER = {'kind': 'teacher', 'max_epochs': 3, 'patience': 5, 'lr': 0.01, 'stop_loss': None}
MULTI = {'kind': 'multistep', 'max_epochs': 10, 'patience': 2, 'lr': 0.01}


def test_two_phase_runs_teacher_then_multistep_with_early_stopping(tmp_path):
    task = Scripted(teacher=[3, 2, 1], score=[9, 8, 7, 5, 6, 6, 6])
    state, log, _ = run(tmp_path, task, cfg(TEACHER, MULTI))
    assert [r['phase_kind'] for r in log] == ['teacher'] * 3 + ['multistep'] * 3
    assert state.best_score == 5 and state.best_epoch == 3
    assert state.finished and state.stop_reason == 'all phases done'
    assert (tmp_path / BEST).exists() and (tmp_path / LAST).exists()


def test_teacher_phase_ends_early_on_patience_or_stop_loss(tmp_path):
    flat = dict(TEACHER, max_epochs=50, patience=2)
    _, log, _ = run(tmp_path / 'a', Scripted(teacher=[1, 1, 1, 1]), cfg(flat, MULTI))
    assert [r['phase_kind'] for r in log][:4] == ['teacher', 'teacher', 'teacher',
                                                  'multistep']
    small = dict(TEACHER, max_epochs=50, stop_loss=0.1)
    _, log, _ = run(tmp_path / 'b', Scripted(teacher=[1, 0.05]), cfg(small, MULTI))
    assert [r['phase_kind'] for r in log][:3] == ['teacher', 'teacher', 'multistep']


def test_one_phase_is_multistep_only(tmp_path):
    _, log, _ = run(tmp_path, Scripted(score=[3, 2, 1]), cfg(dict(MULTI, max_epochs=3)))
    assert [r['phase_kind'] for r in log] == ['multistep'] * 3


def test_nan_guard_skips_and_counts_bad_steps(tmp_path):
    task = Scripted(nan_batches={2})
    state, log, model = run(tmp_path, task, cfg(dict(MULTI, max_epochs=2)))
    assert state.bad_steps == 1 and log[0]['bad_steps'] == 1 and not log[0]['rolled_back']
    assert all(torch.isfinite(p).all() for p in model.parameters())


def test_diverged_epoch_is_rolled_back_with_a_smaller_step(tmp_path):
    task = Scripted(score=[2.0, math.nan, 1.0])
    state, log, _ = run(tmp_path, task, cfg(dict(MULTI, max_epochs=3, patience=5)))
    assert [r['rolled_back'] for r in log] == [False, True, False]
    assert log[2]['lr'] == pytest.approx(0.005) and state.rollbacks == 1
    assert state.best_score == 1.0


def test_seeds_make_epochs_repeatable():
    from hybrid_models.training.loop import seed_epoch
    a = seed_epoch(3, 7).integers(0, 1000, 5), torch.rand(3)
    b = seed_epoch(3, 7).integers(0, 1000, 5), torch.rand(3)
    assert np.array_equal(a[0], b[0]) and torch.equal(a[1], b[1])
