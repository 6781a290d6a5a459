"""
Tools that start nodes stop every one of them when they are told to stop (#25).

A soak ended by `timeout` (SIGTERM) once left its simulator and predictor on the graph,
and the next run on the domain saw two /clock publishers. Each tool here is started as a
user would, left until its nodes run, then sent one signal (to the tool alone, not to its
children); the nodes it started must be gone when it has exited.
"""

import os
from pathlib import Path
import signal
import sys
import time

import pytest

from tests.processes import running

from .conftest import REPO, wait_for

pytestmark = pytest.mark.ros

# The soak's client processes: Python ones (--client python), or C ones (the default).
NODES = ('lib/ship_sim_node/simulator', 'lib/hybrid_predictor/predictor',
         'benchmarks/soak.py client', 'what_if_c.load')
BENCH = str(REPO / 'offline' / 'bench.py')


def tool_argv(tool: str, out: Path) -> list[str]:
    return {
        'soak': [sys.executable, BENCH, 'soak', '--duration', '120', '--rtf', '10',
                 '--forecast-period', '10'],
        'soak-processes': [sys.executable, BENCH, 'soak', '--duration', '120', '--rtf', '10',
                           '--forecast-period', '10', '--clients', '2',
                           '--client-processes', '2'],
        'outage': [sys.executable, BENCH, 'outage', '--case', 'none', '--outage', '60',
                   '--log-dir', str(out)],
        'forecast': [sys.executable, BENCH, 'forecast', '--repeats', '2',
                     '--naive-repeats', '1', '--node-samples', '3000'],
        'demo': [sys.executable, str(REPO / 'offline' / 'demo.py'), '--minutes', '17',
                 '--out', str(out)],
    }[tool]


def node_children(pid: int) -> list[int]:
    """Pids of the node processes whose parent is ``pid``."""
    out = []
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / 'stat').read_text()
            cmdline = (entry / 'cmdline').read_bytes().replace(b'\0', b' ').decode()
        except OSError:
            continue
        ppid = int(stat.rsplit(')', 1)[1].split()[1])
        if ppid == pid and any(n in cmdline for n in NODES):
            out.append(int(entry.name))
    return out


def stop_and_check(launcher, tmp_path, tool: str, sig: int, nodes: int) -> None:
    process = launcher.start(tool_argv(tool, tmp_path), tool)
    pid = process.popen.pid
    assert wait_for(lambda: len(node_children(pid)) >= nodes, 180), process.output()[-3000:]
    children = node_children(pid)
    time.sleep(3.0)   # the nodes come up (rclpy started, on the graph)
    assert process.alive(), process.output()[-3000:]
    os.kill(pid, sig)
    process.popen.wait(60)
    left = [c for c in children if running(c)]
    assert not left, (tool, signal.Signals(sig).name, left, process.output()[-3000:])


@pytest.mark.parametrize('tool, sig, nodes', [
    ('soak', signal.SIGTERM, 2),
    ('demo', signal.SIGINT, 1),
])
def test_a_tool_told_to_stop_stops_the_nodes_it_started(launcher, tmp_path, tool, sig,
                                                        nodes):
    stop_and_check(launcher, tmp_path, tool, sig, nodes)


@pytest.mark.slow  # five more tools and signals, about a minute
@pytest.mark.parametrize('tool, sig, nodes', [
    ('soak', signal.SIGINT, 2),
    ('soak-processes', signal.SIGTERM, 4),   # two nodes, two client processes
    ('demo', signal.SIGTERM, 1),
    ('outage', signal.SIGTERM, 2),
    ('forecast', signal.SIGTERM, 1),
])
def test_every_tool_stops_its_nodes_on_sigint_and_sigterm(launcher, tmp_path, tool, sig,
                                                          nodes):
    stop_and_check(launcher, tmp_path, tool, sig, nodes)
