"""The augmented physics is written only when it forecasts the held-out runs better."""

import pytest

from vessel_diagnosis.findings import augmented_verdict
from vessel_diagnosis.settings import load_settings

EV = load_settings().evaluation


def _metrics(nominal_m, augmented_m, state_gains):
    return {'forecast': {'nominal': {'trajectory': {'mean': nominal_m}},
                         'augmented': {'trajectory': {'mean': augmented_m}}},
            'improvement': {'trajectory': (nominal_m - augmented_m) / nominal_m,
                            'forecast_rmse': state_gains}}


def test_better_forecasts_are_written_with_their_figures():
    verdict = augmented_verdict(_metrics(500.0, 30.0, {'u': 0.9, 'v': 0.02, 'r': -0.03}), EV)
    assert verdict['written'] and verdict['trajectory_gain'] == pytest.approx(0.94)
    assert 'was written' in verdict['sentence'] and '500 -> 30 m (-94 %)' in verdict['sentence']


def test_worse_yaw_rate_forecasts_are_not_written():
    # The KVLCC2 report: trajectory slightly better, yaw rate RMSE +113 %.
    verdict = augmented_verdict(_metrics(100.0, 90.0, {'u': 0.2, 'r': -1.13}), EV)
    assert not verdict['written']
    assert 'not written' in verdict['sentence'] and 'worst state r RMSE +113 %' in (
        verdict['sentence'])


def test_a_worse_trajectory_is_not_written_and_no_held_out_runs_mean_no_file():
    assert not augmented_verdict(_metrics(100.0, 120.0, {'u': 0.0}), EV)['written']
    nothing = augmented_verdict(None, EV)
    assert not nothing['written'] and 'no held-out forecasts' in nothing['sentence']
