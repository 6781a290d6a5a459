"""offline/simulate.py end to end on a tiny dataset, and its one-line errors."""

import json
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

from vessel_datasets.format import read_dataset
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / 'offline' / 'simulate.py'


def run_cli(*args):
    return subprocess.run([sys.executable, str(SCRIPT), *map(str, args)], capture_output=True,
                          text=True, timeout=120)


def test_tiny_dataset_end_to_end(tmp_path):
    out = tmp_path / 'ds'
    result = run_cli('--runs', 3, '--hours', 1 / 60, '--seed', 4, '--out', out, '--chunk', 2)
    assert result.returncode == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary['runs'] == 3 and summary['samples_per_run'] == 61
    ds = read_dataset(out)
    assert ds.run_ids() == ['run_000', 'run_001', 'run_002']
    assert {len(ds.run_ids(s)) for s in ('train', 'val', 'test')} == {1}
    table = ds.load('run_001')
    assert len(table) == 61
    for column in SHIP.dataset_columns + ('u_true', 'phi_true', 'psi_true', 'x_true', 'y_true'):
        assert column in table.columns
    np.testing.assert_array_equal(table['t'].to_numpy(), np.arange(61.0))
    assert table[['x_true', 'y_true']].iloc[0].tolist() == [0.0, 0.0]
    assert (table['n'] > 30).all()                              # rad/s, not rpm
    prov = ds.manifest['provenance']
    assert prov['seed'] == 4 and prov['config']['vessel'] == 'patrol_boat'
    assert prov['config']['physics']['parameters']['name'] == 'patrol_vessel'
    assert set(prov['versions']) >= {'numpy', 'scipy', 'python'}
    assert ds.manifest['runs'][1]['source']['run_index'] == 1
    assert ds.manifest['columns']['psi_true']['unit'] == 'rad'
    assert ds.manifest['columns']['x_true']['unit'] == 'm'


def test_chunking_does_not_change_the_runs(tmp_path):
    from vessel_datasets import simulate as cli
    a, b = tmp_path / 'a', tmp_path / 'b'
    assert cli.main(['--runs', '2', '--hours', '0.01', '--out', str(a), '--quiet',
                     '--chunk', '1']) == 0
    assert cli.main(['--runs', '2', '--hours', '0.01', '--out', str(b), '--quiet']) == 0
    for run in ('run_000', 'run_001'):
        ta, tb = read_dataset(a).load(run), read_dataset(b).load(run)
        np.testing.assert_allclose(ta.to_numpy(), tb.to_numpy(), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize('args, words, code', [
    (['--runs', '0'], 'must be >= 1', 2),
    (['--hours', '-1'], 'must be a number > 0', 2),
    (['--config', 'nope.yaml'], 'cannot read config', 1),
])
def test_bad_input_is_one_clear_line(tmp_path, args, words, code):
    result = run_cli(*args, '--out', tmp_path / 'x', '--quiet')
    assert result.returncode == code
    errors = [line for line in result.stderr.splitlines() if 'error:' in line]
    assert len(errors) == 1 and words in errors[0], result.stderr


def test_refuses_to_overwrite_without_flag(tmp_path):
    out = tmp_path / 'ds'
    assert run_cli('--runs', 1, '--hours', 0.005, '--out', out, '--quiet').returncode == 0
    again = run_cli('--runs', 1, '--hours', 0.005, '--out', out, '--quiet')
    assert again.returncode == 1 and 'already holds a dataset' in again.stderr
    assert again.stderr.count('\n') == 1
    assert run_cli('--runs', 1, '--hours', 0.005, '--out', out, '--quiet',
                   '--overwrite').returncode == 0


def test_help():
    result = run_cli('--help')
    assert result.returncode == 0 and '--runs' in result.stdout and '--seed' in result.stdout


@pytest.mark.parametrize('vessel, family', [('kvlcc2_hsva', 'mmg'), ('otter', 'fossen')])
def test_another_family_vessel_is_simulated_in_its_own_vectors(tmp_path, vessel, family):
    out = tmp_path / vessel
    result = run_cli('--vessel', vessel, '--runs', 2, '--hours', 30 / 3600, '--out', out,
                     '--quiet')
    assert result.returncode == 0, result.stderr
    ds = read_dataset(out)
    boat = load_vessel(vessel)
    assert ds.vessel.name == vessel and ds.vessel.dataset_columns == boat.dataset_columns
    assert ds.manifest['provenance']['config']['physics']['family'] == family
    table = ds.load(ds.run_ids()[0])
    assert len(table) == 301                                 # 30 s at the vessel's 10 Hz
    assert not {'p', 'phi', 'wind_speed'} & set(table.columns)
    for a in boat.actuators:                                 # orders within the vessel's range
        assert a.low <= table[a.name].min() and table[a.name].max() <= a.high + 1.0
    assert table['u'].mean() > 0.5


def test_a_vessel_without_a_scenario_gets_one_line(tmp_path):
    result = run_cli('--vessel', 'snuboat', '--runs', 1, '--hours', 0.01, '--out', tmp_path / 'x')
    assert result.returncode == 1 and result.stderr.count('\n') == 1
    assert "vessel 'snuboat'" in result.stderr and 'names no physics file' in result.stderr
