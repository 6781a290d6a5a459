"""Smoke training end to end: every model kind trains, saves, loads and evaluates."""

from pathlib import Path
import time

import pytest

from hybrid_models.checkpoint import load_model
from hybrid_models.nets import HybridModel
from hybrid_models.training import load_config, train
from offline.benchmarks.toy import write_toy_dataset

ROOT = Path(__file__).resolve().parents[2]
SMOKE = ROOT / 'ros2_ws' / 'src' / 'hybrid_models' / 'config' / 'smoke.yaml'


@pytest.fixture(scope='module')
def toy(tmp_path_factory):
    return write_toy_dataset(tmp_path_factory.mktemp('toy'), n_runs=8, n_samples=400)


def test_smoke_hybrid_trains_both_phases_within_a_minute(toy, tmp_path):
    cfg = load_config(SMOKE, [f'dataset={toy}', 'training.progress=false'])
    start = time.monotonic()
    summary = train(cfg, tmp_path)
    assert time.monotonic() - start < 60
    assert summary['epochs'] >= 2 and summary['val']['score'] > 0
    model, config = load_model(tmp_path / 'model.safetensors')
    assert isinstance(model, HybridModel)
    assert config['dataset']['sha256'] and len(config['bound']['output_range']) == 5
    assert 'regression_coefficients' in config['physics']
    kinds = [line for line in (tmp_path / 'log.jsonl').read_text().splitlines()]
    assert '"reference"' in kinds[0] and '"teacher"' in kinds[1] and '"multistep"' in kinds[-1]
    assert config['selection']['relative_threshold'] == config['model']['relative_threshold']


@pytest.mark.parametrize('overrides', [
    ['model.kind=qlag', 'model.lags=[1, 3]'],
    ['model.kind=lstm', 'training.phases=[{kind: multistep, max_epochs: 2, patience: 2, '
                        'lr: 0.005}]'],
    ['model.relative_threshold=0.15', 'model.bound_in_training=true',
     'model.bound_mode=clamp'],
    ['model.cell=gru', 'model.relative_threshold=0.15'],
])
def test_other_kinds_train_and_evaluate(toy, tmp_path, overrides):
    cfg = load_config(SMOKE, [f'dataset={toy}', 'training.progress=false'] + overrides)
    train(cfg, tmp_path / 'run')
    from hybrid_models.cli import evaluate
    out = tmp_path / 'results'
    args = [str(tmp_path / 'run'), '--dataset', str(toy), '--out', str(out), '--horizon',
            '100', '--window', '20', '--stride', '100', '--labels', 'm', '--threads', '1']
    if 'model.relative_threshold=0.15' in overrides:
        args += ['--sweep', 'm', '--thresholds', '0.1', '0.5', '--physics-only']
    assert evaluate.main(args) == 0
    for name in ('table.md', 'results.json', 'states_over_time.png', 'trajectories.png',
                 'trajectory_error_per_minute.png'):
        assert (out / name).stat().st_size > 0, name
    assert '| m |' in (out / 'table.md').read_text()


def test_an_unknown_recurrent_cell_is_refused_in_one_line():
    from hybrid_models.training.config import ConfigError

    with pytest.raises(ConfigError, match=r"^model.cell: unknown recurrent cell 'rnn'; "
                                          r"use one of lstm, gru$"):
        load_config(SMOKE, ['model.cell=rnn'])


def test_a_hybrid_starts_from_another_hybrids_recurrent_layers(toy, tmp_path):
    import torch

    from hybrid_models.models import build_model
    from hybrid_models.training.train import WARM_START_LAYERS, warm_start

    short = [f'dataset={toy}', 'training.progress=false',
             'training.phases=[{kind: teacher, max_epochs: 1, patience: 1, lr: 0.005}]']
    cfg = load_config(SMOKE, short)
    train(cfg, tmp_path / 'first')
    first, _ = load_model(tmp_path / 'first' / 'model.safetensors')
    fresh = build_model(cfg['model'], first.spec)
    copied = warm_start(fresh, tmp_path / 'first' / 'model.safetensors')
    assert copied['layers'] == ['init', 'lstm'] and copied['tensors'] > 0
    for name, tensor in fresh.state_dict().items():
        if name.startswith(WARM_START_LAYERS):
            assert torch.equal(tensor, first.state_dict()[name]), name
    # The head is the new model's own: zero, so training starts from its physics.
    assert not fresh.head.weight.any() and not fresh.head.bias.any()
    # Trained with it, the checkpoint says so; a hybrid of another size is refused.
    summary = train(load_config(SMOKE, [
        *short, f'training.init_from={tmp_path}/first/model.safetensors']), tmp_path / 'second')
    assert summary['init_from']['path'].endswith('first/model.safetensors')
    other = build_model({**cfg['model'], 'hidden': cfg['model']['hidden'] + 1}, first.spec)
    with pytest.raises(ValueError, match='is not a hybrid of this size'):
        warm_start(other, tmp_path / 'first' / 'model.safetensors')
    gru = build_model({**cfg['model'], 'cell': 'gru'}, first.spec)
    with pytest.raises(ValueError, match='has lstm cells, this model gru cells'):
        warm_start(gru, tmp_path / 'first' / 'model.safetensors')
    lstm = build_model({**cfg['model'], 'kind': 'lstm'}, first.spec)
    with pytest.raises(ValueError, match='only a hybrid starts from another'):
        warm_start(lstm, tmp_path / 'first' / 'model.safetensors')
