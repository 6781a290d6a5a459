"""The diagnose program (vessel_diagnosis.cli): usage, one-line errors and exit codes."""

import json

import numpy as np
import pandas as pd
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from vessel_datasets import synthetic
from vessel_datasets.format import write_dataset
from vessel_description import load_vessel
from vessel_diagnosis import cli as diagnose

SHIP = load_vessel('patrol_boat')

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_INSUFFICIENT = 0, 1, 2, 3


def run(capsys, *argv):
    code = diagnose.main(list(argv))
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_help_documents_the_command(capsys):
    with pytest.raises(SystemExit) as info:
        diagnose.main(['--help'])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for needle in ('--recordings', '--physics', '--out', 'REPORT_DIR', 'Exit status'):
        assert needle in text


def test_missing_arguments_are_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        diagnose.main(['--recordings', 'x'])
    assert info.value.code == EXIT_USAGE
    assert 'required' in capsys.readouterr().err


def test_missing_recordings_give_one_line(capsys, tmp_path):
    code, _, err = run(capsys, '--recordings', str(tmp_path / 'nope'), '--physics',
                       'patrol_vessel.yaml', '--out', str(tmp_path / 'out'), '--quiet')
    assert code == EXIT_INPUT
    assert err == f'diagnose.py: error: {tmp_path / "nope"}: no such file or directory\n'


def test_bad_physics_file_gives_one_line(capsys, tmp_path):
    physics = tmp_path / 'p.yaml'
    physics.write_text('format: vessel-physics/1\nvessel: patrol_vessel.yaml\nterms: [wnd]\n')
    dataset = _short_dataset(tmp_path, 2000)
    code, _, err = run(capsys, '--recordings', str(dataset), '--physics', str(physics),
                       '--out', str(tmp_path / 'out'), '--quiet')
    assert code == EXIT_INPUT
    assert "terms: unknown term 'wnd' (did you mean 'wind'?)" in err
    assert err.count('\n') == 1


def _bag_without(path, topic):
    store = get_typestore(Stores.ROS2_JAZZY)
    traj = synthetic.demo_trajectory(40)
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {t: w.add_connection(t, m, typestore=store)
                 for t, m in synthetic.SIM_TOPICS.items() if t != topic}
        for t, ns, msg in synthetic.sim_messages(traj, store):
            if t != topic:
                w.write(conns[t], ns, store.serialize_cdr(msg, synthetic.SIM_TOPICS[t]))
    return path


def test_recording_without_the_wind_topic_is_refused(capsys, tmp_path):
    bag = _bag_without(tmp_path / 'bag', '/vessel/wind')
    code, _, err = run(capsys, '--recordings', str(bag), '--physics', 'patrol_vessel.yaml',
                       '--vessel', 'patrol_boat', '--out', str(tmp_path / 'out'), '--quiet')
    assert code == EXIT_INPUT
    assert err.startswith(f'diagnose.py: error: {bag}: cannot convert the recording: ')
    assert 'needs /vessel/wind' in err and err.count('\n') == 1
    assert not (tmp_path / 'out' / 'findings.json').exists()


def _short_dataset(tmp_path, seconds):
    traj = synthetic.demo_trajectory(seconds)
    table = pd.DataFrame({'t': np.arange(seconds, dtype=float),
                          **{c: traj.columns[c] for c in SHIP.dataset_columns[1:]}})
    write_dataset(tmp_path / 'ds', {'trial': table}, vessel=SHIP, provenance={'tool': 'test'})
    return tmp_path / 'ds'


def test_too_short_recordings_are_explained(capsys, tmp_path):
    dataset = _short_dataset(tmp_path, 600)
    out = tmp_path / 'out'
    code, _, err = run(capsys, '--recordings', str(dataset), '--physics', 'patrol_vessel.yaml',
                       '--out', str(out), '--quiet')
    assert code == EXIT_INSUFFICIENT
    assert 'needs at least 1200 s' in err and err.count('\n') == 1
    result = json.loads((out / 'findings.json').read_text())
    assert result['status'] == 'insufficient_excitation' and result['findings'] == []
    assert 'Cannot diagnose' in (out / 'report.md').read_text()


def test_one_nan_in_one_run_is_one_line_not_a_traceback(capsys, tmp_path):
    dataset = _short_dataset(tmp_path, 2000)
    table = pd.read_parquet(dataset / 'runs' / 'trial.parquet')
    table.loc[700, 'v'] = np.nan
    table.to_parquet(dataset / 'runs' / 'trial.parquet')
    code, _, err = run(capsys, '--recordings', str(dataset), '--out', str(tmp_path / 'out'),
                       '--quiet')
    assert code == EXIT_INPUT and err.count('\n') == 1
    assert "cannot read the dataset (run 'trial' has NaN/Inf in ['v'])" in err, err


@pytest.mark.parametrize('physics, words', [
    ('kvlcc2_hsva_mmg.yaml', "the MMG standard model (Yasukawa & Yoshimura 2015) takes "
                             "['u', 'v', 'r']"),
    ('otter_fossen.yaml', 'takes'),
])
def test_a_physics_of_another_family_is_one_line(capsys, tmp_path, physics, words):
    dataset = _short_dataset(tmp_path, 2000)
    code, _, err = run(capsys, '--recordings', str(dataset), '--physics', physics, '--out',
                       str(tmp_path / 'out'), '--quiet')
    assert code == EXIT_INPUT and err.count('\n') == 1 and words in err, err
