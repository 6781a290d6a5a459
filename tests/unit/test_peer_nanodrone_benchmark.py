"""offline/peers/nanodrone_benchmark.py, run in .venv-bench on flights the test makes."""

import json
from pathlib import Path
import subprocess

import numpy as np
import pandas as pd
import pytest

REPO = Path(__file__).resolve().parents[2]
ADAPTER = REPO / 'offline' / 'peers' / 'nanodrone_benchmark.py'
BENCH_PYTHON = REPO / '.venv-bench' / 'bin' / 'python'
SNAPSHOT = REPO.parent / '.mirror' / 'idsia-robotics+nanodrone-sysid-benchmark' / 'repo'
SHARED = REPO.parent / 'shared' / 'real' / 'nanodrone'
QUANTITIES = ('position', 'velocity', 'attitude', 'body_rates')
MODELS = ('physics', 'mlp', 'hybrid', 'lstm')
# The benchmark's physics parameters (test/test_physics.py, PhysQuadModel's defaults).
M, G, KT, DT = 0.045, 9.81, 3.72e-08, 0.01

needs_bench = pytest.mark.skipif(
    not BENCH_PYTHON.exists() or not SNAPSHOT.exists(),
    reason='needs .venv-bench (tools/setup.sh bench) and the benchmark snapshot '
           f'({SNAPSHOT})')


def _run(*args):
    return subprocess.run([str(BENCH_PYTHON), str(ADAPTER), *map(str, args)],
                          capture_output=True, text=True, timeout=180)


def _hover_flight(path, rows=80, roll=0.2, rates=(0.0, 0.0, 0.0)):
    """Write a flight of constant motor speeds, tilted `roll` rad about x, at 1 m/s."""
    t = np.arange(rows) * DT
    frame = pd.DataFrame({
        't': t, 'x': 0.1 + 1.0 * t, 'y': -0.2 + 0.0 * t, 'z': 1.0 + 0.0 * t,
        'vx': 1.0 + 0.0 * t, 'vy': 0.0 * t, 'vz': 0.0 * t,
        'qx': np.sin(roll / 2) + 0 * t, 'qy': 0.0 * t, 'qz': 0.0 * t,
        'qw': np.cos(roll / 2) + 0 * t,
        'wx': rates[0] + 0 * t, 'wy': rates[1] + 0 * t, 'wz': rates[2] + 0 * t})
    for i in range(1, 5):
        frame[f'm{i}_erpm'] = 100000.0
    frame.to_parquet(path)
    return frame


@needs_bench
def test_help_and_a_one_line_error(tmp_path):
    result = _run('--help')
    assert result.returncode == 0 and '--horizon' in result.stdout
    result = _run('--flights', tmp_path / 'absent.parquet', '--out', tmp_path / 'x.npz')
    assert result.returncode == 2
    assert result.stderr.strip().count('\n') == 0
    assert result.stderr.startswith('nanodrone_benchmark: error:')


