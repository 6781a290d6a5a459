"""hybrid_predictor.re_forecast: a published forecast recomputed offline from its inputs."""

from types import SimpleNamespace

import numpy as np
import pytest

from hybrid_models.engine import Forecaster
from hybrid_predictor.held_wind import forecast_holding_wind
from hybrid_predictor.node import default_model_path
from hybrid_predictor.plan_message import control_plan
from hybrid_predictor.re_forecast import (
    ReForecast,
    ReForecastError,
    compare,
    predictor_defaults,
)
from hybrid_predictor_interfaces.msg import Forecast
from vessel_datasets.topic_map import topic_map_for
from vessel_datasets.topic_messages import MessageWriter, channel_values
from vessel_description import load_vessel
from vessel_physics import frames
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.simulator import Simulator
from vessel_ros_bridge import messages as m

START = 2000.0   # stamp (s) of simulated t = 0
HORIZON = 40
SECONDS = 150
T_END = 100      # the forecast's last window sample (simulated s)


@pytest.fixture(scope='module')
def run():
    """Return a short simulated run as the simulator node publishes it, and its plan."""
    vessel = load_vessel('patrol_boat')
    topic_map = topic_map_for(vessel)
    sim = Simulator(load_simulation(), n_runs=1, seed=5)
    rng = np.random.default_rng(0)
    plan = np.column_stack([rng.uniform(40.0, 100.0, SECONDS + 1),
                            rng.uniform(-0.1, 0.1, (SECONDS + 1, 2))])
    samples = [sim.sample()]
    for t in range(SECONDS):
        samples.append(sim.advance(dict(zip(vessel.actuator_names, plan[t], strict=True))))
    writer = MessageWriter(topic_map, m.message_types(topic_map), 'odom', 'base_link')
    msgs = []
    for sample in samples:
        values = {k: float(v[0]) for k, v in sample.items()}
        stamp = m.stamp_from_seconds(START + values['t'])
        channels = channel_values(values, topic_map)
        msgs += [(topic, writer.message(topic, channels, stamp)) for topic in writer.topics]
    arrays = {k: np.array([s[k][0] for s in samples]) for k in samples[0]}
    engine = Forecaster.from_checkpoint(default_model_path())
    return SimpleNamespace(vessel=vessel, topic_map=topic_map, msgs=msgs, arrays=arrays,
                           plan=plan, engine=engine)


def kept(run, skip=None):
    re_forecast = ReForecast(run.engine, run.topic_map, predictor_defaults())
    for topic, msg in run.msgs:
        if (topic, m.seconds_from_stamp(msg.header.stamp) - START) != skip:
            re_forecast.add_input(topic, msg)
    re_forecast.add_plan(control_plan(run.vessel, run.plan, plan_id='p1',
                                      stamp=m.stamp_from_seconds(START)))
    return re_forecast


def forecast_message(run, hybrid_flu, x, y, **fields):
    """Return a Forecast as the node publishes it (the fields re_forecast reads)."""
    msg = SimpleNamespace(
        header=SimpleNamespace(stamp=m.stamp_from_seconds(START + T_END)), horizon=HORIZON,
        state_names=list(run.vessel.state_names), hybrid=np.ravel(hybrid_flu), x=x, y=y, z=[],
        controls_assumed=Forecast.CONTROLS_PLAN, plan_id='p1',
        plan_stamp=m.stamp_from_seconds(START),
        model_id=run.engine.model_id, relative_threshold=0.15)
    for key, value in fields.items():
        setattr(msg, key, value)
    return msg


def test_the_offline_window_and_plan_are_the_datasets_for_the_same_run(run):
    # The same forecast cut from the simulator's arrays by the dataset convention
    # (hybrid_models.data): window z[te-59..te], controls from the plan row at te on,
    # the wind held at its last measurement over the earth (the plan names the
    # actuators only).
    a, spec = run.arrays, run.vessel
    window = slice(T_END - run.engine.window + 1, T_END + 1)
    z = np.column_stack([a[s][window] for s in spec.state_names])
    c = np.column_stack([a[s][window] for s in spec.control_names])
    future = np.tile(c[-1], (HORIZON, 1))
    future[:, :3] = run.plan[T_END:T_END + HORIZON]
    expected = forecast_holding_wind(run.engine, z, c, future[None], [True])[0].hybrid[0]

    hybrid, x, y, _ = kept(run).offline(forecast_message(run, 0, 0, 0))
    frd = frames.states_flu_to_frd(hybrid, spec.state_names)
    scale = np.abs(expected).max(axis=0) + 1e-3
    assert np.max(np.abs(frd - expected) / scale) < 1e-5
    assert np.hypot(x[0] - a['y'][T_END], y[0] - a['x'][T_END]) < 20.0   # ENU: x east


