"""hybrid_predictor.plans and .health: plan checks, the forecast track, diagnostics."""

import math
import re

import numpy as np
import pytest

from hybrid_predictor import health
from hybrid_predictor.plans import (
    PlanError,
    PlanLimits,
    bound_hit_fraction,
    check_plan,
    hold_latest,
    plan_controls,
    track,
)

LIMITS = PlanLimits('test_boat', {'shaft_speed': (0.0, 100.0, 'rad/s'),
                                  'rudder_port': (-0.6, 0.6, 'rad'),
                                  'rudder_stbd': (-0.6, 0.6, 'rad'),
                                  'wind_speed': (0.0, 40.0, 'm/s')})
LATEST = np.array([90.0, 0.01, 0.02, 4.0, 0.0, 1.0])
H = 5


def good_plan(**override):
    plan = {'shaft_speed': np.full(H, 80.0), 'rudder_port': np.linspace(0, 0.1, H),
            'rudder_stbd': np.linspace(0, 0.1, H)}
    plan.update(override)
    return plan


def test_actuator_plan_holds_the_latest_wind():
    out = plan_controls(good_plan(), LATEST, H, LIMITS)
    assert out.shape == (H, 6)
    np.testing.assert_array_equal(out[:, 0], 80.0)
    np.testing.assert_array_equal(out[:, 2], np.linspace(0, 0.1, H))
    np.testing.assert_array_equal(out[:, 3:], np.tile(LATEST[3:], (H, 1)))


def test_a_planned_wind_is_used_as_cos_sin_of_its_direction():
    out = plan_controls(good_plan(wind_speed=np.full(H, 7.0),
                                  wind_direction=np.full(H, -math.pi / 2)), LATEST, H, LIMITS)
    np.testing.assert_allclose(out[0, 3:], [7.0, 0.0, -1.0], atol=1e-12)


@pytest.mark.parametrize('override, message', [
    ({'shaft_speed': np.full(H - 1, 80.0)}, 'shaft_speed has 4 entries, need 5'),
    ({'rudder_port': np.array([0, 0, np.nan, 0, 0])}, 'rudder_port[2] is nan'),
    ({'rudder_stbd': np.full(H, np.inf)}, 'rudder_stbd[0] is inf'),
    ({'shaft_speed': np.full(H, 150.0)}, 'shaft_speed[0] = 150 outside [0, 100] rad/s'),
    ({'rudder_port': np.full(H, -0.7)}, 'rudder_port[0] = -0.7 outside [-0.6, 0.6] rad'),
    ({'wind_speed': np.full(H, 1e6), 'wind_direction': np.zeros(H)},
     'wind_speed[0] = 1e+06 outside [0, 40] m/s'),
    ({'wind_speed': np.full(3, 1.0)}, 'wind_speed has 3 entries'),
    ({'wind_speed': np.full(H, 5.0)}, 'wind_direction 0; give both'),
    ({'wind_direction': np.zeros(H)}, 'wind_speed has 0 entries and wind_direction 5'),
    ({'wind_speed': np.full(H, 5.0), 'wind_direction': np.full(H, np.nan)},
     'wind_direction[0] is nan'),
    ({'rudder_stbd': np.zeros(H + 2)}, 'rudder_stbd has 7 entries, need 5'),
    ({'rudder_port': 'abc'}, 'rudder_port is not a sequence of numbers'),
    ({'wind_speed': np.full(H, -1.0), 'wind_direction': np.zeros(H)}, 'wind_speed must be'),
])
def test_malformed_plans_are_refused_with_the_reason(override, message):
    with pytest.raises(PlanError, match=re.escape(message)):
        plan_controls(good_plan(**override), LATEST, H, LIMITS, index=3)


def test_plan_limits_are_the_vessels_declared_ranges_and_wind_needs_one():
    from dataclasses import replace

    from vessel_description import load_vessel

    boat = load_vessel('patrol_boat')
    limits = PlanLimits.of(boat)
    assert limits.ranges['shaft_speed'][:2] == (boat.actuator('n').low, boat.actuator('n').high)
    assert limits.ranges['rudder_stbd'][:2] == (boat.actuator('delta_stbd').low,
                                                boat.actuator('delta_stbd').high)
    assert limits.ranges['wind_speed'][:2] == boat.limits['wind_speed']
    # A vessel with wind but no declared wind range: plans may only leave the wind out.
    no_wind_range = PlanLimits.of(replace(boat, limits={k: v for k, v in boat.limits.items()
                                                        if k != 'wind_speed'}))
    plan = good_plan(wind_speed=np.full(H, 5.0), wind_direction=np.zeros(H))
    with pytest.raises(PlanError, match='declares no range for wind_speed'):
        check_plan(plan, H, no_wind_range)
    check_plan(good_plan(), H, no_wind_range)
    assert PlanLimits.of(load_vessel('snuboat')) is None   # not the plan's controls


