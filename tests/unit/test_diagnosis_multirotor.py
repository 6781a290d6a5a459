"""
The diagnosis of the multirotor family: the Crazyflie 2.1 Brushless.

Default (about a minute): the library and settings, the weak-rotor hook against the
candidate that must name it, what a 6-DOF vehicle changes (heading, regimes, scale
check), and on small simulated flights (4 flights of 15 s) a weak rotor found blind and
nothing in the control. Slow: the scenarios at the size of
docs/results/nanodrone/diagnosis.md through the command-line tools, and the real flights
of the nano-drone benchmark with a coefficient of the nominal file weakened (skipped
without ../shared/real/nanodrone).
"""

import json
from pathlib import Path

import numpy as np
import pytest

from offline import claims
from vessel_description import load_vessel
from vessel_diagnosis.admissible import admissible
from vessel_diagnosis.cli import main as diagnose_main
from vessel_diagnosis.cli_scenario import main as simulate_main
from vessel_diagnosis.concealed import rotor_share
from vessel_diagnosis.library import load_library
from vessel_diagnosis.locate import regimes_for, sea_state
from vessel_diagnosis.pipeline import _check_settings, name_missing_physics
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.recordings import Run, load_recordings
from vessel_diagnosis.scale import ScaleError, check_scale
from vessel_diagnosis.scenarios import (
    load_scenario,
    load_scenario_file,
    scenario_names,
    simulate_scenario,
)
from vessel_diagnosis.settings import load_settings
from vessel_physics.integrator import attitude_rates
from vessel_physics.multirotor import FAMILY
from vessel_physics.physics_file import load_physics

ROOT = Path(__file__).resolve().parents[2]
VESSEL = load_vessel('crazyflie_brushless')
PHYSICS = load_physics(VESSEL.physics, VESSEL)
LIBRARY = load_library(None, FAMILY)
SETTINGS = load_settings(family='multirotor')
EFFECTS = load_scenario_file()['effects']
REAL = ROOT.parent / 'shared' / 'real' / 'nanodrone'


# ------------------------------------------------------------------ library and settings
def test_every_candidate_is_a_term_or_parameter_of_the_family():
    parameters, terms = set(FAMILY.parameter_names()), FAMILY.terms
    for cand in LIBRARY.candidates:
        if cand.kind == 'parameter':
            assert cand.target in parameters, cand
        else:
            assert cand.kind == 'term' and terms[cand.target].kind in ('candidate', 'force')
        assert set(cand.dofs) <= set(FAMILY.dofs) and cand.scale > 0
    names = {c.name for c in LIBRARY.candidates}
    # One rotor-thrust candidate per rotor of the Crazyflie, none for rotors it lacks.
    assert {f'rotor{i}_thrust' for i in range(1, 5)} <= names and 'rotor5_thrust' not in names
    assert {'m', 'Ixx', 'Iyy', 'Izz', 'k_eta', 'k_m', 'rotor_moments', 'cg_offset_x',
            'cg_offset_y', 'heave_bias'} <= names
    assert {c.category for c in LIBRARY.candidates} == {
        'rigid_body', 'propulsion', 'actuator_bias', 'aerodynamics', 'static_bias'}
    # Nothing is left out for the Crazyflie: it feels no wind or current, and the library
    # offers none.
    kept, excluded = admissible(LIBRARY.scaled_to(VESSEL.length_m), VESSEL, FAMILY)
    assert excluded == [] and len(kept.candidates) == len(LIBRARY.candidates)


def test_family_settings_fit_the_multirotor():
    _check_settings(SETTINGS, PHYSICS)            # one force floor per DOF: X Y Z K M N
    assert len(SETTINGS.locate.force_floor) == 6
    # Free runs far shorter than a vessel's: a multirotor leaves its flight within a second.
    assert SETTINGS.regression.horizon_s <= 0.5 < load_settings().regression.horizon_s


