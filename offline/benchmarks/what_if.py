"""
A planner's what-if in the predictor's own code, stage by stage (no DDS): many plans at once.

A ``PredictorCore`` of the model is fed a run of its vessel as its input callbacks would
be (their channels, without the messages, so a vessel's own message types need not be
built): simulated with the actuators held mid-range, or, for a vessel the simulator has
no physics for (the snuboat), the first rows of the longest test run of a recording
(``dataset``). Then it is asked ``what_if`` for ``plans`` plans of ``steps`` steps, each
actuator drawn at random each step within a tenth of its range of its mid-range (a
planner's candidates about its operating point; over the whole range, per-second draws
make the default model's forecasts diverge for four plans in ten, which the predictor
withholds) (the request a sampling planner sends: 1,000 plans x 100 steps). Timed,
median of ``repeats``: the whole answer (plan checks, the forecast with the wind held
over the earth, the published frames and bands, the Forecast messages) and its stages,
with the engine's single pass over the batch as the compute alone; and the request's
reading and the answer's writing and serialization, as the door does them (in C: the
plans as records, the answer from the batch's arrays) and as they were done before
(rosidl's Python messages).
What DDS adds on top is the soak's to measure.
"""

from __future__ import annotations

import time

import numpy as np

SECONDS = 80   # simulated samples fed: a full window and some


