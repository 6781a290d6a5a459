"""Training under torchrun (gloo, 2 processes on this machine) matches one process."""

import json
import os
from pathlib import Path
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest
from safetensors.torch import load_file
import torch

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.training import load_config, train
from hybrid_models.training.config import fill_from_vessel
from hybrid_models.training.distributed import DeviceError, Group, Shard, resolve_device
from hybrid_models.training.train import _train, dataset_vessel
from offline.benchmarks.toy import write_toy_dataset
from vessel_datasets.format import read_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
TORCHRUN = Path(sys.executable).parent / 'torchrun'
# Two short phases; a global batch of 16 sequences gives several steps per epoch.
SHORT = ['training.batch_size=16', 'training.progress=false',
         'training.phases=[{kind: teacher, max_epochs: 2, patience: 9, lr: 0.005}, '
         '{kind: multistep, max_epochs: 2, patience: 9, lr: 0.003}]']
LONG = ['training.batch_size=16', 'training.progress=false',
        'training.phases=[{kind: teacher, max_epochs: 2, patience: 9, lr: 0.005}, '
        '{kind: multistep, max_epochs: 30, patience: 99, lr: 0.003}]']


@pytest.fixture(scope='module')
def toy(tmp_path_factory):
    return write_toy_dataset(tmp_path_factory.mktemp('toy'), n_runs=4, n_samples=240)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def torchrun(toy, out, overrides, extra=(), nproc=2):
    """Command and environment of a local torchrun job of offline/train.py."""
    cmd = [str(TORCHRUN), f'--nproc_per_node={nproc}', '--nnodes=1',
           '--master_addr=127.0.0.1', f'--master_port={free_port()}',
           str(ROOT / 'offline' / 'train.py'), str(SMOKE), '--dataset', str(toy),
           '--out', str(out), '--device', 'cpu', *sum([['--set', s] for s in overrides], []),
           *extra]
    env = {**os.environ, 'GLOO_SOCKET_IFNAME': 'lo', 'OMP_NUM_THREADS': '1'}
    return cmd, env


def log_of(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / 'log.jsonl').read_text().splitlines()]


def test_two_processes_give_the_one_process_loss_curve(toy, tmp_path):
    one = tmp_path / 'one'
    train(load_config(SMOKE, [f'dataset={toy}'] + SHORT), one, device='cpu')
    cmd, env = torchrun(toy, tmp_path / 'two', SHORT)
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr[-3000:]
    a, b = log_of(one), log_of(tmp_path / 'two')
    # Epoch -1 is the reference (the physics alone), computed over both ranks too.
    assert [r['epoch'] for r in a] == [r['epoch'] for r in b] == [-1, 0, 1, 2, 3]
    for key in ('train_loss', 'val_score'):
        np.testing.assert_allclose([r[key] for r in b if key in r],
                                   [r[key] for r in a if key in r], rtol=1e-4, err_msg=key)
    wa = load_file(str(one / 'model.safetensors'))
    wb = load_file(str(tmp_path / 'two' / 'model.safetensors'))
    for key in wa:
        torch.testing.assert_close(wb[key], wa[key], rtol=1e-3, atol=1e-5)
    # Rank 0 alone reports: one JSON summary on stdout.
    assert done.stdout.count('"best_epoch"') == 1


def worker_pid(parent: int, rank: int) -> int | None:
    """Pid of torchrun's worker process of ``rank`` (read from /proc)."""
    try:
        children = Path(f'/proc/{parent}/task/{parent}/children').read_text().split()
    except OSError:
        return None
    for pid in children:
        try:
            env = Path(f'/proc/{pid}/environ').read_bytes().split(b'\0')
        except OSError:
            continue
        if f'RANK={rank}'.encode() in env:
            return int(pid)
    return None


def saved_epoch(path: Path) -> int:
    try:
        return read_header(path)['loop']['epoch']
    except (CheckpointError, FileNotFoundError, KeyError):
        return -1


@pytest.mark.slow
def test_a_killed_rank_resumes_and_ends_as_an_unbroken_job(toy, tmp_path):
    out = tmp_path / 'run'
    cmd, env = torchrun(toy, out, LONG)
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    deadline = time.monotonic() + 180
    while saved_epoch(out / 'last.safetensors') < 4 and proc.poll() is None:
        assert time.monotonic() < deadline, 'training made no progress'
        time.sleep(0.02)
    victim = worker_pid(proc.pid, 1)
    assert victim is not None, 'the run finished before rank 1 could be killed'
    os.kill(victim, signal.SIGKILL)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0, 'torchrun did not notice the killed rank'
    at_kill = saved_epoch(out / 'last.safetensors')
    assert at_kill >= 4

    cmd, env = torchrun(toy, out, LONG, ['--resume'])
    resumed = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert f'resuming at epoch {at_kill}' in resumed.stderr
    # The physics alone's reference (epoch -1) once, then every epoch: no gap, no repeat.
    assert [r['epoch'] for r in log_of(out)] == [-1, *range(32)]

    cmd, env = torchrun(toy, tmp_path / 'unbroken', LONG)
    unbroken = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env=env)
    assert unbroken.returncode == 0, unbroken.stderr[-3000:]
    a = load_file(str(out / 'model.safetensors'))
    b = load_file(str(tmp_path / 'unbroken' / 'model.safetensors'))
    for key in a:
        assert (a[key] == b[key]).all(), key


def test_only_rank_zero_writes(toy, tmp_path):
    cfg = load_config(SMOKE, [f'dataset={toy}'] + SHORT)
    ds = read_dataset(toy)
    spec = dataset_vessel(cfg, ds)
    cfg = fill_from_vessel(cfg, spec)
    out = tmp_path / 'rank1'
    summary = _train(cfg, spec, ds, out, False, Group(rank=1))
    assert summary['rank'] == 1 and summary['epochs'] == 4
    assert not out.exists()


def test_batches_are_dealt_so_ranks_add_up_to_the_global_batch():
    rows = np.arange(37)
    parts = [Shard(r, 3).deal(rows) for r in range(3)]
    assert sorted(np.concatenate([p[0] for p in parts]).tolist()) == rows.tolist()
    # Weighted means of the parts, averaged over ranks (what DDP does), give the mean.
    values = np.random.default_rng(0).normal(size=37)
    ddp = np.mean([values[p[0]].mean() * p[1] for p in parts])
    assert ddp == pytest.approx(values.mean())
    assert Shard(0, 1).deal(rows)[1] == 1.0 and Shard(1, 2).deal(rows[:1]) is None


def test_device_cuda_without_a_gpu_is_refused_in_one_line(toy, tmp_path):
    if torch.cuda.is_available():
        pytest.skip('this machine has a GPU')
    with pytest.raises(DeviceError, match='no CUDA GPU') as exc:
        resolve_device('cuda')
    assert '\n' not in str(exc.value)
    assert resolve_device('auto').type == 'cpu'
    done = subprocess.run([sys.executable, str(ROOT / 'offline' / 'train.py'), str(SMOKE),
                           '--dataset', str(toy), '--out', str(tmp_path / 'x'),
                           '--device', 'cuda'], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.splitlines() == ['train.py: error: --device cuda: no CUDA GPU is '
                                        'visible to torch on this machine']
    assert not (tmp_path / 'x').exists()
