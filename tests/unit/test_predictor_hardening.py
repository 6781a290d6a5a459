"""hybrid_predictor: absurd inputs, future stamps and restarted sources (no ROS)."""

import math

import numpy as np
import pytest

from hybrid_predictor.input_window import REJECTIONS, InputWindow
from hybrid_predictor.plausibility import Plausibility
from vessel_datasets.topic_map import topic_map_for
from vessel_description import VesselError, load_vessel, parse_vessel

from .test_predictor_window import SCALAR_MAP, actuators, state_at

BOAT = load_vessel('patrol_boat')
ODOM = '/vessel/odom'


def odom_values(u=6.0, v=0.1, q=(0.0, 0.0, 0.0, 1.0)):
    """Channels of one patrol-boat odometry message (FLU twist, ENU quaternion)."""
    return {'surge': u, 'sway': -v, 'roll_rate': 0.0, 'yaw_rate': 0.0,
            'qx': q[0], 'qy': q[1], 'qz': q[2], 'qw': q[3], 'pos_x': 0.0, 'pos_y': 0.0}


def roll_quaternion(phi):
    return (math.sin(phi / 2), 0.0, 0.0, math.cos(phi / 2))


@pytest.mark.parametrize('values, frame, reason, text', [
    (odom_values(u=1e6), 'odom', 'implausible', 'u = 1e+06 outside the vessel limits'),
    (odom_values(v=4.5), 'odom', 'implausible', 'v = 4.5 outside'),   # FLU -v is FRD v
    (odom_values(q=(0.0, 0.0, 0.0, 7.0)), 'odom', 'bad_quaternion', 'norm 7'),
    (odom_values(q=(0.0, 0.0, 0.0, 0.0)), 'odom', 'bad_quaternion', 'norm 0'),
    (odom_values(q=roll_quaternion(1.2)), 'odom', 'implausible', 'phi = 1.2 outside'),
    (odom_values(), '', 'no_frame_id', 'empty header.frame_id'),
    ({'actuator.n': 1e4}, '', 'implausible', 'n = 10000 outside'),
    ({'actuator.delta_port': -1.0}, None, 'implausible', 'delta_port = -1 outside'),
])
def test_absurd_finite_samples_are_named(values, frame, reason, text):
    check = Plausibility(topic_map_for(BOAT), quaternion_tolerance=0.01)
    topic = ODOM if 'surge' in values else '/vessel/actuators'
    got = check.check(topic, values, frame)
    assert got is not None and got[0] == reason and text in got[1], got


def test_plausible_samples_pass_including_a_rounded_quaternion():
    check = Plausibility(topic_map_for(BOAT), quaternion_tolerance=0.01)
    q = np.array(roll_quaternion(0.3)) * 1.004
    assert check.check(ODOM, odom_values(u=11.9, q=tuple(q)), 'odom') is None
    # Actuator messages carry no frame-dependent values: an empty frame is fine.
    assert check.check('/vessel/actuators', {'actuator.n': 100.0}, '') is None


def test_a_vessel_without_a_state_limit_is_refused_in_one_line():
    data = BOAT.to_dict()
    del data['limits']['r']
    vessel = parse_vessel(data, 'no_r.yaml')
    with pytest.raises(VesselError, match=r"limits lack \['r'\]"):
        Plausibility(topic_map_for(vessel), quaternion_tolerance=0.01)


def window_with_checks(**kw):
    args = dict(max_gap=2.5, max_age=5.0, max_future=2.0, restart_span=10.0)
    args.update(kw)
    return InputWindow(SCALAR_MAP, window=60, dt=1.0,
                       plausibility=Plausibility(SCALAR_MAP, 0.01), **args)


def push_all(window, t, now):
    for topic, values in (('/state', dict(state_at(t), surge=6.0)),   # u within limits
                          ('/act', actuators(n=90.0, delta_port=0.01, delta_stbd=0.02)),
                          ('/wind', {'wind_speed': 3.0, 'wind_from_angle': 0.0})):
        window.push(topic, t, values, now=now, frame_id='f')


def fill(window, t0, t1):
    for t in np.arange(t0, t1 + 1e-9, 1.0):
        push_all(window, float(t), now=float(t))


def test_rejections_are_counted_per_reason_and_never_used():
    window = window_with_checks()
    fill(window, 0.0, 100.0)
    before = window.assemble(now=100.0)
    assert window.push('/state', 100.5, dict(state_at(100.5), surge=1e6), now=100.5,
                       frame_id='f')
    assert window.push('/state', 100.6, state_at(100.6), now=100.6, frame_id='')
    counts = window.rejected_counts()
    assert set(counts) == set(REJECTIONS)
    assert counts['implausible'] == 1 and counts['no_frame_id'] == 1
    assert sum(counts.values()) == 2
    np.testing.assert_array_equal(window.assemble(now=100.0).states, before.states)


def test_a_future_stamp_is_rejected_and_good_data_goes_on():
    window = window_with_checks()
    fill(window, 0.0, 100.0)
    reason = window.push('/state', 100.0 + 1e6, state_at(101.0), now=100.5, frame_id='f')
    assert 'ahead of the clock' in reason
    assert window.streams['/state'].counts.future == 1
    for t in (101.0, 102.0):
        push_all(window, t, now=t)
    result = window.assemble(now=102.0)
    assert result.ready and result.t_end == 102.0