def _median_ms(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        fn()
        times.append(time.perf_counter() - started)
    return round(1e3 * float(np.median(times)), 1)


def mid_range(vessel) -> dict[str, float]:
    """Return each actuator's middle of its range, in its unit."""
    return {name: 0.5 * (vessel.actuator(name).low + vessel.actuator(name).high)
            for name in vessel.actuator_names}


def fed_samples(vessel, dataset=None) -> list[dict]:
    """
    Return the SECONDS samples fed to the core: simulated, or a recording's (see module doc).

    Each sample maps 't' (s), the states, the pose and the actuators to floats.
    """
    if dataset is None:
        from vessel_physics.errors import ConfigError
        from vessel_physics.simulation.config import load_simulation
        from vessel_physics.simulation.simulator import Simulator
        try:
            sim = Simulator(load_simulation(vessel=vessel.name), n_runs=1, seed=3)
        except ConfigError as exc:
            raise SystemExit(f'what-if: {exc}; give a recording of it (--what-if-dataset)'
                             ) from None
        held = mid_range(vessel)
        samples = [sim.sample()]
        for _ in range(SECONDS - 1):
            samples.append(sim.advance(held))
        return [{k: float(v[0]) for k, v in sample.items()} for sample in samples]
    from vessel_datasets.format import DatasetError, read_dataset
    try:
        recording = read_dataset(dataset)
        recorded = recording.vessel.name
    except DatasetError as exc:
        raise SystemExit(f'what-if: {exc}') from None
    if recorded != vessel.name:
        raise SystemExit(f'what-if: {dataset} is a recording of {recorded!r}; the model '
                         f'serves {vessel.name!r}')
    runs = [recording.load(run) for run in recording.run_ids('test')]
    if not runs:
        raise SystemExit(f'what-if: {dataset} has no test run to feed the predictor')
    return max(runs, key=len).iloc[:SECONDS].to_dict('records')


def candidate_plans(vessel, plans: int, steps: int, seed: int = 0) -> list:
    """
    Return a planner's ``plans`` ControlPlans of ``steps`` steps about the mid-range.

    Each actuator is drawn at random each step within a tenth of its range of the middle
    of its range (see module doc).
    """
    from hybrid_predictor.plan_message import control_plan

    rng = np.random.default_rng(seed)
    middles = mid_range(vessel)
    columns = [(middles[a], 0.1 * (vessel.actuator(a).high - vessel.actuator(a).low))
               for a in vessel.actuator_names]
    return [control_plan(vessel, np.column_stack([
        rng.uniform(mid - spread, mid + spread, steps) for mid, spread in columns]))
        for _ in range(plans)]


def what_if_stages(model, plans: int, steps: int, repeats: int = 5, dataset=None) -> dict:
    """
    Return the what-if's figures for ``plans`` plans of ``steps`` steps (ms, medians).

    Under the node's malloc settings (``vessel_ros_bridge.allocator``; its line is
    returned as ``malloc``): a large answer is written into the pages they keep warm.
    """
    from vessel_ros_bridge.allocator import share_malloc_arenas

    malloc = share_malloc_arenas()
    from rclpy.serialization import deserialize_message, serialize_message
    from what_if_c.door import read_request, response_cdr

    from hybrid_models.engine import Forecaster
    from hybrid_predictor.core import PredictorCore
    from hybrid_predictor.forecast_messages import followed, forecast_batch
    from hybrid_predictor.forecasting import forecast, plan_futures
    from hybrid_predictor.plans import check_plan_messages
    from hybrid_predictor.re_forecast import predictor_defaults
    from hybrid_predictor_interfaces.srv import Predict
    from vessel_datasets.topic_map import topic_map_for
    from vessel_datasets.topic_messages import channel_values

    engine = Forecaster.from_checkpoint(model)
    vessel = engine.spec
    topic_map = topic_map_for(vessel)
    p = dict(predictor_defaults(), horizon=steps, max_plans=max(plans, 1))
    core = PredictorCore(engine, vessel, topic_map, p, {t: t for t in topic_map.topics},
                         sim_time=False)
    leaves = {t: [leaf.channel for leaf in topic_map.leaves() if leaf.topic == t]
              for t in topic_map.topics}
    for values in fed_samples(vessel, dataset):
        channels = channel_values(values, topic_map)
        for topic, names in leaves.items():
            core.push(topic, values['t'], {name: channels[name] for name in names},
                      values['t'], 'odom', time.monotonic())
    now = values['t']
    # The plans as the door gives them: records read in C from the request's bytes.
    request_cdr = serialize_message(Predict.Request(plans=candidate_plans(vessel, plans,
                                                                          steps)))
    requests = read_request(request_cdr).plans
    engine.warm_up(steps, window=engine.window, max_batch=plans)
    with core.lock:
        result = core.assemble(now)
    matrices = check_plan_messages(requests, steps, core.limits)
    futures = plan_futures(vessel, matrices, result.controls[-1])
    batch_controls = np.concatenate([f.controls for f in futures])
    ok, why, batch, withheld = core.what_if(requests, 0.0, now)
    if not ok:
        raise RuntimeError(f'what-if refused: {why}')
    _, _, arrays = forecast(engine, vessel, result, futures)
    messages = batch.messages()
    answer = Predict.Response(success=True, message=why, forecasts=messages, withheld=withheld)
    return {
        'plans': plans, 'steps': steps, 'model': engine.model_id, 'malloc': malloc,
        'plans_withheld': sum(bool(w) for w in withheld),
        'request_kb': round(len(request_cdr) / 1e3, 1),
        'answer_kb': round(len(response_cdr(why, withheld, batch)) / 1e3, 1),
        'answer_ms': _median_ms(lambda: core.what_if(requests, 0.0, now), repeats),
        'stages_ms': {
            'request read in C into records (as the door does, with its CDR)': _median_ms(
                lambda: read_request(request_cdr), repeats),
            'before: request read into rosidl messages': _median_ms(
                lambda: deserialize_message(request_cdr, Predict.Request), repeats),
            'plan checks': _median_ms(lambda: check_plan_messages(requests, steps,
                                                                  core.limits), repeats),
            'forecast, wind held over the earth, frames and bands':
                _median_ms(lambda: forecast(engine, vessel, result, futures), repeats),
            'Forecasts as arrays': _median_ms(lambda: forecast_batch(
                core.served, result.t_end, arrays, [followed(r) for r in requests]), repeats),
            'answer written in C and serialized (what the door sends)': _median_ms(
                lambda: response_cdr(why, withheld, batch), repeats),
            'before: Forecast messages in Python': _median_ms(batch.messages, repeats),
            'before: their answer converted and serialized': _median_ms(
                lambda: serialize_message(answer), repeats),
        },
        'engine_one_pass_ms': _median_ms(
            lambda: engine.forecast(result.states, result.controls, batch_controls), repeats),
    }
