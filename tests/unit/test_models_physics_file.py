"""Physical kind 'physics': a hybrid's physical part from a (nominal or augmented) physics file."""

import numpy as np
import pytest
import torch
import yaml

from hybrid_models.checkpoint import load_model, save_checkpoint
from hybrid_models.engine import Forecaster
from hybrid_models.models import build_model
from hybrid_models.physical import build_physical
from tests.unit.test_models_engine import inputs, make_model, torch_forecast
from vessel_description import load_vessel
from vessel_physics.patrol import PRO_TERMS, SIMULATOR_TERMS
from vessel_physics.patrol.family import mass_matrix
from vessel_physics.physics_file import load_physics

SHIP = load_vessel('patrol_boat')

STATES = torch.tensor([[6.0, 0.3, 0.02, -0.03, 0.04], [3.0, -0.1, 0.0, 0.01, -0.02]],
                      dtype=torch.float64)
CONTROLS = torch.tensor([[85.0, 0.03, 0.02, 8.0, 0.6, 0.8], [60.0, -0.02, -0.01, 3.0, -1.0, 0.0]],
                        dtype=torch.float64)


def physics_file(tmp_path, terms, extra=(), name='physics.yaml'):
    data = {'format': 'vessel-physics/1', 'vessel': 'nominal_vessel.yaml', 'terms': list(terms)}
    if extra:
        data['extra_terms'] = list(extra)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def physical(cfg):
    return build_physical({'substeps': 4, **cfg}, SHIP)


def test_a_physics_file_with_pro_terms_is_pro(tmp_path):
    path = physics_file(tmp_path, PRO_TERMS)
    from_file = physical({'kind': 'physics', 'physics': str(path)})
    pro = physical({'kind': 'pro'})
    assert torch.equal(from_file(STATES, CONTROLS), pro(STATES, CONTROLS))


def test_extra_terms_add_their_force_through_the_mass_matrix(tmp_path):
    surge_force = -25_000.0    # N, e.g. the added resistance of fouling at a steady speed
    plain = physical({'kind': 'physics', 'physics': str(physics_file(tmp_path, PRO_TERMS))})
    augmented = physical({'kind': 'physics', 'physics': str(physics_file(
        tmp_path, PRO_TERMS, [{'term': 'surge_bias', 'dofs': 'X', 'coefficient': surge_force,
                               'category': 'resistance'}], 'augmented.yaml'))})
    gained = augmented.derivative(STATES, CONTROLS) - plain.derivative(STATES, CONTROLS)
    minv = np.linalg.inv(mass_matrix(load_physics('nominal_vessel').params))
    expected = minv @ np.array([surge_force, 0.0, 0.0, 0.0])
    for row in gained.numpy():
        np.testing.assert_allclose(row[:4], expected, rtol=1e-9)
        assert row[4] == 0.0        # phi' = p whatever the forces


def test_needs_a_physics_file_and_names_the_key():
    with pytest.raises(ValueError, match='model.physical.physics'):
        build_physical({'kind': 'physics'}, SHIP)


def test_checkpoint_keeps_the_physics_inline(tmp_path):
    path = physics_file(tmp_path, SIMULATOR_TERMS, [
        {'term': 'surge_linear', 'dofs': 'X', 'coefficient': -900.0}])
    cfg = {'kind': 'hybrid', 'hidden': 8, 'layers': 1, 'dropout': 0.0,
           'physical': {'kind': 'physics', 'physics': str(path), 'substeps': 2}}
    torch.manual_seed(0)
    model = build_model(cfg, SHIP).eval()
    save_checkpoint(tmp_path / 'm.safetensors', model,
                    {'model': model.describe(), 'vehicle': SHIP.to_dict()})
    path.unlink()              # the checkpoint must not need the file any more
    loaded, saved_cfg = load_model(tmp_path / 'm.safetensors')
    stored = saved_cfg['model']['physical']
    assert stored['physics_source'] == str(path)
    assert stored['physics']['extra_terms'][0]['term'] == 'surge_linear'
    assert stored['physics']['parameters']['name'] == load_physics('nominal_vessel').params.name
    z, c = STATES.float(), CONTROLS.float()
    with torch.no_grad():
        assert torch.equal(model.physical(z, c), loaded.physical(z, c))


def test_compiled_engine_runs_the_physics_file(tmp_path):
    # Every simulator term (the wind's table interpolation included) and an extra term:
    # the predictor node must serve a model trained on augmented physics.
    path = physics_file(tmp_path, SIMULATOR_TERMS, [
        {'term': 'surge_bias', 'dofs': 'X', 'coefficient': -20_000.0}])
    model = make_model({'kind': 'physics', 'physics': str(path), 'substeps': 2},
                       threshold=0.15)
    z, c, future = inputs(batch=3)
    expected, expected_phys = torch_forecast(model, z, c, future, torch.float64)
    got = Forecaster.from_model(model, dtype=np.float64).forecast(z, c, future)
    np.testing.assert_allclose(got.hybrid, expected, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(got.physics, expected_phys, rtol=1e-9, atol=1e-11)


@pytest.mark.parametrize('vessel', ['otter', 'kvlcc2_hsva', 'crazyflie_brushless', 'patrol_boat'])
def test_every_familys_name_is_the_kind_of_its_model_and_refuses_another_familys(vessel):
    spec = load_vessel(vessel)
    physics = load_physics(spec.physics, spec)
    family = physics.family
    model = build_physical({'kind': family.name, 'substeps': 1}, spec)
    assert model.physics.terms == tuple(family.model_terms)
    other = next(name for name in ('mmg', 'fossen') if name != family.name)
    with pytest.raises(ValueError, match=f'not the {other} family') as info:
        build_physical({'kind': other}, spec)
    assert '\n' not in str(info.value)