def test_the_weak_rotor_is_the_share_of_the_candidate_that_names_it():
    """The hook takes 15 % of rotor 1's thrust and torque: -0.15 x rotor1_thrust exactly."""
    rng = np.random.default_rng(0)
    z = rng.normal(0.0, 0.5, (5, 8))
    speeds = rng.uniform(900.0, 2800.0, (5, 4))
    state = {s: z[:, i] for i, s in enumerate(VESSEL.state_names)}
    state.update(u_water=z[:, 0], v_water=z[:, 1])
    controls = {a: speeds[:, j] for j, a in enumerate(VESSEL.actuator_names)}
    cfg = EFFECTS['rotor_share']
    assert cfg['actuator'] == PHYSICS.params.rotors[0].actuator == 'm1'
    expected = (cfg['share'] - 1.0) * PHYSICS.term_force('rotor1_thrust', z, speeds)
    got = rotor_share(0.0, state, controls, {})
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
    assert np.abs(got[:, 3:]).min() > 0          # it turns the body: K, M and N


def test_scenarios_of_the_crazyflie():
    assert {'control', 'weak_motor', 'payload'} <= set(scenario_names('crazyflie_brushless'))
    payload = load_scenario('payload', vessel='crazyflie_brushless')
    truth, nominal = payload.simulation.physics, payload.nominal
    assert truth.parameter('m') == pytest.approx(1.2 * nominal.parameter('m'))
    for axis, share in (('Ixx', 0.008), ('Iyy', 0.020), ('Izz', 0.015)):   # the pack's own
        assert truth.parameter(axis) / nominal.parameter(axis) - 1 == pytest.approx(
            share, abs=0.001)
    assert payload.expect == ('rigid_body',)


# ------------------------------------------------------------------ a 6-DOF vehicle
def test_the_heading_of_a_6dof_vehicle_follows_pitch_and_roll_rates():
    predictor = Predictor(PHYSICS, VESSEL.dt, 1)
    z = np.array([[1.0, -0.5, 0.2, 0.4, -0.8, 0.6, 0.5, -0.4]])
    x = np.concatenate([z, [[0.3]]], axis=1)
    dx = predictor.derivative(x, np.full((1, 4), 1700.0), None)
    assert dx[0, -1] == pytest.approx(attitude_rates(*z[0, 3:6], *z[0, 6:8])[2])
    assert dx[0, -1] != pytest.approx(z[0, 5] * np.cos(z[0, 6]))   # not the plane's


def _flight(seconds=10.0, scale=1.0) -> Run:
    t = np.arange(0.0, seconds, VESSEL.dt)
    rng = np.random.default_rng(1)
    z = rng.normal(0.0, 0.3, (len(t), 8)) * np.array([3, 3, 1, 4, 4, 2, 0.5, 0.5]) * scale
    return Run('flight', t, z, np.zeros(len(t)), np.full((len(t), 4), 1700.0))


def test_a_6dof_vehicle_is_mapped_against_heave_and_tilt_not_a_sea_state():
    regimes = regimes_for(VESSEL, [_flight()], FAMILY)
    assert {'heave', 'tilt', 'speed', 'turn_rate', 'heading'} == set(regimes)
    seas, label = sea_state([_flight()], 5.0, VESSEL, FAMILY)
    assert label.startswith('none') and not np.any(seas[0])


def test_scale_check_of_a_6dof_vehicle_judges_its_limits_only():
    figures = check_scale([_flight()], VESSEL, SETTINGS.scale_check)
    assert figures['froude'] is None and figures['turning_rate'] is None
    with pytest.raises(ScaleError, match='p leaves its limits') as info:
        check_scale([_flight(scale=40.0)], VESSEL, SETTINGS.scale_check)
    assert '\n' not in str(info.value)


