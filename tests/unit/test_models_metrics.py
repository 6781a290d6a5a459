"""Metrics: per-state RMSE and the trajectory error, against hand-computed cases."""

import math

import numpy as np
import pytest

from hybrid_models.metrics import forecast_metrics, positions, trajectory_errors
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


def states(n, u=0.0, v=0.0, r=0.0, phi=0.0):
    z = np.zeros((n, 5))
    z[:, 0], z[:, 1], z[:, 3], z[:, 4] = u, v, r, phi
    return z


def test_straight_surge_gives_a_straight_line():
    pos = positions(states(10, u=2.0), SHIP)
    np.testing.assert_allclose(pos[:, 0], 2.0 * np.arange(1, 11))
    np.testing.assert_allclose(pos[:, 1], 0.0)


def test_sway_is_projected_with_the_roll_angle():
    pos = positions(states(4, v=1.0, phi=0.3), SHIP)
    np.testing.assert_allclose(pos[:, 1], math.cos(0.3) * np.arange(1, 5))


def test_turning_follows_the_heading_integral():
    # psi_k = sum_{j<k} r: heading 0, 0.1, 0.2 for the first three samples.
    pos = positions(states(3, u=1.0, r=0.1), SHIP)
    x = np.cumsum(np.cos([0.0, 0.1, 0.2]))
    y = np.cumsum(np.sin([0.0, 0.1, 0.2]))
    np.testing.assert_allclose(pos, np.stack([x, y], 1))


def test_trajectory_error_and_rmse_of_a_constant_surge_bias():
    true = np.stack([states(60, u=5.0)] * 3)
    pred = true.copy()
    pred[..., 0] += 0.1
    err = trajectory_errors(pred, true, SHIP)
    np.testing.assert_allclose(err[0], 0.1 * np.arange(1, 61))
    m = forecast_metrics(pred, true, SHIP)
    assert m['rmse']['u'] == pytest.approx(0.1)
    assert m['rmse']['v'] == 0.0
    assert m['trajectory']['mean'] == pytest.approx(0.1 * 30.5)
    assert m['trajectory']['n'] == 3 and m['trajectory']['ci95'] == pytest.approx(0.0)
    assert not m['diverged']


def test_confidence_interval_uses_per_forecast_means():
    true = np.stack([states(10, u=1.0)] * 4)
    pred = true.copy()
    for i, bias in enumerate([0.0, 0.1, 0.2, 0.3]):
        pred[i, :, 0] += bias
    m = forecast_metrics(pred, true, SHIP)
    per_forecast = np.array([0.0, 0.1, 0.2, 0.3]) * 5.5
    assert m['trajectory']['std'] == pytest.approx(per_forecast.std(ddof=1))
    assert m['trajectory']['ci95'] == pytest.approx(1.96 * per_forecast.std(ddof=1) / 2,
                                                    rel=1e-3)


def test_a_diverged_forecast_is_reported_not_hidden():
    true = np.stack([states(10, u=1.0)] * 2)
    pred = true.copy()
    pred[1, 5:] = np.inf
    m = forecast_metrics(pred, true, SHIP)
    assert m['diverged'] and m['rmse']['u'] is None
