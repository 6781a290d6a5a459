"""Baier et al.'s Table 3 study: its plan, its figures against known errors, peers, claims."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from hybrid_models.data import load_runs
from hybrid_models.evaluation import test_windows as forecast_windows
from hybrid_models.studies import table3
from vessel_datasets.format import write_dataset
from vessel_description import load_vessel
from vessel_physics import frames
from vessel_physics.integrator import body_to_ned

from .tracks import spatial_flight

STATES = ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta')


@pytest.fixture(scope='module')
def flights(tmp_path_factory):
    """Two 6-DOF flights as a Crazyflie dataset (both test runs), and their truth."""
    vehicle = load_vessel('crazyflie_brushless')
    root = tmp_path_factory.mktemp('t3') / 'ds'
    runs, truths = {}, {}
    for k in range(2):
        truth = spatial_flight(seconds=6.0, seed=k)
        table = {'t': truth['t'], **{s: truth[s] for s in STATES}, 'psi': truth['psi'],
                 'x': truth['x'], 'y': truth['y'], 'z': truth['z']}
        table.update({f'm{i + 1}': truth['motors'][i] for i in range(4)})
        runs[f'flight{k}'], truths[f'flight{k}'] = pd.DataFrame(table), truth
    write_dataset(root, runs, vessel=vehicle, provenance={'tool': 'test'},
                  split={'test': list(runs)})
    test_runs = load_runs(root, 'test', vehicle)
    windows = forecast_windows(test_runs, 50, 100, 25, 'measured')
    return vehicle, root, windows, truths


def test_the_plan_trains_qlag_once_and_every_other_model_per_seed():
    jobs = table3.plan(seeds=3)
    labels = [j.label for j in jobs]
    assert labels.count('QLag') == 1 and labels.count('LSTM') == 3
    for phys, name in table3.PAPER_NAME.items():
        hybrid = [j for j in jobs if j.label == f'{name}-2P']
        assert [j.seed for j in hybrid] == [0, 1, 2]
        assert all(f'model.physical.kind={phys}' in j.overrides for j in hybrid)
        assert all(f'training.seed={j.seed}' in j.overrides for j in hybrid)
    assert len({j.name for j in jobs}) == len(jobs)   # a folder each


def test_a_perfect_forecast_has_no_error_in_any_figure(flights):
    vehicle, root, windows, _ = flights
    truth = table3.test_truth(root, windows)
    figures = table3.figures_of(windows.z_target, windows.z_target, vehicle, truth)
    # The forecast's own heading and position are integrated from the window's last
    # sample; the measured ones are the flight's: they agree to the integration's error.
    assert max(figures['paper_rmse'].values()) < 0.02
    assert max(figures['per_step']['position']) < 0.02
    assert max(figures['per_step']['attitude']) < 0.02
    assert max(figures['per_step']['body_rates']) == 0.0


def test_a_known_velocity_error_shows_in_the_paper_columns_and_per_step(flights):
    vehicle, root, windows, _ = flights
    truth = table3.test_truth(root, windows)
    pred = windows.z_target.copy()
    pred[..., STATES.index('w')] += 0.3      # 0.3 m/s downwards in the body
    pred[..., STATES.index('q')] += 0.2      # 0.2 rad/s pitch rate
    exact = table3.figures_of(windows.z_target, windows.z_target, vehicle, truth)
    off = table3.figures_of(pred, windows.z_target, vehicle, truth)
    speed = np.sqrt(sum((off['paper_rmse'][s]) ** 2 for s in ('vx', 'vy', 'vz')))
    assert speed == pytest.approx(0.3, abs=0.02)
    assert off['paper_rmse']['q'] == pytest.approx(0.2, abs=1e-6)   # float32 windows
    assert off['per_step']['body_rates'][0] == pytest.approx(0.2, abs=1e-6)
    # The position error grows as the velocity error integrates: 0.3 m/s over 1 s.
    assert off['per_step']['position'][-1] > 0.25 + exact['per_step']['position'][-1]


def test_a_peers_forecasts_are_aligned_row_by_row_and_turned_into_our_frames(flights,
                                                                              tmp_path):
    """A peer that forecasts the truth (in ENU/FLU, absolute positions) has no error."""
    vehicle, root, windows, truths = flights
    horizon = windows.z_target.shape[1]
    arrays = {}
    for name, truth in truths.items():
        n = len(truth['t'])
        starts = np.arange(0, n - horizon)          # every row: --stride 1
        steps = starts[:, None] + np.arange(1, horizon + 1)
        vel = np.stack(frames.position_ned_to_enu(*body_to_ned(
            truth['u'], truth['v'], truth['w'], truth['phi'], truth['theta'],
            truth['psi'])), -1)
        pos = np.stack(frames.position_ned_to_enu(truth['x'], truth['y'], truth['z']), -1)
        pos = pos + np.array([3.0, -2.0, 1.5])      # the room's origin, not the run's start
        att = np.stack(frames.orientation_ned_to_enu(truth['phi'], truth['psi'],
                                                     truth['theta']), -1)
        rates = np.stack(frames.body_frd_to_flu(truth['p'], truth['q'], truth['r']), -1)
        arrays[f'{name}.start'] = starts
        for who in ('truth', 'oracle'):
            for q, a in (('position', pos), ('velocity', vel), ('attitude', att),
                         ('body_rates', rates)):
                arrays[f'{name}.{who}.{q}'] = a[steps]
    np.savez(tmp_path / 'peers.npz', flights=np.array(list(truths)), **arrays)
    peers = table3.read_peers(tmp_path / 'peers.npz', root, windows, vehicle)
    assert set(peers) == {'oracle'}
    truth = table3.test_truth(root, windows)
    true = table3.quantities(windows.z_target, vehicle, truth, measured_heading=True)
    figures = table3.benchmark_figures(peers['oracle'], true)
    for q in ('position', 'velocity', 'attitude', 'body_rates'):
        assert max(figures[q]) < 1e-5, q          # the windows are float32
    np.testing.assert_allclose(peers['oracle']['z'], windows.z_target, atol=1e-5)
    # A peer that lacks a window's row is refused, naming the flight.
    late = arrays['flight1.start'] >= 60          # the forecast from row 49 is missing
    for key in [k for k in arrays if k.startswith('flight1.')]:
        arrays[key] = arrays[key][late]
    np.savez(tmp_path / 'gappy.npz', **arrays)
    with pytest.raises(KeyError, match='flight1 lacks forecasts'):
        table3.read_peers(tmp_path / 'gappy.npz', root, windows, vehicle)


def row(label, traj, value, kind='model'):
    return {'label': label, 'kind': kind, 'metrics': {'trajectory': {'mean': traj}},
            'paper_rmse': dict.fromkeys(table3.PAPER_STATES, value)}


def test_the_papers_findings_are_judged_on_the_rows():
    rows = [row('QLag', 0.09, 0.2), row('LSTM', 0.02, 0.08)]
    rows += [row(f'{n}-2P', 0.05, 0.13) for n in table3.PAPER_NAME.values()]
    rows[-1] = row('MinQ+Qua-2P', 0.025, 0.12)
    sweep = [{'relative_threshold': None, 'paper_rmse': dict.fromkeys(table3.PAPER_STATES,
                                                                     0.12)},
             {'relative_threshold': 0.04, 'paper_rmse': dict.fromkeys(table3.PAPER_STATES,
                                                                     0.2)},
             {'relative_threshold': 0.08, 'paper_rmse': dict.fromkeys(table3.PAPER_STATES,
                                                                     0.125)}]
    # The best by validation (Lin-2P here) needs 30 %; the paper's MinQ+Qua-2P 8 %.
    loose = [dict(r, relative_threshold=0.3) if r['relative_threshold'] == 0.08 else r
             for r in sweep]
    sweeps = {'Lin-2P': loose, 'MinQ+Qua-2P': sweep}
    claims = table3.check_claims(rows, 'Lin-2P', sweeps)
    assert claims['lstm_best']['holds']
    assert not claims['hybrids_close_behind_and_ahead_of_qlag']['holds']   # 0.05 > 1.5 x
    assert claims['minq_qua_best_hybrid']['holds']
    bound = claims['bounded_at_8_percent']
    assert bound['per_hybrid']['MinQ+Qua-2P']['smallest_threshold_within_tolerance'] == 0.08
    assert bound['per_hybrid']['Lin-2P']['smallest_threshold_within_tolerance'] == 0.3
    assert bound['holds']                                     # the finding names MinQ+Qua
    claims = table3.check_claims(rows, 'Lin-2P', {'Lin-2P': loose})
    assert not claims['bounded_at_8_percent']['holds']        # only the best was swept
    rows[1] = row('LSTM', 0.04, 0.08)
    claims = table3.check_claims(rows, 'MinQ+Qua-2P', {'MinQ+Qua-2P': sweep})
    assert not claims['lstm_best']['holds']
    assert claims['lstm_best']['lowest_trajectory'] == 'MinQ+Qua-2P'


RESULTS = Path(__file__).resolve().parents[2] / 'docs' / 'results' / 'nanodrone'


@pytest.mark.parametrize('protocol', ['paper', 'benchmark', 'sim', 'sim_benchmark'])
def test_the_documented_table3_is_the_committed_results(protocol):
    """README.md's tables are table3.paper_table of the committed results.json, digit for digit."""
    result = json.loads((RESULTS / protocol / 'results.json').read_text())
    table = table3.paper_table(result['rows']).strip()
    assert table in (RESULTS / 'README.md').read_text()
    assert table in (RESULTS / protocol / 'REPORT.md').read_text()
    # The findings the README states are the ones judged on these rows: on the real
    # flights the bound at 8 % does not hold, on the simulated ones it does.
    claims = result['claims']
    assert claims['hybrids_close_behind_and_ahead_of_qlag']['holds']
    assert not claims['lstm_best']['holds']
    assert claims['bounded_at_8_percent']['holds'] == protocol.startswith('sim')


