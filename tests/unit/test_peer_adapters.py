"""The peer adapters of offline/peers (narx, sindy, deepsysid_lstm), on problems made here."""

import importlib.util
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[2]
PEERS = REPO / 'offline' / 'peers'
BENCH_PYTHON = REPO / '.venv-bench' / 'bin' / 'python'


def _peer_io():
    if 'peer_io' in sys.modules:
        return sys.modules['peer_io']
    spec = importlib.util.spec_from_file_location('peer_io', PEERS / 'peer_io.py')
    module = importlib.util.module_from_spec(spec)
    sys.modules['peer_io'] = module
    spec.loader.exec_module(module)
    return module


def _has(module: str) -> bool:
    if not BENCH_PYTHON.exists():
        return False
    return subprocess.run([str(BENCH_PYTHON), '-c', f'import {module}'],
                          capture_output=True).returncode == 0


def needs(module: str):
    return pytest.mark.skipif(not _has(module), reason=f'needs .venv-bench with {module} '
                              '(tools/setup.sh bench)')


# z[t+1] = A z[t] + B c[t]: a stable linear system, identifiable exactly.
A = np.array([[0.95, 0.10], [-0.05, 0.90]])
B = np.array([[0.20], [0.05]])
W, H = 5, 30


def _linear_run(rng, rows):
    c = rng.normal(size=(rows, 1))
    z = np.zeros((rows, 2))
    z[0] = rng.normal(size=2)
    for t in range(rows - 1):
        z[t + 1] = A @ z[t] + B @ c[t]
    return z, c


def _windows(runs, stride=17):
    zw, cw, cf, zt = [], [], [], []
    for z, c in runs:
        for t0 in range(W, len(z) - H + 1, stride):
            zw.append(z[t0 - W:t0])
            cw.append(c[t0 - W:t0])
            cf.append(c[t0 - 1:t0 - 1 + H])
            zt.append(z[t0:t0 + H])
    return {'z_window': np.array(zw), 'c_window': np.array(cw), 'c_future': np.array(cf),
            'z_target': np.array(zt)}


def _problem(path, seeds=(0,), constant_control=False):
    rng = np.random.default_rng(3)
    train = [_linear_run(rng, 300) for _ in range(3)]
    val = [_linear_run(rng, 120)]
    test = [_linear_run(rng, 150) for _ in range(2)]
    names = ['delta']
    if constant_control:   # a second control that never changes (a tank test's rpm)
        names.append('n')
        train, val, test = ([(z, np.concatenate([c, np.full_like(c, 7.0)], axis=1))
                             for z, c in runs] for runs in (train, val, test))
    test = _windows(test)
    _peer_io().write_problem(path, state_names=['u', 'r'], control_names=names, dt=0.1,
                             window=W, horizon=H, seeds=list(seeds), train=train, val=val,
                             val_windows=_windows(val),
                             test_windows={k: test[k] for k in ('z_window', 'c_window',
                                                                 'c_future')})
    return test['z_target']


def _run(script, *args, timeout=240):
    return subprocess.run([str(BENCH_PYTHON), str(PEERS / script), *map(str, args)],
                          capture_output=True, text=True, timeout=timeout)


def test_problem_round_trip_and_history(tmp_path):
    truth = _problem(tmp_path / 'p.npz', seeds=(0, 1))
    p = _peer_io().read_problem(tmp_path / 'p.npz')
    assert (p.n_state, p.window, p.horizon, p.seeds) == (2, W, H, [0, 1])
    assert len(p.train) == 3 and p.test_windows['z_window'].shape == (len(truth), W, 2)
    z, c = _peer_io().history(p.test_windows)
    # The control row that ends the window is the first of the horizon's.
    assert c.shape == (len(truth), W + H - 1, 1)
    np.testing.assert_array_equal(c[:, W - 1], p.test_windows['c_future'][:, 0])
    with pytest.raises(_peer_io().PeerError, match='not a peer problem'):
        np.savez(tmp_path / 'bad.npz', x=np.zeros(2))
        _peer_io().read_problem(tmp_path / 'bad.npz')


