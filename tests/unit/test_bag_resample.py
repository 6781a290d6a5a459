"""Cleaning (NaN, duplicate, out-of-order), gap detection and fixed-rate resampling."""

import numpy as np
import pytest

from vessel_datasets.extract import clean
from vessel_datasets.resample import (
    aligned_grid,
    coverage,
    find_gaps,
    intersect,
    period_ns,
    plan_runs,
    sample,
)

S = 1_000_000_000  # ns per second


def test_clean_counts_each_reason_exactly():
    # Arrival order: 0 1 2 2(dup) 1(old) 3 nan(4) 5 5(dup) 4(old) 6
    t = np.array([0, 1, 2, 2, 1, 3, 4, 5, 5, 4, 6]) * S
    v = np.arange(11, dtype=float)[:, None]
    v[6, 0] = np.nan
    kept_t, kept_v, dropped = clean(t, v)
    assert dropped == {'nan': 1, 'duplicate': 2, 'out_of_order': 2}
    assert (kept_t == np.array([0, 1, 2, 3, 5, 6]) * S).all()
    assert kept_v[:, 0].tolist() == [0, 1, 2, 5, 7, 10]


def test_clean_nan_sample_does_not_shadow_later_ones():
    # A NaN sample's stamp is not "accepted", so an equal stamp after it is kept.
    t = np.array([0, 1, 1, 2]) * S
    v = np.array([[0.0], [np.nan], [1.0], [2.0]])
    kept_t, _, dropped = clean(t, v)
    assert dropped == {'nan': 1, 'duplicate': 0, 'out_of_order': 0}
    assert (kept_t == np.array([0, 1, 2]) * S).all()


def test_inf_counts_as_nan():
    _, _, dropped = clean(np.array([0, S]), np.array([[np.inf, 0.0], [1.0, 1.0]]))
    assert dropped['nan'] == 1


def test_gaps_and_coverage():
    t = np.array([0, 1, 2, 6, 7, 20]) * S
    gaps = find_gaps('/a', t, int(2.5 * S))
    assert [(g.start_ns // S, g.end_ns // S) for g in gaps] == [(2, 6), (7, 20)]
    assert gaps[0].duration_s == 4.0
    assert coverage(t, int(2.5 * S)) == [(0, 2 * S), (6 * S, 7 * S), (20 * S, 20 * S)]


def test_intersect():
    a = [(0, 10), (20, 30)]
    b = [(5, 25), (28, 40)]
    assert intersect(a, b) == [(5, 10), (20, 25), (28, 30)]


def test_aligned_grid_uses_multiples_of_the_period():
    grid = aligned_grid(int(0.3 * S), int(3.2 * S), S)
    assert (grid == np.array([1, 2, 3]) * S).all()
    assert len(aligned_grid(int(0.3 * S), int(0.9 * S), S)) == 0
    assert period_ns(10.0) == S // 10


def test_plan_runs_splits_at_a_gap_of_any_topic():
    a = np.arange(0, 100) * S                                       # 0..99 s
    b = np.concatenate([np.arange(0, 40), np.arange(45, 100)]) * S  # silent 39..45 s
    runs, short, gaps = plan_runs({'/a': a, '/b': b}, {'/a': 2 * S, '/b': 2 * S}, S,
                                  min_samples=11)
    assert [(r.start_ns // S, r.end_ns // S, len(r.grid_ns)) for r in runs] == \
        [(0, 39, 40), (45, 99, 55)]
    assert short == []
    assert [(g.topic, g.start_ns // S, g.end_ns // S) for g in gaps] == [('/b', 39, 45)]


def test_plan_runs_reports_short_runs():
    a = np.concatenate([np.arange(0, 5), np.arange(10, 40)]) * S
    runs, short, _ = plan_runs({'/a': a}, {'/a': 2 * S}, S, min_samples=11)
    assert [len(r.grid_ns) for r in runs] == [30]
    assert [len(r.grid_ns) for r in short] == [5]


def test_per_topic_max_gap():
    slow = np.arange(0, 100, 5) * S  # a 0.2 Hz topic
    fast = np.arange(0, 96) * S
    runs, _, gaps = plan_runs({'/fast': fast, '/slow': slow}, {'/fast': 2 * S, '/slow': 6 * S},
                              S, min_samples=2)
    assert len(runs) == 1 and gaps == []
    assert len(runs[0].grid_ns) == 96


def test_sample_linear_and_hold():
    t = np.array([0, 2, 4]) * S
    values = np.array([[0.0, 10.0], [2.0, 20.0], [4.0, 30.0]])
    grid = np.arange(0, 5) * S
    out = sample(t, values, grid, ['linear', 'hold'])
    assert out[:, 0].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert out[:, 1].tolist() == [10.0, 10.0, 20.0, 20.0, 30.0]


def test_sample_is_exact_at_sample_times_far_from_the_epoch():
    t0 = 1_700_000_000 * S
    t = t0 + np.arange(0, 4) * S + 1  # 1 ns after the grid: float seconds would lose it
    values = np.array([[1.0], [2.0], [3.0], [4.0]])
    grid = t0 + np.arange(1, 4) * S
    out = sample(t, values, grid, ['hold'])
    assert out[:, 0].tolist() == [1.0, 2.0, 3.0]


def test_unknown_method_is_refused():
    with pytest.raises(ValueError, match='cubic'):
        sample(np.array([0, S]), np.zeros((2, 1)), np.array([0, S]), ['cubic'])
