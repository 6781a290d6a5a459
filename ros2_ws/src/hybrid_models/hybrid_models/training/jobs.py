"""
Trainings as resumable subprocesses of the ``train`` program, for tools that train several.

``train_job(label, config, overrides, out)`` trains one model into ``out`` (kept when
already finished, continued from its last epoch when a run was killed) and returns a
summary; its output goes to ``out/train.log``. Tools run several at once in a thread pool.
"""

from pathlib import Path
import subprocess
import sys
import time

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.training import MODEL_FILE

# A process per training: its memory is returned when it ends, and a kill loses only it.
TRAIN_MODULE = 'hybrid_models.cli.train'


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
        rc = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    status = 'ok' if rc == 0 else f'failed (exit {rc}, see {out / "train.log"})'
    return {'label': label, 'status': status, 'dir': str(out),
            'seconds': round(time.monotonic() - start, 1)}
