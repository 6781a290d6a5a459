"""Do no harm: a hybrid is served at the threshold its validation runs choose, 0 included."""

from pathlib import Path

import numpy as np
import pytest
import torch

from hybrid_models.checkpoint import load_model
from hybrid_models.data import load_runs
from hybrid_models.metrics import StepErrors, reported_steps
from hybrid_models.models import build_model
from hybrid_models.selection import choose, harms, threshold_grid
from hybrid_models.toy import TOY_VESSEL, write_linear_dataset
from hybrid_models.training import load_config, train
from hybrid_models.training.loop import REFERENCE_EPOCH
from hybrid_models.training.tasks import RecurrentTask
from hybrid_models.training.train import select_threshold

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'


def profile(position, rmse_u, steps=(1, 2)):
    return {'steps': list(steps), 'position_m': list(position),
            'rmse': {'u': list(rmse_u)}}


def test_the_grid_always_holds_the_physics_alone_and_respects_the_cap():
    assert threshold_grid([0.1, 0.5, None], None) == [0.0, 0.1, 0.5, None]
    assert threshold_grid([0.1, 0.5, None], 0.3) == [0.0, 0.1, 0.3]
    assert threshold_grid([], 0.2) == [0.0, 0.2]
    with pytest.raises(ValueError, match='>= 0'):
        threshold_grid([-0.1], None)


def test_a_threshold_worse_at_any_reported_figure_is_not_admissible():
    physics = profile([1.0, 2.0], [0.1, 0.2])
    assert harms(profile([0.9, 1.9], [0.1, 0.19]), physics) == []
    assert harms(profile([0.9, 2.1], [0.1, 0.1]), physics) == ['position at step 2']
    assert harms(profile([0.9, 1.0], [0.11, 0.1]), physics) == ['u at step 1']
    assert harms(profile([None, 1.0], [0.1, 0.1]), physics) == ['position at step 1']


def test_the_best_admissible_threshold_is_served_and_the_physics_when_none_helps():
    physics = {'score': 1.0, 'profile': profile([1.0, 2.0], [0.1, 0.2])}
    rows = [{'relative_threshold': 0.0, **physics},
            {'relative_threshold': 0.1, 'score': 0.8, 'profile': profile([0.9, 1.8], [.1, .2])},
            # Better on the score, but worse late in the horizon: refused.
            {'relative_threshold': 0.5, 'score': 0.6, 'profile': profile([0.5, 2.5], [.1, .2])}]
    chosen = choose(rows, physics)
    assert chosen['relative_threshold'] == 0.1 and chosen['score'] == 0.8
    assert chosen['candidates'][2]['harms'] == ['position at step 2']
    assert choose(rows[:1] + rows[2:], physics)['relative_threshold'] == 0.0


def test_step_errors_of_parts_add_up_to_the_whole_and_profile_the_quarters():
    rng = np.random.default_rng(0)
    true = rng.standard_normal((6, 40, 5))
    pred = true + 0.1 * rng.standard_normal(true.shape)
    whole = StepErrors.of(pred, true, TOY_VESSEL)
    parts = StepErrors.of(pred[:2], true[:2], TOY_VESSEL) + StepErrors.of(
        pred[2:], true[2:], TOY_VESSEL)
    np.testing.assert_allclose(parts.sse, whole.sse)
    back = StepErrors.from_flat(whole.flat(), 40, 5)
    np.testing.assert_allclose(back.position, whole.position)
    assert reported_steps(40) == [10, 20, 30, 40]
    prof = whole.profile(TOY_VESSEL)
    assert prof['steps'] == [10, 20, 30, 40]
    u_at_20 = np.sqrt(((pred[:, 19, 0] - true[:, 19, 0]) ** 2).mean())
    assert prof['rmse']['u'][1] == pytest.approx(u_at_20)


@pytest.fixture(scope='module')
def linear(tmp_path_factory):
    return write_linear_dataset(tmp_path_factory.mktemp('linear'))


def test_a_hybrid_on_data_its_physics_explains_exactly_is_served_as_the_physics(
        linear, tmp_path):
    cfg = load_config(SMOKE, [f'dataset={linear}', 'training.progress=false'])
    summary = train(cfg, tmp_path)
    selection = summary['selection']
    assert selection['relative_threshold'] == 0.0, selection['reason']
    assert summary['model']['relative_threshold'] == 0.0
    model, _ = load_model(tmp_path / 'model.safetensors')
    runs = load_runs(linear, 'val', TOY_VESSEL)
    task = RecurrentTask(TOY_VESSEL, runs, runs, cfg['training'], np.ones(5))
    hybrid = task.validation_errors(model)
    with model.served_at(0.0):
        physics = task.validation_errors(model)
    np.testing.assert_array_equal(hybrid.sse, physics.sse)
    # Training started from the physics (a zero correction) and no epoch beat it.
    log = (tmp_path / 'log.jsonl').read_text().splitlines()
    assert f'"epoch": {REFERENCE_EPOCH}' in log[0] and '"reference"' in log[0]


def _fitted_hybrid(dataset, cfg):
    """Return a hybrid whose Lin physics is fitted on the training runs, head at zero."""
    torch.manual_seed(0)
    model = build_model(cfg['model'], TOY_VESSEL)
    train_runs = load_runs(dataset, 'train', TOY_VESSEL)
    z = np.concatenate([r.z[:-1] for r in train_runs])
    c = np.concatenate([r.c[:-1] for r in train_runs])
    zn = np.concatenate([r.z[1:] for r in train_runs])
    model.physical.fit(z, c, zn)
    model.output_range.copy_(torch.ones(5))
    return model


def test_a_correction_that_hurts_on_validation_is_served_at_threshold_0(linear):
    cfg = load_config(SMOKE, [f'dataset={linear}'])
    model = _fitted_hybrid(linear, cfg)
    with torch.no_grad():
        model.head.bias.fill_(0.5)   # a constant push away from the exact physics
    runs = load_runs(linear, 'val', TOY_VESSEL)
    task = RecurrentTask(TOY_VESSEL, runs, runs, cfg['training'], np.ones(5))
    chosen = select_threshold(model, task, cfg['training'], best_epoch=3)
    assert chosen['relative_threshold'] == 0.0 and model.relative_threshold == 0.0
    assert all(row['harms'] for row in chosen['candidates'] if row['relative_threshold'])


def test_a_correction_that_helps_on_validation_is_served_bounded(linear):
    cfg = load_config(SMOKE, [f'dataset={linear}'])
    model = _fitted_hybrid(linear, cfg)
    bias = torch.tensor([0.02, -0.01, 0.0, 0.0, 0.0])
    with torch.no_grad():
        model.physical.bias -= bias     # physics now off by a constant
        model.head.bias.copy_(bias)     # and the correction undoes it (residual_std 1)
    runs = load_runs(linear, 'val', TOY_VESSEL)
    task = RecurrentTask(TOY_VESSEL, runs, runs, cfg['training'], np.ones(5))
    chosen = select_threshold(model, task, cfg['training'], best_epoch=3)
    assert chosen['relative_threshold'] > 0, chosen['reason']
    assert chosen['score'] < 0.5 * chosen['physics']['score']
    assert model.relative_threshold == chosen['relative_threshold']
