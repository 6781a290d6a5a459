"""hybrid_predictor.core: the predictor between messages and forecasts, without a graph."""

import time
from types import SimpleNamespace

import numpy as np
import pytest
from rclpy.serialization import deserialize_message
from what_if_c.door import response_cdr

from hybrid_models.engine import Forecaster
from hybrid_predictor.core import PredictorCore
from hybrid_predictor.forecast_messages import path_message
from hybrid_predictor.health import OK, STALE
from hybrid_predictor.node import default_model_path
from hybrid_predictor.plan_message import control_plan
from hybrid_predictor.re_forecast import ReForecast, predictor_defaults
from hybrid_predictor_interfaces.msg import Forecast
from hybrid_predictor_interfaces.srv import Predict
from vessel_datasets.topic_map import topic_map_for
from vessel_datasets.topic_messages import MessageWriter, channel_reader, channel_values
from vessel_description import load_vessel
from vessel_physics.simulation.config import load_simulation
from vessel_physics.simulation.simulator import Simulator
from vessel_ros_bridge import messages as m

START = 500.0   # stamp (s) of simulated t = 0
SECONDS = 80
PLAN_FROM = 76  # the plan's first row (simulated s)
PLAN_ROWS = 1100  # more than the horizon (900 steps) after PLAN_FROM
NO_SERVICE = {'requests': 0, 'refused': 0, 'failure': ''}


@pytest.fixture(scope='module')
def run():
    """Return a simulated run as the simulator node publishes it, sample by sample."""
    vessel = load_vessel('patrol_boat')
    topic_map = topic_map_for(vessel)
    sim = Simulator(load_simulation(), n_runs=1, seed=3)
    rng = np.random.default_rng(1)
    plan = np.column_stack([rng.uniform(40.0, 100.0, PLAN_ROWS),
                            rng.uniform(-0.1, 0.1, (PLAN_ROWS, 2))])
    writer = MessageWriter(topic_map, m.message_types(topic_map), 'odom', 'base_link')
    samples = [sim.sample()]
    for t in range(SECONDS):
        samples.append(sim.advance(dict(zip(vessel.actuator_names, plan[t], strict=True))))
    msgs = []
    for sample in samples:
        values = {k: float(v[0]) for k, v in sample.items()}
        stamp = m.stamp_from_seconds(START + values['t'])
        channels = channel_values(values, topic_map)
        msgs.append([(topic, writer.message(topic, channels, stamp)) for topic in writer.topics])
    return SimpleNamespace(vessel=vessel, topic_map=topic_map, msgs=msgs, plan=plan,
                           engine=Forecaster.from_checkpoint(default_model_path()))


def fresh_core(run, **changes):
    p = dict(predictor_defaults(), **changes)
    labels = {topic: f'/vessel/{topic}' for topic in run.topic_map.topics}
    return PredictorCore(run.engine, run.vessel, run.topic_map, p, labels, sim_time=False)


def feed(core, run, samples, topics=None):
    """Push samples (indices) as the node's input callbacks do; return the jobs flagged."""
    readers = {t: channel_reader(run.topic_map, t) for t in run.topic_map.topics}
    woken = 0
    for k in samples:
        for topic, msg in run.msgs[k]:
            if topics is not None and topic not in topics:
                continue
            t = m.seconds_from_stamp(msg.header.stamp)
            reason, _ = core.push(topic, t, readers[topic](msg), t + 0.01, msg.header.frame_id,
                                  time.monotonic())
            assert not reason, reason
            if topic == core.window.state_topic:
                woken += core.state_arrived(t, time.time_ns())
            else:
                woken += core.resume_deferred()
    return woken


def test_a_state_is_forecast_as_the_offline_re_forecast_recomputes_it(run):
    core = fresh_core(run)
    assert core.report(START, time.monotonic(), None, NO_SERVICE).level == STALE
    plan = control_plan(run.vessel, run.plan[PLAN_FROM:], plan_id='p7',
                        stamp=m.stamp_from_seconds(START + PLAN_FROM))
    assert core.set_plan(plan) == ''
    assert feed(core, run, range(SECONDS - 1)) > 0
    now = START + SECONDS - 1
    job = core.next_job(lambda: now)
    assert job.synced and job.result.ready and job.pending.forecast
    outcome = core.forecast(job, now)
    msg = outcome.message
    assert outcome.withheld == '' and msg.controls_assumed == Forecast.CONTROLS_PLAN
    assert msg.plan_id == 'p7' and msg.horizon == run.vessel.horizon
    # Live = offline by construction: the re-forecast runs the same code on the messages.
    offline = ReForecast(run.engine, run.topic_map, predictor_defaults())
    for k in range(SECONDS):
        for topic, sample in run.msgs[k]:
            offline.add_input(topic, sample)
    offline.add_plan(plan)
    difference = offline.difference(msg)
    assert max(difference.states.values()) == 0.0 and difference.position_m == 0.0
    assert len(path_message(msg, 10).poses) == len(range(0, msg.horizon - 1, 10)) + 1
    report = core.report(now, time.monotonic(), None, NO_SERVICE)
    assert report.level == OK and report.values['forecasts_published'] == '1', report.message


def test_a_plan_too_old_is_not_followed_and_says_nothing(run):
    core = fresh_core(run)
    core.set_plan(control_plan(run.vessel, run.plan, plan_id='old',
                               stamp=m.stamp_from_seconds(START)))
    feed(core, run, range(SECONDS - 1))
    now = START + SECONDS - 1
    outcome = core.forecast(core.next_job(lambda: now), now)
    assert outcome.message.controls_assumed == Forecast.CONTROLS_HELD
    assert outcome.stale_plan == ''


