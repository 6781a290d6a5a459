"""hybrid_models.novelty: the bound fades where the correction's inputs leave training's."""

import numpy as np
import pytest
import torch

from hybrid_models import novelty
from hybrid_models.checkpoint import CheckpointError, load_model, save_checkpoint
from hybrid_models.engine import Forecaster
from hybrid_models.hybrid_step import correction_input
from tests.unit.test_models_engine import H, inputs, make_model, torch_forecast


def training_inputs(n=400, dims=11, seed=0):
    """Correlated inputs, as normalised states and controls are."""
    rng = np.random.default_rng(seed)
    return rng.normal(size=(n, dims)) @ rng.normal(scale=0.5, size=(dims, dims))


def test_the_share_is_one_on_every_training_input_and_shrinks_beyond_them():
    train = training_inputs()
    val = training_inputs(50, seed=1)
    calibration = novelty.calibrate(train, val)
    weights = calibration.weights()
    for rows in (train, val):
        assert (novelty.available(rows, weights) == 1.0).all()
    centre = calibration.mean
    direction = np.linalg.solve(calibration.whiten.T, np.ones(train.shape[1]))
    farther = [centre + k * direction for k in (1, 10, 100, 1000)]
    shares = novelty.available(np.stack(farther), weights)[:, 0]
    assert shares[-1] < 0.05
    assert (np.diff(shares) < 0).all() or shares[0] == 1.0
    d = novelty.distance(np.stack(farther), weights)[:, 0]
    outside = d > calibration.radius
    np.testing.assert_allclose(shares[outside], calibration.radius / d[outside])


def test_a_calibration_survives_its_checkpoint_entry_and_refuses_too_few_inputs():
    calibration = novelty.calibrate(training_inputs(), training_inputs(20, seed=2), 'src')
    again = novelty.Novelty.from_dict(calibration.to_dict())
    np.testing.assert_array_equal(again.whiten, calibration.whiten)
    assert (again.radius, again.source) == (calibration.radius, 'src')
    with pytest.raises(ValueError, match='two or more finite'):
        novelty.calibrate(np.ones((1, 3)), np.ones((0, 3)))


def saved(path, model):
    """Write ``model`` as a checkpoint at ``path`` (the config's vessel and description)."""
    save_checkpoint(path, model, {'vehicle': model.spec.to_dict(), 'model': model.describe()})


def calibrated(model, steps):
    """Calibrate ``model`` on the inputs of its own plain forecast's first ``steps`` steps."""
    z, c, future = inputs(batch=4)
    fade, model.novelty_fade = model.novelty_fade, False
    _, physics = torch_forecast(model, z, c, future, torch.float64)
    model.novelty_fade = fade
    norm = {k: getattr(model, k).double().numpy()
            for k in ('state_mean', 'state_std', 'control_mean', 'control_std')}
    seen = correction_input(norm, physics[:, :steps], future[:, :steps]).reshape(-1, 11)
    rng = np.random.default_rng(4)
    model.novelty = novelty.calibrate(seen + rng.normal(scale=1e-3, size=seen.shape),
                                      seen)
    return model


def test_served_with_the_fade_a_hybrid_keeps_its_plain_bound_inside_and_less_outside():
    z, c, future = inputs(batch=4)
    plain = make_model('lin', threshold=0.15).double()
    faded = make_model('lin', threshold=0.15).double()
    expected, _ = torch_forecast(plain, z, c, future, torch.float64)
    # Trained on every input the forecast meets: the plain bound; on its first step's
    # alone: less of it as the forecast moves away.
    for steps, same in ((H, True), (1, False)):
        calibrated(faded, steps).novelty_fade = True
        got, physics = torch_forecast(faded, z, c, future, torch.float64)
        engine = Forecaster.from_model(faded, dtype=np.float64).forecast(z, c, future)
        np.testing.assert_allclose(engine.hybrid, got, rtol=1e-9, atol=1e-11)
        share = engine.available
        assert share.shape == (4, H)
        if same:
            assert (share > 1 - 1e-12).all()
            np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-14)
        else:
            assert share[:, -1].max() < 0.5
            bound = plain.bound.numpy()
            assert (np.abs(got - physics) <= share[..., None] * bound + 1e-12).all()
            assert np.abs(got - physics)[:, -1].max() < np.abs(expected - physics)[:, -1].max()


