"""Do no harm: a hybrid is served at the threshold its validation runs choose, 0 included."""

from pathlib import Path

import numpy as np
import pytest
import torch

from hybrid_models.checkpoint import load_model
from hybrid_models.data import load_runs
from hybrid_models.metrics import StepErrors, reported_steps
from hybrid_models.models import build_model
from hybrid_models.selection import choose_schedule, harms, threshold_grid
from hybrid_models.training import load_config, train
from hybrid_models.training.loop import REFERENCE_EPOCH
from hybrid_models.training.tasks import RecurrentTask
from hybrid_models.training.train import select_threshold
from offline.benchmarks.toy import TOY_VESSEL, write_linear_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'


def profile(position, normalized, steps=(1, 2), rmse_u=None):
    out = {'steps': list(steps), 'position_m': list(position), 'normalized': list(normalized),
           'rmse': {'u': list(rmse_u or normalized)}}
    return out


def test_the_grid_always_holds_the_physics_alone_and_respects_the_cap():
    assert threshold_grid([0.1, 0.5, None], None) == [0.0, 0.1, 0.5, None]
    assert threshold_grid([0.1, 0.5, None], 0.3) == [0.0, 0.1, 0.3]
    assert threshold_grid([], 0.2) == [0.0, 0.2]
    with pytest.raises(ValueError, match='>= 0'):
        threshold_grid([-0.1], None)


def test_a_forecast_worse_in_position_or_state_error_at_a_reported_step_harms():
    physics = profile([1.0, 2.0], [0.1, 0.2])
    assert harms(profile([0.9, 1.9], [0.1, 0.19]), physics) == []
    assert harms(profile([0.9, 2.1], [0.1, 0.1]), physics) == ['position at step 2']
    assert harms(profile([0.9, 1.0], [0.11, 0.1]), physics) == ['state error at step 1']
    assert harms(profile([None, 1.0], [0.1, 0.1]), physics) == ['position at step 1']
    assert harms(profile([0.9, 2.1], [0.1, 0.1]), physics, until_step=1) == []
    # One state may be a little worse when the others gain more: reported, not judged.
    assert harms(profile([0.9, 1.9], [0.1, 0.19], rmse_u=[0.5, 0.5]), physics) == []


def fake_validation(errors_by_threshold):
    """evaluate(schedules): each quarter's errors come from the threshold serving it."""
    def evaluate_one(schedule):
        starts = [start for start, _ in schedule] + [float('inf')]
        served = [next(t for (_, t), e in zip(schedule, starts[1:], strict=True) if q < e)
                  for q in range(2)]
        position = [errors_by_threshold[t][0][q] for q, t in enumerate(served)]
        normalized = [errors_by_threshold[t][1][q] for q, t in enumerate(served)]
        return {'score': sum(normalized), 'profile': profile(position, normalized)}
    return lambda schedules: [evaluate_one(schedule) for schedule in schedules]


def test_the_best_admissible_threshold_is_served_and_the_physics_when_none_helps():
    physics = {'score': 0.3, 'profile': profile([1.0, 2.0], [0.1, 0.2])}
    table = {0.0: ([1.0, 2.0], [0.1, 0.2]),
             0.1: ([0.9, 1.8], [0.09, 0.15]),
             # Better on the score, but worse in the first quarter: refused.
             0.5: ([1.1, 1.0], [0.11, 0.05])}
    chosen = choose_schedule(fake_validation(table), [0.0, 0.1, 0.5], physics, dt=1.0)
    assert chosen['relative_threshold'] == 0.1
    assert any('position at step 1' in row['harms'] for row in chosen['candidates'])
    worse = {0.0: table[0.0], 0.1: ([1.1, 2.2], [0.2, 0.3])}
    none = choose_schedule(fake_validation(worse), [0.0, 0.1], physics, dt=1.0)
    assert none['relative_threshold'] == 0.0 and 'physics alone' in none['reason']


def test_a_correction_that_hurts_only_at_first_is_served_after_the_first_quarter():
    physics = {'score': 0.3, 'profile': profile([1.0, 2.0], [0.1, 0.2])}
    table = {0.0: ([1.0, 2.0], [0.1, 0.2]), 0.2: ([1.2, 1.0], [0.12, 0.1])}
    chosen = choose_schedule(fake_validation(table), [0.0, 0.2], physics, dt=0.5)
    assert chosen['relative_threshold'] == [[0.0, 0.0], [0.5, 0.2]]
    assert 'until 0.5 s' in chosen['reason']


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
    assert chosen['physics']['profile']['normalized']


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


