"""A killed training run resumes from its last epoch and ends where an unbroken run ends."""

import os
from pathlib import Path
import signal
import time

import pytest
from safetensors.torch import load_file

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.training import load_config, train
from hybrid_models.training.jobs import launcher
from offline.benchmarks.toy import write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
LONGER = ['training.phases=[{kind: teacher, max_epochs: 3, patience: 9, lr: 0.005}, '
          '{kind: multistep, max_epochs: 12, patience: 99, lr: 0.003}]',
          'training.progress=false']


def saved_epoch(path: Path) -> int:
    try:
        return read_header(path)['loop']['epoch']
    except (CheckpointError, FileNotFoundError, KeyError):
        return -1


def test_resume_after_kill_loses_at_most_one_epoch(tmp_path):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=300)
    out, log = tmp_path / 'run', tmp_path / 'train.log'
    # The train program, as a study starts it (forked by the tool's launcher).
    argv = [str(SMOKE), '--dataset', str(toy), '--out', str(out), '--quiet'] + sum(
        [['--set', s] for s in LONGER], [])
    pid, ended = launcher().start(argv, log)
    deadline = time.monotonic() + 60
    while saved_epoch(out / 'last.safetensors') < 5 and not ended.done():
        assert time.monotonic() < deadline, 'training made no progress'
        time.sleep(0.01)
    os.kill(pid, signal.SIGKILL)
    assert ended.result(timeout=30) == -signal.SIGKILL, 'the run finished before it was killed'
    lines_before = (out / 'log.jsonl').read_text().splitlines()
    at_kill = saved_epoch(out / 'last.safetensors')
    # At most the epoch in flight is lost: the checkpoint is at most one behind the log
    # (whose first line is the reference, epoch -1).
    assert at_kill >= len(lines_before) - 2 and at_kill >= 5

    assert launcher().start(argv + ['--resume'], log)[1].result(timeout=120) == 0, \
        log.read_text()[-2000:]
    assert f'resuming at epoch {at_kill}' in log.read_text()
    epochs = [int(line.split('"epoch": ')[1].split(',')[0])
              for line in (out / 'log.jsonl').read_text().splitlines()]
    assert epochs == list(range(-1, len(epochs) - 1))   # no gap, no repeat

    # The same config run without interruption ends with identical weights.
    cfg = load_config(SMOKE, [f'dataset={toy}'] + LONGER)
    train(cfg, tmp_path / 'unbroken')
    a = load_file(str(out / 'model.safetensors'))
    b = load_file(str(tmp_path / 'unbroken' / 'model.safetensors'))
    assert a.keys() == b.keys()
    for key in a:
        assert (a[key] == b[key]).all(), key


class Killed(BaseException):
    """Stands for SIGKILL inside the training loop (no handler catches it)."""


@pytest.mark.parametrize('when', ['before', 'after'])
def test_a_kill_around_the_checkpoint_write_leaves_a_log_the_resume_continues(
        tmp_path, monkeypatch, when):
    from hybrid_models.training import loop

    toy = write_toy_dataset(tmp_path / 'toy', n_runs=4, n_samples=200)
    cfg = load_config(SMOKE, [f'dataset={toy}', 'training.progress=false'])
    save_last, calls = loop._save_last, []

    def killed_at_the_third(*args):
        calls.append(1)
        if len(calls) == 3 and when == 'before':
            raise Killed
        save_last(*args)
        if len(calls) == 3:
            raise Killed

    monkeypatch.setattr(loop, '_save_last', killed_at_the_third)
    with pytest.raises(Killed):
        train(cfg, tmp_path / 'run')
    monkeypatch.setattr(loop, '_save_last', save_last)
    train(cfg, tmp_path / 'run', resume=True)
    epochs = [int(line.split('"epoch": ')[1].split(',')[0])
              for line in (tmp_path / 'run' / 'log.jsonl').read_text().splitlines()]
    assert epochs == list(range(-1, len(epochs) - 1)), epochs   # no gap, no repeat
    assert len(epochs) > 4


@pytest.mark.parametrize('content', [b'garbage'])
def test_resume_refuses_a_foreign_last_checkpoint(tmp_path, content):
    toy = write_toy_dataset(tmp_path / 'toy', n_runs=4, n_samples=200)
    (tmp_path / 'run').mkdir()
    (tmp_path / 'run' / 'last.safetensors').write_bytes(content)
    cfg = load_config(SMOKE, [f'dataset={toy}', 'training.progress=false'])
    with pytest.raises(CheckpointError, match='not a hybrid_models checkpoint'):
        train(cfg, tmp_path / 'run', resume=True)
