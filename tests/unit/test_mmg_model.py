"""The MMG standard model as the hybrid's physical part (hybrid_models.physical.mmg_model)."""

import math

import numpy as np
import pytest
import torch

from hybrid_models.engine import Forecaster
from hybrid_models.models import build_model
from hybrid_models.physical import build_physical
from vessel_description import load_vessel, parse_vessel
from vessel_physics.integrator import free_run
from vessel_physics.physics_file import load_physics

TANKER = load_vessel('kvlcc2_hsva')
W, H = 10, 30


def test_one_step_is_the_mmg_equation_of_motion():
    model = build_physical({'kind': 'mmg', 'substeps': 3}, TANKER)
    physics = load_physics('kvlcc2_hsva_mmg.yaml')
    z = np.array([[1.17, 0.02, 0.01], [1.0, -0.05, -0.03]])
    c = np.array([[64.27, 0.2], [64.27, -0.35]])   # [n rad/s, delta rad], the vessel's order
    expected = free_run(physics.derivative, z, c[:, None, :], TANKER.dt, 3)[:, -1]
    np.testing.assert_allclose(model.predict(z, c), expected, rtol=1e-12)
    rebuilt = build_physical(model.describe(), TANKER)   # as a checkpoint stores it
    np.testing.assert_allclose(rebuilt.predict(z, c), expected, rtol=1e-12)
    assert model.describe()['physics']['parameters']['name'] == 'kvlcc2_hsva_mmg'


def test_actuators_are_found_by_kind_not_position():
    data = TANKER.to_dict()
    data['actuators'] = list(reversed(data['actuators']))   # delta first, then n
    swapped = parse_vessel(data)
    z = np.array([[1.17, 0.02, 0.01]])
    ours = build_physical({'kind': 'mmg'}, TANKER).predict(z, np.array([[64.27, 0.2]]))
    theirs = build_physical({'kind': 'mmg'}, swapped).predict(z, np.array([[0.2, 64.27]]))
    np.testing.assert_allclose(theirs, ours, rtol=1e-12)


def test_subsets_and_residual_regression():
    z = np.array([[1.17, 0.0, 0.0]])
    c = np.array([[64.27, 0.0]])
    drag_only = build_physical({'kind': 'mmg', 'terms': ['inertial', 'hull']}, TANKER)
    assert drag_only.predict(z, c)[0, 0] < z[0, 0]            # no thrust: it slows down
    composite = build_physical({'kind': 'mmg+hyd'}, TANKER)
    assert composite.kind == 'mmg+hyd'


@pytest.mark.parametrize('vessel, message', [
    ('patrol_boat', 'not the mmg family'),
    ('snuboat', 'names none'),
])
def test_other_vessels_are_refused_in_one_line(vessel, message):
    with pytest.raises(ValueError, match=message) as info:
        build_physical({'kind': 'mmg'}, load_vessel(vessel))
    assert '\n' not in str(info.value)


def test_a_twin_rudder_vessel_is_refused():
    data = TANKER.to_dict()
    data['actuators'] = data['actuators'] + [{'name': 'delta2', 'kind': 'rudder',
                                               'unit': 'rad', 'range': [-0.6, 0.6]}]
    with pytest.raises(ValueError, match='one propeller and one rudder'):
        build_physical({'kind': 'mmg'}, parse_vessel(data))


def test_the_compiled_engine_forecasts_what_torch_forecasts():
    torch.manual_seed(0)
    model = build_model({'kind': 'hybrid', 'hidden': 8, 'layers': 1, 'dropout': 0.0,
                         'physical': {'kind': 'mmg', 'substeps': 2}}, TANKER)
    with torch.no_grad():
        model.state_mean.copy_(torch.tensor([1.1, 0.0, 0.0]))
        model.state_std.copy_(torch.tensor([0.1, 0.05, 0.02]))
        model.control_mean.copy_(torch.tensor([64.0, 0.0]))
        model.control_std.copy_(torch.tensor([1.0, 0.3]))
        model.residual_std.copy_(torch.tensor([1e-3, 1e-3, 1e-3]))
        model.output_range.copy_(torch.tensor([0.5, 0.3, 0.1]))
    model.set_threshold(0.1)
    model = model.eval().double()
    rng = np.random.default_rng(0)
    z = np.tile([1.15, 0.0, 0.0], (W, 1)) + rng.normal(scale=1e-3, size=(W, 3))
    c = np.tile([64.27, 0.0], (W, 1))
    future = np.tile(c[-1], (2, H, 1))
    future[1, :, 1] = math.radians(20.0)
    t = lambda a: torch.as_tensor(a, dtype=torch.float64)  # noqa: E731
    with torch.no_grad():
        expected, phys, _ = model.forecast(t(np.tile(z, (2, 1, 1))), t(np.tile(c, (2, 1, 1))),
                                           t(future), return_parts=True)
    got = Forecaster.from_model(model, dtype=np.float64).forecast(z, c, future)
    np.testing.assert_allclose(got.physics, phys.numpy(), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(got.hybrid, expected.numpy(), rtol=1e-9, atol=1e-12)
    assert got.physics[1, -1, 2] > 0.0    # 20 deg of rudder: turning to starboard
