"""The predictor on two clocks: the forecast schedule, time lines, the wall watchdog (#25)."""

import math

import numpy as np
import pytest

from hybrid_predictor import health
from hybrid_predictor.schedule import ForecastSchedule
from hybrid_predictor.time_line import TimeLines

STATE = '/boat1/odom'


# ------------------------------------------------------------------ the schedule
def forecast_count(period: float, stamps) -> int:
    schedule = ForecastSchedule(period)
    return sum(schedule.due(t) for t in stamps)


@pytest.mark.parametrize('seed', range(5))
def test_states_at_the_forecast_period_are_each_forecast_despite_jitter(seed):
    # 5 Hz states whose stamps jitter by up to 20 ms, as a loaded publisher's do: the old
    # "t - last >= period" rule skipped about half of them at a 0.2 s period.
    rng = np.random.default_rng(seed)
    stamps = 100.0 + 0.2 * np.arange(50) + rng.uniform(-0.02, 0.02, 50)
    assert forecast_count(0.2, stamps) == 50
    old_rule, last = 0, -math.inf
    for t in stamps:
        if t - last >= 0.2:
            old_rule, last = old_rule + 1, t
    assert old_rule < 45   # what the node did before: the cause of the flaky test


def test_a_longer_period_keeps_its_average_rate_and_a_gap_restarts_the_grid():
    stamps = 0.2 * np.arange(500) + np.random.default_rng(1).uniform(-0.03, 0.03, 500)
    assert forecast_count(1.0, stamps) == pytest.approx(100, abs=1)
    schedule = ForecastSchedule(1.0)
    assert schedule.due(0.0) and not schedule.due(0.5) and schedule.due(1.0)
    assert schedule.due(10.0) and not schedule.due(10.5) and schedule.due(11.0)
    assert schedule.due(5.0)   # the stamps went back: a new time line, forecast at once
    assert ForecastSchedule(0.0).due(1.0) and forecast_count(0.0, [1.0, 1.1, 1.2]) == 3


# ------------------------------------------------------------------ time lines
def test_a_steady_new_lag_takes_over_after_the_span_and_a_burst_never_does():
    lines = TimeLines(tolerance=5.0, span=5.0)
    for k in range(10):                     # live, on the node's clock
        assert not lines.state(100.0 + k, 100.2 + k)
    # A pause of 30 s: the stamps go on where they stopped, now 30 s behind the clock.
    takes = [lines.state(110.0 + k, 140.2 + k) for k in range(8)]
    assert takes.index(True) == 5           # 5 s of the node's clock after the first
    lines.take_over(145.2)
    assert lines.offset == pytest.approx(30.2) and lines.shifted()
    assert lines.on_line(120.0, 150.2) and 'stamps of /x 30.2 s behind' in lines.describe('/x')

    burst = TimeLines(tolerance=5.0, span=5.0)
    # A window that ended 30 s ago, all at once, then nothing: never followed.
    assert not any(burst.state(t, 200.0) for t in np.arange(100.0, 170.0))
    burst.expire(206.0)
    assert burst.candidate is None and burst.offset == 0.0


def test_a_late_clock_under_fast_sim_time_neither_re_anchors_nor_claims_two_sources():
    # At 20x simulated time a /clock message processed 0.4 s late puts the stamps 8 s of
    # the node's clock ahead of it: off the line for a moment of wall time only.
    lines = TimeLines(tolerance=5.0, span=5.0)
    now, wall = 1000.0, 50.0
    for k in range(40):
        now, wall = now + 1.0, wall + 0.05
        late = 8.0 if 10 <= k < 20 else 0.0
        assert not lines.state(now, now - late, wall)
    assert lines.offset == 0.0 and lines.contested_lag is None


def test_two_live_time_lines_are_reported_and_never_followed():
    lines = TimeLines(tolerance=5.0, span=2.0)
    now = 1000.0
    for _ in range(20):                     # our source and a second one 600 s behind
        now += 0.5
        assert not lines.state(now - 0.1, now)
        assert not lines.state(now - 600.0, now)
    assert lines.offset == 0.0 and lines.contested_lag == pytest.approx(600.0)


def window(**kwargs):
    from hybrid_predictor.input_window import InputWindow
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel

    topic_map = topic_map_for(load_vessel('patrol_boat'))
    return InputWindow(topic_map, 60, 1.0, max_gap=2.5, max_age=5.0, max_future=5.0,
                       restart_span=30.0, labels={'/vessel/odom': STATE}, **kwargs)


def feed(w, t, now):
    w.push('/vessel/actuators', t, {'actuator.n': 85.0, 'actuator.delta_port': 0.01,
                                    'actuator.delta_stbd': 0.01}, now)
    w.push('/vessel/wind', t, {'wind_x': 3.0, 'wind_y': 1.0}, now)
    return w.push('/vessel/odom', t, {'surge': 6.0, 'sway': 0.0, 'roll_rate': 0.0,
                                      'yaw_rate': 0.0, 'qx': 0.0, 'qy': 0.0, 'qz': 0.0,
                                      'qw': 1.0, 'pos_x': 6.0 * t, 'pos_y': 0.0}, now)


