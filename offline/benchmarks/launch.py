"""
Benchmark: a study's small trainings forked from the launcher, against one process each.

A study trains many models; each used to start the train program as a process of its
own and import torch and the training code first (seconds of CPU before its first
epoch). The launcher (``hybrid_models.training.launcher``) imports them once and forks
every training. Both ways train the same tiny models (``smoke.yaml``, two epochs, one
thread) on the same toy dataset, one after another; the figure is the ratio of their
wall times. Goal: the launched trainings take at most half the time.
"""

import argparse
from pathlib import Path
import subprocess
import sys
import tempfile
import time

REPO = Path(__file__).resolve().parents[2]
SMOKE = REPO / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHORT = ['training.progress=false', 'training.threads=1',
         'training.phases=[{kind: teacher, max_epochs: 1, patience: 1, lr: 0.005}, '
         '{kind: multistep, max_epochs: 1, patience: 1, lr: 0.003}]']
GOAL_RATIO = 2.0


# A run that takes seconds to minutes, for CI (`bench.py --quick launch`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--trainings', '2')


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add this suite's options."""
    parser.add_argument('--trainings', type=int, default=6,
                        help='trainings each way (default 6, a two-fold three-seed study)')


def _one_process_each(toy: Path, out: Path, count: int) -> float:
    from hybrid_models.training.jobs import TRAIN_MODULE

    start = time.perf_counter()
    for i in range(count):
        cmd = [sys.executable, '-m', TRAIN_MODULE, str(SMOKE), '--out',
               str(out / f'run{i}'), '--quiet'] + sum(
            (['--set', s] for s in [f'dataset={toy}', f'training.seed={i}', *SHORT]), [])
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def _launched(toy: Path, out: Path, count: int) -> float:
    from hybrid_models.training.jobs import train_job

    start = time.perf_counter()
    for i in range(count):
        result = train_job(f'run{i}', SMOKE, [f'dataset={toy}', f'training.seed={i}', *SHORT],
                           out / f'run{i}')
        if result['status'] != 'ok':
            raise RuntimeError(f"launched training {i}: {result['status']}")
    return time.perf_counter() - start


def run(args) -> dict:
    """Train ``--trainings`` models each way; return the wall times and their ratio."""
    from .toy import write_toy_dataset

    if args.trainings < 1:
        raise SystemExit('bench.py launch: error: --trainings must be at least 1')
    with tempfile.TemporaryDirectory() as tmp:
        toy = write_toy_dataset(Path(tmp) / 'toy', n_runs=6, n_samples=260)
        separate = _one_process_each(toy, Path(tmp) / 'separate', args.trainings)
        launched = _launched(toy, Path(tmp) / 'launched', args.trainings)
    ratio = separate / launched
    return {
        'suite': 'launch',
        'trainings': args.trainings,
        'one_process_each_s': round(separate, 2),
        'launched_s': round(launched, 2),
        'per_training_one_process_each_s': round(separate / args.trainings, 2),
        'per_training_launched_s': round(launched / args.trainings, 2),
        'speed_up': round(ratio, 2),
        'goals': {'speed_up': f'>= {GOAL_RATIO:g}'},
        'met': {'speed_up': ratio >= GOAL_RATIO},
    }
