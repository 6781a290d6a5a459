"""
The diagnosis of an MMG vessel on recordings with a known answer.

The one engine with the MMG family's library and settings.

A KVLCC2-like vessel is simulated with a lower resistance and a constant yaw moment (a
propeller or hull asymmetry) that the nominal parameters do not have. The diagnosis must
name exactly those, with intervals that contain their estimates and the truth, write the
augmented physics because held-out forecasts improve, and exclude what the vessel cannot
have.
"""

import contextlib
import io
import json
import math

import numpy as np
import pandas as pd
import pytest
import yaml

from vessel_datasets.format import read_dataset, write_dataset
from vessel_description import load_vessel, parse_vessel
from vessel_diagnosis import cli as diagnose
from vessel_diagnosis.admissible import admissible
from vessel_diagnosis.library import load_library
from vessel_diagnosis.pipeline import diagnose as diagnose_dataset
from vessel_diagnosis.recordings import RecordingsError
from vessel_diagnosis.scale import ScaleError
from vessel_diagnosis.settings import load_settings
from vessel_diagnosis.workflow import augmented_physics_file
from vessel_physics.integrator import free_run
from vessel_physics.mmg import FAMILY
from vessel_physics.mmg.params import froude_scaled
from vessel_physics.physics_file import load_physics

TANKER = load_vessel('kvlcc2_hsva')
N_RUNS, SECONDS = 10, 90.0
TRUE_R0, TRUE_N0 = 0.016, 4.0      # nominal: R_0' 0.022, N_0 0 N m
NOISE = [1e-3, 1e-3, 1e-4]          # m/s, m/s, rad/s: sensor noise of u, v, r


FINE = 10                           # integration steps per sample: the rudder moves between


def simulate_runs(physics, seed=0):
    """Zig-zag-like runs: rate-limited rudder square waves of several amplitudes, noise."""
    rng = np.random.default_rng(seed)
    dt = TANKER.dt
    steps = int(SECONDS / dt)
    t = np.arange(steps + 1) * dt
    fine = np.arange(steps * FINE + 1) * (dt / FINE)
    amplitude = np.radians(rng.uniform(5.0, 25.0, N_RUNS))
    period = rng.uniform(20.0, 40.0, N_RUNS)
    order = amplitude[:, None] * np.sign(np.sin(2 * math.pi * fine[None, :] / period[:, None]
                                                + rng.uniform(0, 2 * math.pi, (N_RUNS, 1))))
    delta = np.zeros_like(order)
    rate = math.radians(15.8) * dt / FINE
    for k in range(1, len(fine)):
        delta[:, k] = delta[:, k - 1] + np.clip(order[:, k] - delta[:, k - 1], -rate, rate)
    fine_controls = np.stack([np.full_like(delta, 64.27), delta], axis=-1)
    z0 = np.tile([1.15, 0.0, 0.0], (N_RUNS, 1))
    z = free_run(physics.derivative, z0, fine_controls[:, :-1], dt / FINE)[:, ::FINE]
    controls = fine_controls[:, ::FINE]
    z = z + rng.normal(scale=NOISE, size=z.shape)
    runs = {}
    for i in range(N_RUNS):
        psi = np.concatenate([[0.0], np.cumsum(z[i, :-1, 2] * dt)])
        runs[f'run{i:02d}'] = pd.DataFrame({
            't': t, 'u': z[i, :, 0], 'v': z[i, :, 1], 'r': z[i, :, 2], 'psi': psi,
            'x': np.cumsum(z[i, :, 0]) * dt, 'y': np.cumsum(z[i, :, 1]) * dt,
            'n': controls[i, :, 0], 'delta': controls[i, :, 1]})
    return runs


@pytest.fixture(scope='module')
def nominal():
    return load_physics(TANKER.physics, TANKER)


@pytest.fixture(scope='module')
def dataset(tmp_path_factory, nominal):
    truth = nominal.with_parameters(R_0=TRUE_R0, N_0=TRUE_N0)
    path = tmp_path_factory.mktemp('mmg') / 'dataset'
    runs = simulate_runs(truth)
    write_dataset(path, runs, vessel=TANKER, provenance={'tool': 'test'},
                  split={'train': list(runs)[:7], 'val': [], 'test': list(runs)[7:]})
    return path


@pytest.fixture(scope='module')
def settings_file(tmp_path_factory):
    """Fewer bootstrap replicates (the tests' budget)."""
    path = tmp_path_factory.mktemp('settings') / 'mmg.yaml'
    path.write_text(yaml.safe_dump({'selection': {'bootstrap': 60}}))
    return path


@pytest.fixture(scope='module')
def cli_run(dataset, settings_file, tmp_path_factory):
    """Diagnose through the CLI, as a user would; return (exit code, stdout, out dir)."""
    out = tmp_path_factory.mktemp('out')
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = diagnose.main(['--recordings', str(dataset), '--out', str(out), '--config',
                              str(settings_file), '--quiet'])
    return code, buffer.getvalue(), out


@pytest.fixture(scope='module')
def result(cli_run):
    return json.loads((cli_run[2] / 'findings.json').read_text())


