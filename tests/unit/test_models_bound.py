"""The residual bound: its definition, and that it is never exceeded."""

import math

import numpy as np
import pytest
import torch

from hybrid_models.bound import apply_bound, half_width, output_range
from hybrid_models.evaluation import smallest_threshold, trajectory_of
from hybrid_models.nets import HybridModel
from hybrid_models.physical import build_physical
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


def test_output_range_is_the_central_95_percent_spread():
    x = np.linspace(0.0, 1.0, 100_001)[:, None] * [1.0, 10.0]
    np.testing.assert_allclose(output_range(x), [0.95, 9.5], rtol=1e-6)


def test_half_width_follows_the_papers_size_ratio():
    # Paper: physical range [-5, 5] and LSTM range [-1, 1] is a threshold of 20 %.
    assert half_width(0.2, np.array([10.0]))[0] == pytest.approx(1.0)
    assert math.isinf(half_width(None, np.array([10.0]))[0])
    assert half_width(0.0, np.array([10.0]))[0] == 0.0     # T = 0: physics alone
    for bad in (-0.1, math.nan):
        with pytest.raises(ValueError):
            half_width(bad, np.array([1.0]))


@pytest.mark.parametrize('mode', ['tanh', 'clamp'])
def test_bound_is_never_exceeded(mode):
    torch.manual_seed(0)
    bound = torch.tensor([1e-4, 0.01, 1.0, 50.0, math.inf])
    x = torch.randn(20000, 5) * torch.logspace(-6, 6, 20000)[:, None]
    x = torch.cat([x, torch.tensor([[1e30, -1e30, 3e38, -3e38, 7.0]])])
    y = apply_bound(x, bound, mode)
    assert (y[:, :4].abs() <= bound[:4]).all()
    assert torch.equal(y[:, 4], x[:, 4])          # infinite bound: untouched
    assert torch.equal(apply_bound(x, torch.zeros(5), mode), torch.zeros_like(x))
    small = x[:, :4].abs() < 1e-3 * bound[:4]
    assert torch.allclose(y[:, :4][small], x[:, :4][small], rtol=1e-5)


def make_hybrid(**kw):
    model = HybridModel(SHIP, build_physical({'kind': 'lin'}, SHIP), hidden=8, layers=2,
                        dropout=0.0, **kw)
    model.physical.bias.copy_(torch.tensor([6.0, 0, 0, 0, 0]))
    model.output_range.copy_(torch.tensor([4.0, 0.6, 0.04, 0.03, 0.08]))
    # Blow the head up so the raw residual would be far beyond any bound.
    with torch.no_grad():
        model.head.weight.mul_(1e3)
        model.head.bias.fill_(50.0)
    return model


@pytest.mark.parametrize('mode', ['tanh', 'clamp'])
def test_hybrid_residual_stays_within_bound_in_forecasts(mode):
    model = make_hybrid(bound_mode=mode).eval()
    model.set_threshold(0.15)
    expected = 0.15 * model.output_range / 2
    assert torch.allclose(model.bound, expected)
    zw, cw, cf = torch.randn(16, 10, 5), torch.randn(16, 10, 6), torch.randn(16, 40, 6)
    with torch.no_grad():
        _, _, res = model.forecast(zw, cw, cf, return_parts=True)
        tf = model.teacher_forced(zw, cw, cf, torch.randn(16, 40, 5))
    for r in (res, tf):
        assert (r.abs() <= model.bound).all()
        assert (r.abs() > 0.5 * model.bound).any()    # the bound is actually active


def test_bound_applies_in_training_only_when_asked():
    zw, cw, cf = torch.randn(4, 5, 5), torch.randn(4, 5, 6), torch.randn(4, 8, 6)
    for in_training, limited in ((False, False), (True, True)):
        model = make_hybrid(bound_in_training=in_training).train()
        model.set_threshold(0.1)
        _, _, res = model.forecast(zw, cw, cf, return_parts=True)
        assert bool((res.abs() <= model.bound).all()) == limited


def test_threshold_needs_the_output_range():
    model = HybridModel(SHIP, build_physical({'kind': 'lin'}, SHIP), hidden=4)
    with pytest.raises(ValueError, match='output range is not set'):
        model.set_threshold(0.15)


def sweep_row(threshold, u, v, diverged=False, trajectory=100.0):
    return {'relative_threshold': threshold, 'diverged': diverged, 'rmse': {'u': u, 'v': v},
            'trajectory': {'mean': trajectory}}