# ------------------------------------------------------------------ found blind
@pytest.fixture(scope='module')
def small(tmp_path_factory):
    """Name the missing physics of a scenario on 4 simulated flights of 15 s."""
    cache = {}

    def run(name):
        if name not in cache:
            out = simulate_scenario(name, tmp_path_factory.mktemp(name), runs=4,
                                    hours=15.0 / 3600.0, seed=7, vessel='crazyflie_brushless')
            scenario = load_scenario(name, vessel='crazyflie_brushless')
            settings = load_settings(overrides={'selection': {'bootstrap': 50, 'rounds': 2}},
                                     family='multirotor')
            cache[name] = scenario, name_missing_physics(
                load_recordings([out]), scenario.nominal, settings, LIBRARY, VESSEL)
        return cache[name]
    return run


def test_a_weak_rotor_is_found_blind(small):
    _, named = small('weak_motor')
    assert named.status == 'findings', named.records
    assert [r['term'] for r in named.records] == ['rotor1_thrust']
    record = named.records[0]
    lo, hi = record['ci95']
    assert record['category'] == 'actuator_bias' and record['inclusion_probability'] >= 0.8
    assert lo <= EFFECTS['rotor_share']['share'] - 1.0 <= hi and hi < 0.0
    assert {'p', 'q'} <= set(record['affected_states'])


def test_the_control_reports_nothing(small):
    _, named = small('control')
    assert named.status == 'nothing_significant', named.records
    assert named.records == [] and named.kept_out == [] and named.enough


# ------------------------------------------------------------------ end to end (slow)
@pytest.fixture(scope='module')
def diagnosed(tmp_path_factory):
    """offline/simulate_scenario.py and diagnose.py on a scenario (12 flights of 40 s, seed 3)."""
    cache = {}

    def run(name):
        if name not in cache:
            base = tmp_path_factory.mktemp(f'e2e_{name}')
            data, report = base / 'data', base / 'report'
            assert simulate_main(['--vessel', 'crazyflie_brushless', '--scenario', name,
                                  '--runs', '12', '--seconds', '40', '--seed', '3',
                                  '--out', str(data)]) == 0
            assert diagnose_main(['--recordings', str(data), '--physics',
                                  str(data / 'nominal_physics.yaml'), '--out', str(report),
                                  '--quiet']) == 0
            cache[name] = json.loads((report / 'findings.json').read_text()), report
        return cache[name]
    return run


@pytest.mark.slow
def test_weak_motor_end_to_end(diagnosed):
    findings, report = diagnosed('weak_motor')
    assert findings['status'] == 'findings'
    assert [r['term'] for r in findings['findings']] == ['rotor1_thrust']
    record = findings['findings'][0]
    lo, hi = record['ci95']
    assert lo <= -0.15 <= hi and record['aliases'] == []
    verdict = findings['augmented_verdict']
    assert verdict['written'] and verdict['trajectory_gain'] > 0.9
    assert (report / 'augmented_physics.yaml').is_file()


@pytest.mark.slow
def test_control_end_to_end(diagnosed):
    findings, report = diagnosed('control')
    assert findings['status'] == 'nothing_significant', findings['findings']
    assert findings['kept_out'] == [] and not (report / 'augmented_physics.yaml').exists()


@pytest.mark.slow
def test_payload_end_to_end(diagnosed):
    """
    The payload is named by the mass; what translation shows, k_eta / m, is its 1 / 1.2.

    A rigid body's motion fixes its forces and inertias only up to a common factor: with
    the pack's inertia (+0.8 to +2.0 %) left out of the model (too small to change
    forecasts), k_eta may take the moments' share of it, and m the rest.
    """
    findings, _ = diagnosed('payload')
    assert findings['status'] == 'findings'
    first = findings['findings'][0]
    assert first['term'] == 'm' and first['category'] == 'rigid_body'
    change = {r['term']: r['relative_change'] for r in findings['findings']
              if r['kind'] == 'parameter'}
    assert set(change) <= {'m', 'k_eta', 'Ixx', 'Iyy', 'Izz', 'k_m'}
    ratio = (1.0 + change['m']) / (1.0 + change.get('k_eta', 0.0))
    assert ratio == pytest.approx(1.2, abs=0.005)
    assert abs(change.get('k_eta', 0.0)) <= 0.02         # at most the inertias' share
    assert findings['augmented_verdict']['written']


