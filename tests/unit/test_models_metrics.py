"""Metrics: per-state RMSE and the trajectory error, against hand-computed cases."""

import math

import numpy as np
import pytest

from hybrid_models.metrics import (
    dead_reckoning,
    forecast_metrics,
    positions,
    trajectory_errors,
)
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


def test_a_steady_turn_is_the_closed_form_polygon_on_the_turning_circle():
    # Constant u and r: step j moves u dt along heading j r dt, so the track is
    # sum_j u dt e^{i j theta} = u dt (e^{i(k+1)theta} - 1) / (e^{i theta} - 1), a regular
    # polygon inscribed in a circle of radius u dt / (2 sin(theta / 2)) -> u / r.
    u, r, n = 3.0, 0.02, 400
    theta = r * SHIP.dt
    xy, heading = dead_reckoning(states(n, u=u, r=r), SHIP)
    k = np.arange(n)
    closed = u * SHIP.dt * (np.exp(1j * (k + 1) * theta) - 1) / (np.exp(1j * theta) - 1)
    np.testing.assert_allclose(xy[:, 0] + 1j * xy[:, 1], closed, atol=1e-9)
    np.testing.assert_allclose(heading, (k + 1) * theta, atol=1e-12)
    centre = -u * SHIP.dt / (np.exp(1j * theta) - 1)
    radius = np.abs(xy[:, 0] + 1j * xy[:, 1] - centre)
    np.testing.assert_allclose(radius, u / r, rtol=1e-4)
    # The heading at the end of a step is the one the next step moves along.
    steps = np.diff(xy, axis=0)
    np.testing.assert_allclose(np.arctan2(steps[:, 1], steps[:, 0]),
                               np.angle(np.exp(1j * heading[:-1])), atol=1e-9)


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
