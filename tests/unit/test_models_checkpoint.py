"""Checkpoints: round trip, and refusal of files that are not ours."""

import pickle

import numpy as np
import pytest
import torch

from hybrid_models.checkpoint import (
    CheckpointError,
    load_checkpoint,
    load_model,
    read_header,
    restore_optimizer,
    save_checkpoint,
)
from hybrid_models.models import build_model
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')

CFG = {'kind': 'hybrid', 'hidden': 8, 'layers': 2, 'dropout': 0.0,
       'physical': {'kind': 'hyd', 'masks': 'coupled'}, 'relative_threshold': 0.15}


def saved_hybrid(path):
    model = build_model(CFG, SHIP)
    with torch.no_grad():
        model.physical.weight.normal_(std=0.01)
        model.output_range.copy_(torch.arange(1.0, 6.0))
    model.set_threshold(0.15)
    save_checkpoint(path, model, {'model': model.describe(), 'vehicle': SHIP.to_dict(),
                                  'metrics': {'x': 1.5}})
    return model


def test_round_trip_restores_weights_buffers_and_config(tmp_path):
    model = saved_hybrid(tmp_path / 'm.safetensors')
    loaded, cfg = load_model(tmp_path / 'm.safetensors')
    assert cfg['metrics'] == {'x': 1.5}
    assert loaded.relative_threshold == 0.15
    for key, value in model.state_dict().items():
        assert torch.equal(value, loaded.state_dict()[key]), key
    assert torch.allclose(loaded.bound, 0.15 * torch.arange(1.0, 6.0) / 2)
    zw, cw, cf = torch.randn(2, 5, 5), torch.randn(2, 5, 6), torch.randn(2, 7, 6)
    model.eval()
    with torch.no_grad():
        assert torch.equal(model.forecast(zw, cw, cf), loaded.forecast(zw, cw, cf))


def test_optimizer_state_round_trip(tmp_path):
    model = build_model({'kind': 'lstm', 'hidden': 4}, SHIP)
    opt = torch.optim.Adam(model.parameters(), lr=0.01)
    model.forecast(torch.randn(2, 3, 5), torch.randn(2, 3, 6),
                   torch.randn(2, 4, 6)).sum().backward()
    opt.step()
    save_checkpoint(tmp_path / 'l.safetensors', model, {'model': model.describe()}, opt)
    opt2 = torch.optim.Adam(model.parameters(), lr=0.5)
    restore_optimizer(opt2, load_checkpoint(tmp_path / 'l.safetensors'))
    assert opt2.param_groups[0]['lr'] == 0.01
    for p in model.parameters():
        assert torch.equal(opt.state[p]['exp_avg'], opt2.state[p]['exp_avg'])


class Boom:
    def __reduce__(self):
        return (print, ('pwned',))


@pytest.mark.parametrize('content', [
    pickle.dumps({'model': Boom()}),
    np.random.default_rng(0).bytes(4096),
    b'',
    b'\x10\x00\x00\x00\x00\x00\x00\x00{"a": 1}        ',
])
def test_foreign_files_are_refused_with_one_line(tmp_path, content, capsys):
    path = tmp_path / 'evil.safetensors'
    path.write_bytes(content)
    with pytest.raises(CheckpointError) as info:
        load_model(path)
    message = str(info.value)
    assert 'not a hybrid_models checkpoint' in message and '\n' not in message
    assert 'pwned' not in capsys.readouterr().out


def test_torch_save_file_is_refused(tmp_path):
    path = tmp_path / 'model.pt'
    torch.save({'w': torch.zeros(3)}, path)
    with pytest.raises(CheckpointError, match='not a hybrid_models checkpoint'):
        read_header(path)


def test_truncated_checkpoint_is_refused(tmp_path):
    saved_hybrid(tmp_path / 'm.safetensors')
    data = (tmp_path / 'm.safetensors').read_bytes()
    (tmp_path / 'cut.safetensors').write_bytes(data[:len(data) // 2])
    with pytest.raises(CheckpointError):
        load_model(tmp_path / 'cut.safetensors')


def test_evaluate_cli_refuses_a_hostile_file_with_one_line(tmp_path, capsys):
    from hybrid_models.cli import evaluate
    path = tmp_path / 'model.safetensors'
    path.write_bytes(pickle.dumps({'model': Boom()}))
    assert evaluate.main([str(path), '--dataset', str(tmp_path), '--out',
                          str(tmp_path / 'o')]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'not a hybrid_models checkpoint' in err[0]
