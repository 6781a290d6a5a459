"""vessel_bringup.processes.Children: a tool stops its children on SIGINT, however started."""

import os
import signal
import subprocess
import sys
import textwrap

import pytest

from tests.processes import gone_within, running

# A tool: starts one child (a long sleep) and waits; prints the child's pid.
TOOL = textwrap.dedent("""
    import sys, time
    from vessel_bringup.processes import Children
    with Children() as children:
        child = children.start([sys.executable, '-c', 'import time; time.sleep(60)'],
                               'sleeper', quiet=True)
        print(child.pid, flush=True)
        time.sleep(60)
""")


@pytest.mark.parametrize('inherited', ['default', 'ignored'])
def test_sigint_stops_the_tool_and_its_child_even_when_it_started_ignored(inherited):
    # A background job of a non-interactive shell starts with SIGINT ignored, and
    # Python then leaves it ignored: the tool must stop all the same. The shell's trap
    # ignores it before exec, as such a shell does.
    trap = "trap '' INT; " if inherited == 'ignored' else ''
    with subprocess.Popen(['sh', '-c', f'{trap}exec "$0" -c "$1"', sys.executable, TOOL],
                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) as tool:
        try:
            child = int(tool.stdout.readline())
            assert running(child)
            os.kill(tool.pid, signal.SIGINT)
            code = tool.wait(20)
            assert code != 0 and 'KeyboardInterrupt' in tool.stderr.read()
            assert gone_within(child, 5), 'the child outlived its tool'
        finally:
            tool.kill()
