"""Window indexing and coverage of the training sequences."""

import numpy as np

from hybrid_models.data import RunArrays, cut_windows, forecast_starts, tiling_windows


def ramp_run(n, run_id='a'):
    t = np.arange(n, dtype=np.float32)
    z = np.stack([t + 0.1 * k for k in range(5)], axis=1)
    c = np.stack([1000 + t + 0.1 * k for k in range(6)], axis=1)
    return RunArrays(run_id, z, c, z + 0.5)


def test_window_indexing_matches_the_documented_convention():
    run = ramp_run(50)
    w = cut_windows([run], [np.array([10])], window=4, horizon=3, target='true')
    np.testing.assert_array_equal(w.z_window[0, :, 0], [6, 7, 8, 9])
    np.testing.assert_array_equal(w.c_window[0, :, 0], [1006, 1007, 1008, 1009])
    # Step k predicts z[t0+k] from the control c[t0+k-1].
    np.testing.assert_array_equal(w.c_future[0, :, 0], [1009, 1010, 1011])
    np.testing.assert_array_equal(w.z_target[0, :, 0], [10.5, 11.5, 12.5])


def test_forecast_starts_stay_inside_the_run():
    starts = forecast_starts(length=100, window=10, horizon=30, stride=20)
    np.testing.assert_array_equal(starts, [10, 30, 50, 70])
    assert len(forecast_starts(30, 10, 30, 5)) == 0


def test_tiling_sequences_cover_every_predictable_sample():
    # The authors' windows covered half of each file; ours cover all of [window, T).
    runs = [ramp_run(337, 'a'), ramp_run(200, 'b')]
    window, length = 60, 50
    covered = [set(), set()]
    for offset in range(length):
        w = tiling_windows(runs, window, length, offset)
        for i, t0 in zip(w.run_index, w.t0, strict=True):
            span = set(range(t0, t0 + length))
            assert not covered[i] & span or offset > 0
            covered[i] |= span
        # Within one epoch the spans do not overlap and miss < 2 * length samples.
        for i, run in enumerate(runs):
            t0s = np.sort(w.t0[w.run_index == i])
            assert (np.diff(t0s) == length).all()
            assert run.length - window - len(t0s) * length < 2 * length
    for i, run in enumerate(runs):
        assert covered[i] == set(range(window, run.length))