def test_a_forecast_equal_to_its_re_forecast_and_one_that_is_not(run):
    re_forecast = kept(run)
    hybrid, x, y, _ = re_forecast.offline(forecast_message(run, 0, 0, 0))
    same = forecast_message(run, hybrid, x, y)
    changed = hybrid.copy()
    changed[HORIZON // 2, 1] += 1e-3   # v, m/s
    summary = compare(re_forecast, [same])
    assert summary['compared'] == 1 and summary['equal']
    assert max(summary['max_abs_difference'].values()) == 0.0
    summary = compare(re_forecast, [same, forecast_message(run, changed, x, y)])
    assert not summary['equal']
    assert summary['max_abs_difference']['v'] == pytest.approx(1e-3, rel=1e-6)
    assert summary['max_abs_difference']['u'] == 0.0


@pytest.mark.parametrize('fields, skip, why', [
    ({'plan_stamp': m.stamp_from_seconds(START + 1)}, None, 'was not kept'),
    ({'model_id': 'other@123'}, None, 'not of'),
    ({'relative_threshold': 0.3}, None, 'relative threshold'),
    ({}, ('/vessel/odom', T_END - 10), 'a message missed'),
    ({'header': SimpleNamespace(stamp=m.stamp_from_seconds(START + 30))}, None,
     'does not reach back'),
])
def test_a_forecast_that_cannot_be_recomputed_says_why(run, fields, skip, why):
    with pytest.raises(ReForecastError, match=why):
        kept(run, skip).offline(forecast_message(run, 0, 0, 0, **fields))


def delayed(topic_map, seconds):
    """Return the topic map with surge, sway and position measured ``seconds`` late."""
    from dataclasses import replace

    late = ('surge', 'sway', 'point')
    return replace(topic_map, entries=tuple(
        replace(e, delay_s=seconds) if e.name in late else e for e in topic_map.entries))


def test_a_delayed_map_is_re_forecast_from_the_samples_up_to_its_newest_state(run):
    from hybrid_predictor.input_window import InputWindow
    from vessel_datasets.topic_messages import channel_reader

    topic_map = delayed(run.topic_map, 2.0)
    # The node: every sample up to the newest state, assembled there; the window (and
    # the forecast's stamp) ends the map's delay earlier.
    node = InputWindow.of_node(topic_map, run.engine.window, 1.0, predictor_defaults())
    newest = START + T_END + 2.0
    for topic, msg in run.msgs:
        t = m.seconds_from_stamp(msg.header.stamp)
        if t <= newest:
            node.push(topic, t, channel_reader(topic_map, topic)(msg))
    expected = node.assemble(now=newest, until=newest)
    assert expected.ready and expected.t_end == START + T_END

    re_forecast = ReForecast(run.engine, topic_map, predictor_defaults())
    for topic, msg in run.msgs:
        re_forecast.add_input(topic, msg)
    re_forecast.add_plan(control_plan(run.vessel, run.plan, plan_id='p1',
                                      stamp=m.stamp_from_seconds(START)))
    got = re_forecast.window_at(START + T_END)
    assert got.ready and got.t_end == expected.t_end
    np.testing.assert_array_equal(got.states, expected.states)
    np.testing.assert_array_equal(got.controls, expected.controls)
    assert re_forecast.offline(forecast_message(run, 0, 0, 0))[0].shape == (HORIZON, 5)


def test_samples_timed_when_sent_are_re_forecast_within_their_arrival_slack(run):
    from vessel_datasets.topic_messages import channel_reader

    exact = kept(run).offline(forecast_message(run, 0, 0, 0))[0]
    # Timed by a sender 10 ms before the node stamped them on arrival.
    sent = ReForecast(run.engine, run.topic_map, predictor_defaults())
    for topic, msg in run.msgs:
        values = channel_reader(run.topic_map, topic)(msg)
        sent.add_sample(topic, m.seconds_from_stamp(msg.header.stamp) - 0.01, values)
    sent.add_plan(control_plan(run.vessel, run.plan, plan_id='p1',
                               stamp=m.stamp_from_seconds(START)))
    np.testing.assert_allclose(sent.offline(forecast_message(run, 0, 0, 0), 0.05)[0], exact,
                               rtol=1e-6, atol=1e-9)
    with pytest.raises(ReForecastError, match='the kept states end at'):
        sent.offline(forecast_message(run, 0, 0, 0))