def test_forecasts_at_several_thresholds_in_one_batch_are_each_thresholds_own(linear):
    cfg = load_config(SMOKE, [f'dataset={linear}'])
    model = _fitted_hybrid(linear, cfg)
    with torch.no_grad():
        model.head.bias.copy_(torch.tensor([0.3, -0.2, 0.1, 0.0, 0.05]))
    runs = load_runs(linear, 'val', TOY_VESSEL)
    task = RecurrentTask(TOY_VESSEL, runs, runs, cfg['training'], np.ones(5))
    # The physics alone, a bound that binds, none, and the physics first then a bound.
    schedules = [0.0, 0.05, None, [(0.0, 0.0), (3 * TOY_VESSEL.dt, 0.5)]]
    batched = task.validation_forecasts_at(model, schedules)
    assert len(batched) == len(schedules)
    for schedule, (pred, true, runs_of) in zip(schedules, batched, strict=True):
        with model.served_at(schedule):
            alone, alone_true, alone_runs = task.validation_forecasts(model)
        np.testing.assert_allclose(pred, alone, rtol=1e-5, atol=1e-6)
        np.testing.assert_array_equal(true, alone_true)
        np.testing.assert_array_equal(runs_of, alone_runs)
    # The thresholds did give different forecasts: the copies kept their own bounds.
    assert not np.allclose(batched[0][0], batched[1][0])
    assert not np.allclose(batched[1][0], batched[2][0])
    np.testing.assert_allclose(batched[3][0][:, :3], batched[0][0][:, :3], rtol=1e-5)


def test_a_difference_the_validation_runs_cannot_resolve_is_not_harm():
    rng = np.random.default_rng(0)
    physics_errors = rng.uniform(0.5, 1.5, (40, 2))
    noise = physics_errors + rng.normal(0.0, 0.3, (40, 2))
    noisy = noise - noise.mean(axis=0) + physics_errors.mean(axis=0) + 0.01  # a bit worse
    clearly = physics_errors + 0.2                                           # always worse
    base = profile(physics_errors.mean(axis=0), physics_errors.mean(axis=0))
    runs = np.arange(40) % 8          # five forecasts from each of eight validation runs
    per = {'position': physics_errors, 'state': physics_errors, 'run': runs}

    def judged(errors, confidence):
        return harms(profile(errors.mean(axis=0), errors.mean(axis=0)), base, None,
                     ({'position': errors, 'state': errors, 'run': runs}, per), confidence)

    assert judged(noisy, 0.95) == []
    assert judged(noisy, None) != []           # any worse mean counts without a test
    assert judged(clearly, 0.95) == ['position at step 1', 'position at step 2',
                                     'state error at step 1', 'state error at step 2']


def test_one_run_against_the_others_is_judged_by_runs_not_by_forecasts():
    # One long validation run where the correction hurts, five shorter ones where it
    # helps: 60 forecasts against 5 x 8, but six runs, and the runs decide.
    runs = np.concatenate([np.zeros(60, int), np.repeat(np.arange(1, 6), 8)])
    physics_errors = np.ones((100, 1))
    hybrid = np.concatenate([np.full(60, 1.5), np.full(40, 0.7)])[:, None]
    base = profile([1.0], [1.0], steps=(1,))
    worse = profile([hybrid.mean()], [hybrid.mean()], steps=(1,))
    pairs = ({'position': hybrid, 'state': hybrid, 'run': runs},
             {'position': physics_errors, 'state': physics_errors, 'run': runs})
    assert hybrid.mean() > 1.0
    assert harms(worse, base, None, pairs, 0.95) == []
    assert harms(worse, base, None, pairs, None) == ['position at step 1',
                                                    'state error at step 1']


def test_the_correction_scale_comes_from_the_data_when_asked_not_from_the_physics(
        linear, tmp_path):
    from hybrid_models.training.config import ConfigError

    base = [f'dataset={linear}', 'training.progress=false', 'training.selection.do_no_harm=false',
            'training.phases=[{kind: teacher, max_epochs: 1, patience: 1, lr: 0.001}]']
    train_runs = load_runs(linear, 'train', TOY_VESSEL)
    change = np.concatenate([np.diff(r.z, axis=0) for r in train_runs]).std(axis=0)
    scales = {}
    for scale in ('physics_residual', 'state_change'):
        cfg = load_config(SMOKE, base + [f'model.residual_scale={scale}'])
        out = tmp_path / scale
        train(cfg, out)
        scales[scale] = load_model(out / 'model.safetensors')[0].residual_std.numpy()
    np.testing.assert_allclose(scales['state_change'], change, rtol=1e-5)
    # The toy's physics explains its data exactly: its one-step residual is far smaller.
    assert np.all(scales['physics_residual'] < 0.1 * change)
    with pytest.raises(ConfigError, match='residual_scale'):
        load_config(SMOKE, base + ['model.residual_scale=bigger'])


def test_a_choice_judged_on_one_validation_run_says_so():
    def figures(errors, runs):
        return {'score': float(errors.mean()), 'profile': profile(errors.mean(axis=0),
                                                                  errors.mean(axis=0)),
                'per_forecast': {'position': errors, 'state': errors, 'run': runs}}

    physics_errors = np.ones((6, 2))
    better = np.full((6, 2), 0.8)
    for runs, caveat in [(np.zeros(6, int), True), (np.arange(6) % 2, False)]:
        chosen = choose_schedule(lambda schedules, r=runs: [figures(better, r)] * len(schedules),
                                 [0.0, 0.1], figures(physics_errors, runs), dt=1.0,
                                 confidence=0.95)
        assert chosen['relative_threshold'] == 0.1
        assert chosen['validation_runs'] == len(np.unique(runs))
        assert ('judged on one validation run' in chosen['reason']) == caveat