def test_the_quadrotor_figures_of_the_top_readme_are_the_committed_results():
    readme = (RESULTS.parents[2] / 'README.md').read_text()
    section = readme[readme.index("**The paper's quadrotor**"):]
    table = {line.split('|')[1].strip(): line for line in section.split('\n\n')[1].splitlines()}
    rows = {p: {r['label']: r for r in json.loads(
        (RESULTS / p / 'results.json').read_text())['rows']} for p in ('paper', 'benchmark')}

    def traj(protocol, label):
        row = rows[protocol][label]
        sd = (row.get('spread') or {}).get('trajectory', {}).get('mean')
        mean = f'{row["metrics"]["trajectory"]["mean"]:.3f}'
        return mean + (f' ± {sd:.3f}' if sd is not None else '')

    best = table['best hybrid (MinQ+Qua-2P; MinQ+Lin-2P)']
    assert f"| {traj('paper', 'MinQ+Qua-2P')} m |" in best
    assert (f"| {traj('benchmark', 'MinQ+Qua-2P')} m; {traj('benchmark', 'MinQ+Lin-2P')} m |"
            in best)
    for label in ('LSTM', 'QLag'):
        assert f"| {traj('paper', label)} m | {traj('benchmark', label)} m |" in table[label]
    assert table["the benchmark's hybrid, physics, LSTM"].endswith('| ' + ', '.join(
        traj('benchmark', f'benchmark {p}') for p in ('hybrid', 'physics', 'lstm')) + ' m |')
