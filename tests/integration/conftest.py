"""
Fixtures for tests that run installed ROS 2 executables as separate processes.

Every process talks DDS on loopback only (ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST) in
a domain of this test session's own, and is stopped at teardown whatever the test's
outcome: SIGINT first (nodes shut down cleanly), then SIGTERM, then SIGKILL, each to
the whole process group.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import subprocess
import sys
import threading
import time
import warnings

import pytest
from vessel_bringup.processes import restore_sigint

REPO = Path(__file__).resolve().parents[2]
INSTALL = REPO / 'ros2_ws' / 'install'

# The test process itself joins the graph (clients, subscribers), so the DDS settings
# must be in place before rclpy is imported anywhere.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(110 + os.getpid() % 100))
# Parallel workers (pytest-xdist gw0, gw1, ...) each take the next domain: their graphs
# never meet (domain IDs stop at 232 on loopback).
_WORKER = os.environ.get('PYTEST_XDIST_WORKER', 'gw0')
os.environ['ROS_DOMAIN_ID'] = str(
    (int(os.environ['ROS_DOMAIN_ID']) + int(_WORKER.removeprefix('gw'))) % 233)
os.environ.setdefault('ROS_LOG_DIR', str(REPO / 'ros2_ws' / 'log' / 'ros'))
# The test process's writers repair a lost sample within 0.1 s (the profile says why);
# processes the tests start do not inherit it (child_environment).
TEST_PROCESS_PROFILE = Path(__file__).with_name('fastdds_test_process.xml')
os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(TEST_PROCESS_PROFILE)
# A suite started in the background of a script (`make test &`, a CI runner's job) runs
# with SIGINT ignored, and every process it starts inherits that: a `ros2 launch` then
# outlived its SIGINT by the whole 10 s stop step, and the demo ignored the SIGINT its
# stop test sent and ran its 17 simulated minutes (48 s). The processes are started as
# from a terminal: SIGINT at its default here, which a child then starts with.
restore_sigint()


def child_environment(**extra: str) -> dict:
    """Return the environment of a process a test starts: this one's, without its profile."""
    env = {k: v for k, v in os.environ.items() if k != 'FASTRTPS_DEFAULT_PROFILES_FILE'}
    return {**env, **extra}


def installed_executable(package: str, name: str) -> Path:
    """Path where `ros2 run PACKAGE NAME` finds the executable (install/PKG/lib/PKG)."""
    path = INSTALL / package / 'lib' / package / name
    if not path.is_file():
        pytest.fail(f'{path} is missing: build the workspace (make setup) first')
    return path


@dataclass
class Process:
    """A started child process and the file its output goes to."""

    popen: subprocess.Popen
    log_path: Path
    name: str
    # A supervisor (ros2 launch) gets the first SIGINT alone and passes it on to its
    # children; the whole group signalled at once would interrupt them twice.
    supervisor: bool = False

    def output(self) -> str:
        """Everything the process printed so far (stdout and stderr)."""
        return self.log_path.read_text(errors='replace')

    def alive(self) -> bool:
        """Return True while the process runs."""
        return self.popen.poll() is None


@dataclass
class Launcher:
    """Starts processes for one test and stops all of them afterwards."""

    log_dir: Path
    processes: list[Process] = field(default_factory=list)

    def start(self, argv: list[str], name: str, env: dict | None = None,
              supervisor: bool = False) -> Process:
        """Start argv in its own process group, output to a log file."""
        log_path = self.log_dir / f'{name}.log'
        child_env = child_environment(PYTHONUNBUFFERED='1', **(env or {}))
        with open(log_path, 'wb') as log:
            popen = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                     env=child_env, start_new_session=True, cwd=REPO)
        process = Process(popen, log_path, name, supervisor)
        self.processes.append(process)
        return process

    def start_node(self, package: str, executable: str, *args: str,
                   name: str | None = None, env: dict | None = None) -> Process:
        """Start an installed node executable, as `ros2 run` would."""
        argv = [str(installed_executable(package, executable)), *args]
        return self.start(argv, name or executable, env)

    def start_script(self, script: Path, *args: str, name: str | None = None,
                     env: dict | None = None) -> Process:
        """Start a Python script with this interpreter (the venv's)."""
        return self.start([sys.executable, str(script), *args], name or script.stem, env)

    def stop(self, process: Process, timeout: float = 10.0) -> int | None:
        """Stop one process group gently, then firmly; return its exit code."""
        from vessel_bringup.processes import STOP_STEPS, stop_group

        steps = ((STOP_STEPS[0][0], timeout), *STOP_STEPS[1:])
        began = time.monotonic()
        code = stop_group(process.popen, leader_first=process.supervisor, steps=steps)
        if time.monotonic() - began >= timeout:
            # A node must end on SIGINT; one that needed SIGTERM is named in the run's
            # warnings summary with its last words, where CI's log keeps it.
            warnings.warn(f'{process.name} outlived SIGINT by {timeout:.0f} s (exit code '
                          f'{code}); its last output:\n{process.output()[-1500:]}',
                          stacklevel=2)
        return code

    def stop_all(self) -> None:
        """Stop every process this launcher started."""
        for process in reversed(self.processes):
            self.stop(process)


