"""hybrid_models.bands: calibrated forecast bands, stored in checkpoints and served."""

import json
from pathlib import Path

import numpy as np
import pytest

from hybrid_models.bands import Bands, BandsError, calibrate, coverage, knot_steps, widening
from hybrid_models.metrics import reported_steps
from vessel_description import load_vessel

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'
SHIP = load_vessel('patrol_boat')
H = 120


def forecasts(n, seed, scale=1.0, drift=0.0):
    """Forecasts and truths (n, H, 5) whose errors grow like sqrt(step), plus a drift."""
    rng = np.random.default_rng(seed)
    steps = np.arange(1, H + 1)[None, :, None]
    sigma = scale * np.array([0.05, 0.02, 0.002, 0.001, 0.003]) * np.sqrt(steps)
    pred = np.tile([6.0, 0.0, 0.0, 0.0, 0.0], (n, H, 1)) + rng.normal(size=(n, H, 5)) * 0.1
    error = rng.normal(size=(n, H, 5)) * sigma + drift * steps * sigma / np.sqrt(H)
    return pred, pred + error


def test_knots_hold_the_reported_steps_and_start_at_the_first_step():
    for horizon in (1, 7, 200, 900):
        steps = knot_steps(horizon)
        assert steps[0] == 1 and steps[-1] == horizon
        assert np.all(np.diff(steps) > 0)
        assert set(reported_steps(horizon)) <= set(steps.tolist())


def test_bands_cover_their_level_on_fresh_forecasts_and_never_narrow():
    pred, true = forecasts(2000, seed=0)
    bands = calibrate(pred, true, SHIP, relative_threshold=0.15)
    lower, upper, position = bands.at(H)
    assert lower.shape == upper.shape == (2, H, 5) and position.shape == (2, H)
    # Monotone in the horizon, nested by level, and around zero error.
    assert np.all(np.diff(lower, axis=1) <= 1e-12) and np.all(np.diff(upper, axis=1) >= -1e-12)
    assert np.all(np.diff(position, axis=1) >= -1e-12)
    assert np.all(lower[1] <= lower[0]) and np.all(upper[1] >= upper[0])
    assert np.all(lower[:, -1] < 0) and np.all(upper[:, -1] > 0)
    fresh = coverage(bands, *forecasts(2000, seed=1), SHIP)
    for li, level in enumerate(bands.levels):
        for name, per_level in fresh['states'].items():
            assert np.allclose(per_level[li], level, atol=0.04), (name, level, per_level)
        assert np.allclose(fresh['position'][li], level, atol=0.04)
    # A model that departs (errors twice as large, drifting) leaves the band.
    departed = coverage(bands, *forecasts(2000, seed=2, scale=2.0, drift=2.0), SHIP)
    assert max(departed['states']['u'][1]) < 0.7


def test_bands_at_a_horizon_are_made_once_and_no_caller_can_change_them():
    pred, true = forecasts(500, seed=0)
    bands = calibrate(pred, true, SHIP, relative_threshold=0.15)
    first, again = bands.at(H), bands.at(H)
    assert all(a is b for a, b in zip(first, again, strict=True))
    lower, upper, position = first
    with pytest.raises(ValueError, match='read-only'):
        lower[0, 0, 0] = 0.0
    # Each horizon its own: a longer one is NaN past the calibrated horizon.
    longer = bands.at(H + 5)[1]
    assert np.array_equal(longer[:, :H], upper) and np.isnan(longer[:, H:]).all()
    # Between the knots, each state's band is the linear interpolation of its knots.
    for li in range(len(bands.levels)):
        assert np.allclose(upper[li, :, 2], np.interp(np.arange(1, H + 1), bands.steps,
                                                      bands.upper[li, :, 2]))