def test_the_fade_and_its_calibration_live_in_the_checkpoint(tmp_path):
    model = calibrated(make_model('lin', threshold=0.15), 1)
    path = tmp_path / 'model.safetensors'
    saved(path, model)
    loaded, config = load_model(path)
    assert loaded.novelty_fade is False and config['novelty'][0]['radius'] > 0
    assert Forecaster.from_checkpoint(path).forecast(*inputs(batch=1)).available is None
    model.novelty_fade = True
    saved(path, model)
    served = Forecaster.from_checkpoint(path).forecast(*inputs(batch=1))
    assert served.available[0, 0] == 1.0 and served.available[0, -1] < 0.5
    model.novelty = None
    saved(path, model)
    with pytest.raises(CheckpointError, match='holds no novelty calibration'):
        load_model(path)
    with pytest.raises(CheckpointError, match='holds no novelty calibration'):
        Forecaster.from_checkpoint(path)


def test_set_novelty_turns_the_fade_on_and_off_and_refuses_an_uncalibrated_model(tmp_path,
                                                                                 capsys):
    from hybrid_models.cli.set_novelty import main as set_novelty

    model = calibrated(make_model('lin', threshold=0.15), 1)
    path, faded = tmp_path / 'model.safetensors', tmp_path / 'faded.safetensors'
    saved(path, model)
    assert set_novelty([str(path), 'on', '--out', str(faded)]) == 0
    assert 'novelty fade on' in capsys.readouterr().out
    assert load_model(faded)[0].novelty_fade and not load_model(path)[0].novelty_fade
    plain, _ = torch_forecast(load_model(path)[0].double(), *inputs(batch=1), torch.float64)
    on, _ = torch_forecast(load_model(faded)[0].double(), *inputs(batch=1), torch.float64)
    assert not np.allclose(plain, on)
    assert set_novelty([str(faded), 'off']) == 0
    off, _ = torch_forecast(load_model(faded)[0].double(), *inputs(batch=1), torch.float64)
    np.testing.assert_array_equal(off, plain)
    model.novelty = None
    saved(path, model)
    assert set_novelty([str(path), 'on']) == 2
    assert 'holds no novelty calibration' in capsys.readouterr().err


def test_an_ensemble_fades_each_member_by_its_own_calibration_as_torch_does(tmp_path):
    from hybrid_models.ensemble import pack

    members = [make_model('lin', threshold=0.15).double() for _ in range(2)]
    with torch.no_grad():   # another correction on the same physics
        members[1].head.weight.mul_(-2.0)
    for m in members:
        calibrated(m, 1).novelty_fade = True
    ensemble = pack(members)
    z, c, future = inputs(batch=2)
    expected, _ = torch_forecast(ensemble, z, c, future, torch.float64)
    served = Forecaster.from_model(ensemble, dtype=np.float64).forecast(z, c, future)
    np.testing.assert_allclose(served.hybrid, expected, rtol=1e-9, atol=1e-11)
    assert served.available.shape == (2, H) and served.available[:, -1].max() < 0.5
    path = tmp_path / 'ensemble.safetensors'
    save_checkpoint(path, ensemble, {'vehicle': ensemble.members[0].spec.to_dict(),
                                     'model': ensemble.describe()})
    loaded, config = load_model(path)
    assert len(config['novelty']) == 2 and all(m.novelty_fade for m in loaded.members)
    again, _ = torch_forecast(loaded.double(), z, c, future, torch.float64)
    np.testing.assert_allclose(again, expected, rtol=1e-6)   # weights stored in float32


def test_a_model_without_a_bound_is_refused_in_one_line_by_both_bound_tools(tmp_path, capsys):
    from hybrid_models.cli.set_novelty import main as set_novelty
    from hybrid_models.cli.set_threshold import main as set_threshold
    from hybrid_models.models import build_model

    lstm = build_model({'kind': 'lstm', 'hidden': 8, 'layers': 1}, make_model('lin', 0.1).spec)
    path = tmp_path / 'lstm.safetensors'
    saved(path, lstm)
    assert set_threshold([str(path), '0.1']) == 2
    assert set_novelty([str(path), 'on']) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"set_threshold: error: {path}: only hybrid models (and ensembles of them) have a "
        f"bound (this is 'lstm')",
        f"set_novelty: error: {path}: only hybrid models (and ensembles of them) have a bound "
        f"to fade (this is 'lstm')"]
