"""
Trainings as resumable processes of the ``train`` program, for tools that train several.

``train_job(label, config, overrides, out)`` trains one model into ``out`` (kept when
already finished, continued from its last epoch when a run was killed) and returns a
summary; its output goes to ``out/train.log``. Tools run several at once in a thread pool.
Each training is a process forked by the tool's launcher (``launcher``), which imported
torch once for all of them.
"""

import atexit
from concurrent.futures import Future
import ctypes
import itertools
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import threading
import time

from hybrid_models.checkpoint import CheckpointError, read_header
from hybrid_models.training import MODEL_FILE

# A process per training: its memory is returned when it ends, and a kill loses only it.
TRAIN_MODULE = 'hybrid_models.cli.train'
LAUNCHER_MODULE = 'hybrid_models.training.launcher'
PR_SET_PDEATHSIG = 1   # prctl(2): the signal a process gets when its parent dies
# The process id of the parent to end with: the tool's for its launcher, the launcher's
# for each training it forks.
PARENT_ENV = 'HYBRID_MODELS_TRAIN_PARENT'


def die_with_parent() -> None:
    """
    End this process with the parent ``PARENT_ENV`` names, if one is named (Linux).

    A tool stopped by a signal, or killed, must not leave trainings running on: they
    would compete for the cores and write into runs a restarted tool trains again. The
    launcher ends with the tool and each training with the launcher; a training stopped
    this way resumes from its last epoch. Called by each at start, by the process itself
    (a ``preexec_fn`` would run Python in a forked multi-threaded tool).
    """
    parent = os.environ.get(PARENT_ENV)
    if not parent or not sys.platform.startswith('linux'):
        return
    ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    if os.getppid() != int(parent):   # the parent ended before the line above
        os.kill(os.getpid(), signal.SIGTERM)


def finished(run_dir: Path) -> bool:
    """Tell whether a training's final model file exists and its loop ended."""
    try:
        header = read_header(Path(run_dir) / MODEL_FILE)
    except (CheckpointError, FileNotFoundError):
        return False
    return 'loop' not in header or header['loop'].get('finished', True)


class Launcher:
    """The tool's side of its launcher process: start trainings, wait for their ends."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.ids = itertools.count()
        self.started: dict[int, Future] = {}   # id -> the training's process id
        self.ended: dict[int, Future] = {}     # id -> its exit code
        # Forked by a thread that lives as long as the launcher: the kernel sends the
        # parent-death signal when the forking THREAD ends. Forked by a tool's pool
        # worker, the launcher was ended with the pool, and the training the tool started
        # next (reproduce_table2's bound variant) failed with "exit -15" on every new run.
        spawned: Future = Future()
        threading.Thread(target=self._spawn_and_read, args=(spawned,), name='launcher',
                         daemon=True).start()
        self.proc = spawned.result()
        atexit.register(self.close)

    def _spawn_and_read(self, spawned: Future) -> None:
        try:
            proc = subprocess.Popen(
                [sys.executable, '-m', LAUNCHER_MODULE], stdin=subprocess.PIPE,
                stdout=subprocess.PIPE, env={**os.environ, PARENT_ENV: str(os.getpid())})
        except OSError as exc:
            spawned.set_exception(exc)
            return
        spawned.set_result(proc)
        self.proc = proc
        self._read()

    def close(self) -> None:
        """End the launcher once its trainings are done (it ends with the tool anyway)."""
        with self.lock:
            if not self.proc.stdin.closed:
                self.proc.stdin.close()
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.terminate()

    def alive(self) -> bool:
        """Tell whether the launcher still takes trainings."""
        return self.proc.poll() is None

    def start(self, argv: list[str], log: Path) -> tuple[int, Future]:
        """Start ``train`` with ``argv``, output to ``log``; return (its pid, its exit code)."""
        with self.lock:
            job = next(self.ids)
            started, ended = self.started[job], self.ended[job] = Future(), Future()
            self.proc.stdin.write((json.dumps({'id': job, 'argv': argv, 'log': str(log)})
                                   + '\n').encode())
            self.proc.stdin.flush()
        return started.result(), ended

    def _read(self) -> None:
        for line in self.proc.stdout:
            message = json.loads(line)
            with self.lock:
                if 'pid' in message:
                    self.started.pop(message['id']).set_result(message['pid'])
                else:
                    self.ended.pop(message['id']).set_result(message['exit'])
        self.proc.wait()
        with self.lock:   # the launcher ended: what it had not answered fails
            for future in [*self.started.values(), *self.ended.values()]:
                future.set_exception(RuntimeError(
                    f'the training launcher ended (exit {self.proc.returncode})'))
            self.started.clear()
            self.ended.clear()


_launcher: Launcher | None = None
_launcher_lock = threading.Lock()


def launcher() -> Launcher:
    """Return this tool's launcher, started on first use (again if it ended)."""
    global _launcher
    with _launcher_lock:
        if _launcher is None or not _launcher.alive():
            _launcher = Launcher()
        return _launcher


def train_job(label: str, config: Path, overrides: list[str], out: Path) -> dict:
    """Train one model in a process of its own, resumable; return {label, status, dir, ...}."""
    out = Path(out)
    if finished(out):
        return {'label': label, 'status': 'kept', 'dir': str(out)}
    # Absolute paths: the launcher works in the directory the tool was in when it started.
    argv = [str(Path(config).resolve()), '--out', str(out.resolve()), '--resume',
            '--quiet'] + sum((['--set', s] for s in overrides), [])
    out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    try:
        rc = launcher().start(argv, out.resolve() / 'train.log')[1].result()
        problem = None if rc == 0 else f'exit {rc}'
    except (RuntimeError, OSError) as exc:   # the launcher itself ended
        problem = str(exc)
    status = 'ok' if problem is None else f'failed ({problem}, see {out / "train.log"})'
    return {'label': label, 'status': status, 'dir': str(out),
            'seconds': round(time.monotonic() - start, 1)}