def test_a_paused_wall_clock_source_is_re_anchored_and_forecast_again():
    w = window(re_anchor_after=5.0)
    for k in range(70):
        feed(w, 1000.0 + k, 1000.1 + k)
    assert w.assemble(1069.1).ready
    # Paused 30 s: the source continues where it stopped, 30 s behind the wall clock.
    for k in range(4):
        feed(w, 1070.0 + k, 1100.1 + k)
    stale = w.assemble(1103.1)
    assert stale.status == 'stale' and 'arrived live' in stale.reason, stale.reason
    assert STATE in stale.reason          # named as the node resolved it
    for k in range(4, 8):
        feed(w, 1070.0 + k, 1100.1 + k)
    result = w.assemble(1107.2)
    assert result.ready and len(w.re_anchors) == 1, result.reason
    assert w.lines.offset == pytest.approx(30.1)


def test_a_source_restarted_on_an_older_time_line_is_followed_within_one_window():
    w = window(re_anchor_after=5.0)
    for k in range(70):
        feed(w, 5000.0 + k, 5000.1 + k)
    # Restarted with its old start time: stamps from 5000 again, the wall clock at 5100.
    ready_at = None
    for k in range(70):
        feed(w, 5000.0 + k, 5100.1 + k)
        if ready_at is None and w.assemble(5100.1 + k).ready:
            ready_at = k
    assert ready_at is not None and ready_at <= 61, ready_at   # one window of samples
    assert w.restarts == 0 and len(w.re_anchors) == 1


def test_without_re_anchoring_a_lagging_source_stays_stale():
    w = window()                           # re_anchor_after defaults to never
    for k in range(70):
        feed(w, 1000.0 + k, 1030.1 + k)
    assert w.assemble(1099.1).status == 'stale' and not w.re_anchors


# ------------------------------------------------------------------ health
def report(h, now, wall, newest=None, **kwargs):
    return h.report(now, newest, 10, {}, wall=wall, **kwargs)


def test_a_paused_source_under_sim_time_is_error_on_the_wall_clock():
    h = health.Health(silence_error=1.5, max_age=5.0, watchdog=3.0, sim_time=True,
                      state_topic=STATE)
    h.record_window('ok', '', 1.0)
    h.record_input(100.0, 10.0, state=True)
    h.record_forecast(100.0, 5.0, 0.0, 10.0)
    assert report(h, 100.0, 10.0, 100.0)[0] == health.OK
    # /clock stops with the simulator: the node's clock stands at 100 s.
    assert report(h, 100.0, 12.0, 100.0)[0] == health.OK
    level, message, values = report(h, 100.0, 13.5, 100.0)
    assert level == health.ERROR, message
    assert '/clock has not moved for 3.5 s of wall time' in message
    assert f'no {STATE} accepted for 3.5 s of wall time' in message
    assert values['wall_s_since_last_state'] == '3.50'
    # It moves again and states arrive: OK at once.
    h.record_input(101.0, 40.0, state=True)
    h.record_forecast(101.0, 5.0, 0.0, 40.0)
    assert report(h, 101.0, 40.1, 101.0)[0] == health.OK


def test_on_the_wall_clock_staleness_is_said_once_not_twice():
    h = health.Health(silence_error=1.5, max_age=5.0, watchdog=3.0)
    h.record_window('stale', 'old', 1.0)
    h.record_input(100.0, 100.0, state=True)
    level, message, _ = report(h, 106.0, 106.0, 100.0)
    assert level == health.ERROR and 'inputs stale' in message
    assert 'wall time' not in message and '/clock' not in message


def test_two_clock_publishers_a_shifted_line_and_an_unbounded_model_are_named():
    h = health.Health(silence_error=1.5, max_age=5.0, watchdog=3.0, sim_time=True,
                      state_topic=STATE, unbounded='model m is served unbounded')
    h.record_window('ok', '', 1.0)
    h.record_input(100.0, 10.0, state=True)
    h.record_forecast(100.0, 5.0, 0.0, 10.0)
    level, message, values = report(h, 100.0, 10.0, 100.0,
                                     clock_publishers=['/boat1/simulator', '/x/simulator'])
    assert level == health.ERROR and '2 publishers on /clock (/boat1/simulator, ' \
        '/x/simulator)' in message and values['clock_publishers'] == '2'
    assert 'served unbounded' in message

    lines = TimeLines(tolerance=5.0, span=1.0)
    for k in range(4):
        lines.state(70.0 + k, 100.0 + k)
    lines.take_over(103.0)
    h.record_input(103.5, 13.5, state=True)
    h.record_forecast(103.5, 5.0, 0.0, 13.5)
    level, message, values = report(h, 104.0, 14.0, 73.5, lines=lines)
    assert level == health.WARN, message
    assert f"stamps of {STATE} 30.0 s behind the node's clock, followed for 1 s" in message
    assert values['clock_offset_s'] == '30.00' and values['re_anchors'] == '1'
    assert values['input_age_s'] == '0.50'
    lines.contested_lag = 630.0
    level, message, _ = report(h, 104.0, 14.0, 73.5, lines=lines)
    assert level == health.ERROR and f'two time lines on {STATE}: live samples 600.0 s' \
        in message


def test_wind_speed_beyond_the_vessel_limit_is_implausible():
    from hybrid_predictor.plausibility import Plausibility
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel

    check = Plausibility(topic_map_for(load_vessel('patrol_boat')), 0.01).check
    assert check('/vessel/wind', {'wind_x': 3.0, 'wind_y': 4.0}, 'base_link') is None
    reason, message = check('/vessel/wind', {'wind_x': 1e6, 'wind_y': 0.0}, 'base_link')
    assert reason == 'implausible' and 'wind speed = 1e+06 outside' in message
