"""hybrid_models.quadrotor_measures: the nano-drone benchmark's error measures, by hand."""

import numpy as np
import pytest

from hybrid_models import quadrotor_measures as qm


def _about_z(angle):
    return np.array([0.0, 0.0, np.sin(angle / 2), np.cos(angle / 2)])


def _forecast(b=3, h=4, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(b, h, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return {'position': rng.normal(size=(b, h, 3)), 'velocity': rng.normal(size=(b, h, 3)),
            'attitude': q, 'body_rates': rng.normal(size=(b, h, 3))}


def test_zero_error_when_the_forecast_is_the_truth():
    truth = _forecast()
    errors = qm.errors_per_step(truth, {k: v.copy() for k, v in truth.items()})
    assert set(errors) == set(qm.QUANTITIES)
    for name, e in errors.items():
        assert e.shape == (3, 4)
        assert np.allclose(e, 0.0, atol=1e-7), name


def test_a_constant_offset_gives_its_norm_at_every_step():
    truth = _forecast()
    pred = {k: v.copy() for k, v in truth.items()}
    pred['position'] += np.array([0.3, 0.0, 0.4])        # 0.5 m
    pred['velocity'] -= np.array([1.0, 2.0, 2.0])        # 3 m/s
    pred['body_rates'] += np.array([0.0, 0.12, 0.0])     # 0.12 rad/s
    mae = qm.mae_per_step(qm.errors_per_step(truth, pred))
    assert np.allclose(mae['position'], 0.5)
    assert np.allclose(mae['velocity'], 3.0)
    assert np.allclose(mae['body_rates'], 0.12)
    assert np.allclose(mae['attitude'], 0.0, atol=1e-7)
    sums = qm.simulation_error(mae, steps=4)
    assert sums['position'] == pytest.approx(2.0)
    with pytest.raises(ValueError):
        qm.simulation_error(mae, steps=50)


def test_a_known_rotation_gives_its_angle():
    truth = np.array([_about_z(0.3), [0.0, 0.0, 0.0, 1.0]])
    pred = np.array([_about_z(0.3 + 0.25), qm.rotvec_to_quat([0.0, 0.4, 0.0])])
    assert np.allclose(qm.geodesic_angle(truth, pred), [0.25, 0.4])
    # As the benchmark computes it the sign of the quaternion counts: -q scores 2 pi - angle.
    assert qm.geodesic_angle(truth[0], -pred[0]) == pytest.approx(2 * np.pi - 0.25)
    assert qm.geodesic_angle(truth[0], -pred[0], shortest=True) == pytest.approx(0.25)


def test_the_attitude_maps_agree_with_each_other_and_a_closed_form():
    r = np.array([[0.0, 0.0, 0.0], [1e-5, -2e-5, 0.0], [0.4, -0.2, 1.1], [0.0, 2.5, 0.0]])
    q = qm.rotvec_to_quat(r)
    assert np.allclose(np.linalg.norm(q, axis=-1), 1.0)
    assert np.allclose(q[3], [0.0, np.sin(1.25), 0.0, np.cos(1.25)])
    assert np.allclose(qm.quat_to_rotvec(q), r, atol=1e-12)
    # The data set's log is not normalised: a quaternion of norm s gives s times the angle.
    assert np.allclose(qm.quat_to_rotvec(1.01 * q[2]), 1.01 * r[2])


def test_the_benchmark_alignment_pairs_step_h_with_the_window_h_minus_1_later():
    # One flight of states 0..9, windows of 3 steps: the forecast is the truth itself.
    n, steps = 7, 3
    states = np.arange(10, dtype=float)[:, None] * np.array([1.0, 0.0, 0.0])
    pred = np.stack([states[i + 1:i + 1 + steps] for i in range(n)])
    first = {'position': pred[:, 0]}
    mae = qm.benchmark_table_mae(first, {'position': pred})
    assert np.allclose(mae['position'], 0.0)
    # Two flights end to end: step h pairs h - 1 forecasts with the other flight's states.
    other = pred + np.array([100.0, 0.0, 0.0])
    both = np.concatenate([pred, other])
    mae = qm.benchmark_table_mae({'position': both[:, 0]}, {'position': both})
    assert mae['position'][0] == 0.0
    # Step 2 of the first flight's last window (state 8) meets the other's state 1 + 100.
    assert mae['position'][1] == pytest.approx((101.0 - 8.0) / (2 * n - 1))
    with pytest.raises(ValueError):
        qm.errors_per_step({'position': np.zeros((2, 3, 3))}, {'position': np.zeros((2, 4, 3))})
