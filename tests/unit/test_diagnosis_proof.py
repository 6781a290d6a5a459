"""
The proof at full size (slow): blind diagnosis of concealed effects, held-out gains, time.

Each scenario is simulated as 10 half-hour runs; the dataset's 30 % test split is held
out. After modelling, the one-step RMSE of the states the effect dominates must drop by
at least 50 % and the 900-step trajectory error by at least 30 % on the held-out runs;
the control must report nothing. Ten hours of recordings must be diagnosed in at most
five minutes on this 2-core machine.
"""

import json
import time

import pytest

from vessel_diagnosis import cli as diagnose
from vessel_diagnosis.scenarios import load_scenario, simulate_scenario

ONE_STEP_GAIN = 0.5
TRAJECTORY_GAIN = 0.3
TIME_LIMIT_S = 300.0

pytestmark = pytest.mark.slow


def _diagnose(name, tmp_path, runs, hours, seed=3):
    data = simulate_scenario(name, tmp_path / 'data', runs=runs, hours=hours, seed=seed)
    out = tmp_path / 'report'
    start = time.perf_counter()
    code = diagnose.main(['--recordings', str(data), '--physics',
                          str(data / 'nominal_physics.yaml'), '--out', str(out), '--quiet'])
    elapsed = time.perf_counter() - start
    return code, json.loads((out / 'findings.json').read_text()), out, elapsed


@pytest.mark.parametrize('name', ['current', 'wind', 'fouling', 'rudder_offset'])
def test_concealed_effect_is_modelled_and_improves_held_out_forecasts(name, tmp_path):
    scenario = load_scenario(name)
    code, result, out, _ = _diagnose(name, tmp_path, runs=10, hours=0.5)
    assert code == 0 and result['status'] == 'findings'
    assert result['findings'][0]['category'] == scenario.expect[0]
    gains = result['metrics']['improvement']
    for state in scenario.affected_states:
        assert gains['one_step_rmse'][state] >= ONE_STEP_GAIN, (state, gains)
    assert gains['trajectory'] >= TRAJECTORY_GAIN, gains
    for name_ in ('report.md', 'findings.json', 'augmented_physics.yaml', 'before_after.png',
                  'locate_force_maps.png'):
        assert (out / name_).is_file()


def test_control_reports_nothing_at_full_size(tmp_path):
    code, result, out, _ = _diagnose('control', tmp_path, runs=10, hours=0.5)
    assert code == 0 and result['status'] == 'nothing_significant'
    assert result['findings'] == [] and result['augmented_physics'] is None
    assert 'Nothing significant is missing' in (out / 'report.md').read_text()


def test_ten_hours_diagnose_within_five_minutes(tmp_path):
    code, result, _, elapsed = _diagnose('current', tmp_path, runs=10, hours=1.0, seed=5)
    assert code == 0 and result['recordings']['hours'] == pytest.approx(10.0, abs=0.01)
    assert result['findings'][0]['category'] == 'current'
    assert elapsed <= TIME_LIMIT_S, f'{elapsed:.0f} s for 10 h of recordings'
