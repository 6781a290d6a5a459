"""examples/choose_plan.py: the controller's example picks plans by distance and risk."""

import importlib.util
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from vessel_description import load_vessel

EXAMPLE = Path(__file__).resolve().parents[2] / 'examples' / 'choose_plan.py'
spec = importlib.util.spec_from_file_location('choose_plan', EXAMPLE)
choose_plan = importlib.util.module_from_spec(spec)
spec.loader.exec_module(choose_plan)

H = 4


def forecast(end, radius_50, radius_90):
    """Return the Forecast fields the example reads: a straight track to ``end``, bands."""
    track = np.linspace(0.0, 1.0, H)[:, None] * np.asarray(end, float)
    radii = np.stack([np.linspace(0, radius_50, H), np.linspace(0, radius_90, H)])
    return SimpleNamespace(horizon=H, x=track[:, 0].tolist(), y=track[:, 1].tolist(),
                           band_levels=[0.5, 0.9], band_note='',
                           band_position_radius=radii.ravel().tolist())


def test_risk_weight_trades_the_mean_miss_against_the_calibrated_radius():
    goal = (1000.0, 0.0)
    near_but_uncertain = forecast((950.0, 0.0), 40.0, 200.0)     # misses by 50 m
    far_but_sure = forecast((900.0, 0.0), 5.0, 20.0)             # misses by 100 m
    forecasts = [far_but_sure, near_but_uncertain]
    best, costs = choose_plan.choose(forecasts, goal, risk_weight=0.0)
    assert best == 1 and costs == pytest.approx([100.0, 50.0])
    best, costs = choose_plan.choose(forecasts, goal, risk_weight=1.0)
    assert best == 0 and costs == pytest.approx([120.0, 250.0])
    # The 50 % band is less cautious: the nearer plan wins again.
    best, _ = choose_plan.choose(forecasts, goal, risk_weight=1.0, level=0.5)
    assert best == 1


def test_a_forecast_without_bands_at_the_level_is_refused_with_the_reason():
    bare = SimpleNamespace(horizon=H, x=[0.0] * H, y=[0.0] * H, band_levels=[],
                           band_position_radius=[], band_note='no calibrated bands')
    with pytest.raises(ValueError, match='not at 0.9 \\(no calibrated bands\\)'):
        choose_plan.plan_cost(bare, (0.0, 0.0), 1.0)


@pytest.mark.parametrize('name', ['patrol_boat', 'snuboat', 'kvlcc2_hsva'])
def test_candidate_plans_hold_set_points_inside_each_actuators_range(name):
    vessel = load_vessel(name)
    plans = choose_plan.candidate_plans(vessel, 7, count=20, seed=1)
    assert len(plans) == 20 and all(p.shape == (7, len(vessel.actuators)) for p in plans)
    stacked = np.stack(plans)
    for i, actuator in enumerate(vessel.actuators):
        assert actuator.low <= stacked[..., i].min() and stacked[..., i].max() <= actuator.high
    assert len({tuple(p[0]) for p in plans}) == 20          # distinct candidates
