"""The demo's forecasts equal their offline re-forecast, live and from its recorded bag."""

import json
from pathlib import Path
import subprocess
import sys

import pytest

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
STATES = ('u', 'v', 'p', 'r', 'phi')


# Measured cause of the failures (1 to 2 of ~30 forecasts in some runs, on a loaded
# machine): the node's forecast worker stops waiting for a state's actuators and wind
# after sync_timeout and forecasts with the previous second's (re-forecast with those two
# samples dropped: difference 0.0). A defect of the node's online path, not of this test.
@pytest.mark.xfail(strict=False, reason="predictor forecasts before a state's actuators "
                   'and wind arrive when sync_timeout expires under load (issue #27 item 4)')
def test_demo_forecasts_equal_the_offline_ones_live_and_from_the_recorded_bag(tmp_path):
    # A short demo: 6 simulated minutes at 20x, 60-step forecasts, recorded. Faster, a
    # loaded machine's predictor skips most states (backlog) and few forecasts remain.
    bag, out = tmp_path / 'bag', tmp_path / 'out'
    demo = subprocess.run(
        [sys.executable, str(REPO / 'offline' / 'demo.py'), '--minutes', '6', '--horizon',
         '60', '--speed-up', '20', '--evaluate-every', '5', '--out', str(out), '--record',
         str(bag)], capture_output=True, text=True, timeout=300)
    assert demo.returncode == 0, demo.stdout[-2000:] + demo.stderr[-3000:]
    assert 'live = offline' in demo.stdout
    live = json.loads((out / 'demo.json').read_text())['live_vs_offline']
    # Forecasts whose window began after the predictor's first one (module re_forecast).
    assert live['compared'] >= 3, json.dumps(live)
    assert live['equal'], json.dumps(live)
    assert max(live['max_relative_difference'].values()) <= live['tolerance_relative']

    again = subprocess.run([sys.executable, str(REPO / 'offline' / 're_forecast.py'),
                            '--bag', str(bag)], capture_output=True, text=True, timeout=300)
    assert again.returncode == 0, again.stdout[-2000:] + again.stderr[-2000:]
    recorded = json.loads(again.stdout)
    assert recorded['compared'] >= 50 and recorded['equal'], recorded
    assert set(recorded['max_abs_difference']) == set(STATES)
    assert recorded['max_position_difference_m'] <= 1e-3
