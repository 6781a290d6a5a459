"""vessel_datasets.format: the dataset contract between producers and consumers."""

import json

import numpy as np
import pandas as pd
import pytest

from vessel_datasets.format import (
    DatasetError,
    read_dataset,
    split_runs,
    write_dataset,
)
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


def make_run(n=10, offset=0.0):
    data = {c: np.linspace(0, 1, n) + offset for c in SHIP.dataset_columns}
    data['t'] = np.arange(n, dtype=float)
    return pd.DataFrame(data)


def test_split_is_by_whole_runs_seeded_and_sized_60_10_30():
    ids = [f'run_{i:03d}' for i in range(96)]
    split = split_runs(ids, seed=3)
    assert [len(split[s]) for s in ('train', 'val', 'test')] == [57, 10, 29]
    assert sorted(split['train'] + split['val'] + split['test']) == ids
    assert split == split_runs(list(reversed(ids)), seed=3)
    assert split != split_runs(ids, seed=4)


def test_every_split_gets_a_run_when_there_are_few():
    split = split_runs(['a', 'b', 'c'], seed=0)
    assert sorted(len(v) for v in split.values()) == [1, 1, 1]


def test_bad_fractions_are_refused():
    with pytest.raises(DatasetError, match='summing to 1'):
        split_runs(['a'], seed=0, fractions=(0.5, 0.5, 0.5))


def test_round_trip_keeps_tables_units_and_split(tmp_path):
    runs = {f'run_{i}': make_run(offset=i) for i in range(5)}
    write_dataset(tmp_path, runs, vessel=SHIP, provenance={'tool': 'test'}, seed=1,
                  run_sources={'run_0': {'bag': 'x.mcap'}})
    ds = read_dataset(tmp_path)
    assert ds.rate_hz == 1.0
    assert sorted(ds.run_ids()) == sorted(runs)
    assert sum(len(ds.run_ids(s)) for s in ('train', 'val', 'test')) == 5
    pd.testing.assert_frame_equal(ds.load('run_3'), runs['run_3'])
    manifest = json.loads((tmp_path / 'manifest.json').read_text())
    assert manifest['columns']['u']['unit'] == 'm/s'
    assert manifest['columns']['n']['unit'] == 'rad/s'
    assert manifest['runs'][0]['source'] == {'bag': 'x.mcap'}


def test_explicit_split_is_kept_and_checked(tmp_path):
    runs = {'a': make_run(), 'b': make_run()}
    write_dataset(tmp_path, runs, vessel=SHIP, provenance={},
                  split={'train': ['a'], 'test': ['b']})
    assert read_dataset(tmp_path).run_ids('test') == ['b']
    with pytest.raises(DatasetError, match='unknown or repeated'):
        write_dataset(tmp_path / 'x', runs, vessel=SHIP, provenance={},
                      split={'train': ['a', 'zzz']})


@pytest.mark.parametrize('corrupt, message', [
    (lambda t: t.drop(columns=['phi']), 'lacks columns'),
    (lambda t: t.assign(u=np.nan), 'NaN/Inf'),
    (lambda t: t.assign(t=t['t'][::-1].to_numpy()), 'strictly increasing'),
])
def test_invalid_runs_are_refused_with_the_reason(tmp_path, corrupt, message):
    with pytest.raises(DatasetError, match=message):
        write_dataset(tmp_path, {'bad': corrupt(make_run())}, vessel=SHIP, provenance={})


def test_a_directory_without_manifest_is_not_a_dataset(tmp_path):
    with pytest.raises(DatasetError, match='not a dataset'):
        read_dataset(tmp_path)


def test_a_physics_file_of_the_vessels_own_travels_with_the_dataset(tmp_path):
    import shutil

    import yaml

    from vessel_datasets.format import resplit
    from vessel_description.vessel import vessels_dir
    from vessel_physics.files import config_dir
    from vessel_physics.physics_file import load_physics

    # A user's vessel file naming a physics file beside it (a packaged MMG file renamed).
    user = tmp_path / 'user'
    user.mkdir()
    shutil.copyfile(config_dir() / 'kvlcc2_hsva_mmg.yaml', user / 'my_tanker_mmg.yaml')
    data = yaml.safe_load((vessels_dir() / 'kvlcc2_hsva.yaml').read_text())
    data.update(name='my_tanker', physics='my_tanker_mmg.yaml')
    (user / 'my_tanker.yaml').write_text(yaml.safe_dump(data))
    vessel = load_vessel(user / 'my_tanker.yaml')
    runs = {f'run_{i}': pd.DataFrame(
        {**{c: np.zeros(10) for c in vessel.dataset_columns}, 't': np.arange(10) / 10.0})
        for i in range(3)}
    write_dataset(tmp_path / 'ds', runs, vessel=vessel, provenance={'tool': 'test'})
    shutil.rmtree(user)   # the dataset must not need the user's folder any more
    ds = read_dataset(tmp_path / 'ds')
    assert ds.vessel.physics == 'physics_my_tanker_mmg.yaml'
    carried = load_physics(ds.vessel.physics, ds.vessel)
    assert carried.params.L_pp == 7.0 and carried.family.name == 'mmg'
    view = resplit(ds, tmp_path / 'view', {'train': ['run_0'], 'test': ['run_1']})
    assert load_physics(view.vessel.physics, view.vessel).params == carried.params
    # A packaged physics file is named as it is: every installation has it.
    write_dataset(tmp_path / 'ds2', runs, vessel=load_vessel('kvlcc2_hsva'),
                  provenance={'tool': 'test'})
    assert read_dataset(tmp_path / 'ds2').vessel.physics == 'kvlcc2_hsva_mmg.yaml'


def test_a_physics_entry_that_is_no_physics_file_does_not_stop_the_writing(tmp_path):
    """A vessel naming its own file as physics (a name clash) writes; its users refuse it."""
    import yaml

    from vessel_description.vessel import vessels_dir

    data = yaml.safe_load((vessels_dir() / 'kvlcc2_hsva.yaml').read_text())
    data.update(name='clash', physics='clash.yaml')
    (tmp_path / 'clash.yaml').write_text(yaml.safe_dump(data))
    vessel = load_vessel(tmp_path / 'clash.yaml')
    runs = {f'run_{i}': pd.DataFrame(
        {**{c: np.zeros(10) for c in vessel.dataset_columns}, 't': np.arange(10) / 10.0})
        for i in range(3)}
    write_dataset(tmp_path / 'ds', runs, vessel=vessel, provenance={'tool': 'test'})
    assert read_dataset(tmp_path / 'ds').vessel.physics == 'clash.yaml'
