"""hybrid_models.studies.peers: problems from our splits, adapters run, answers scored as ours."""

import json
from pathlib import Path
import shutil
import sys

import numpy as np
import pandas as pd
import pytest

from hybrid_models.data import evaluation_protocol, forecast_windows, load_runs
from hybrid_models.metrics import forecast_metrics
from hybrid_models.studies import peers, table3
from vessel_datasets.format import write_dataset
from vessel_description import load_vessel

REPO = Path(__file__).resolve().parents[2]

# A stand-in adapter in the product's interpreter: every seed holds the window's last
# state (seed s adds s), so the study's scoring can be checked by hand.
HOLD = """
import sys
import numpy as np
import peer_io

def solve(problem, args, say):
    last = problem.test_windows['z_window'][:, -1:]
    pred = np.stack([np.repeat(last, problem.horizon, axis=1) + s for s in problem.seeds])
    return {'pred': pred, 'seeds': problem.seeds, 'fit_seconds': [1.0] * len(pred),
            'forecast_seconds': [0.1] * len(pred), 'meta': {'peer': 'hold'}}

sys.exit(peer_io.run('narx', 'hold', solve))
"""
FAILS = """
import sys
print('sindy: error: the peer gave up', file=sys.stderr)
sys.exit(1)
"""


@pytest.fixture()
def setup(tmp_path):
    vessel = load_vessel('snuboat')
    rng = np.random.default_rng(0)
    runs = {}
    for k in range(5):
        rows = 400
        table = {'t': np.arange(rows) * vessel.dt, 'psi': np.zeros(rows), 'x': np.zeros(rows),
                 'y': np.zeros(rows)}
        for s in vessel.state_names:
            table[s] = np.cumsum(rng.normal(scale=0.01, size=rows))
        for c in vessel.control_names:
            table[c] = rng.normal(size=rows)
        runs[f'run{k}'] = pd.DataFrame(table)
    ds = tmp_path / 'ds'
    write_dataset(ds, runs, vessel=vessel, provenance={'tool': 'test'},
                  split={'train': ['run0', 'run1', 'run2'], 'val': ['run3'], 'test': ['run4']})
    root = tmp_path / 'repo'
    (root / 'offline' / 'peers').mkdir(parents=True)
    shutil.copy(REPO / 'offline' / 'peers' / 'peer_io.py', root / 'offline' / 'peers')
    (root / 'offline' / 'peers' / 'narx.py').write_text(HOLD)
    (root / 'offline' / 'peers' / 'sindy.py').write_text(FAILS)
    return vessel, ds, root


def test_a_peer_is_scored_on_our_windows_as_our_models_are(setup, tmp_path):
    vessel, ds, root = setup
    out = tmp_path / 'out'
    said = []
    summary = peers.study(None, out, ['narx'], [0, 1], None, Path(sys.executable), root,
                          dataset=ds, say=said.append)
    window, horizon, stride = evaluation_protocol(vessel)
    windows = forecast_windows(load_runs(ds, 'test', vessel), window, horizon, stride, 'true')
    truth = windows.z_target
    scale = truth.reshape(-1, truth.shape[-1]).std(axis=0)
    row = summary['rows'][0]
    assert row['label'] == 'peer: NARX (SysIdentPy)' and row['seeds'] == 2
    for s in (0, 1):
        hold = np.repeat(windows.z_window[:, -1:], horizon, axis=1) + s
        expected = forecast_metrics(hold, truth, vessel, state_std=scale)
        got = row['per_seed_metrics'][s]
        assert got['rmse'] == pytest.approx(expected['rmse'])
        assert got['trajectory']['mean'] == pytest.approx(expected['trajectory']['mean'])
    assert row['spread']['rmse']['u'] > 0          # two different seeds
    assert row['fit_seconds'] == [[1.0, 1.0]]
    # The problem holds no test targets; the table names the row and its fit time.
    with np.load(peers.write_problems(None, tmp_path / 'w', [0], root, ds)[0][0].path) as f:
        assert not any(k.startswith('test_z_target') for k in f.files)
    table = (out / 'table.md').read_text()
    assert '| peer: NARX (SysIdentPy) |' in table and '| 1.0 ± 0.0 |' in table
    assert 'fold 0 (' not in table     # one fold, nothing diverged: no table per fold
    # The same problem and adapter: kept, not run again.
    peers.study(None, out, ['narx'], [0, 1], None, Path(sys.executable), root, dataset=ds,
                say=said.append)
    assert said[-1] == 'narx fold 0: kept'


