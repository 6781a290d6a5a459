"""hybrid_predictor.plans and .health: plan checks, the forecast track, diagnostics."""

import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from hybrid_predictor import health
from hybrid_predictor.plans import (
    PlanError,
    PlanLimits,
    answer_steps,
    answer_stride,
    bound_hit_fraction,
    check_plan,
    check_plan_messages,
    hold_latest,
    plan_controls,
    track,
)
from vessel_description import load_vessel

H = 5
PATROL = load_vessel('patrol_boat')
LIMITS = PlanLimits.of(PATROL)
LATEST = np.array([90.0, 0.01, 0.02, 4.0, 0.0, 1.0])
ACTUATORS = ['n', 'delta_port', 'delta_stbd']
ACTUATOR_UNITS = ['rad/s', 'rad', 'rad']


def actuator_rows(n=80.0):
    return np.column_stack([np.full(H, n), np.linspace(0, 0.1, H), np.linspace(0, 0.1, H)])


def planned(names=None, units=None, values=None, limits=LIMITS, **kwargs):
    names = ACTUATORS if names is None else names
    units = ACTUATOR_UNITS if units is None else units
    values = actuator_rows() if values is None else values
    return check_plan(names, units, values, H, limits, **kwargs)


def test_an_actuator_plan_holds_the_latest_wind():
    out = plan_controls(planned(), LATEST)
    assert out.shape == (H, 6)
    np.testing.assert_array_equal(out[:, 0], 80.0)
    np.testing.assert_array_equal(out[:, 2], np.linspace(0, 0.1, H))
    np.testing.assert_array_equal(out[:, 3:], np.tile(LATEST[3:], (H, 1)))


def test_columns_in_any_order_land_in_the_vessels_order_with_a_planned_wind():
    wind = np.tile([7.0, 0.0, -1.0], (H, 1))     # 7 m/s from port
    names = ['wind_dir_sin', 'delta_stbd', 'wind_speed', 'n', 'wind_dir_cos', 'delta_port']
    units = ['1', 'rad', 'm/s', 'rad/s', '1', 'rad']
    rows = actuator_rows()
    values = np.column_stack([wind[:, 2], rows[:, 2], wind[:, 0], rows[:, 0], wind[:, 1],
                              rows[:, 1]])
    out = plan_controls(planned(names, units, values.ravel()), LATEST)
    np.testing.assert_array_equal(out, np.column_stack([rows, wind]))


# The vessels of this repository with other controls: each plans in its own names.
OTHER_VESSELS = {
    'snuboat': (['n_port', 'n_stbd', 'delta_port', 'delta_stbd'],
                ['rad/s', 'rad/s', 'rad', 'rad'], [120.0, -60.0, 0.2, -0.1]),
    'kvlcc2_hsva': (['n', 'delta'], ['rad/s', 'rad'], [64.27, 0.6]),
}


@pytest.mark.parametrize('vessel', sorted(OTHER_VESSELS))
def test_every_vessel_plans_in_its_own_controls(vessel):
    names, units, row = OTHER_VESSELS[vessel]
    limits = PlanLimits.of(load_vessel(vessel))
    assert limits.names == tuple(names) and limits.units == tuple(units)
    out = plan_controls(check_plan(names, units, np.tile(row, H), H, limits),
                         np.zeros(len(names)))
    np.testing.assert_array_equal(out, np.tile(row, (H, 1)))
    # The patrol boat's plan is refused for it, in one line naming its controls.
    with pytest.raises(PlanError, match=re.escape(f'vessel {vessel!r}: {names[0]} [')):
        check_plan(ACTUATORS, ACTUATOR_UNITS, actuator_rows(), H, limits)


