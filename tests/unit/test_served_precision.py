"""
The predictor serves float32: its forecasts are those of float64 to within a tolerance.

``offline/bench.py forecast --precision-dataset DIR`` measures it on a dataset's test
forecasts (docs/predictor.md, "Float32"); here on a small simulated dataset the test makes.
"""

import json
import subprocess
import sys

from hybrid_models.engine import Forecaster
from offline.benchmarks.forecast import default_model, precision

from .test_simulate_cli import ROOT

# The tolerance docs/predictor.md states: the largest float32 - float64 difference at any
# step of any forecast below a thousandth of the state's test RMSE, and the trajectory
# error the same to 1e-4 of itself.
OF_RMSE = 1e-3
OF_TRAJECTORY = 1e-4


def test_float32_forecasts_are_the_float64_ones_within_the_stated_tolerance(tmp_path):
    data = tmp_path / 'ds'
    done = subprocess.run([sys.executable, str(ROOT / 'offline' / 'simulate.py'), '--runs', '3',
                           '--seconds', '1100', '--seed', '5', '--out', str(data), '--quiet'],
                          capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    model = default_model()
    measured = precision(Forecaster.from_checkpoint(model), model, data)
    print(json.dumps(measured, indent=1))
    assert measured['test_runs'] == 1 and measured['forecasts'] >= 1
    assert set(measured['max_difference_over_rmse']) == {'u', 'v', 'p', 'r', 'phi'}
    assert all(0.0 < share < OF_RMSE for share in measured['max_difference_over_rmse'].values())
    single, double = measured['trajectory_m']['float32'], measured['trajectory_m']['float64']
    assert abs(single - double) <= OF_TRAJECTORY * double
