"""
The diagnosis names concealed effects blind, and reports nothing when nothing is missing.

Each scenario of vessel_diagnosis/config/scenarios.yaml is simulated small (6 runs of
6 minutes: the simulator's cost is per time step, vectorized over runs; a coarser sea
spectrum) and identified with the nominal physics that lacks
the effect. The full-size proof with held-out improvements is test_diagnosis_proof.py.
"""

import copy
import json

import pytest

from vessel_description import load_vessel
from vessel_diagnosis import scenarios
from vessel_diagnosis.findings import summary_line
from vessel_diagnosis.library import load_library
from vessel_diagnosis.pipeline import diagnose, name_missing_physics
from vessel_diagnosis.recordings import load_recordings
from vessel_diagnosis.scenarios import load_scenario, simulate_scenario
from vessel_diagnosis.settings import load_settings
from vessel_physics.patrol import FAMILY
from vessel_physics.physics_file import load_physics

SMALL = {'waves': {'components': 12}}          # a coarser sea: faster, same physics
SHIP = load_vessel('patrol_boat')
SETTINGS = load_settings(overrides={'selection': {'bootstrap': 50, 'rounds': 2}})


@pytest.fixture(scope='module')
def identified(tmp_path_factory):
    cache = {}

    def run(name):
        if name not in cache:
            out = simulate_scenario(name, tmp_path_factory.mktemp(name), runs=6, hours=0.1,
                                    seed=11, overrides=SMALL)
            scenario = load_scenario(name)
            cache[name] = (scenario, name_missing_physics(
                load_recordings([out]), scenario.nominal, SETTINGS, load_library(None, FAMILY),
                SHIP), out)
        return cache[name][:2]
    run.data = lambda name: cache[name][2]
    return run


def test_control_reports_nothing(identified):
    _, named = identified('control')
    assert named.status == 'nothing_significant'
    assert named.records == []


# Fouling stands for the three in the default run; current and wind, each as long again,
# are slow checks (the full-size proof of all three is test_diagnosis_proof.py).
@pytest.mark.parametrize('name', [pytest.param('current', marks=pytest.mark.slow),
                                  pytest.param('wind', marks=pytest.mark.slow), 'fouling'])
def test_concealed_effect_is_named(identified, name):
    scenario, named = identified(name)
    assert named.status == 'findings'
    strongest = named.records[0]
    assert strongest['category'] == scenario.expect[0], named.records
    for record in named.records:
        assert record['inclusion_probability'] >= SETTINGS.selection.inclusion_threshold
        lo, hi = record['ci95']
        assert lo <= record['coefficient'] <= hi and not lo <= 0.0 <= hi


@pytest.mark.slow       # shares the current scenario's identification
def test_current_is_estimated_per_run(identified, tmp_path):
    scenario, named = identified('current')
    record = next(r for r in named.records if r['category'] == 'current')
    assert 1.0 <= record['coefficient'] <= 1.5            # RMS speed, drawn in [1.0, 1.5]
    for run in record['per_run'].values():
        assert 0.9 <= run['speed'] <= 1.6


def test_fouling_is_more_surge_resistance(identified):
    _, named = identified('fouling')
    resistance = [r for r in named.records if r['category'] == 'resistance']
    assert resistance and all(r['dof'] == 'X' and r['coefficient'] < 0 for r in resistance)


@pytest.mark.slow       # a scenario of its own (12 s): the refusal, not a finding
def test_constant_orders_cannot_be_diagnosed(identified):
    scenario, named = identified('constant_orders')
    assert named.status == scenario.status == 'insufficient_excitation'
    assert named.records == []
    assert {'propulsion', 'wind'} <= set(named.not_checkable)
    assert named.signals['delta_port_rad']['std_within_runs'] < 0.002   # what the report says


FINDING_FIELDS = {'dof', 'term', 'category', 'coefficient', 'unit', 'ci95',
                  'inclusion_probability', 'held_out_gain', 'affected_states', 'aliases',
                  'cannot_be_told_apart'}


