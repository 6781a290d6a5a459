"""
The MMG family's diagnosis on recordings with a known answer (vessel_diagnosis.mmg_family).

A KVLCC2-like vessel is simulated with a lower resistance and a constant yaw moment (a
propeller or hull asymmetry) that the nominal parameters do not have. The diagnosis must
name exactly those, with intervals that contain their estimates and the truth, write the
augmented file because held-out forecasts improve, and exclude what the vessel cannot
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
from vessel_diagnosis import mmg_family
from vessel_diagnosis.recordings import RecordingsError
from vessel_diagnosis.scale import ScaleError
from vessel_diagnosis.settings import config_dir
from vessel_physics import mmg

TANKER = load_vessel('kvlcc2_hsva')
N_RUNS, SECONDS = 10, 90.0
TRUE_R0, TRUE_N0 = 0.016, 4.0      # nominal: R_0' 0.022, N_0 0 N m
NOISE = [1e-3, 1e-3, 1e-4]          # m/s, m/s, rad/s: sensor noise of u, v, r


def simulate_runs(params, seed=0):
    """Zig-zag-like runs: rate-limited rudder square waves of several amplitudes, noise."""
    rng = np.random.default_rng(seed)
    dt = TANKER.dt
    steps = int(SECONDS / dt)
    t = np.arange(steps + 1) * dt
    amplitude = np.radians(rng.uniform(5.0, 25.0, N_RUNS))
    period = rng.uniform(20.0, 40.0, N_RUNS)
    order = amplitude[:, None] * np.sign(np.sin(2 * math.pi * t[None, :] / period[:, None]
                                                + rng.uniform(0, 2 * math.pi, (N_RUNS, 1))))
    delta = np.zeros_like(order)
    rate = math.radians(15.8) * dt
    for k in range(1, steps + 1):
        delta[:, k] = delta[:, k - 1] + np.clip(order[:, k] - delta[:, k - 1], -rate, rate)
    controls = np.stack([np.full_like(delta, 64.27), delta], axis=-1)
    z0 = np.tile([1.15, 0.0, 0.0], (N_RUNS, 1))
    z = mmg.simulate(params, z0, controls[:, :-1], dt, substeps=2)
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
    return mmg.load_mmg(mmg.find_params_file(TANKER.physics))


@pytest.fixture(scope='module')
def dataset(tmp_path_factory, nominal):
    truth = nominal.replace(R_0=TRUE_R0, N_0=TRUE_N0)
    path = tmp_path_factory.mktemp('mmg') / 'dataset'
    runs = simulate_runs(truth)
    write_dataset(path, runs, vessel=TANKER, provenance={'tool': 'test'},
                  split={'train': list(runs)[:7], 'val': [], 'test': list(runs)[7:]})
    return path


@pytest.fixture(scope='module')
def settings_file(tmp_path_factory):
    """Write the shipped settings with fewer bootstrap replicates (the tests' budget)."""
    data = yaml.safe_load((config_dir() / mmg_family.SETTINGS_FILE).read_text())
    path = tmp_path_factory.mktemp('settings') / 'mmg.yaml'
    path.write_text(yaml.safe_dump({**data, 'n_bootstrap': 40}))
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
    found = result['identification']['candidates']
    chosen = {n for n, v in found.items() if v['selected']}
    assert chosen == {'R_0', 'N_0'}
    assert 'parameter corrections' in result['verdict'] and 'effects outside' in result['verdict']


def test_intervals_contain_the_estimate_and_the_truth(result, nominal):
    found = result['identification']['candidates']
    for name, true_value in (('R_0', TRUE_R0), ('N_0', TRUE_N0)):
        v = found[name]
        low, high = v['ci95']
        estimate = v['nominal'] + v['correction']
        assert low <= v['correction'] <= high
        assert low <= true_value - v['nominal'] <= high
        assert abs(estimate - true_value) < 0.1 * abs(true_value)


def test_augmented_file_written_because_held_out_forecasts_improve(result, tmp_path):
    change = result['held_out_forecast_rmse']['relative_change']
    assert result['augmented_written'] and np.mean(list(change.values())) < -0.05
    assert result['recordings']['held_out_runs'] == ['run07', 'run08', 'run09']


def test_what_cannot_exist_is_excluded_and_said(result):
    assert set(result['excluded']) == {'roll', 'wind', 'current'}
    assert 'no wind sensor' in result['excluded']['wind']
    tried = set(result['candidates_tried'])
    assert tried and not tried & {'wind', 'current'}


@pytest.mark.slow
def test_nothing_found_on_the_nominal_physics_itself(tmp_path, nominal, settings_file):
    runs = simulate_runs(nominal, seed=1)
    write_dataset(tmp_path / 'ds', runs, vessel=TANKER, provenance={'tool': 'test'},
                  split={'train': list(runs)[:7], 'val': [], 'test': list(runs)[7:]})
    result = mmg_family.diagnose_mmg(tmp_path / 'ds', tmp_path / 'out',
                                     mmg_family.load_mmg_settings(settings_file))
    assert result['verdict'].startswith('nothing') and not result['augmented_written']
    assert not (tmp_path / 'out' / 'augmented_mmg.yaml').exists()
    assert 'no augmented file is written' in (tmp_path / 'out' / 'report.md').read_text()


def test_cli_routes_an_mmg_vessel_and_writes_a_readable_file(cli_run, result):
    code, stdout, out = cli_run
    assert code == 0 and 'found parameter corrections' in stdout
    written = mmg.load_mmg(out / 'augmented_mmg.yaml')
    found = result['identification']['candidates']
    assert written.N_0 == pytest.approx(found['N_0']['correction'])
    assert written.R_0 == pytest.approx(found['R_0']['nominal'] + found['R_0']['correction'])
    assert 'written to `augmented_mmg.yaml`' in (out / 'report.md').read_text()


def test_a_vessel_of_another_family_is_refused(tmp_path):
    data = TANKER.to_dict()
    data['physics'] = 'nominal_vessel.yaml'
    runs = {'a': pd.DataFrame({c: np.zeros(20) for c in ('t', 'u', 'v', 'r', 'psi', 'x', 'y',
                                                         'n', 'delta')})}
    runs['a']['t'] = np.arange(20) * 0.1
    write_dataset(tmp_path / 'ds', runs, vessel=parse_vessel(data), provenance={})
    with pytest.raises(RecordingsError, match='not an MMG parameter file'):
        mmg_family.load_mmg_runs(tmp_path / 'ds')


def test_wind_sensor_changes_the_reason_not_the_exclusion():
    data = TANKER.to_dict()
    data['environment'] = ['wind']
    reasons = mmg_family.excluded_categories(parse_vessel(data))
    assert 'no wind-load candidates' in reasons['wind']


def test_a_full_scale_vessel_file_is_refused_on_model_scale_recordings(dataset, tmp_path):
    data = TANKER.to_dict()
    data['particulars'] = {**data['particulars'], 'length_m': 320.0}   # the real KVLCC2
    ship_scale = tmp_path / 'ds'
    runs = {run_id: read_dataset(dataset).load(run_id) for run_id in read_dataset(dataset)
            .run_ids()}
    write_dataset(ship_scale, runs, vessel=parse_vessel(data), provenance={})
    # The 7 m model's physics file is for another scale: refused, naming both lengths.
    with pytest.raises(RecordingsError, match='made for L_pp 7 m, but vessel .* is 320 m'):
        mmg_family.diagnose_mmg(ship_scale, tmp_path / 'out')
    # With a physics file for 320 m, the recordings themselves turn too fast for it.
    full = mmg.froude_scaled(mmg.load_mmg(mmg.find_params_file(TANKER.physics)), 320.0)
    (tmp_path / 'full.yaml').write_text(yaml.safe_dump(
        {'format': mmg.FORMAT, **full.__dict__}))
    with pytest.raises(ScaleError, match='turns of'):
        mmg_family.diagnose_mmg(ship_scale, tmp_path / 'out', params_file=tmp_path / 'full.yaml')