# ------------------------------------------------------------------ the real flights (slow)
WEAK_K_ETA = ROOT / 'docs' / 'results' / 'nanodrone' / 'diagnosis' / 'weak_k_eta_physics.yaml'
# The thrust coefficient the flights' accelerometer gives with six pole pairs (import.md),
# an estimate independent of the diagnosis.
ACCELEROMETER_K_ETA = 3.5e-8
# A whole diagnosis of the flights takes minutes (the module's fixture keeps each one).
WHOLE_DIAGNOSIS_TIMEOUT_S = 1800


@pytest.fixture(scope='module')
def real(tmp_path_factory):
    """Convert the 20 usable flights as run.sh does (the paper's split); diagnose them."""
    from vessel_datasets.table_to_dataset import main as convert
    base = tmp_path_factory.mktemp('nanodrone')
    flights = sorted(str(p) for p in REAL.glob('*/*.parquet') if not p.stem.endswith('_na'))
    assert len(flights) == 20
    assert convert([*flights, '--vessel', 'crazyflie_brushless', '--out',
                    str(base / 'paper_ds'), '--quiet']) == 0
    cache = {}

    def run(physics):
        if physics not in cache:
            out = base / Path(physics or 'nominal').stem
            argv = ['--recordings', str(base / 'paper_ds'), '--out', str(out), '--quiet']
            assert diagnose_main(argv + (['--physics', str(physics)] if physics else [])) == 0
            cache[physics] = json.loads((out / 'findings.json').read_text())
        return cache[physics]
    return run


def _thrust_findings(findings):
    """Return the findings that change the hover thrust: k_eta, or its look-alikes."""
    return [r for r in findings['findings'] if r['term'] in ('k_eta', 'm', 'heave_bias')]


@pytest.mark.slow
@pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} is absent (third-party flights)')
@pytest.mark.timeout(WHOLE_DIAGNOSIS_TIMEOUT_S)
def test_real_flights_diagnosis_names_its_documented_terms(real):
    """docs/results/nanodrone/diagnosis/nominal, run again whole by its documented command."""
    now = claims.figures_of(real(None))
    assert now['terms'] and now['trajectory']
    assert claims.diagnosis_differences('nanodrone', now) == []


@pytest.mark.slow
@pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} is absent (third-party flights)')
@pytest.mark.timeout(WHOLE_DIAGNOSIS_TIMEOUT_S)
def test_real_flights_name_the_thrust_coefficient_of_the_accelerometer(real):
    findings = real(None)
    thrust = _thrust_findings(findings)
    assert [r['term'] for r in thrust] == ['k_eta']
    record = thrust[0]
    assert {'m', 'heave_bias'} <= {a['term'] for a in record['aliases']}   # look-alikes
    assert ACCELEROMETER_K_ETA * 0.92 <= record['value'] <= ACCELEROMETER_K_ETA * 1.08
    assert findings['augmented_verdict']['written']


@pytest.mark.slow
@pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} is absent (third-party flights)')
@pytest.mark.timeout(WHOLE_DIAGNOSIS_TIMEOUT_S)
def test_real_flights_with_a_weakened_k_eta_name_it_or_its_look_alikes(real):
    weak = load_physics(WEAK_K_ETA, VESSEL)
    assert weak.parameter('k_eta') == pytest.approx(0.7 * PHYSICS.parameter('k_eta'))
    findings = real(WEAK_K_ETA)
    thrust = _thrust_findings(findings)
    assert len(thrust) == 1, findings['summary']
    record = thrust[0]
    named = {record['term']} | {a['term'] for a in record['aliases']}
    assert 'k_eta' in named
    # More thrust than the weakened file gives: k_eta up, m down or a lift (Z < 0).
    assert {'k_eta': 1, 'm': -1, 'heave_bias': -1}[record['term']] * record['coefficient'] > 0