def test_full_report_and_augmented_physics(identified, tmp_path):
    identified('fouling')
    data = identified.data('fouling')
    settings = load_settings(overrides={
        'selection': {'bootstrap': 50, 'rounds': 2},
        # 6-minute runs: forecasts short enough to fit after the calibration span, so that
        # the held-out forecasts can show that the augmented physics earns its file.
        'evaluation': {'calibration_s': 60, 'horizon_s': 200, 'stride_s': 40},
        'excitation': {'min_duration_s': 600}})
    result = diagnose([data], data / 'nominal_physics.yaml', tmp_path, settings)
    on_disk = json.loads((tmp_path / 'findings.json').read_text())
    assert on_disk == result and result['schema'] == 'vessel-diagnosis/1'
    assert result['status'] == 'findings' and result['findings'][0]['category'] == 'resistance'
    for finding in result['findings']:
        assert FINDING_FIELDS <= set(finding)
    assert set(result['metrics']['one_step_rmse']) == {'nominal', 'augmented'}
    assert result['metrics']['improvement']['one_step_rmse']['u'] > 0
    verdict = result['augmented_verdict']
    assert verdict['written'] and verdict['trajectory_gain'] >= (
        settings.evaluation.min_trajectory_gain)
    assert result['augmented_physics']['physics'] == 'augmented_physics.yaml'
    assert {'summary', 'maps', 'ranking', 'windows'} <= set(result['locate'])
    physics = load_physics(tmp_path / 'augmented_physics.yaml')
    for finding in result['findings']:
        if finding['kind'] == 'parameter':
            assert getattr(physics.params, finding['parameter']) == pytest.approx(
                finding['value'])
        else:
            term = next(t for t in physics.extra_terms if t.info['candidate'] == finding['term'])
            assert term.coefficient == pytest.approx(finding['coefficient'])
    report = (tmp_path / 'report.md').read_text()
    assert verdict['sentence'] in report and 'forecasts the held-out runs better' in report
    assert 'Vessel: `patrol_boat`' in report and 'Scale check: Froude number' in report
    for heading in ('## 1. Where', '## 2. What is missing', '## 3. Augmented physics',
                    '## 4. Before and after'):
        assert heading in report
    for figure in ('locate_force_maps.png', 'locate_multistep_maps.png', 'locate_windows.png',
                   'candidates.png', 'before_after.png'):
        assert (tmp_path / figure).stat().st_size > 10_000


@pytest.mark.slow       # a scenario of its own (11 s)
def test_a_certain_term_pruned_for_its_small_effect_is_still_reported(tmp_path, monkeypatch):
    """Twice the nominal surge added mass: certain, yet forecasts barely change."""
    nominal = load_scenario('control').nominal
    truth = 2.0 * nominal.parameter('Xudot')
    data = copy.deepcopy(scenarios.load_scenario_file())
    data['vessels']['patrol_boat']['scenarios']['heavy_surge'] = {
        'description': 'twice the surge added mass', 'truth_parameters': {'Xudot': truth}}
    monkeypatch.setattr(scenarios, 'load_scenario_file', lambda: data)
    out = simulate_scenario('heavy_surge', tmp_path, runs=6, hours=0.1, seed=11,
                            overrides=SMALL)
    named = name_missing_physics(load_recordings([out]), nominal, SETTINGS,
                                 load_library(None, FAMILY), SHIP)
    assert named.status == 'findings' and named.records == []
    [kept] = named.kept_out
    lo, hi = kept['ci95']
    assert kept['parameter'] == 'Xudot' and lo <= truth - nominal.parameter('Xudot') <= hi < 0
    noise_lo, noise_hi = kept['ci95_noise']         # the bootstrap's alone, inside the widened
    assert lo <= noise_lo < noise_hi <= hi
    assert kept['held_out_gain'] < SETTINGS.validation.min_improvement
    assert 'held-out predictions' in kept['why_kept_out']
    line = summary_line(named.status, named.records, named.not_checkable, kept_out=named.kept_out)
    assert 'kept out of the augmented physics' in line and 'added_mass (Xudot' in line
