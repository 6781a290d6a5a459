"""
A warm process that forks every training of a tool: torch is imported once, not per run.

Starting the ``train`` program costs about 4.5 s of CPU before its first epoch (torch
and the training code 2.8 s, ``torch._dynamo`` 1.7 s on the first optimizer), which a
study of many small trainings paid for each one. A tool's trainings are forked instead
from one launcher process that imported them already: each is still a process of its
own (its memory returned when it ends, a kill loses only it) running the train
program's ``main`` with the arguments it would get on the command line, its output
appended to its run's ``train.log``.

The tool writes one JSON line a training to the launcher's stdin, ``{"id", "argv",
"log"}``; the launcher answers ``{"id", "pid"}`` when the training started and
``{"id", "exit"}`` when it ended (exit code as ``subprocess`` gives it: negative for a
signal). The launcher ends with the tool (``die_with_parent``), and its trainings with
the launcher; on EOF of its stdin it ends after its trainings.

    python -m hybrid_models.training.launcher      # started by jobs.train_job, not a user
"""

from __future__ import annotations

import json
import os
import select
import signal
import sys
import traceback

from hybrid_models.training.jobs import PARENT_ENV, TRAIN_MODULE, die_with_parent

# Imported before the first fork: what every training would import again otherwise.
WARM_MODULES = (TRAIN_MODULE, 'torch._dynamo')


def _say(channel: int, message: dict) -> None:
    # One write of one line: the tool's reader never sees two messages interleaved.
    os.write(channel, (json.dumps(message) + '\n').encode())


def _train(program, job: dict, launcher_pid: int, channel: int) -> None:
    """Run one training in this forked child; never returns."""
    code = 1
    try:
        os.close(channel)   # only the launcher answers the tool
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.default_int_handler)   # Ctrl-C stops a training
        log = os.open(job['log'], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
        os.dup2(log, 1)
        os.dup2(log, 2)
        os.close(log)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.close(null)
        # The train program ends with its parent: here, the launcher.
        os.environ[PARENT_ENV] = str(launcher_pid)
        code = program.main(job['argv'])
    except SystemExit as exc:   # argparse's --help or usage errors
        code = exc.code if isinstance(exc.code, int) else 1
    except BaseException:   # noqa: BLE001 - reported in the run's log, as a process would
        traceback.print_exc()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code if isinstance(code, int) else 1)


def _lines(fd: int, buffer: bytearray) -> tuple[list[dict], bool]:
    """Read what is ready on ``fd``; return the complete JSON lines and whether EOF came."""
    chunk = os.read(fd, 65536)
    buffer.extend(chunk)
    *complete, rest = buffer.split(b'\n')
    buffer[:] = rest
    return [json.loads(line) for line in complete if line.strip()], not chunk


def main() -> int:
    """Serve the tool's trainings until its stdin ends and they are done."""
    die_with_parent()
    # Ctrl-C reaches the whole process group: the tool ends, and the launcher with it.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    # The tool reads only the launcher's messages on stdout: anything else printed here
    # (an import's warning) goes to stderr.
    channel = os.dup(sys.stdout.fileno())
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    import importlib
    for name in WARM_MODULES:
        importlib.import_module(name)
    program = sys.modules[WARM_MODULES[0]]
    me = os.getpid()
    wake_r, wake_w = os.pipe()
    os.set_blocking(wake_w, False)
    signal.set_wakeup_fd(wake_w)
    signal.signal(signal.SIGCHLD, lambda *_: None)   # a handler, so the wake-up fd is written
    stdin = sys.stdin.fileno()
    running: dict[int, int] = {}   # pid -> job id
    buffer, open_ = bytearray(), True
    while open_ or running:
        ready, _, _ = select.select([stdin, wake_r] if open_ else [wake_r], [], [])
        if wake_r in ready:
            os.read(wake_r, 4096)
            while running:
                pid, status = os.waitpid(-1, os.WNOHANG)
                if pid == 0:
                    break
                _say(channel, {'id': running.pop(pid),
                               'exit': os.waitstatus_to_exitcode(status)})
        if stdin in ready:
            jobs, eof = _lines(stdin, buffer)
            open_ = not eof
            for job in jobs:
                pid = os.fork()
                if pid == 0:
                    _train(program, job, me, channel)
                running[pid] = job['id']
                _say(channel, {'id': job['id'], 'pid': pid})
    return 0


if __name__ == '__main__':
    sys.exit(main())
