"""Closed-form regression components and their combination with first principles."""

import numpy as np
import pytest
import torch

from hybrid_models.physical import CompositeModel, PhysicalModel, build_physical
from hybrid_models.physical.regression import ridge_lstsq
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


class Halving(PhysicalModel):
    """A stand-in first-principles model: z_next = z / 2."""

    kind = 'halving'

    def step(self, z, c, arrays, repeat=None):
        return 0.5 * z


def random_pairs(n=500, seed=0):
    rng = np.random.default_rng(seed)
    z = rng.normal(size=(n, 5)) * [3, 0.3, 0.02, 0.02, 0.05] + [6, 0, 0, 0, 0]
    c = rng.normal(size=(n, 6)) * [10, 0.03, 0.03, 1, 0.5, 0.5] + [80, 0, 0, 2, 0, 0]
    return z, c


def test_ridge_lstsq_recovers_exact_coefficients():
    rng = np.random.default_rng(1)
    x = rng.normal(size=(200, 3)) * [1, 100, 0.01]
    w_true = np.array([0.5, -0.02, 30.0])
    w, b = ridge_lstsq(x, x @ w_true + 4.0, ridge=0.0)
    np.testing.assert_allclose(w, w_true, rtol=1e-9)
    assert b == pytest.approx(4.0)


def test_lin_fits_a_linear_system_exactly():
    z, c = random_pairs()
    rng = np.random.default_rng(2)
    P, Q, b = rng.normal(size=(5, 5)) * 0.1, rng.normal(size=(5, 6)) * 0.01, rng.normal(size=5)
    z_next = z @ P.T + c @ Q.T + b
    model = build_physical({'kind': 'lin', 'ridge': 0.0}, SHIP).fit(z, c, z_next)
    np.testing.assert_allclose(model.predict(z, c), z_next, atol=1e-9)
    coef = model.coefficients()
    assert coef['u']['v'] == pytest.approx(P[0, 1], abs=1e-9)
    assert coef['phi']['n'] == pytest.approx(Q[4, 0], abs=1e-9)


def test_hyd_masked_coefficients_stay_zero():
    z, c = random_pairs()
    target = z + 0.01 * np.abs(z[:, [0]]) * z[:, [1]]   # |u|v acts on every state
    model = build_physical({'kind': 'hyd', 'masks': 'diagonal'}, SHIP)
    model.fit(z, c, target)
    j = model.features.names.index('|u|v')
    u_row, phi_row = 0, 4
    # |u|v is a sway/roll/yaw term: not in the surge or (diagonal) roll-angle rows.
    weight = model.arrays()['weight']
    assert weight[u_row, j] == 0 and weight[phi_row, j] == 0
    assert weight[1, j] == pytest.approx(0.01, rel=1e-6)


def test_composite_fits_the_first_principles_one_step_residual():
    z, c = random_pairs()
    z_next = 0.5 * z + 0.01 * c[:, :5] + 0.2
    reg = build_physical({'kind': 'lin', 'ridge': 0.0}, SHIP)
    model = CompositeModel(Halving(SHIP), reg).fit(z, c, z_next)
    assert model.kind == 'halving+lin'
    # The regression learned only the residual: no weight on the states.
    w = model.arrays()['regression.weight']
    np.testing.assert_allclose(w[:, 6:], 0.0, atol=1e-9)
    np.testing.assert_allclose(model.predict(z, c), z_next, atol=1e-9)


def test_bad_kinds_are_refused():
    for kind in ('lin+min', 'foo', 'min+lin+hyd', ''):
        with pytest.raises(ValueError, match='unknown physical model'):
            build_physical({'kind': kind}, SHIP)


def test_regression_is_differentiable_in_torch():
    model = build_physical({'kind': 'qua'}, SHIP)
    z = torch.ones(3, 5, requires_grad=True)
    model(z, torch.ones(3, 6)).sum().backward()
    assert z.grad is not None


def test_learned_values_round_trip_and_are_checked():
    z, c = random_pairs()
    model = build_physical({'kind': 'pro+hyd'}, SHIP).fit(z, c, 0.9 * z)
    arrays = model.arrays()
    assert set(arrays) == {'regression.weight', 'regression.bias', 'regression.fitted'}
    fresh = build_physical(model.describe(), SHIP).load_arrays(arrays)
    np.testing.assert_array_equal(fresh.predict(z, c), model.predict(z, c))
    with pytest.raises(ValueError, match='shape'):
        fresh.load_arrays({**arrays, 'regression.bias': np.zeros(3)})
    with pytest.raises(ValueError, match='learned values'):
        fresh.load_arrays({'regression.weight': arrays['regression.weight']})
