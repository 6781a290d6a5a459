"""hybrid_models.cross_bands: bands from out-of-fold forecasts, and their honest coverage."""

import numpy as np
import pytest

from hybrid_models.bands import BandsError, calibrate, coverage, coverage_table, knot_steps
from hybrid_models.cross_bands import (
    HeldOut,
    cross_calibrate,
    fold_robust_levels,
    held_out_coverage,
    least_covered,
)
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')
H = 60


def fold(index, n, seed, scale=1.0):
    """Return a fold of n forecasts of two runs, errors growing like sqrt(step) * ``scale``."""
    rng = np.random.default_rng(seed)
    steps = np.arange(1, H + 1)[None, :, None]
    sigma = scale * np.array([0.05, 0.02, 0.002, 0.001, 0.003]) * np.sqrt(steps)
    pred = np.tile([6.0, 0.0, 0.0, 0.0, 0.0], (n, H, 1)) + rng.normal(size=(n, H, 5)) * 0.1
    true = pred + rng.normal(size=(n, H, 5)) * sigma
    return HeldOut(index, (f'run{index}a', f'run{index}b'), pred, true)


def test_pooled_out_of_fold_forecasts_calibrate_the_bands_and_say_so():
    folds = [fold(k, 300 + 100 * k, seed=k) for k in range(3)]
    bands = cross_calibrate(folds, SHIP, 0.15, source={'model': 'hybrid'},
                            calibration='pooled')
    pooled = calibrate(np.concatenate([f.pred for f in folds]),
                       np.concatenate([f.true for f in folds]), SHIP, 0.15)
    assert np.array_equal(bands.upper, pooled.upper)
    assert np.array_equal(bands.position, pooled.position)
    assert bands.serves(0.15) and not bands.serves(None)
    assert bands.source['note'] == ('cross-validated over 3 folds, 1200 forecasts of 6 runs '
                                    'at relative threshold 0.15')
    assert bands.origin == bands.source['note'] and bands.source['model'] == 'hybrid'
    assert bands.source['forecasts'] == 1200 and bands.source['folds'] == 3


def test_held_out_coverage_is_near_the_level_when_folds_are_alike():
    folds = [fold(k, 600, seed=10 + k) for k in range(4)]
    cover = held_out_coverage(folds, SHIP, 0.15)
    assert cover['forecasts'] == 2400 and len(cover['per_fold']) == 4
    for li, level in enumerate(cover['levels']):
        for name, per_level in cover['states'].items():
            assert np.allclose(per_level[li], level, atol=0.04), (name, level)
        assert np.allclose(cover['position'][li], level, atol=0.04)


def test_held_out_coverage_finds_the_fold_the_others_do_not_stand_for():
    # One fold's errors are three times the others': bands from all folds cover the
    # pooled forecasts nearly as promised in sample, but held out that fold leaves them.
    folds = [fold(0, 400, seed=20, scale=3.0)] + [fold(k, 400, seed=20 + k) for k in (1, 2, 3)]
    cover = held_out_coverage(folds, SHIP, 0.15)
    odd = cover['per_fold'][0]
    assert odd['fold'] == 0 and max(odd['states']['u'][1]) < 0.6
    assert all(min(c['states']['u'][1]) > 0.97 for c in cover['per_fold'][1:])
    fraction, name, step = least_covered(odd, 0.9)
    assert fraction == min(min(f[1]) for f in (*odd['states'].values(), odd['position']))
    series = odd['position'] if name == 'position' else odd['states'][name]
    assert series[1][odd['steps'].index(step)] == fraction
    # Pooled = the folds' fractions weighted by their forecasts.
    expected = np.mean([c['states']['u'][1] for c in cover['per_fold']], axis=0)
    assert np.allclose(cover['states']['u'][1], expected)
    in_sample = coverage(cross_calibrate(folds, SHIP, 0.15),
                         np.concatenate([f.pred for f in folds]),
                         np.concatenate([f.true for f in folds]), SHIP)
    assert min(in_sample['states']['u'][1]) > max(cover['states']['u'][1])