@needs_bench
def test_physics_one_step_matches_a_hand_computation(tmp_path):
    frame = _hover_flight(tmp_path / 'hover.parquet')
    out = tmp_path / 'hover.npz'
    result = _run('--flights', tmp_path / 'hover.parquet', '--out', out, '--horizon', 10,
                  '--stride', 7, '--models', 'physics,naive')
    assert result.returncode == 0, result.stderr
    data = np.load(out)
    start = data['hover.start']
    assert list(start) == list(range(0, 70, 7))
    for model in ('truth', 'physics', 'naive'):
        for q in QUANTITIES:
            assert data[f'hover.{model}.{q}'].shape == (10, 10, 4 if q == 'attitude' else 3)
    # By hand: four rotors at 100000 eRPM = 100000 * 2 pi / 360 rad/s, thrust Kt sum w^2
    # along the body z axis, tilted 0.2 rad about x; no rotation, so RK4 is exact.
    omega = 100000.0 * 2 * np.pi / 360
    thrust = 4 * KT * omega ** 2
    acc = np.array([0.0, -np.sin(0.2), np.cos(0.2)]) * thrust / M - np.array([0, 0, G])
    k = start[3]
    p0 = frame[['x', 'y', 'z']].to_numpy()[k]
    v0 = frame[['vx', 'vy', 'vz']].to_numpy()[k]
    assert np.allclose(data['hover.physics.position'][3, 0], p0 + v0 * DT + 0.5 * acc * DT ** 2,
                       atol=2e-6)
    assert np.allclose(data['hover.physics.velocity'][3, 0], v0 + acc * DT, atol=2e-6)
    q = data['hover.physics.attitude'][3, 0]
    assert np.allclose(q, [np.sin(0.1), 0.0, 0.0, np.cos(0.1)], atol=1e-6)
    # Ten steps: constant acceleration, position quadratic in time.
    t = DT * np.arange(1, 11)[:, None]
    assert np.allclose(data['hover.physics.position'][3], p0 + v0 * t + 0.5 * acc * t ** 2,
                       atol=2e-5)
    # The truth is the flight's next rows; the naive model holds the first state.
    assert np.allclose(data['hover.truth.position'][3, 0],
                       frame[['x', 'y', 'z']].to_numpy()[k + 1], atol=1e-6)
    assert np.allclose(data['hover.naive.position'][3], p0, atol=1e-6)
    meta = json.loads(out.with_suffix('.json').read_text())
    assert meta['horizon'] == 10 and meta['stride'] == 7 and meta['models'] == ['physics', 'naive']
    assert len(meta['benchmark']['commit']) == 40


@needs_bench
def test_physics_holds_the_body_rates_as_the_benchmark_model_does(tmp_path):
    _hover_flight(tmp_path / 'spin.parquet', rows=40, rates=(0.5, -0.3, 1.0))
    out = tmp_path / 'spin.npz'
    result = _run('--flights', tmp_path / 'spin.parquet', '--out', out, '--horizon', 20,
                  '--models', 'physics')
    assert result.returncode == 0, result.stderr
    rates = np.load(out)['spin.physics.body_rates']
    assert np.allclose(rates, [0.5, -0.3, 1.0], atol=1e-6)


@needs_bench
@pytest.mark.skipif(not (SHARED / 'test' / 'melon_20251017_run5.parquet').exists(),
                    reason='needs the shared nano-drone flights (../shared/real/nanodrone)')
def test_all_models_on_a_slice_of_a_shared_flight(tmp_path):
    flight = pd.read_parquet(SHARED / 'test' / 'melon_20251017_run5.parquet').iloc[3000:3160]
    flight.to_parquet(tmp_path / 'melon.parquet')
    out = tmp_path / 'melon.npz'
    result = _run('--flights', tmp_path / 'melon.parquet', '--out', out, '--stride', 11)
    assert result.returncode == 0, result.stderr
    data = np.load(out)
    assert list(data['flights']) == ['melon']
    b = len(range(0, 160 - 50, 11))
    assert list(data['melon.start']) == list(range(0, 110, 11))
    for model in ('truth',) + MODELS:
        for q in QUANTITIES:
            value = data[f'melon.{model}.{q}']
            assert value.shape == (b, 50, 4 if q == 'attitude' else 3)
            assert np.all(np.isfinite(value)), (model, q)
        assert np.allclose(np.linalg.norm(data[f'melon.{model}.attitude'], axis=-1), 1.0)
    # Each model's first step stays near the truth (a few cm, a few cm/s).
    for model in MODELS:
        err = np.linalg.norm(data[f'melon.{model}.position'][:, 0]
                             - data['melon.truth.position'][:, 0], axis=-1)
        assert err.max() < 0.05, model
    meta = json.loads(out.with_suffix('.json').read_text())
    assert 'out/export/residual/residual.onnx' in meta['model_files_sha256']
    assert meta['flights'][0]['motors'].startswith('m*_erpm')