def test_widening_pools_a_level_quantile_instead_of_ratcheting_it_up():
    rng = np.random.default_rng(3)
    noisy_level = 1.0 + 0.05 * rng.normal(size=200)
    fitted = widening(noisy_level)
    assert np.all(np.diff(fitted) >= 0)
    assert abs(fitted.mean() - noisy_level.mean()) < 1e-9     # least squares keeps the mean
    assert fitted[-1] < np.maximum.accumulate(noisy_level)[-1]
    rising = np.linspace(0.0, 1.0, 30)
    np.testing.assert_allclose(widening(rising), rising)


def test_bands_go_through_a_checkpoint_config_and_hold_only_at_their_threshold():
    pred, true = forecasts(300, seed=4)
    schedule = [[0.0, 0.0], [60.0, 0.15]]
    bands = calibrate(pred, true, SHIP, relative_threshold=schedule, source={'runs': 3})
    back = Bands.from_dict(json.loads(json.dumps(bands.to_dict())), SHIP.state_names)
    for got, expected in zip(back.at(H), bands.at(H), strict=True):
        np.testing.assert_array_equal(got, expected)
    assert back.serves([(0, 0.0), (60, 0.15)]) and not back.serves(0.15)
    assert np.isnan(back.at(H + 5)[1][:, H:]).all()            # none beyond the horizon
    with pytest.raises(BandsError, match='do not fit'):
        Bands.from_dict(bands.to_dict(), ('u', 'v', 'r'))
    with pytest.raises(BandsError, match='too few'):
        calibrate(pred[:10], true[:10], SHIP, 0.15)
    with pytest.raises(BandsError, match='not finite'):
        calibrate(np.full_like(pred, np.nan), true, SHIP, 0.15)


# Slow (8 s: a training and four compiled engines). By default the skiff's predictor test
# (tests/integration/test_predictor_any_vessel.py) still trains a model whose bands the
# node publishes.
@pytest.mark.slow
def test_training_writes_bands_that_the_engine_serves_and_set_bands_renews(tmp_path):
    from safetensors.numpy import load_file

    from hybrid_models.cli.set_bands import main as set_bands
    from hybrid_models.cli.set_threshold import main as set_threshold
    from hybrid_models.engine import Forecaster
    from hybrid_models.training import load_config, train
    from offline.benchmarks.toy import write_toy_dataset

    toy = write_toy_dataset(tmp_path / 'toy', n_runs=6, n_samples=300)
    cfg = load_config(SMOKE, [f'dataset={toy}', 'training.progress=false'])
    train(cfg, tmp_path / 'run')
    path = tmp_path / 'run' / 'model.safetensors'
    engine = Forecaster.from_checkpoint(path)
    assert engine.bands is not None, engine.bands_note
    assert engine.bands.source['split'] == 'val' and engine.bands.source['forecasts'] > 20
    # Another threshold: the bands are not served, and the node is told why.
    assert set_threshold([str(path), '0.5', '--out', str(tmp_path / 'other.safetensors')]) == 0
    other = Forecaster.from_checkpoint(tmp_path / 'other.safetensors')
    assert other.bands is None and 'not at the served 0.5' in other.bands_note
    # set_bands gives them again, the weights bit for bit as they were.
    assert set_bands([str(tmp_path / 'other.safetensors'), '--dataset', str(toy),
                      '--horizon', '100']) == 0
    renewed = Forecaster.from_checkpoint(tmp_path / 'other.safetensors')
    assert renewed.bands is not None and renewed.bands.relative_threshold == 0.5
    before, after = load_file(str(path)), load_file(str(tmp_path / 'other.safetensors'))
    assert all(np.array_equal(before[k], after[k]) for k in before if 'bound' not in k)
    # Runs the model was trained on cannot calibrate it; a bad level is refused.
    from hybrid_models.checkpoint_format import read_header, rewrite_config
    from vessel_datasets.format import read_dataset

    config = read_header(path)
    config['dataset']['train_runs'] += read_dataset(toy).manifest['split']['val']
    rewrite_config(path, config, tmp_path / 'seen.safetensors')
    assert set_bands([str(tmp_path / 'seen.safetensors'), '--dataset', str(toy),
                      '--horizon', '100']) == 2
    assert set_bands([str(path), '--dataset', str(toy), '--levels', '1.5']) == 2