def test_a_state_forecast_before_its_actuators_came_is_counted(run):
    core = fresh_core(run, sync_timeout=0.0)
    state = core.window.state_topic
    feed(core, run, range(SECONDS - 2))
    assert core.next_job(lambda: START + SECONDS) is not None   # the backlog's job
    assert feed(core, run, [SECONDS - 2], topics={state}) == 1
    job = core.next_job(lambda: START + SECONDS)
    assert not job.synced and job.result.ready   # the previous actuators still in reach
    core.forecast(job, START + SECONDS)
    assert core.counts['forecasts_before_sample_complete'] == 1
    # Its actuators then come: nothing was deferred, so nothing is forecast again.
    others = set(run.topic_map.topics) - {state}
    assert feed(core, run, [SECONDS - 2], topics=others) == 0


def test_what_if_refuses_in_one_line_and_answers_each_plan(run):
    core = fresh_core(run, max_plans=3)
    plan = control_plan(run.vessel, run.plan[:run.vessel.horizon])
    ok, why, out, _ = core.what_if([plan] * 4, 0.0, START)
    assert not ok and why == 'send 1 to 3 plans, got 4' and out is None
    ok, why, _, _ = core.what_if([plan], 0.0, START)
    assert not ok and why.startswith('no forecast: ')
    feed(core, run, range(SECONDS - 1))
    now = START + SECONDS - 1
    ok, why, batch, withheld = core.what_if([plan, plan], 0.0, now)
    assert ok and withheld == ['', ''], why
    out = batch.messages()
    assert [f.hybrid for f in out[:1]] == [out[1].hybrid]
    assert out[0].controls_assumed == Forecast.CONTROLS_PLAN


def test_a_plan_the_model_cannot_forecast_is_withheld_alone(run, monkeypatch):
    core = fresh_core(run)
    feed(core, run, range(SECONDS - 1))
    now = START + SECONDS - 1
    # 100 s of random orders over the whole ranges, a new one every second, then mid-range:
    # the default model's Hyd physics diverges for some of these plans (docs/predictor.md,
    # "A thousand plans").
    rng = np.random.default_rng(0)
    actuators = [run.vessel.actuator(a) for a in run.vessel.actuator_names]
    rest = run.vessel.horizon - 100
    plans = [control_plan(run.vessel, np.column_stack([
        np.concatenate([rng.uniform(a.low, a.high, 100), np.full(rest, (a.low + a.high) / 2)])
        for a in actuators])) for _ in range(8)]
    ok, why, batch, withheld = core.what_if(plans, 0.0, now)
    out = batch.messages()
    assert ok and len(out) == len(withheld) == 8, why
    bad = [i for i, w in enumerate(withheld) if w]
    assert 0 < len(bad) < 8 and f'({len(bad)} withheld; plan {bad[0]}: ' in why
    for msg, w in zip(out, withheld, strict=True):
        steps = 0 if w else run.vessel.horizon
        assert msg.horizon == steps and len(msg.hybrid) == steps * len(msg.state_names)
        assert np.isfinite(msg.hybrid).all() and msg.controls_assumed == Forecast.CONTROLS_PLAN
    # The door writes this answer in C from the batch: the answer of these messages.
    answer = Predict.Response(success=True, message=why, forecasts=out, withheld=withheld)
    assert deserialize_message(response_cdr(why, withheld, batch), Predict.Response) == answer
    monkeypatch.setattr(core, 'withheld',
                        lambda hybrid, arrays: ['non-finite values'] * len(hybrid))
    ok, why, out, withheld = core.what_if(plans[:2], 0.0, now)
    assert not ok and out is None and withheld == []
    assert why == 'every forecast withheld; plan 0: forecast withheld: non-finite values'


def test_a_clock_jump_clears_the_window_and_counts(run):
    core = fresh_core(run)
    feed(core, run, range(SECONDS - 1))
    core.clock_jumped(START)
    assert core.pending is None and core.counts['clock_resets'] == 1
    with core.lock:
        assert not core.assemble(START + SECONDS).ready


def test_a_model_served_with_the_novelty_fade_reports_the_share_of_its_bound(run):
    from hybrid_models.checkpoint import load_model, read_header
    from hybrid_models.novelty import calibrate

    path = default_model_path()
    model, _ = load_model(path)
    # Trained, as far as the fade knows, on inputs about the normalisation's centre alone.
    rng = np.random.default_rng(0)
    n = run.vessel.n_state + run.vessel.n_control
    model.novelty = calibrate(rng.normal(scale=0.05, size=(200, n)), np.empty((0, n)))
    model.novelty_fade = True
    engine = Forecaster.from_model(model, model_id='faded', config=read_header(path))
    outcomes = {}
    for name, served in (('plain', run.engine), ('faded', engine)):
        p = dict(predictor_defaults())
        labels = {topic: f'/vessel/{topic}' for topic in run.topic_map.topics}
        core = PredictorCore(served, run.vessel, run.topic_map, p, labels, sim_time=False)
        feed(core, run, range(SECONDS - 1))
        now = START + SECONDS - 1
        outcomes[name] = core.forecast(core.next_job(lambda now=now: now), now).message
    assert len(outcomes['plain'].bound_available) == 0
    msg = outcomes['faded']
    share = np.asarray(msg.bound_available)
    assert share.shape == (msg.horizon,) and ((share > 0) & (share <= 1)).all()
    assert share.min() < 0.5
    correction = np.abs(np.reshape(np.subtract(msg.hybrid, msg.physics), (msg.horizon, -1)))
    assert (correction <= share[:, None] * np.asarray(msg.residual_bound) + 1e-9).all()
