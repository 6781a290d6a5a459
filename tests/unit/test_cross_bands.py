"""hybrid_models.cross_bands: bands from out-of-fold forecasts, and their honest coverage."""

import numpy as np
import pytest

from hybrid_models.bands import BandsError, calibrate, coverage, coverage_table
from hybrid_models.cross_bands import (
    HeldOut,
    cross_calibrate,
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
    bands = cross_calibrate(folds, SHIP, 0.15, source={'model': 'hybrid'})
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
        held_out_coverage([fold(0, 100, seed=1)], SHIP, None)
    folds = [fold(k, 200, seed=30 + k) for k in range(2)]
    bands = cross_calibrate(folds, SHIP, None)
    cover = held_out_coverage(folds, SHIP, None)
    table = coverage_table(bands, cover, SHIP)
    assert len(table) == 2 + len(cover['levels']) * len(cover['steps'])
    lower, upper, position = bands.at(H)
    k = cover['steps'][0] - 1
    first = table[2].split(' | ')
    assert first[2] == f"{position[0, k]:.4g} ({cover['position'][0][0]:.2f})"
    assert first[3] == f"{upper[0, k, 0] - lower[0, k, 0]:.4g} ({cover['states']['u'][0][0]:.2f})"