def test_smallest_threshold_needs_every_state_within_the_tolerance():
    sweep = [sweep_row(None, 0.10, 0.05), sweep_row(0.0, 0.30, 0.05),
             sweep_row(0.02, 0.104, 0.06), sweep_row(0.05, 0.104, 0.0524),
             sweep_row(0.1, 0.101, 0.050)]
    reference = {'u': 0.10, 'v': 0.05}
    assert smallest_threshold(sweep, reference, 0.05) == 0.05      # 0.02 fails on v
    assert smallest_threshold(sweep, reference, 0.0) is None       # only the free row is exact
    assert smallest_threshold(sweep, {'u': 0.30, 'v': 0.05}, 0.0) == 0.0   # physics alone
    diverged = [sweep_row(0.05, 0.1, 0.05, diverged=True), sweep_row(0.2, 0.1, 0.05)]
    assert smallest_threshold(diverged, reference, 0.05) == 0.2
    with pytest.raises(ValueError, match='tolerance'):
        smallest_threshold(sweep, reference, -0.1)


def test_smallest_threshold_on_the_trajectory_error():
    sweep = [sweep_row(0.0, 0.3, 0.1, trajectory=480.0), sweep_row(0.05, 0.2, 0.1, trajectory=90),
             sweep_row(0.3, 0.1, 0.05, trajectory=41.0), sweep_row(None, 0.1, 0.05, trajectory=40)]
    assert smallest_threshold(sweep, {'trajectory': 40.0}, 0.05, trajectory_of) == 0.3
    assert smallest_threshold(sweep, {'trajectory': 500.0}, 0.05, trajectory_of) == 0.0
    assert smallest_threshold(sweep, {'u': 0.1}, 0.05) == 0.3           # one state alone


def test_a_schedule_bounds_each_step_by_the_entry_it_ends_in():
    from hybrid_models.bound import step_bounds
    b = step_bounds([[0, 0.0], [0.5, 0.1], [1.0, None]], np.array([2.0, 4.0]), 0.1, 12)
    np.testing.assert_array_equal(b[:5], 0.0)            # steps ending at 0.1 .. 0.5 s
    np.testing.assert_allclose(b[5:10], [[0.1, 0.2]] * 5)
    assert np.isinf(b[10:]).all()
    np.testing.assert_allclose(step_bounds(0.1, np.array([2.0]), 1.0, 3), [[0.1]] * 3)
    with pytest.raises(ValueError, match='increasing starts'):
        step_bounds([[0.5, 0.1]], np.array([1.0]), 0.1, 3)


def test_a_schedule_served_by_torch_and_the_compiled_engine_alike(tmp_path):
    from hybrid_models.engine import Forecaster
    from hybrid_models.models import build_model
    from hybrid_models.normalization import Normalizer
    from vessel_description import load_vessel
    ship = load_vessel('patrol_boat')
    torch.manual_seed(0)
    model = build_model({'kind': 'hybrid', 'hidden': 6, 'layers': 1, 'dropout': 0.0,
                         'physical': {'kind': 'lin'}}, ship).double()
    with torch.no_grad():
        model.physical.weight[:, 6:] = 0.9 * torch.eye(5, dtype=torch.float64)
        model.head.bias.fill_(1.0)
    model.set_normalization(Normalizer(np.zeros(5), np.ones(5)),
                            Normalizer(np.zeros(6), np.ones(6)))
    model.output_range.copy_(torch.ones(5, dtype=torch.float64))
    schedule = [[0.0, 0.0], [3.0, 0.2]]
    model.set_threshold(schedule)
    zw, cw, cf = (torch.randn(1, 4, 5, dtype=torch.float64),
                  torch.randn(1, 4, 6, dtype=torch.float64), torch.randn(1, 6, 6,
                                                                        dtype=torch.float64))
    with torch.no_grad():
        hybrid, physics, _ = model.eval().forecast(zw, cw, cf, return_parts=True)
    correction = (hybrid - physics)[0].abs()
    assert (correction[:3] == 0).all() and (correction[3:] > 0).all()
    assert (correction[3:] <= 0.1 + 1e-12).all()
    engine = Forecaster.from_model(model, dtype=np.float64)
    assert engine.relative_threshold == schedule
    served = engine.forecast(zw[0].numpy(), cw[0].numpy(), cf.numpy())
    np.testing.assert_allclose(served.hybrid[0], hybrid[0].numpy(), rtol=1e-9, atol=1e-12)


def test_a_served_threshold_as_one_number_is_the_loosest_that_holds_at_every_step():
    import math

    from hybrid_models.bound import loosest

    assert loosest(0.15) == 0.15 and loosest(0) == 0.0
    assert math.isnan(loosest(None))
    assert loosest([[0, 0.0], [2.0, 0.3], [5.0, 0.1]]) == 0.3
    assert math.isnan(loosest([[0, 0.05], [3.0, None]]))