@pytest.fixture
def launcher(tmp_path, request):
    """Start processes in a test; all are stopped at teardown, pass or fail."""
    runner = Launcher(tmp_path)
    yield runner
    runner.stop_all()
    failed = getattr(request.node, 'rep_call', None)
    if failed is not None and failed.failed:
        for process in runner.processes:
            sys.stderr.write(f'--- output of {process.name} ---\n{process.output()[-4000:]}\n')


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    """Keep each phase's report on the test item, so fixtures can see failures."""
    report = yield
    setattr(item, 'rep_' + report.when, report)
    return report


@pytest.fixture
def ros_node():
    """Give the test an rclpy node with its own context; shut it down afterwards."""
    import rclpy

    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node(f'test_client_{os.getpid()}', context=context)
    yield node
    node.destroy_node()
    rclpy.shutdown(context=context)


def spin_until(node, predicate, timeout: float) -> bool:
    """Spin node until predicate() is true or timeout seconds pass; return predicate()."""
    from rclpy.executors import SingleThreadedExecutor

    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline and not predicate():
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.remove_node(node)
        executor.shutdown()
    return predicate()


def answer_of(node, client, request, timeout: float = 30.0, resend_after: float = 10.0):
    """Return the first ~/predict answer that is not busy (``what_if_client.ask``)."""
    from hybrid_predictor.what_if_client import ask

    answer = ask(node, client, request, timeout=timeout, resend_after=resend_after)
    assert answer is not None, 'no service response'
    return answer


def wait_for(predicate, timeout: float) -> bool:
    """Poll predicate() until true or timeout seconds pass; return predicate()."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not predicate():
        time.sleep(0.05)
    return bool(predicate())


class Graph:
    """A test node spun in a background thread, with what it hears."""

    def __init__(self, name: str, state_topic: str | None = None):
        from diagnostic_msgs.msg import DiagnosticArray
        import rclpy

        from hybrid_predictor_interfaces.msg import Forecast
        from vessel_ros_bridge.executors import MultiThreadedExecutor

        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(f'{name}_{os.getpid()}', context=self.context)
        self.forecasts, self.diagnostics = [], []   # (monotonic s, message)
        self.node.create_subscription(Forecast, '/vessel/forecast', lambda m: self.forecasts
                                      .append((time.monotonic(), m)), 50)
        self.node.create_subscription(DiagnosticArray, '/diagnostics', lambda m: self
                                      .diagnostics.append((time.monotonic(), m)), 50)
        self.state_stamps = []   # s, of the Odometry on state_topic, if given
        if state_topic is not None:
            from nav_msgs.msg import Odometry

            from vessel_ros_bridge.messages import seconds_from_stamp

            self.node.create_subscription(Odometry, state_topic, lambda m: self.state_stamps
                                          .append(seconds_from_stamp(m.header.stamp)), 50)
        self.executor = MultiThreadedExecutor(num_threads=3, context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def close(self) -> None:
        """Stop spinning and leave the graph."""
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def status(self, since: float = 0.0):
        """Return the latest predictor status received after ``since`` (monotonic s)."""
        for t, msg in reversed(self.diagnostics):
            if t >= since:
                return msg.status[0]
        return None

    def values(self) -> dict:
        """Return the key/values of the latest predictor status."""
        status = self.status()
        return {kv.key: kv.value for kv in status.values} if status else {}

    def count(self, key: str) -> int:
        """Return a counter of the latest status (0 if absent)."""
        return int(self.values().get(key, 0))

    def stamp(self, k: int = -1) -> float:
        """Return the stamp (s) of the k-th forecast received."""
        from vessel_ros_bridge.messages import seconds_from_stamp

        return seconds_from_stamp(self.forecasts[k][1].header.stamp)

    def call(self, client, request, timeout: float = 30.0):
        """Call a service and wait for its response."""
        future = client.call_async(request)
        assert wait_for(future.done, timeout), 'no response'
        return future.result()