MALFORMED = [
    ({'names': []}, "no control_names; vessel 'patrol_boat' takes n [rad/s], delta_port"),
    ({'names': ['shaft_speed', 'delta_port', 'delta_stbd']},
     "['shaft_speed'] not among the controls of vessel 'patrol_boat'"),
    ({'names': ['n', 'delta_port', 'n']}, "['n'] given more than once"),
    ({'names': ['n', 'delta_port'], 'units': ['rad/s', 'rad'],
      'values': actuator_rows()[:, :2]}, "actuators ['delta_stbd'] missing"),
    ({'names': ACTUATORS + ['wind_speed'], 'units': ACTUATOR_UNITS + ['m/s'],
      'values': np.column_stack([actuator_rows(), np.full(H, 5.0)])},
     "give ['wind_speed', 'wind_dir_cos', 'wind_dir_sin'] together"),
    ({'units': ['rpm', 'rad', 'rad']}, "n in 'rpm'; vessel 'patrol_boat' declares it in "
                                       "'rad/s'"),
    ({'units': ['rad/s', 'rad']}, '2 control_units for 3 control_names'),
    ({'values': actuator_rows().ravel()[:-1]}, '14 values are not whole rows of 3 controls'),
    ({'values': actuator_rows()[:-1]}, '4 steps of 3 controls, need 5'),
    ({'values': np.vstack([actuator_rows()] * 2)}, '10 steps of 3 controls, need 5'),
    ({'values': 'abc'}, 'values is not a sequence of numbers'),
    ({'values': np.where(np.eye(H, 3, -1) > 0, np.nan, actuator_rows())},
     'n[1] is nan'),
    ({'values': actuator_rows(150.0)}, 'n[0] = 150 outside [0, 104.72] rad/s'),
    ({'values': actuator_rows() + [0, -0.9, 0]}, 'delta_port[0] = -0.9 outside'),
    ({'names': ACTUATORS + ['wind_speed', 'wind_dir_cos', 'wind_dir_sin'],
      'units': ACTUATOR_UNITS + ['m/s', '1', '1'],
      'values': np.column_stack([actuator_rows(), np.tile([50.0, 1.0, 0.0], (H, 1))])},
     'wind_speed[0] = 50 outside [0, 40] m/s'),
    ({'names': ACTUATORS + ['wind_speed', 'wind_dir_cos', 'wind_dir_sin'],
      'units': ACTUATOR_UNITS + ['m/s', '1', '1'],
      'values': np.column_stack([actuator_rows(), np.tile([5.0, 0.5, 0.5], (H, 1))])},
     '(wind_dir_cos, wind_dir_sin)[0] = (0.5, 0.5) is not a unit direction'),
]


@pytest.mark.parametrize('change, message', MALFORMED)
def test_malformed_plans_are_refused_in_one_line_with_the_reason(change, message):
    with pytest.raises(PlanError, match=re.escape(message)) as refused:
        planned(**change, index=3)
    assert str(refused.value).startswith('plan 3: ') and '\n' not in str(refused.value)


def message(names=None, units=None, values=None, step_period=0.0):
    """Return a ControlPlan-like message (the fields check_plan_message reads)."""
    values = actuator_rows() if values is None else values
    return SimpleNamespace(control_names=ACTUATORS if names is None else names,
                           control_units=ACTUATOR_UNITS if units is None else units,
                           values=values if isinstance(values, str) else
                           np.asarray(values, float).ravel(), step_period=step_period)


def test_a_request_of_many_plans_is_checked_as_each_plan_alone():
    rng = np.random.default_rng(0)
    plans = [message(values=actuator_rows(rng.uniform(0, 100))) for _ in range(6)]
    coarse = [message(values=actuator_rows(60.0)[:3], step_period=2 * PATROL.dt)] * 2
    for batch in (plans, coarse, plans[:3] + coarse):   # shared and mixed layouts
        alone = [check_plan(p.control_names, p.control_units, p.values, H, LIMITS,
                            step_period=p.step_period) for p in batch]
        for got, want in zip(check_plan_messages(batch, H, LIMITS), alone, strict=True):
            np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize(('change', 'message_'), MALFORMED)
def test_a_request_is_refused_for_its_first_malformed_plan_in_its_line(change, message_):
    plans = [message() for _ in range(4)]
    plans[2] = message(**change)
    plans[3] = message(values=actuator_rows(150.0))   # also malformed, but later
    with pytest.raises(PlanError, match=re.escape(message_)) as refused:
        check_plan_messages(plans, H, LIMITS)
    assert str(refused.value).startswith('plan 2: ')


def test_a_coarse_plan_holds_each_row_for_its_step_period():
    dt, horizon = PATROL.dt, 25
    coarse = np.column_stack([[60.0, 70.0, 80.0], [0.0, 0.1, -0.1], [0.0, 0.1, -0.1]])
    # Rows of three forecast steps each: 9 rows cover 25 steps (the last one cut).
    rows = np.repeat(np.tile(coarse, (3, 1)), 3, axis=0)[:horizon]
    out = check_plan(ACTUATORS, ACTUATOR_UNITS, np.tile(coarse, (3, 1)), horizon, LIMITS,
                     step_period=3 * dt)
    np.testing.assert_array_equal(out[:, :3], rows)
    assert out.shape == (horizon, 6) and np.isnan(out[:, 3:]).all()
    # The same plan given step by step is the same matrix.
    np.testing.assert_array_equal(out, check_plan(ACTUATORS, ACTUATOR_UNITS, rows, horizon,
                                                  LIMITS))
    # On the topic a plan may be longer: every row is expanded.
    longer = check_plan(ACTUATORS, ACTUATOR_UNITS, np.tile(coarse, (4, 1)), horizon, LIMITS,
                        exact=False, step_period=3 * dt)
    assert len(longer) == 36


