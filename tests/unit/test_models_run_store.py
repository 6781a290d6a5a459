"""Windows read lazily from the run cache are exactly those cut from runs in memory."""

import numpy as np
import pytest

from hybrid_models import run_store
from hybrid_models.data import (
    cut_windows,
    forecast_starts,
    gather_windows,
    load_runs,
    one_step_pairs,
    tiling_windows,
)
from hybrid_models.normalization import Normalizer
from hybrid_models.streaming import Moments, RowSample
from offline.benchmarks.toy import TOY_VESSEL, write_toy_dataset
from vessel_datasets.format import read_dataset

FIELDS = ('z_window', 'c_window', 'c_future', 'z_target', 'run_index', 't0')


@pytest.fixture(scope='module')
def toy(tmp_path_factory):
    return read_dataset(write_toy_dataset(tmp_path_factory.mktemp('toy'), n_runs=5,
                                          n_samples=230))


@pytest.fixture
def small_chunks(monkeypatch):
    # Chunks that do not divide the runs, so pairs across chunk borders are exercised.
    monkeypatch.setattr(run_store, 'CHUNK_ROWS', 37)


def assert_same(a, b):
    for name in FIELDS:
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x, y), name


def test_lazy_windows_equal_the_in_memory_windows(toy, tmp_path, small_chunks):
    split = 'train'
    memory = load_runs(toy, split, TOY_VESSEL)
    store = run_store.build_split(toy, split, TOY_VESSEL, tmp_path, 10_000, seed=0)
    assert [r.run_id for r in store.runs] == [r.run_id for r in memory]
    assert [r.length for r in store.runs] == [r.length for r in memory]
    for offset in (0, 7):
        assert_same(tiling_windows(store.runs, 20, 15, offset),
                    tiling_windows(memory, 20, 15, offset))
    for target in ('measured', 'true'):
        starts = [forecast_starts(r.length, 20, 100, 30) for r in memory]
        assert_same(cut_windows(store.runs, starts, 20, 100, target),
                    cut_windows(memory, starts, 20, 100, target))
    # A shuffled batch gathered lazily is the same rows of the whole set, in that order.
    whole = tiling_windows(memory, 20, 15, 3)
    idx = np.random.default_rng(1).permutation(len(whole))[:40]
    assert_same(gather_windows(store.runs, whole.run_index[idx], whole.t0[idx], 20, 15),
                whole.subset(idx))


def test_streamed_statistics_match_the_whole_data(toy, tmp_path, small_chunks):
    memory = load_runs(toy, 'train', TOY_VESSEL)
    z, c, z_next = one_step_pairs(memory)
    store = run_store.build_split(toy, 'train', TOY_VESSEL, tmp_path, 10_000, seed=0,
                                  write=False)
    assert not any(r.path.exists() for r in store.runs)   # a reading-only process
    for moments, rows in ((store.state, z), (store.control, c)):
        ref = Normalizer.fit(rows)
        got = moments.normalizer()
        np.testing.assert_allclose(got.mean, ref.mean, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(got.std, ref.std, rtol=1e-10)
    # Below capacity the sample is every pair, in order: the physics fit is unchanged.
    assert store.pairs.complete
    assert np.array_equal(store.pairs.rows(), np.concatenate([z, c, z_next], axis=1))


def test_a_full_row_sample_keeps_a_uniform_subset_of_the_capacity():
    sample = RowSample(capacity=500, seed=3)
    data = np.arange(20_000, dtype=np.float64)[:, None]
    for i in range(0, len(data), 999):
        sample.add(data[i:i + 999])
    rows = sample.rows()[:, 0]
    assert len(rows) == 500 and not sample.complete
    assert len(set(rows)) == 500 and (np.diff(rows) > 0).all()     # distinct, in order
    # Uniform: the sample's median is near the data's (binomial sd ~ 0.022 of the range).
    assert abs(np.median(rows) / len(data) - 0.5) < 0.1


def test_moments_of_chunks_equal_moments_of_the_whole():
    x = np.random.default_rng(0).normal(3.0, 2.0, size=(1000, 4))
    m = Moments(4)
    for part in np.array_split(x, 7):
        m.add(part)
    np.testing.assert_allclose(m.normalizer().std, x.std(axis=0), rtol=1e-12)


def test_a_run_with_nan_is_refused(tmp_path):
    import pandas as pd
    ds = read_dataset(write_toy_dataset(tmp_path / 'toy', n_runs=3, n_samples=60))
    run = ds.manifest['runs'][0]
    table = pd.read_parquet(ds.root / run['file'])
    table.loc[5, 'u'] = np.nan
    table.to_parquet(ds.root / run['file'], index=False)
    split = run['split']
    with pytest.raises(ValueError, match='NaN'):
        run_store.build_split(ds, split, TOY_VESSEL, tmp_path, 100, seed=0, write=False)
