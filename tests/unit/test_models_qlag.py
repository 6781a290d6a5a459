"""QLag: the lagged quadratic-control regression, fitted and run multistep."""

import numpy as np
import torch

from hybrid_models.data import RunArrays, forecast_windows
from hybrid_models.qlag import QLag
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


def lagged_system(n=400, seed=0):
    """z_{t+1,k} = 0.6 z_{t,k} + 0.2 z_{t-1,k} + 0.01 c_{t,k}^2 + 0.1 c_{t-1,k+1}."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(n, 6))
    z = np.zeros((n, 5))
    z[:2] = rng.normal(size=(2, 5))
    for t in range(1, n - 1):
        z[t + 1] = 0.6 * z[t] + 0.2 * z[t - 1] + 0.01 * c[t, :5] ** 2 + 0.1 * c[t - 1, 1:]
    return RunArrays('a', z.astype(np.float32), c.astype(np.float32), z.astype(np.float32))


def test_qlag_recovers_a_lagged_quadratic_system_and_forecasts_it():
    run = lagged_system()
    model = QLag(SHIP, lag=2, ridge=0.0).double().fit([run])
    names = model.feature_names
    w = model.weight.numpy()
    np.testing.assert_allclose(w[0, names.index('u[t]')], -0.4, atol=1e-4)   # increment
    np.testing.assert_allclose(w[0, names.index('u[t-1]')], 0.2, atol=1e-4)
    np.testing.assert_allclose(w[0, names.index('n^2[t]')], 0.01, atol=1e-4)
    np.testing.assert_allclose(w[0, names.index('delta_port[t-1]')], 0.1, atol=1e-4)
    np.testing.assert_allclose(w[3, names.index('wind_speed^2[t]')], 0.01, atol=1e-4)
    np.testing.assert_allclose(w[3, names.index('u[t]')], 0.0, atol=1e-4)
    win = forecast_windows([run], window=10, horizon=50, stride=100)
    with torch.no_grad():
        pred = model.forecast(*(torch.as_tensor(a, dtype=torch.float64)
                                for a in (win.z_window, win.c_window, win.c_future)))
    np.testing.assert_allclose(pred.numpy(), win.z_target, atol=2e-3)
