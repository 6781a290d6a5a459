"""A damped regression physics keeps each state's own gain <= 1 over the vessel's envelope."""

import numpy as np
import pytest

from hybrid_models.physical import build_physical
from hybrid_models.physical.envelope import envelope_escapes
from hybrid_models.physical.regression import RegressionModel
from hybrid_models.physical.stability import MAX_GAIN, envelope_points, feature_slopes
from vessel_description import load_vessel

SNUBOAT = load_vessel('snuboat')   # u, v, r; limits u [-1, 3], r [-2, 2]


def straight_runs(rows: int = 4000, seed: int = 0):
    """
    Rows of a boat recorded slowly: r' = 0.95 r + 0.04 u r + 0.05 delta, u < 0.5 m/s.

    Inside the recordings the yaw rate's own gain is at most 0.97; extrapolated to the
    vessel's 3 m/s it is 1.07: the fit is right where it was recorded and diverges in a
    fast turn, as the snuboat's Hyd fit did on straight runs.
    """
    rng = np.random.default_rng(seed)
    z = np.column_stack([rng.uniform(0.0, 0.5, rows), rng.normal(0, 0.05, rows),
                         rng.normal(0, 0.2, rows)])
    c = np.column_stack([rng.uniform(50, 100, (rows, 2)), rng.uniform(-0.3, 0.3, (rows, 2))])
    u, v, r = z.T
    nxt = np.column_stack([0.98 * u + 1e-4 * c[:, 0] + 1e-4 * c[:, 1], 0.9 * v - 0.01 * r,
                           0.95 * r + 0.04 * u * r + 0.025 * (c[:, 2] + c[:, 3])])
    return z, c, nxt + rng.normal(0, 1e-4, nxt.shape)


def own_gains(model, z):
    points = envelope_points(z, SNUBOAT.limits, SNUBOAT.state_names)
    weight = model.arrays()['weight']
    return np.array([(feature_slopes(model.features.array_features, points,
                                     np.zeros((len(points), 4)), i) @ weight[i]).max()
                     for i in range(3)])


def fast_turn(model, steps: int = 300) -> float:
    """|r| after ``steps`` with the rudders amidships from a 2.5 m/s, 0.5 rad/s turn."""
    z = np.array([[2.5, 0.0, 0.5]])
    c = np.array([[150.0, 150.0, 0.0, 0.0]])
    for _ in range(steps):
        z = model.predict(z, c)
    return float(abs(z[0, 2]))


def test_the_damped_fit_keeps_the_own_gains_and_stops_a_fast_turn_diverging():
    z, c, nxt = straight_runs()
    free = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8).fit(z, c, nxt)
    damped = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8, damped=True).fit(z, c, nxt)
    assert own_gains(free, z)[2] > 1.05          # the recordings allow the extrapolation
    assert (own_gains(damped, z) <= MAX_GAIN + 1e-6).all()
    assert fast_turn(free) > SNUBOAT.limits['r'][1]   # grows out of the vessel's limits
    assert fast_turn(damped) <= 0.5              # never above where it started
    # Where it was recorded the damped fit is as good as the free one.
    rmse = [np.sqrt(((m.predict(z, c) - nxt) ** 2).mean(axis=0)) for m in (free, damped)]
    assert rmse[1][2] < 2 * rmse[0][2] + 1e-3 and rmse[1][0] < 2 * rmse[0][0] + 1e-4
    assert damped.describe()['damped'] is True


def test_a_fit_already_damped_is_left_as_the_free_fit():
    z, c, nxt = straight_runs()
    nxt[:, 2] = 0.95 * z[:, 2] - 0.01 * z[:, 0] * z[:, 2]     # gain < 1 everywhere
    free = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8).fit(z, c, nxt)
    damped = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8, damped=True).fit(z, c, nxt)
    assert (own_gains(free, z) < MAX_GAIN).all()
    np.testing.assert_array_equal(damped.arrays()['weight'], free.arrays()['weight'])


def test_the_envelope_check_passes_the_damped_fit_of_escaping_data():
    z, c, nxt = straight_runs()
    fast = SNUBOAT.limits['u'][1]
    z[:50, 0], nxt[:50, 0] = fast, 0.98 * fast    # a few rows at speed: roll-outs start there
    nxt[:50, 2] = 0.95 * z[:50, 2] + 0.04 * fast * z[:50, 2]
    free = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8).fit(z, c, nxt)
    damped = RegressionModel(SNUBOAT, 'hyd', ridge=1e-8, damped=True).fit(z, c, nxt)
    rows = np.concatenate([np.arange(50), np.arange(50, len(z), 60)])
    assert envelope_escapes(free, SNUBOAT, z[rows], c[rows], 600)['escaped'] > 0
    assert envelope_escapes(damped, SNUBOAT, z[rows], c[rows], 600)['escaped'] == 0


@pytest.mark.parametrize(('cfg', 'message'), [
    ({'kind': 'min+lin', 'damped': True}, 'forecasts the next state alone'),
    ({'kind': 'hyd', 'damped': 'yes'}, 'true or false'),
])
def test_damped_is_refused_where_it_means_nothing(cfg, message):
    with pytest.raises(ValueError, match=message):
        build_physical(cfg, load_vessel('patrol_boat'))