def test_one_fold_is_refused_and_the_table_shows_widths_and_coverage():
    with pytest.raises(BandsError, match='at least 2 folds'):
        cross_calibrate([fold(0, 100, seed=1)], SHIP, None)
    with pytest.raises(BandsError, match='at least 2 folds'):
        held_out_coverage([fold(0, 100, seed=1)], SHIP, None, calibration='pooled')
    folds = [fold(k, 200, seed=30 + k) for k in range(2)]
    # Fold-robust levels are chosen among the calibration folds: held out, 2 are too few.
    with pytest.raises(BandsError, match="at least 3 folds .*'pooled' needs 2"):
        held_out_coverage(folds, SHIP, None)
    with pytest.raises(BandsError, match='calibration must be one of'):
        cross_calibrate(folds, SHIP, None, calibration='median')
    bands = cross_calibrate(folds, SHIP, None)
    cover = held_out_coverage(folds, SHIP, None, calibration='pooled')
    table = coverage_table(bands, cover, SHIP)
    assert len(table) == 2 + len(cover['levels']) * len(cover['steps'])
    lower, upper, position = bands.at(H)
    k = cover['steps'][0] - 1
    first = table[2].split(' | ')
    assert first[2] == f"{position[0, k]:.4g} ({cover['position'][0][0]:.2f})"
    assert first[3] == f"{upper[0, k, 0] - lower[0, k, 0]:.4g} ({cover['states']['u'][0][0]:.2f})"


def offset_fold(index, n, seed, offset):
    """Return a fold whose u is off by ``offset`` times its error's sd (runs gone wrong)."""
    f = fold(index, n, seed)
    true = f.true.copy()
    true[:, :, 0] += offset * 0.05 * np.sqrt(np.arange(1, H + 1))
    return HeldOut(f.fold, f.runs, f.pred, true)


def test_fold_robust_levels_stay_nominal_where_folds_are_alike():
    folds = [fold(k, 600, seed=40 + k) for k in range(4)]
    taken = fold_robust_levels(folds, SHIP)
    assert taken.shape == (2, len(knot_steps(H)), 6)
    assert np.all(np.abs(taken[0] - 0.5) <= 0.06) and np.all(np.abs(taken[1] - 0.9) <= 0.03)
    bands = cross_calibrate(folds, SHIP, 0.15)
    assert np.array_equal(bands.source['quantile_levels'], taken.tolist())
    assert 'chosen leave-one-fold-out' in bands.origin


def test_fold_robust_bands_hold_their_level_where_some_folds_are_offset():
    # Two of six folds are mispredicted in u by an offset: pooled quantiles, in sample
    # nearly right, fall short on folds held out; levels chosen leave-one-fold-out widen
    # the u band until held-out folds are covered as promised.
    folds = [offset_fold(0, 300, 50, 2.5), offset_fold(1, 300, 51, -2.0)] + [
        fold(k, 300, seed=50 + k) for k in range(2, 6)]
    pooled = held_out_coverage(folds, SHIP, None, calibration='pooled')
    robust = held_out_coverage(folds, SHIP, None)
    u_pooled, u_robust = np.array(pooled['states']['u'][1]), np.array(robust['states']['u'][1])
    assert u_pooled.max() < 0.8
    # Held out, an offset fold leaves one like it among the calibration folds: the levels
    # chosen there widen less than its own absence would need, so part of the gap stays.
    assert np.all(np.abs(u_robust - 0.9) < 0.5 * np.abs(u_pooled - 0.9)), (u_pooled, u_robust)
    # The states the offset does not touch stay near their level.
    assert np.all(np.abs(np.array(robust['states']['r'][1]) - 0.9) < 0.05)
    taken = fold_robust_levels(folds, SHIP)
    assert taken[1, :, 0].min() > taken[1, :, 3].max()
