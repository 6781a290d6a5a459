"""
Every benchmark suite runs end to end in its short form (offline/bench.py --quick SUITE).

The full figures are `make bench`'s; here a suite that crashes, or stops giving one of its
headline figures, fails CI (the slow tier). Each runs as a user would, in a process of its
own; the figures' values are not judged: a short run says nothing of them.
"""

import json
from pathlib import Path
import subprocess
import sys

import pytest

from .conftest import child_environment

pytestmark = [pytest.mark.ros, pytest.mark.slow]

REPO = Path(__file__).resolve().parents[2]
# Suite -> a figure its JSON must carry (a crash or a renamed figure fails).
HEADLINE = {'sim': 'real_time_ratio', 'convert': 'converter', 'forecast': 'engine_p50_ms',
            'soak': 'busy_stages_ms', 'outage': 'cases', 'departure': 'steps_scored',
            'scale': 'training_throughput', 'launch': 'speed_up', 'diagnose': 'diagnose_s'}


@pytest.mark.parametrize('suite', sorted(HEADLINE))
def test_a_benchmark_suite_runs_in_its_short_form(suite, tmp_path):
    done = subprocess.run([sys.executable, str(REPO / 'offline' / 'bench.py'), '--quick',
                           suite], capture_output=True, text=True, cwd=tmp_path,
                          env=child_environment(), timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    figures = json.loads(done.stdout)
    assert HEADLINE[suite] in figures, sorted(figures)
    if suite == 'forecast':   # the GPU's figures beside the CPU's, or why there are none
        assert {'absent', 'engine_p50_ms'} & set(figures['gpu']), figures['gpu']


def test_every_suite_has_a_short_form():
    import importlib

    sys.path.insert(0, str(REPO / 'offline'))
    from bench import SUITES

    assert sorted(SUITES) == sorted(HEADLINE)   # a new suite joins this test
    for module, _ in SUITES.values():
        assert importlib.import_module(module).QUICK, module
