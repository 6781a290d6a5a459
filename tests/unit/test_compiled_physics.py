"""The compiled physical step trains the hybrid as torch's autograd would, faster."""

import numpy as np
import pytest
import torch

from hybrid_models.models import build_model
from vessel_description import load_vessel

KVLCC2 = load_vessel('kvlcc2_hsva')
PATROL = load_vessel('patrol_boat')
OTTER = load_vessel('otter')


def gradients(spec, physical, z, c, compiled: bool):
    torch.manual_seed(0)
    model = build_model({'kind': 'hybrid', 'hidden': 8, 'layers': 2, 'dropout': 0.0,
                         'physical': physical, 'correction_init': 'random'}, spec)
    if physical['kind'] == 'lin':
        with torch.no_grad():
            model.physical.weight[:, spec.n_control:] = 0.9 * torch.eye(spec.n_state)
    model.output_range.copy_(torch.ones(spec.n_state))
    if compiled:
        model.physical.compile()
    zw, cw, cf = (torch.as_tensor(a, dtype=torch.float32) for a in z + c)
    pred = model.forecast(zw, cw, cf)
    loss = (pred ** 2).mean()
    loss.backward()
    return pred.detach(), {n: p.grad.clone() for n, p in model.named_parameters()}


@pytest.mark.parametrize('spec, physical', [
    (KVLCC2, {'kind': 'mmg', 'substeps': 1}),
    (PATROL, {'kind': 'min', 'substeps': 2}),
    (PATROL, {'kind': 'lin'}),
    (OTTER, {'kind': 'physics', 'physics': 'otter_fossen.yaml', 'substeps': 2}),
])
def test_compiled_physics_gives_autograd_forecasts_and_gradients(spec, physical):
    rng = np.random.default_rng(1)
    base = np.array([1.0, 0.05, 0.01, 0.02, 0.03][:spec.n_state]) if spec.has_roll else \
        np.array([1.0, 0.02, 0.005])
    controls = {'kvlcc2_hsva': [64.0, 0.2], 'patrol_boat': [70.0, 0.05, 0.05, 5.0, 0.6, 0.8],
                'otter': [60.0, 50.0]}
    zw = base + 0.01 * rng.standard_normal((4, 10, spec.n_state))
    cw = np.asarray(controls[spec.name]) * (1 + 0.05 * rng.standard_normal((4, 10,
                                                                             spec.n_control)))
    cf = np.asarray(controls[spec.name]) * (1 + 0.05 * rng.standard_normal((4, 30,
                                                                             spec.n_control)))
    pred, grads = gradients(spec, physical, (zw,), (cw, cf), compiled=False)
    pred_c, grads_c = gradients(spec, physical, (zw,), (cw, cf), compiled=True)
    torch.testing.assert_close(pred_c, pred, rtol=1e-4, atol=1e-5)
    for name, g in grads.items():
        scale = g.abs().max().item()
        torch.testing.assert_close(grads_c[name], g, rtol=1e-3, atol=1e-3 * scale,
                                   msg=name)
