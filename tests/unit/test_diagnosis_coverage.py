"""
The 95 % intervals cover known answers, also where one global coefficient cannot fit.

Known-answer scenarios of the MMG (KVLCC2) and Fossen (Otter) families: a coefficient
of the nominal physics weakened by 30 %, and the same with the true value differing from
run to run by 15 % (misspecified: the model has one value for all runs). The reported
interval (widened by the between-run spread) must contain the simulated value where the
coefficient is found; where the runs disagree the bootstrap's interval alone does not,
and the widened one covers other runs' values more often. That it covers each held-out
run's own value as often as it claims is a known shortfall with 4 diagnosis runs
(strict xfail). The measured table (20 and 10 seeds) is in docs/diagnosis.md.
"""

from functools import cache

import numpy as np
import pytest

from vessel_diagnosis.coverage import known_changes, measure
from vessel_diagnosis.scenarios import load_scenario

SEEDS = range(8)
MIN_COVERAGE = 0.85        # of a 95 % interval over 8 seeds: 7 of 8 at least
# The first test of a vessel measures both its scenarios, 16 diagnoses (about 4 min for
# the KVLCC2, 8 for the Otter on 2 busy cores): longer than the suite's 300 s per test.
MEASUREMENT_TIMEOUT_S = 1800


def test_known_answer_is_what_the_nominal_physics_lacks():
    scenario = load_scenario('weak_rudder', vessel='kvlcc2_hsva')
    published = scenario.simulation.physics.parameter('f_alpha')
    assert known_changes(scenario) == {'f_alpha': pytest.approx(0.3 * published)}
    assert known_changes(load_scenario('control', vessel='kvlcc2_hsva')) == {}


def test_run_spread_draws_each_run_its_own_value_reproducibly():
    scenario = load_scenario('weak_yaw_damping_varying', vessel='otter')
    mean = scenario.simulation.physics.parameter('Nr')
    values = np.array([scenario.run_physics(3, run).parameter('Nr') for run in range(200)])
    assert scenario.run_physics(3, 7).parameter('Nr') == values[7]
    assert np.mean(values) == pytest.approx(mean, rel=0.03)
    assert np.std(values) / abs(mean) == pytest.approx(0.15, rel=0.15)


SCENARIOS = {'kvlcc2_hsva': (('weak_rudder', 'weak_rudder_varying'), 120.0),
             'otter': (('weak_yaw_damping', 'weak_yaw_damping_varying'), 200.0)}


@cache
def measured(vessel: str) -> tuple[dict, dict]:
    """Summaries (fixed, varying) over 8 seeds of 6 runs: measured once per vessel."""
    names, seconds = SCENARIOS[vessel]
    result = measure(vessel, names, SEEDS, runs=6, seconds=seconds)
    return tuple(next(iter(result[n]['summary'].values())) for n in names)


@pytest.mark.slow
@pytest.mark.timeout(MEASUREMENT_TIMEOUT_S)
@pytest.mark.parametrize('vessel', SCENARIOS)
def test_found_intervals_contain_the_simulated_value(vessel):
    for summary in measured(vessel):
        assert summary['found'] >= MIN_COVERAGE, summary
        # an interval exists only where the coefficient was found
        assert summary['ci95_truth'] / summary['found'] >= MIN_COVERAGE, summary


@pytest.mark.slow
@pytest.mark.timeout(MEASUREMENT_TIMEOUT_S)
@pytest.mark.parametrize('vessel', SCENARIOS)
def test_where_runs_disagree_the_bootstrap_alone_misses_and_the_widened_covers_more(vessel):
    _, varying = measured(vessel)
    assert varying['ci95_noise_truth'] <= 0.5, varying
    assert varying['ci95_held_out'] > varying['ci95_noise_held_out'], varying
    assert varying['ci95_median_width'] > 2.0 * varying['ci95_noise_median_width'], varying


@pytest.mark.slow
@pytest.mark.timeout(MEASUREMENT_TIMEOUT_S)
@pytest.mark.xfail(strict=True, reason='known shortfall: with 4 diagnosis runs the between-run '
                   'spread (DerSimonian-Laird, 4 groups) is underestimated; the widened '
                   "intervals contained 69 % (KVLCC2) and 56 % (Otter) of the held-out runs' "
                   'own values over 8 seeds (docs/diagnosis.md, Intervals)')
@pytest.mark.parametrize('vessel', SCENARIOS)
def test_each_held_out_runs_own_value_is_covered_as_claimed(vessel):
    _, varying = measured(vessel)
    assert varying['ci95_held_out'] >= MIN_COVERAGE, varying