def test_a_failing_peer_is_said_in_its_own_line(setup, tmp_path):
    _, ds, root = setup
    with pytest.raises(peers.PeerStudyError, match='^sindy: error: the peer gave up$'):
        peers.study(None, tmp_path / 'out', ['sindy'], [0], None, Path(sys.executable), root,
                    dataset=ds, say=lambda m: None)
    with pytest.raises(peers.PeerStudyError, match='unknown peer'):
        peers.study(None, tmp_path / 'out', ['arx'], [0], None, Path(sys.executable), root,
                    dataset=ds)


def test_a_table3_study_is_one_fold_of_its_dataset_with_the_target_it_forecast(setup,
                                                                               tmp_path):
    # reproduce_table3 describes its target in words; the problems must take the
    # windows' target it forecast (table3.TARGET), not fail on the description.
    _, ds, root = setup
    study = tmp_path / 'table3'
    study.mkdir()
    protocol = {'window': 20, 'horizon': 30, 'stride': 7,
                'target': 'true where simulated, else measured', 'seeds': [0]}
    (study / 'results.json').write_text(json.dumps(
        {'dataset': {'path': str(ds)}, 'protocol': protocol, 'rows': []}))
    problems, result = peers.write_problems(study, tmp_path / 'work', [0], root)
    assert result['protocol']['target'] == table3.TARGET
    assert [p.index for p in problems] == [0]
    vessel = load_vessel('snuboat')
    expected = forecast_windows(load_runs(ds, 'test', vessel), 20, 30, 7, 'measured')
    assert problems[0].truth.shape == (len(expected.z_target), 30, 3)
    np.testing.assert_array_equal(problems[0].truth, expected.z_target)


# A stand-in adapter whose first test forecast diverges (NaN from its third step).
DIVERGES_ONCE = HOLD.replace("    return {'pred': pred,", "    pred[:, 0, 2:] = np.nan\n"
                             "    return {'pred': pred,")


def test_one_diverged_forecast_is_counted_not_left_to_hide_the_others(setup, tmp_path):
    vessel, ds, root = setup
    (root / 'offline' / 'peers' / 'narx.py').write_text(DIVERGES_ONCE)
    out = tmp_path / 'out'
    summary = peers.study(None, out, ['narx'], [0], None, Path(sys.executable), root,
                          dataset=ds, say=lambda m: None)
    row = summary['rows'][0]
    assert row['metrics']['diverged'] and row['metrics']['trajectory']['mean'] is None
    fold = row['per_fold'][0]
    assert fold['diverged'] == [1]
    window, horizon, stride = evaluation_protocol(vessel)
    windows = forecast_windows(load_runs(ds, 'test', vessel), window, horizon, stride, 'true')
    hold = np.repeat(windows.z_window[1:, -1:], horizon, axis=1)
    expected = forecast_metrics(hold, windows.z_target[1:], vessel)
    assert fold['final'] == [pytest.approx(expected['trajectory']['final_mean'])]
    assert '(1 diverged)' in (out / 'table.md').read_text()


@pytest.mark.parametrize('results', sorted((REPO / 'docs' / 'results' / 'peers').glob(
    '*/results.json')), ids=lambda p: p.parent.name)
def test_each_committed_peer_table_is_its_results_rendered(results):
    # The tables docs/results/peers/README.md quotes are what their results.json holds.
    summary = json.loads(results.read_text())
    per_fold = peers.fold_table(summary)
    rendered = peers.table(summary) + ('\n' + per_fold if per_fold else '')
    assert rendered == (results.parent / 'table.md').read_text()
