"""
The 95 % intervals contain their estimates and cover the truth (synthetic, known answer).

A nonlinear model y = a (1 - exp(-b x)) with correlated noise in blocks of two runs,
fitted by Gauss-Newton as the diagnosis refits its terms; the design handed to
``Identifier.intervals`` is the model linearized at the estimate, as in ``Identifier.run``.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from vessel_diagnosis.design import Column, Design
from vessel_diagnosis.identify import Identifier, Point, rms_speed_interval
from vessel_diagnosis.settings import load_settings

TRUTH = np.array([2.0, 0.5])
START = np.array([1.5, 0.8])
N, BLOCK, RUNS = 1200, 50, 2       # samples, samples per bootstrap block, runs
SETTINGS = load_settings()
COLUMNS = (Column('a', 'a'), Column('b', 'b'))


def _data(seed):
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 6.0, N)
    noise = np.zeros(N)
    for k in range(1, N):            # AR(1): neighbouring residuals are correlated
        noise[k] = 0.8 * noise[k - 1] + 0.1 * rng.standard_normal()
    return x, TRUTH[0] * (1.0 - np.exp(-TRUTH[1] * x)) + noise


def _linearized(x, y, theta):
    """Return the design (residual, Jacobian) at ``theta`` and the bootstrap strata."""
    a, b = theta
    residual = y - a * (1.0 - np.exp(-b * x))
    jacobian = np.stack([1.0 - np.exp(-b * x), a * x * np.exp(-b * x)], axis=1)
    shape = (N, 1, 1)                # one row, one state per "segment"
    design = Design(residual.reshape(shape), jacobian.reshape(shape + (2,)), COLUMNS,
                    np.ones(1), np.arange(N) // BLOCK, np.ones(2))
    segments = SimpleNamespace(run_index=np.arange(N) * RUNS // N)
    return design, segments


def _gauss_newton(x, y, iterations):
    theta = START.copy()
    for _ in range(iterations):
        design, _ = _linearized(x, y, theta)
        X, r, _ = design.stacked()
        theta = theta + np.linalg.lstsq(X, r, rcond=None)[0]
    return theta


def _interval(x, y, theta):
    design, segments = _linearized(x, y, theta)
    identifier = Identifier(None, None, SETTINGS)
    boot = identifier.intervals(design, segments, Point({'a': theta[0], 'b': theta[1]}))
    return np.percentile(boot, [2.5, 97.5], axis=0).T      # (2, 2): [lo, hi] per coefficient


def test_interval_contains_an_estimate_the_refit_stopped_short_of_the_optimum():
    x, y = _data(0)
    estimate = _gauss_newton(x, y, 1)          # the refit ran out of iterations
    optimum = _gauss_newton(x, y, 20)
    assert np.abs(estimate - optimum).max() > 0.05   # the case that needs the fix
    for (lo, hi), value in zip(_interval(x, y, estimate), estimate, strict=True):
        assert lo <= value <= hi


@pytest.mark.parametrize('seed', [1, 2, 3])
def test_interval_of_the_converged_fit_contains_it(seed):
    x, y = _data(seed)
    estimate = _gauss_newton(x, y, 20)
    for (lo, hi), value in zip(_interval(x, y, estimate), estimate, strict=True):
        assert lo < value < hi


def test_intervals_cover_the_true_values_over_seeds():
    covered = np.zeros(2)
    seeds = range(40)
    for seed in seeds:
        x, y = _data(100 + seed)
        estimate = _gauss_newton(x, y, 20)
        ci = _interval(x, y, estimate)
        covered += (ci[:, 0] <= TRUTH) & (TRUTH <= ci[:, 1])
    # 95 % nominal; a block bootstrap of 40 samples per run covers a little less.
    assert (covered >= 0.85 * len(seeds)).all(), covered


def test_rms_speed_interval_contains_a_small_current_and_keeps_a_strong_one():
    rng = np.random.default_rng(0)
    runs, spread = 6, 0.1                   # per-component bootstrap spread (m/s)
    for truth in (0.0, 0.03, 1.2):
        estimate = np.concatenate([np.full(runs, truth), np.zeros(runs)])   # north, east
        estimate = estimate + 0.02 * rng.standard_normal(2 * runs)
        boot = estimate + spread * rng.standard_normal((400, 2 * runs))
        lo, hi = rms_speed_interval(boot, estimate)
        speed = np.sqrt(np.mean(np.square(estimate)) * 2.0)
        assert lo <= speed <= hi
        if truth > 1.0:                      # strong current: a tight interval around it
            assert hi - lo < 0.2 and lo > 1.0
