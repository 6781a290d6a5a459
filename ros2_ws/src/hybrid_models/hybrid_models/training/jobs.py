"""
Trainings as resumable subprocesses of the ``train`` program, for tools that train several.

``train_job(label, config, overrides, out)`` trains one model into ``out`` (kept when
already finished, continued from its last epoch when a run was killed) and returns a
summary; its output goes to ``out/train.log``. Tools run several at once in a thread pool.
"""

import ctypes
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.training import MODEL_FILE

# A process per training: its memory is returned when it ends, and a kill loses only it.
TRAIN_MODULE = 'hybrid_models.cli.train'
PR_SET_PDEATHSIG = 1   # prctl(2): the signal a process gets when its parent dies
PARENT_ENV = 'HYBRID_MODELS_TRAIN_PARENT'   # set by train_job: the tool's process id


def die_with_parent() -> None:
    """
    End this training with the tool that started it, if one did (Linux).

    A tool stopped by a signal, or killed, must not leave trainings running on: they
    would compete for the cores and write into runs a restarted tool trains again. A
    training stopped this way resumes from its last epoch. Called by the training
    itself at start (a ``preexec_fn`` would run Python in a forked multi-threaded tool).
    """
    parent = os.environ.get(PARENT_ENV)
    if not parent or not sys.platform.startswith('linux'):
        return
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != int(parent):   # the tool ended before the line above
        os.kill(os.getpid(), signal.SIGTERM)


def finished(run_dir: Path) -> bool:
    """Tell whether a training's final model file exists and its loop ended."""
    try:
        header = read_header(Path(run_dir) / MODEL_FILE)
    except (CheckpointError, FileNotFoundError):
        return False
    return 'loop' not in header or header['loop'].get('finished', True)


def train_job(label: str, config: Path, overrides: list[str], out: Path) -> dict:
    """Train one model in a subprocess (resumable); return {label, status, dir[, seconds]}."""
    out = Path(out)
    if finished(out):
        return {'label': label, 'status': 'kept', 'dir': str(out)}
    cmd = [sys.executable, '-m', TRAIN_MODULE, str(config), '--out', str(out), '--resume',
           '--quiet'] + sum((['--set', s] for s in overrides), [])
    out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    with open(out / 'train.log', 'a') as log:
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT,
                            env={**os.environ, PARENT_ENV: str(os.getpid())}).returncode
    status = 'ok' if rc == 0 else f'failed (exit {rc}, see {out / "train.log"})'
    return {'label': label, 'status': status, 'dir': str(out),
            'seconds': round(time.monotonic() - start, 1)}