def test_a_topic_plan_may_be_longer_than_the_horizon_but_not_ragged():
    long = {k: np.concatenate([v, v]) for k, v in good_plan().items()}
    arrays = check_plan(long, H, LIMITS, exact=False)
    assert len(arrays['shaft_speed']) == 2 * H and len(arrays['wind_speed']) == 0
    with pytest.raises(PlanError, match='need 5'):
        check_plan(long, H, LIMITS)
    with pytest.raises(PlanError, match='need at least 5'):
        check_plan(good_plan(shaft_speed=np.full(H - 1, 80.0)), H, LIMITS, exact=False)


def test_hold_latest_repeats_the_last_controls():
    out = hold_latest(LATEST, H)
    assert out.shape == (1, H, 6) and (out[0] == LATEST).all()


def test_track_is_the_metric_track_rotated_and_shifted_to_the_pose():
    from vessel_description import load_vessel

    states = np.zeros((H, 5))
    states[:, 0] = 2.0   # straight ahead at u (the metric's heading 0 is north)
    north, east, heading = track(states, (100.0, 50.0, math.pi / 2),
                                 load_vessel('patrol_boat'))
    np.testing.assert_allclose(north, 100.0, atol=1e-12)      # heading east
    np.testing.assert_allclose(east, 50.0 + 2.0 * np.arange(1, H + 1))
    np.testing.assert_allclose(heading, math.pi / 2)


def test_bound_hits_count_corrections_at_the_bound():
    physics = np.zeros((1, 4, 2))
    hybrid = np.array([[[0.1, 0.0], [0.0995, 0.0], [0.05, 0.0], [-0.1, 2.0]]])
    bound = np.array([0.1, np.inf])
    assert bound_hit_fraction(hybrid, physics, bound) == pytest.approx(3 / 4)
    assert bound_hit_fraction(hybrid, physics, np.array([np.inf, np.inf])) == 0.0


def test_health_levels_follow_what_happens_on_the_nodes_clock():
    h = health.Health(silence_error=1.5, max_age=5.0, rejection_warn_fraction=0.2)
    level, message, _ = h.report(0.0, None, 0, {})
    assert level == health.STALE and 'waiting' in message
    h.record_window('incomplete', 'state gap of 4.0 s', 0.5)
    h.record_input(0.0)   # silence counts from the first input
    h.record_input(1.0)
    level, message, _ = h.report(2.0, 1.0, 10, {})
    assert level == health.ERROR and 'no forecast for 2.0 s: state gap of 4.0 s' in message
    h.record_window('ok', '', 1.0)
    for k, ms in enumerate((5.0, 6.0, 7.0)):
        h.record_forecast(10.0 + k, ms, 0.0)
    level, message, values = h.report(12.5, 12.0, 20, {'non_finite': 2})
    assert level == health.OK and values['forecast_latency_p50_ms'] == '6.00'
    assert values['input_age_s'] == '0.50' and values['rejected_non_finite'] == '2'
    # 8 of the next 10 inputs rejected: a high rate warns.
    level, message, _ = h.report(12.9, 12.0, 22, {'non_finite': 10})
    assert level == health.WARN and '8 of 10 inputs rejected' in message
    h.record_withheld('u reaches 1e+14')
    level, message, values = h.report(12.95, 12.0, 24, {'non_finite': 10})
    assert level == health.WARN and 'u reaches 1e+14' in message
    assert values['forecasts_withheld'] == '1'
    # Silence: the age and the time since the last forecast grow with the clock.
    level, message, values = h.report(20.0, 12.0, 24, {'non_finite': 10})
    assert level == health.ERROR and 'no forecast for 8.0 s' in message
    assert 'newest state is 8.0 s old' in message and values['input_age_s'] == '8.00'
    h.record_forecast(21.0, 5.0, 0.5)
    level, message, _ = h.report(21.1, 21.0, 30, {'non_finite': 10})
    assert level == health.WARN and 'bound' in message
    h.clock_jumped(3.0)   # /clock went back: silence counts from the jump
    assert 'no forecast' not in h.report(3.5, None, 30, {'non_finite': 10})[1]
