"""The hybrid and LSTM forecasters: both code paths agree, normalization is applied."""

import numpy as np
import pytest
import torch

from hybrid_models.models import build_model
from hybrid_models.normalization import Normalizer
from hybrid_models.recurrent import CELLS
from vessel_description import load_vessel

SHIP = load_vessel('patrol_boat')


def hybrid(**kw):
    torch.manual_seed(0)
    model = build_model({'kind': 'hybrid', 'hidden': 6, 'layers': 2, 'dropout': 0.0,
                         'physical': {'kind': 'lin'}, **kw}, SHIP)
    with torch.no_grad():
        model.physical.weight[:, 6:] = 0.9 * torch.eye(5)
    model.set_normalization(Normalizer(np.arange(1.0, 6.0), np.full(5, 2.0)),
                            Normalizer(np.zeros(6), np.full(6, 3.0)))
    return model.eval()


@pytest.mark.parametrize('cell', list(CELLS))
def test_teacher_forcing_equals_stepping_with_true_states(cell):
    # The fused torch module trains what the Array API step serves (hybrid_models.recurrent).
    model = hybrid(cell=cell)
    zw, cw = torch.randn(3, 7, 5), torch.randn(3, 7, 6)
    cf, z_true = torch.randn(3, 9, 6), torch.randn(3, 9, 5)
    with torch.no_grad():
        z_prev = torch.cat([zw[:, -1:], z_true[:, :-1]], dim=1)
        z_phy = torch.stack([model.physical(z_prev[:, k], cf[:, k]) for k in range(9)], 1)
        fused = model.teacher_forced(zw, cw, cf, z_phy)
        recurrent = model.start(zw, cw)
        for k in range(9):
            _, zp, res, recurrent = model.step(z_prev[:, k], cf[:, k], recurrent)
            torch.testing.assert_close(zp, z_phy[:, k])
            torch.testing.assert_close(res, fused[:, k], rtol=1e-5, atol=1e-6)


def test_multistep_feeds_predictions_back():
    model = hybrid()
    zw, cw, cf = torch.randn(2, 5, 5), torch.randn(2, 5, 6), torch.randn(2, 4, 6)
    with torch.no_grad():
        z, z_phy, res = model.forecast(zw, cw, cf, return_parts=True)
        torch.testing.assert_close(z, z_phy + res)
        torch.testing.assert_close(z_phy[:, 1], model.physical(z[:, 0], cf[:, 1]))


def test_lstm_baseline_output_is_denormalized():
    torch.manual_seed(0)
    model = build_model({'kind': 'lstm', 'hidden': 5, 'layers': 1}, SHIP).eval()
    model.set_normalization(Normalizer(np.arange(5.0), np.full(5, 10.0)),
                            Normalizer(np.zeros(6), np.ones(6)))
    with torch.no_grad():
        model.head.weight.zero_()
        model.head.bias.fill_(0.5)
        out = model.forecast(torch.randn(2, 4, 5), torch.randn(2, 4, 6), torch.randn(2, 3, 6))
    torch.testing.assert_close(out, (torch.arange(5.0) + 5.0).expand(2, 3, 5))
