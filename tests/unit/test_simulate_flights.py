"""
offline/simulate.py for a multirotor: flights of mixed kinds, held-out kinds as the test.

The kind of each flight is in the manifest, and ``--test-kinds`` makes the kinds a study
holds out the test split (the nano-drone benchmark tests on its melon flights).
"""

import numpy as np
import pytest

from vessel_datasets import simulate as cli
from vessel_datasets.format import read_dataset
from vessel_description import load_vessel

CRAZYFLIE = load_vessel('crazyflie_brushless')


def test_flights_of_mixed_kinds_with_the_melons_held_out(tmp_path, capsys):
    out = tmp_path / 'flights'
    assert cli.main(['--vessel', CRAZYFLIE.name, '--runs', '7', '--seconds', '1', '--seed',
                     '2', '--out', str(out), '--quiet', '--test-kinds', 'melon']) == 0
    summary = capsys.readouterr().out
    assert '"samples_per_run": 101' in summary and '"random": 3' in summary
    ds = read_dataset(out)
    kinds = {r['id']: r['source']['kind'] for r in ds.manifest['runs']}
    assert list(kinds.values()) == ['random', 'square', 'multisine', 'random', 'melon',
                                    'aggressive', 'random']      # the scenario's cycle
    assert ds.run_ids('test') == ['run_004']
    assert sorted(ds.run_ids('train') + ds.run_ids('val')) == sorted(set(kinds) - {'run_004'})
    assert len(ds.run_ids('val')) == 1
    table = ds.load('run_005')
    assert list(table.columns[:len(CRAZYFLIE.dataset_columns)]) == list(
        CRAZYFLIE.dataset_columns)
    assert {'z', 'z_true', 'theta_true', 'w_true'} <= set(table.columns)
    np.testing.assert_allclose(table['t'], np.arange(101) / 100.0)
    assert table[['x_true', 'y_true', 'z_true']].iloc[0].tolist() == [0.0, 0.0, 0.0]
    assert (table[['m1', 'm2', 'm3', 'm4']] > 500).all().all()   # rad/s, flying
    prov = ds.manifest['provenance']
    assert prov['seconds'] == 1.0 and prov['config']['flight']['kinds'][4] == 'melon'
    assert prov['config']['dt'] == 0.002 and ds.manifest['rate_hz'] == 100.0
    source = ds.manifest['runs'][4]['source']
    assert source['run_index'] == 4 and 0.6 <= source['radius_m'] <= 0.8


@pytest.mark.parametrize('args, code, words', [
    (['--seconds', '1', '--hours', '1'], 2, 'not allowed with argument'),
    (['--vessel', 'otter', '--test-kinds', 'melon'], 1, 'flies no trajectories'),
    (['--vessel', CRAZYFLIE.name, '--runs', '1', '--test-kinds', 'melon'], 1,
     'no run flies them (the runs fly random)'),
    (['--test-kinds', 'loop'], 2, "invalid choice: 'loop'"),
])
def test_bad_flight_options_are_one_line(tmp_path, capsys, args, code, words):
    argv = [*args, '--out', str(tmp_path / 'x'), '--quiet']
    if '--seconds' not in args:
        argv += ['--seconds', '0.05']
    try:
        result = cli.main(argv)
    except SystemExit as exit_:       # argparse's own errors
        result = exit_.code
    err = capsys.readouterr().err
    assert result == code and words in err, err
    assert not (tmp_path / 'x' / 'manifest.json').exists()