@pytest.mark.parametrize('period, message', [
    (2.5, 'step_period must be 0 (every step) or a whole multiple of the forecast step '
          '1 s, got 2.5'),
    (-2.0, 'got -2.0'), (0.5, 'got 0.5'), (math.inf, 'got inf'), (math.nan, 'got nan'),
])
def test_a_step_period_off_the_forecast_steps_is_refused(period, message):
    with pytest.raises(PlanError, match=re.escape(message)) as refused:
        planned(step_period=period, index=2)
    assert str(refused.value).startswith('plan 2: step_period')


def test_a_coarse_plan_of_the_wrong_length_says_how_many_rows_it_needs():
    with pytest.raises(PlanError, match=re.escape(
            'plan 0: 2 rows of 2 s, need 3 for 5 forecast steps of 1 s')):
        planned(values=actuator_rows()[:2], step_period=2 * PATROL.dt)


def test_an_answer_carries_the_steps_ending_at_every_answer_period():
    assert answer_stride(0.0, 0.1, 900) == 1
    assert answer_stride(1.0, 0.1, 900) == 10
    np.testing.assert_array_equal(answer_steps(900, 10), np.arange(9, 900, 10))
    np.testing.assert_array_equal(answer_steps(5, 1), np.arange(5))
    with pytest.raises(PlanError, match=re.escape(
            'answer_period 0.7 s does not divide the horizon (900 steps of 0.1 s)')):
        answer_stride(0.7, 0.1, 900)
    with pytest.raises(PlanError, match='answer_period must be 0'):
        answer_stride(0.15, 0.1, 900)


def test_plan_limits_are_the_vessels_declared_ranges_and_wind_needs_one():
    from dataclasses import replace

    assert LIMITS.ranges['n'] == (PATROL.actuator('n').low, PATROL.actuator('n').high)
    assert LIMITS.ranges['wind_speed'] == PATROL.limits['wind_speed']
    # A vessel with wind but no declared wind range: plans may only leave the wind out.
    no_wind_range = PlanLimits.of(replace(PATROL, limits={
        k: v for k, v in PATROL.limits.items() if k != 'wind_speed'}))
    wind = dict(names=ACTUATORS + ['wind_speed', 'wind_dir_cos', 'wind_dir_sin'],
                units=ACTUATOR_UNITS + ['m/s', '1', '1'],
                values=np.column_stack([actuator_rows(), np.tile([5.0, 1.0, 0.0], (H, 1))]))
    with pytest.raises(PlanError, match='declares no range for wind_speed'):
        planned(**wind, limits=no_wind_range)
    assert np.isnan(planned(limits=no_wind_range)[:, 3:]).all()


def test_a_topic_plan_may_be_longer_than_the_horizon():
    long = np.vstack([actuator_rows()] * 2)
    assert planned(values=long, exact=False).shape == (2 * H, 6)
    with pytest.raises(PlanError, match='need at least 5'):
        planned(values=actuator_rows()[:-1], exact=False)


def test_hold_latest_repeats_the_last_controls():
    out = hold_latest(LATEST, H)
    assert out.shape == (1, H, 6) and (out[0] == LATEST).all()


def test_track_is_the_metric_track_rotated_and_shifted_to_the_pose():
    states = np.zeros((H, 5))
    states[:, 0] = 2.0   # straight ahead at u (the metric's heading 0 is north)
    path = track(states, (100.0, 50.0, math.pi / 2), load_vessel('patrol_boat'))
    np.testing.assert_allclose(path.north, 100.0, atol=1e-12)      # heading east
    np.testing.assert_allclose(path.east, 50.0 + 2.0 * np.arange(1, H + 1))
    np.testing.assert_allclose(path.heading, math.pi / 2)
    assert path.down is None                                      # a vessel in the plane


def test_a_six_dof_track_climbs_from_the_windows_height():
    quad = load_vessel('crazyflie_brushless')
    states = np.zeros((100, 8))
    states[:, 0], states[:, 2] = 1.0, -0.5    # forward 1 m/s, climbing 0.5 m/s (z down)
    path = track(states, (3.0, 4.0, 0.0, -1.5), quad)
    np.testing.assert_allclose(path.north, 3.0 + 0.01 * np.arange(1, 101))
    np.testing.assert_allclose(path.east, 4.0, atol=1e-12)
    np.testing.assert_allclose(path.down, -1.5 - 0.005 * np.arange(1, 101))


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


def test_a_service_that_answers_no_more_is_an_error_even_before_any_input():
    h = health.Health(silence_error=1.5, max_age=5.0)
    h.service_stopped = 'waiting for requests failed (1): error not set'
    level, message, _ = h.report(0.0, None, 0, {})
    assert level == health.ERROR
    assert message == '~/predict answers no more: waiting for requests failed (1): error not set'
    h.service_stopped = ''
    assert h.report(0.0, None, 0, {})[0] == health.STALE   # the door answers again