def test_names_exactly_the_changed_physics(result):
    assert {f['term'] for f in result['findings']} == {'R_0', 'N_0'}
    assert result['nominal_physics']['family'] == 'mmg'
    assert {f['category'] for f in result['findings']} == {'resistance', 'static_bias'}


def test_intervals_contain_the_estimate_and_the_truth(result, nominal):
    found = {f['term']: f for f in result['findings']}
    for name, true_value in (('R_0', TRUE_R0), ('N_0', TRUE_N0)):
        f = found[name]
        low, high = f['ci95']
        estimate = nominal.parameter(name) + f['coefficient']
        assert low <= f['coefficient'] <= high
        assert low <= true_value - nominal.parameter(name) <= high
        assert abs(estimate - true_value) < 0.1 * abs(true_value)
        assert f['ci95_noise'][0] >= low and f['ci95_noise'][1] <= high   # never narrower


def test_augmented_file_written_because_held_out_forecasts_improve(result):
    improvement = result['metrics']['improvement']
    assert result['augmented_verdict']['written'] and improvement['trajectory'] > 0.05
    assert result['recordings']['held_out_runs'] == ['run07', 'run08', 'run09']


def test_what_cannot_exist_is_excluded_and_said(result):
    excluded = {e['category'] for e in result['excluded']}
    assert excluded == {'current'}          # a tank; the MMG library has no wind or roll
    assert 'basin' in result['excluded_lines'][0]
    assert 'current' not in {c['name'] for c in result['candidates']}


@pytest.mark.slow
def test_nothing_found_on_the_nominal_physics_itself(tmp_path, nominal, settings_file):
    runs = simulate_runs(nominal, seed=1)
    write_dataset(tmp_path / 'ds', runs, vessel=TANKER, provenance={'tool': 'test'},
                  split={'train': list(runs)[:7], 'val': [], 'test': list(runs)[7:]})
    result = diagnose_dataset([tmp_path / 'ds'], None, tmp_path / 'out',
                              load_settings(settings_file, family='mmg'))
    assert result['status'] == 'nothing_significant' and not result['augmented_physics']
    assert not (tmp_path / 'out' / 'augmented_physics.yaml').exists()
    assert 'Nothing significant is missing' in (tmp_path / 'out' / 'report.md').read_text()


def test_cli_routes_an_mmg_vessel_and_writes_a_readable_file(cli_run, result):
    code, stdout, out = cli_run
    assert code == 0 and stdout.startswith('findings: Missing physics found')
    written = load_physics(augmented_physics_file(out), TANKER)
    assert written.family is FAMILY
    found = {f['term']: f for f in result['findings']}
    assert written.params.N_0 == pytest.approx(found['N_0']['coefficient'])
    assert written.params.R_0 == pytest.approx(found['R_0']['value'])
    assert 'augmented_physics.yaml' in (out / 'report.md').read_text()


def test_a_vessel_of_another_family_is_refused(tmp_path):
    data = TANKER.to_dict()
    data['physics'] = 'nominal_vessel.yaml'
    runs = {'a': pd.DataFrame({c: np.zeros(20) for c in ('t', 'u', 'v', 'r', 'psi', 'x', 'y',
                                                         'n', 'delta')})}
    runs['a']['t'] = np.arange(20) * 0.1
    write_dataset(tmp_path / 'ds', runs, vessel=parse_vessel(data), provenance={})
    with pytest.raises(RecordingsError, match='the 4-DOF patrol-boat model .* takes'):
        diagnose_dataset([tmp_path / 'ds'], None, tmp_path / 'out')


def test_wind_sensor_changes_nothing_for_a_family_that_feels_no_wind():
    data = TANKER.to_dict()
    data['environment'] = ['wind']
    library = load_library(None, FAMILY)
    kept, excluded = admissible(library, parse_vessel(data), FAMILY)
    assert not any(c.category == 'wind' for c in kept.candidates)


def test_a_full_scale_vessel_file_is_refused_on_model_scale_recordings(dataset, tmp_path):
    data = TANKER.to_dict()
    data['particulars'] = {**data['particulars'], 'length_m': 320.0}   # the real KVLCC2
    ship_scale = tmp_path / 'ds'
    runs = {run_id: read_dataset(dataset).load(run_id) for run_id in read_dataset(dataset)
            .run_ids()}
    write_dataset(ship_scale, runs, vessel=parse_vessel(data), provenance={})
    # The 7 m model's physics file is for another scale: refused, naming both lengths.
    with pytest.raises(RecordingsError, match='made for L_pp 7 m, but vessel .* is 320 m'):
        diagnose_dataset([ship_scale], None, tmp_path / 'out')
    # With a physics file for 320 m, the recordings themselves turn too fast for it.
    full = froude_scaled(load_physics(TANKER.physics).params, 320.0)
    (tmp_path / 'full.yaml').write_text(yaml.safe_dump(FAMILY.parameter_values(full)))
    with pytest.raises(ScaleError, match='turns of'):
        diagnose_dataset([ship_scale], tmp_path / 'full.yaml', tmp_path / 'out')
