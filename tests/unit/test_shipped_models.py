"""The models hybrid_predictor ships: each serves its vessel file, chosen by the vessel."""

from pathlib import Path

import numpy as np
import pytest

from hybrid_models.engine import Forecaster
from hybrid_predictor.node import default_model_path
from hybrid_predictor.vessel_source import served_vessel
from vessel_description import load_vessel

MODELS = Path(__file__).resolve().parents[2] / 'ros2_ws/src/hybrid_predictor/models'


@pytest.mark.parametrize('folder, vessel', [('default', 'patrol_boat'),
                                            ('crazyflie_brushless', 'crazyflie_brushless')])
def test_each_shipped_model_serves_its_vessel_file_and_has_a_card(folder, vessel):
    path = MODELS / folder / 'model.safetensors'
    engine = Forecaster.from_checkpoint(path)
    spec, note = served_vessel(vessel, engine.spec, str(path))
    assert spec.name == vessel and 'vessel file' in note
    assert (MODELS / folder / 'MODEL_CARD.md').read_text().startswith('# Model card')
    z = np.zeros((engine.window, len(spec.state_names)))
    c = np.zeros((engine.window, len(spec.control_names)))
    out = engine.forecast(z, c, np.zeros((1, 5, len(spec.control_names))))
    assert out.hybrid.shape == (1, 5, len(spec.state_names)) and np.isfinite(out.hybrid).all()


def test_the_default_model_is_the_vessels_own_where_one_is_shipped():
    assert default_model_path('crazyflie_brushless').parent.name == 'crazyflie_brushless'
    assert default_model_path(str(load_vessel('crazyflie_brushless').source)
                              ).parent.name == 'crazyflie_brushless'
    assert default_model_path('otter').parent.name == 'default'
    assert default_model_path('').parent.name == 'default'