def test_a_restarted_source_resets_the_window_instead_of_being_shut_out():
    window = window_with_checks()
    fill(window, 4000.0, 4600.0)
    # The source restarts from its start time; the node's clock went back with it.
    for k in range(61):
        push_all(window, 1000.0 + k, now=1000.0 + k)
    assert window.restarts == 1
    assert window.rejected_counts()['out_of_order'] == 0
    result = window.assemble(now=1060.0)
    assert result.ready and result.t_end == 1060.0


def test_an_old_sample_from_a_live_source_is_out_of_order_not_a_restart():
    window = window_with_checks()
    fill(window, 0.0, 100.0)
    # 99 s older than the newest but also 99 s old by the clock: a replayed message.
    assert 'older than the last' in window.push('/state', 1.0, state_at(1.0), now=100.0,
                                                 frame_id='f')
    assert window.restarts == 0 and window.assemble(now=100.0).ready


def test_configure_refuses_non_positive_spans():
    with pytest.raises(ValueError, match='positive'):
        window_with_checks(restart_span=0.0)


def test_a_forecast_outside_the_limits_or_not_finite_is_withheld():
    from hybrid_predictor.plausibility import forecast_problem

    good = np.tile([6.0, 0.1, 0.0, 0.01, 0.02], (1, 900, 1))
    track = (np.zeros(900), np.zeros(900), np.zeros(900))
    assert forecast_problem(good, track, BOAT) is None
    absurd = good.copy()
    absurd[0, 500, 0] = 7e14
    assert 'u reaches 7e+14, outside the vessel limits [-3, 12]' in \
        forecast_problem(absurd, track, BOAT)
    assert forecast_problem(good, (np.full(900, np.nan),) * 3, BOAT) == 'non-finite values'


def test_a_batch_is_judged_as_each_of_its_forecasts_alone():
    from hybrid_predictor.plausibility import forecast_problem, forecast_problems

    hybrid = np.tile([6.0, 0.1, 0.0, 0.01, 0.02], (5, 900, 1))
    track = [np.zeros((5, 900)) for _ in range(3)]
    hybrid[1, 500, 0] = 7e14                 # a state beyond its limits
    hybrid[2, 10, 3] = np.nan                # a non-finite state
    track[1][3, 899] = np.inf                # a non-finite track
    hybrid[4, 0, 1] = -np.inf
    alone = [forecast_problem(hybrid[i], tuple(a[i] for a in track), BOAT) for i in range(5)]
    assert alone[0] is None and all(alone[1:])
    assert forecast_problems(hybrid, tuple(track), BOAT) == alone
    assert forecast_problems(hybrid, (*track, np.zeros(0)), BOAT) == alone   # no z


QUAD_TOPICS = {
    'body_velocity': {'frame': 'flu', **{name: {'topic': '/quad/odom', 'field': field}
                                         for name, field in (
        ('surge', 'twist.twist.linear.x'), ('sway', 'twist.twist.linear.y'),
        ('heave', 'twist.twist.linear.z'), ('roll_rate', 'twist.twist.angular.x'),
        ('pitch_rate', 'twist.twist.angular.y'), ('yaw_rate', 'twist.twist.angular.z'))}},
    'attitude': {'frame': 'enu_flu',
                 'quaternion': {'topic': '/quad/odom', 'field': 'pose.pose.orientation'}},
    'position': {'frame': 'enu', 'point': {'topic': '/quad/odom', 'field': 'pose.pose.position'}},
    'actuators': {f'm{i}': {'topic': '/quad/rotors', 'field': f'velocity[m{i}]'}
                  for i in range(1, 5)},
}


def test_a_six_dof_vehicles_heave_pitch_rate_and_pitch_are_held_to_its_limits():
    from vessel_datasets.topic_map import parse_topic_map
    from vessel_physics import frames

    quad = load_vessel('crazyflie_brushless')
    check = Plausibility(parse_topic_map(QUAD_TOPICS, quad), quaternion_tolerance=0.01).check
    assert check('/quad/odom', {'heave': 5.9, 'pitch_rate': 29.0}, 'odom') is None
    # FLU heave up 7 m/s is w = -7 in FRD, below the limit -6.
    reason, text = check('/quad/odom', {'heave': 7.0}, 'odom')
    assert reason == 'implausible' and text.startswith('/quad/odom: w = -7')
    reason, text = check('/quad/odom', {'pitch_rate': -31.0}, 'odom')
    assert reason == 'implausible' and 'q = 31' in text
    # An orientation pitched 1.5 rad nose up (FRD theta; limits +-1.45) is absurd.
    q = dict(zip(('qx', 'qy', 'qz', 'qw'), frames.orientation_ned_to_enu(0.0, 0.3, 1.5),
                 strict=True))
    reason, text = check('/quad/odom', q, 'odom')
    assert reason == 'implausible' and 'theta = 1.5' in text
    q = dict(zip(('qx', 'qy', 'qz', 'qw'), frames.orientation_ned_to_enu(0.2, 0.3, 1.2),
                 strict=True))
    assert check('/quad/odom', q, 'odom') is None