def test_tuning_keeps_the_point_of_lowest_validation_score(tmp_path):
    peer_io = _peer_io()
    _problem(tmp_path / 'p.npz')
    problem = peer_io.read_problem(tmp_path / 'p.npz')
    offsets = {'exact': 0.0, 'off': 0.5, 'diverged': np.nan}
    lines = []
    tuned = peer_io.tune([{'name': n} for n in offsets],
                         lambda point: (point['name'], {'terms': len(point['name'])}),
                         lambda name, windows: windows['z_target'] + offsets[name],
                         problem, lines.append)
    assert tuned.point == {'name': 'exact'} and tuned.model == 'exact'
    assert [row['val_score'] for row in tuned.grid] == [0.0, pytest.approx(
        (0.5 / peer_io.state_scale(problem.train)).sum()), float('inf')]
    assert [row['terms'] for row in tuned.grid] == [5, 3, 8]
    assert tuned.seconds >= tuned.fit_seconds >= 0 and len(lines) == 3
    assert lines[1].startswith('name off, terms 3: validation score')


@pytest.mark.parametrize('script', ['narx.py', 'sindy.py', 'deepsysid_lstm.py'])
def test_help_and_a_one_line_error(tmp_path, script):
    if not BENCH_PYTHON.exists():
        pytest.skip('needs .venv-bench (tools/setup.sh bench)')
    result = _run(script, '--help')
    assert result.returncode == 0 and '--problem' in result.stdout
    result = _run(script, '--problem', tmp_path / 'absent.npz', '--out', tmp_path / 'a.npz')
    assert result.returncode == 1
    assert result.stderr.strip().count('\n') == 0, result.stderr
    assert result.stderr.startswith(f"{script[:-3].replace('_', '-')}: error: cannot read")


@needs('sysidentpy')
def test_narx_identifies_a_linear_system_exactly(tmp_path):
    truth = _problem(tmp_path / 'p.npz')
    result = _run('narx.py', '--problem', tmp_path / 'p.npz', '--out', tmp_path / 'a.npz')
    assert result.returncode == 0, result.stderr
    answer = _peer_io().read_answer(tmp_path / 'a.npz')
    assert answer['pred'].shape == (1,) + truth.shape
    # Open loop over 30 steps from the window: only exact identification stays this close.
    np.testing.assert_allclose(answer['pred'][0], truth, atol=1e-6)
    meta = answer['meta']
    assert meta['chosen']['degree'] == 1 and meta['one_step_check'] < 1e-9
    assert len(meta['grid']) == 5 and not meta['stochastic']


@needs('pysindy')
def test_sindy_identifies_a_linear_system_exactly(tmp_path):
    truth = _problem(tmp_path / 'p.npz')
    result = _run('sindy.py', '--problem', tmp_path / 'p.npz', '--out', tmp_path / 'a.npz')
    assert result.returncode == 0, result.stderr
    answer = _peer_io().read_answer(tmp_path / 'a.npz')
    assert answer['pred'].shape == (1,) + truth.shape
    np.testing.assert_allclose(answer['pred'][0], truth, atol=1e-6)
    # A and B (four and two entries) and, scaled to zero mean, one constant per state.
    assert answer['meta']['terms'] == 8


@pytest.mark.slow
@needs('deepsysid')
def test_deepsysid_lstm_forecasts_every_window_per_seed(tmp_path):
    truth = _problem(tmp_path / 'p.npz', seeds=(0, 1), constant_control=True)
    result = _run('deepsysid_lstm.py', '--problem', tmp_path / 'p.npz', '--out',
                  tmp_path / 'a.npz', '--quick', '--epochs-scale', '0.01')
    assert result.returncode == 0, result.stderr
    answer = _peer_io().read_answer(tmp_path / 'a.npz')
    assert answer['pred'].shape == (2,) + truth.shape
    assert np.isfinite(answer['pred']).all()
    assert list(answer['seeds']) == [0, 1] and len(answer['fit_seconds']) == 2
    # Two seeds train two different networks.
    assert np.abs(answer['pred'][0] - answer['pred'][1]).max() > 1e-6
    assert answer['meta']['static']['loss'] == 'mse'
    assert answer['meta']['static']['epochs_predictor'] == 8
    # deepsysid divides by each control's spread: a constant one is left out, and said.
    assert answer['meta']['controls_left_out'] == ['n']
