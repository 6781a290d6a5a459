#!/usr/bin/env python3
r"""
Replay a held-out real flight over DDS into the running predictor; compare with offline.

Starts the installed predictor with the Crazyflie's vehicle file and a trained
checkpoint (one forecast per state message: forecast_period 0), publishes a test run of
the nanodrone dataset as the vehicle's own messages (odometry and rotor speeds, the
topics its vehicle file names) at 100 Hz, stamped on the flight's clock
(hybrid_predictor.replay), and collects /vessel/forecast. Every forecast is recomputed
offline from the messages as they were sent (hybrid_predictor.re_forecast) and the two
are compared; the node's own count of forecasts made before a state's rotor speeds
arrived says which may differ. While the flight plays it asks the what-if service for
forecasts of rotor-speed plans (the latest speeds, and a roll and a yaw command around
them) and sends a plan in rpm and one naming a rotor the craft lacks, which must be
refused. Prints one JSON document.

usage (repo root, after `make setup` and docs/results/nanodrone/run.sh):
  tools/with_env.sh python docs/results/nanodrone/replay.py \\
      --model /tmp/real/nanodrone/paper_runs/MinQ+Qua-2P/seed0/model.safetensors \\
      --dataset /tmp/real/nanodrone/paper_ds --run melon_20251017_run4
"""

import argparse
import json
from pathlib import Path
import tempfile
import time

import numpy as np

ROTORS = ('m1', 'm2', 'm3', 'm4')
VEHICLE = 'crazyflie_brushless'


def main() -> int:
    """Replay, collect, recompute, compare; print JSON."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--model', required=True, help='Crazyflie checkpoint')
    parser.add_argument('--dataset', required=True, help='the nanodrone dataset')
    parser.add_argument('--run', required=True, help='a test run of it')
    parser.add_argument('--seconds', type=float, default=20.0, help='how much to replay')
    args = parser.parse_args()

    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    from vessel_bringup.processes import Children, rclpy_options

    from hybrid_models.engine import Forecaster
    from hybrid_predictor.re_forecast import ReForecast, compare, predictor_defaults
    from hybrid_predictor.replay import RunReplay
    from hybrid_predictor.what_if_client import ask
    from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
    from hybrid_predictor_interfaces.srv import Predict
    from vessel_datasets.format import read_dataset
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel

    ds = read_dataset(args.dataset)
    if args.run not in ds.run_ids('test'):
        raise SystemExit(f'replay: error: {args.run} is no test run of {args.dataset} '
                         f'(test runs: {", ".join(ds.run_ids("test"))})')
    table = ds.load(args.run)
    table = table[table['t'] <= args.seconds]
    # The topics are the vehicle file's (the dataset's manifest keeps its states, not how
    # a live craft publishes them): the file the predictor is started with.
    topic_map = topic_map_for(load_vessel(VEHICLE))

    def plan(speeds, units='rad/s', names=ROTORS):
        return ControlPlan(control_names=list(names), control_units=[units] * len(names),
                           values=[float(x) for x in speeds] * 100, step_period=0.01)

    logs = Path(tempfile.mkdtemp(prefix='nanodrone_replay_'))
    with Children(logs) as children:
        predictor = children.node('hybrid_predictor', 'predictor', params={
            'model_path': str(args.model), 'vessel': VEHICLE,
            'forecast_period': 0.0})
        rclpy.init(**rclpy_options())
        node = rclpy.create_node('nanodrone_replay')
        forecasts, diagnostics = [], []
        node.create_subscription(Forecast, '/vessel/forecast', forecasts.append, 1000)
        node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics.append, 10)
        client = node.create_client(Predict, '/vessel/predictor/predict')
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        deadline = time.monotonic() + 120
        while 'compiled in' not in (logs / 'predictor.log').read_text():
            if time.monotonic() > deadline or predictor.poll() is not None:
                raise SystemExit('replay: error: the predictor did not start: '
                                 + (logs / 'predictor.log').read_text()[-1000:])
            executor.spin_once(timeout_sec=0.2)
        replay = RunReplay(node, topic_map, {'/vessel/odom': Odometry,
                                             '/vessel/actuators': JointState})
        half = len(table) // 2
        replay.play(table.iloc[:half], time.time(),
                    lambda s: executor.spin_once(timeout_sec=s))
        latest = table[list(ROTORS)].to_numpy()[half - 1]
        roll = latest * np.array([0.97, 0.97, 1.03, 1.03])    # right rotors slower
        yaw = latest * np.array([1.03, 0.97, 1.03, 0.97])     # ccw rotors faster
        answers = {}
        for name, request in (
                ('three plans', Predict.Request(plans=[plan(latest), plan(roll), plan(yaw)])),
                ('a plan in rpm', Predict.Request(plans=[plan(latest * 9.55, 'rpm')])),
                ('a rotor the craft lacks', Predict.Request(plans=[plan(
                    latest, names=('m1', 'm2', 'm3', 'm5'))]))):
            answer = ask(node, client, request, timeout=30)
            answers[name] = None if answer is None else {
                'success': answer.success, 'message': answer.message,
                'forecasts': len(answer.forecasts),
                'distinct': len({tuple(f.hybrid) for f in answer.forecasts}),
                'finite': bool(all(np.isfinite(f.hybrid).all() for f in answer.forecasts))}
        start = replay.sent[-1][0] + 0.01 if replay.sent else time.time()
        replay.play(table.iloc[half:], start, lambda s: executor.spin_once(timeout_sec=s))
        end = time.monotonic() + 3
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        status = {kv.key: kv.value for array in diagnostics[-1:] for s in array.status
                  if s.name.endswith(': forecast') for kv in s.values}
        node.destroy_node()
        rclpy.try_shutdown()
    kept = ReForecast(Forecaster.from_checkpoint(args.model), topic_map, predictor_defaults())
    for t, topic, values in replay.sent:
        kept.add_sample(topic, t, values)
    summary = compare(kept, forecasts)
    print(json.dumps({
        'run': args.run, 'replayed_s': float(table['t'].iloc[-1]),
        'states_published': len(table), 'forecasts_published': len(forecasts),
        'live_vs_offline': summary,
        'forecasts_before_sample_complete': status.get('forecasts_before_sample_complete'),
        'forecast_latency_ms': {k: status.get(k) for k in ('forecast_latency_p50_ms',
                                                           'forecast_latency_p99_ms')},
        'what_if': answers}, indent=2))
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
