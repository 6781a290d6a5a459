"""
Child processes of the tools that start nodes (the demo, the benchmarks, the tests).

A tool that starts the simulator or the predictor must never leave them behind: a node
left on the graph keeps publishing (a second /clock, a second /vessel/odom) into every
later run on the same domain. ``Children`` starts each child in a process group of its
own (a signal meant for the tool's terminal never reaches it half-way) and stops every
one of them -- SIGINT, then SIGTERM, then SIGKILL, each to the whole group -- when the
tool's ``with`` block ends, whether it ends normally, by an exception, or because the
tool was told to stop: SIGTERM and SIGHUP are turned into ``SystemExit`` while the
block runs and SIGINT raises KeyboardInterrupt (also in a tool started with SIGINT
ignored, which Python would otherwise leave so), so the ``finally`` clauses of the tool
and this module's clean-up run before the tool exits.

A tool that joins the graph itself should start rclpy with
``rclpy.init(signal_handler_options=SignalHandlerOptions.NO)`` (see ``rclpy_options``)
so rclpy's own handlers do not swallow the signal.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

# Signals that end a tool (and so its children); SIGINT raises KeyboardInterrupt itself.
EXIT_SIGNALS = (signal.SIGTERM, signal.SIGHUP)
# How long (s) each step of stopping a child waits before the next, firmer one.
STOP_STEPS = ((signal.SIGINT, 10.0), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0))


def executable(package: str, name: str) -> Path:
    """Return where ``ros2 run PACKAGE NAME`` finds the executable; raise FileNotFoundError."""
    from ament_index_python.packages import PackageNotFoundError, get_package_prefix

    try:
        prefix = get_package_prefix(package)
    except PackageNotFoundError:
        raise FileNotFoundError(f'package {package} is not installed; run `make setup` '
                                f'first') from None
    path = Path(prefix) / 'lib' / package / name
    if not path.is_file():
        raise FileNotFoundError(f'{path} is missing; run `make setup` first')
    return path


def node_argv(package: str, name: str, *ros_args: str, params: dict | None = None,
              namespace: str | None = None) -> list[str]:
    """
    Return the command line of an installed node with parameters and a namespace.

    ``ros_args`` (e.g. ``-p name:=value`` a user gave) come after ``params``, so they win.
    """
    argv = [str(executable(package, name)), '--ros-args']
    for key, value in (params or {}).items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        argv += ['-p', f'{key}:={text}']
    if namespace:
        argv += ['-r', f'__ns:=/{namespace.strip("/")}']
    return argv + list(ros_args)


def stop_group(process: subprocess.Popen, leader_first: bool = False,
               steps=STOP_STEPS) -> int | None:
    """
    Stop a child's process group gently, then firmly; return its exit code.

    ``leader_first``: the first SIGINT goes to the leader alone (a supervisor such as
    ``ros2 launch`` passes it on to its children; the whole group signalled at once
    would interrupt them twice).
    """
    for number, (sig, wait) in enumerate(steps):
        if process.poll() is not None:
            break
        send = os.kill if leader_first and number == 0 else os.killpg
        try:
            send(process.pid, sig)
        except ProcessLookupError:
            break
        try:
            process.wait(wait)
        except subprocess.TimeoutExpired:
            continue
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(process.pid, signal.SIGKILL)   # anything of the group still left
    try:
        return process.wait(5.0)
    except subprocess.TimeoutExpired:
        return None


def restore_sigint():
    """
    Make SIGINT raise KeyboardInterrupt where the process started with it ignored.

    A process started with SIGINT ignored (a background job of a non-interactive shell,
    a test runner's worker) keeps it ignored, and Python then raises no
    KeyboardInterrupt; processes it starts inherit that. Return the handler replaced,
    or None when SIGINT was left as it was. Main thread only (ValueError elsewhere).
    """
    if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, signal.SIG_DFL):
        return signal.signal(signal.SIGINT, signal.default_int_handler)
    return None


def _exit_on_signal(signum, _frame):
    raise SystemExit(128 + signum)


class Children:
    """
    Start node processes; stop all of them when the ``with`` block is left, however.

    ``with Children(log_dir) as children: children.node('hybrid_predictor', 'predictor')``.
    Outside a ``with`` block call ``stop_all`` yourself.
    """

    def __init__(self, log_dir: Path | None = None):
        self.log_dir = Path(log_dir) if log_dir else None
        self.processes: list[subprocess.Popen] = []
        self._old_handlers: dict = {}

    def start(self, argv: list[str], name: str, env: dict | None = None,
              quiet: bool = False) -> subprocess.Popen:
        """Start ``argv`` in a process group of its own; output to ``log_dir/NAME.log``."""
        kwargs = dict(start_new_session=True, env=env)
        if self.log_dir is not None:
            self.log_dir.mkdir(parents=True, exist_ok=True)
            with open(self.log_dir / f'{name}.log', 'wb') as log:
                process = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                           **kwargs)
        elif quiet:
            process = subprocess.Popen(argv, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, **kwargs)
        else:
            process = subprocess.Popen(argv, **kwargs)
        self.processes.append(process)
        return process

    def node(self, package: str, name: str, *ros_args: str, params: dict | None = None,
             namespace: str | None = None, label: str | None = None,
             env: dict | None = None) -> subprocess.Popen:
        """Start an installed node as ``ros2 run`` would (see ``node_argv``)."""
        argv = node_argv(package, name, *ros_args, params=params, namespace=namespace)
        return self.start(argv, label or (f'{namespace}_{name}' if namespace else name), env)

    def stop(self, process: subprocess.Popen) -> int | None:
        """Stop one child (and its group); return its exit code."""
        code = stop_group(process)
        if process in self.processes:
            self.processes.remove(process)
        return code

    def stop_all(self) -> None:
        """Stop every child still running, the last started first."""
        for process in reversed(list(self.processes)):
            self.stop(process)

    def __enter__(self) -> Children:
        for sig in EXIT_SIGNALS:
            with contextlib.suppress(ValueError):   # not the main thread: leave as is
                self._old_handlers[sig] = signal.signal(sig, _exit_on_signal)
        # A tool that says it stops on SIGINT must, however it was started.
        with contextlib.suppress(ValueError):
            replaced = restore_sigint()
            if replaced is not None:
                self._old_handlers[signal.SIGINT] = replaced
        return self

    def __exit__(self, *exc) -> None:
        # A second signal while the children are stopped must not cut the stop short.
        for sig in (*EXIT_SIGNALS, signal.SIGINT):
            with contextlib.suppress(ValueError):
                self._old_handlers.setdefault(sig, signal.getsignal(sig))
                signal.signal(sig, signal.SIG_IGN)
        try:
            self.stop_all()
        finally:
            for sig, handler in self._old_handlers.items():
                with contextlib.suppress(ValueError, TypeError):
                    signal.signal(sig, handler)
            self._old_handlers.clear()


def rclpy_options() -> dict:
    """Keyword arguments for ``rclpy.init`` in a tool that manages its own signals."""
    from rclpy.signals import SignalHandlerOptions

    return {'signal_handler_options': SignalHandlerOptions.NO}


def wait_until(predicate, timeout: float, poll: float = 0.1) -> bool:
    """Poll ``predicate()`` until true or ``timeout`` seconds pass; return its value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        time.sleep(poll)
    return bool(predicate())


def say(text: str) -> None:
    """Report progress of a long tool run on stderr (stdout carries its result)."""
    print(text, file=sys.stderr, flush=True)
