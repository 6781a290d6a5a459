"""
Demo: the simulator and the predictor running together, forecasts checked against truth.

Starts the installed ``ship_sim_node simulator`` (faster than real time) and
``hybrid_predictor predictor`` (the embedded default model) as separate processes, as
``ros2 run`` would, all on DDS confined to this machine. A client listens to the
forecasts and to the simulator's noise-free state, lets forecasts mature (a 900-step
forecast needs 15 simulated minutes of truth), then prints the forecast-against-truth
RMSE per state and the trajectory error, and writes a PNG of one forecast against
what happened. Every process it starts is stopped on exit, also on Ctrl-C.

The client acts as a controller would: it steers the vessel through /vessel/cmd along a
plan of shaft-speed and rudder set-points (made by the simulator's human-like operator
model with a seed of its own) and publishes the same plan on /vessel/control_plan, so
each forecast follows the controls that are actually applied, as in the paper's
evaluation. With --no-plan the predictor assumes the latest controls hold instead.
The nodes are stopped however the demo ends (``vessel_bringup.processes``), by
SIGTERM and SIGHUP too.

Live = offline: the client also keeps what the predictor was given (its input topics as
received and the plan) and recomputes every kept forecast offline with the same
checkpoint (``hybrid_predictor.re_forecast``), reporting the largest difference per
state. ``--record DIR`` records the inputs, the plan, the forecasts and the truth into
a bag (``vessel_recorder``), which ``offline/re_forecast.py --bag DIR`` re-forecasts.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
import sys
import time

import numpy as np

from vessel_bringup.processes import Children, node_argv, rclpy_options, stop_group

STATES = ('u', 'v', 'p', 'r', 'phi')
RECORDED = ('odom', 'actuators', 'wind', 'control_plan', 'forecast', 'odom_true')
UNITS = ('m/s', 'm/s', 'rad/s', 'rad/s', 'rad')
VESSEL = 'patrol_boat'   # what the simulator sails by default and the embedded model serves
START = 1_000_000.0   # stamp of simulated t = 0 (any fixed value; keeps stamps readable)


def parse_args(argv=None):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--minutes', type=float, default=22.0,
                        help='simulated minutes to run (default 22; forecasts must mature: '
                             'more than the window plus the horizon)')
    parser.add_argument('--horizon', type=int, default=0, metavar='STEPS',
                        help="forecast steps (default 0: the vessel's, 900 one-second steps)")
    parser.add_argument('--speed-up', type=float, default=30.0,
                        help='real-time factor of the simulator (default 30)')
    parser.add_argument('--seed', type=int, default=11, help='simulation seed (default 11)')
    parser.add_argument('--evaluate-every', type=int, default=20, metavar='S',
                        help='evaluate one forecast every S simulated seconds (default 20)')
    parser.add_argument('--no-plan', action='store_true',
                        help='do not steer; forecasts assume the latest controls hold')
    # Relative to the working directory: tools/with_env.sh runs from the repository root.
    parser.add_argument('--out', type=Path, default=Path('out') / 'demo',
                        help='folder for the PNG and JSON (default out/demo)')
    parser.add_argument('--record', type=Path, metavar='DIR',
                        help='also record inputs, plan, forecasts and truth into this bag '
                             'directory (must not exist); re-forecast it with '
                             'offline/re_forecast.py --bag DIR')
    args = parser.parse_args(argv)
    # Forecasts mature after the window and the horizon of the vessel file.
    from vessel_description import load_vessel

    vessel = load_vessel(VESSEL)
    needed = vessel.window_s + (args.horizon * vessel.dt if args.horizon else vessel.horizon_s)
    if args.minutes * 60 <= needed or not 0.01 <= args.speed_up <= 1000 or \
            args.evaluate_every < 1 or args.horizon < 0:
        parser.error(f'--minutes must exceed {needed / 60:g} (window and horizon), '
                     f'--speed-up lie in [0.01, 1000], --evaluate-every be >= 1, '
                     f'--horizon >= 0')
    if args.record is not None and args.record.exists():
        parser.error(f'--record {args.record} exists; name a new directory')
    return args


def make_plan(seed: int, seconds: int) -> np.ndarray:
    """Return set-points (seconds, 3): n (rad/s), delta_port, delta_stbd (rad) per second."""
    from vessel_physics.simulation.config import load_simulation
    from vessel_physics.simulation.operator import Operator

    config = load_simulation()
    operator = Operator([np.random.default_rng(seed)], config.operator, config.vessel)
    return np.array([np.concatenate(operator.setpoints(float(t))) for t in range(seconds)])


def collect(seconds: float, speed_up: float, every: int, start_simulator,
            plan: np.ndarray | None = None, kept=None, stop_simulator=None):
    """
    Wait for the predictor, start the simulator, listen until `seconds` of truth arrived.

    With a ``plan`` the client steers the vessel along it and announces it to the
    predictor. ``kept`` (a ``hybrid_predictor.re_forecast.ReForecast``) receives what the
    predictor is given: its input messages and the plan. ``stop_simulator`` is called
    once the truth is complete, before a /diagnostics report of the predictor that counts
    every forecast heard is awaited (at most 5 s). Returns (truth by simulated
    second, kept forecasts by their start second, the stamps (s) of every forecast heard,
    the values of the predictor's newest /diagnostics status).
    """
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    import rclpy
    from sensor_msgs.msg import JointState

    from hybrid_predictor.plan_message import control_plan
    from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
    from vessel_description import load_vessel
    from vessel_ros_bridge import messages as m
    from vessel_ros_bridge.names import DEFAULT_NAMESPACE, node_topic

    rclpy.init(**rclpy_options())
    # In the nodes' namespace, so the shared relative topic names resolve as theirs do.
    node = rclpy.create_node('demo_client', namespace=DEFAULT_NAMESPACE)
    truth: dict[int, tuple] = {}
    forecasts: dict[int, Forecast] = {}
    heard: list[float] = []

    command_pub = node.create_publisher(JointState, m.COMMAND_TOPIC, 10)
    plan_pub = node.create_publisher(ControlPlan, 'control_plan', 10)

    def on_truth(msg):
        t = int(round(m.seconds_from_stamp(msg.header.stamp) - START))
        if plan is not None and 0 <= t < len(plan):
            # Set-points for the coming second; the simulator steps after this arrives.
            command_pub.publish(m.joint_state_from_actuators(
                dict(zip(('n', 'delta_port', 'delta_stbd'), plan[t], strict=True)),
                msg.header.stamp))
            if t % 10 == 0:
                plan_pub.publish(plan_message)
        state = m.state_from_odometry(msg)
        truth[t] = (np.array([state[s] for s in STATES]), msg.pose.pose.position.x,
                    msg.pose.pose.position.y)

    next_kept = [0]

    def on_forecast(msg):
        # One forecast every `every` simulated seconds, whichever states the predictor
        # forecast: at many times real time it skips states that waited as backlog, so
        # a fixed grid of start times would miss most forecasts.
        heard.append(m.seconds_from_stamp(msg.header.stamp) - START)
        t = int(round(heard[-1]))
        if t >= next_kept[0]:
            forecasts[t] = msg
            next_kept[0] = t + every

    if plan is not None:
        plan_message = control_plan(load_vessel(VESSEL), plan,
                                    stamp=m.stamp_from_seconds(START))
        if kept is not None:
            kept.add_plan(plan_message)
    if kept is not None:
        # The predictor's inputs as it receives them, with its queue depth (reliable).
        for topic, msg_class in m.message_types(kept.topic_map).items():
            node.create_subscription(msg_class, node_topic(topic),
                                     lambda msg, topic=topic: kept.add_input(topic, msg), 100)
    node.create_subscription(Odometry, m.ODOM_TRUE_TOPIC, on_truth, 100)
    node.create_subscription(Forecast, 'forecast', on_forecast, 10)
    ready = []   # the predictor's /diagnostics, the newest last
    node.create_subscription(DiagnosticArray, '/diagnostics', ready.append, 10)
    deadline = time.monotonic() + 120.0
    while not ready and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)   # the predictor compiles its model first
    if not ready:
        node.destroy_node()
        rclpy.try_shutdown()
        sys.exit('demo: error: the predictor did not come up within 120 s')
    start_simulator()
    deadline = time.monotonic() + 60.0 + 3.0 * seconds / speed_up
    last_report = 0.0
    try:
        while time.monotonic() < deadline and len(truth) < seconds:
            rclpy.spin_once(node, timeout_sec=0.1)
            if time.monotonic() - last_report > 3.0:
                print(f'  simulated {len(truth) / 60:5.1f} of {seconds / 60:.0f} min, '
                      f'{len(forecasts)} forecasts kept', file=sys.stderr, flush=True)
                last_report = time.monotonic()
        if stop_simulator is not None:
            stop_simulator()
            # Until a report counts every forecast heard: the last state's forecast can
            # be made after the simulator stopped, its actuators and wind cut off (then
            # counted as made before its sample was complete), after a report was sent.
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline and int(
                    predictor_status(ready).get('forecasts_published', 0)) < len(heard):
                rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return truth, forecasts, heard, predictor_status(ready)


def predictor_status(reports) -> dict:
    """Return the values of the predictor's newest forecast status among /diagnostics reports."""
    for array in reversed(reports):
        for status in array.status:
            if status.name.endswith(': forecast'):
                return {kv.key: kv.value for kv in status.values}
    return {}


def model_states(values, msg) -> np.ndarray:
    """Return a Forecast's states (horizon, n) in the model's FRD, as the truth is read."""
    from vessel_physics.frames import states_flu_to_frd

    return states_flu_to_frd(np.reshape(values, (msg.horizon, len(STATES))), msg.state_names)


def evaluate(truth, forecasts):
    """Compare every matured forecast with the truth; return the figures and the pairs."""
    pairs = []
    for t0, msg in sorted(forecasts.items()):
        steps = range(t0 + 1, t0 + 1 + msg.horizon)
        if not all(k in truth for k in steps):
            continue   # not matured yet, or truth samples missing
        predicted = model_states(msg.hybrid, msg)
        actual = np.array([truth[k][0] for k in steps])
        true_track = np.array([truth[k][1:] for k in steps])
        track_error = np.hypot(np.asarray(msg.x) - true_track[:, 0],
                               np.asarray(msg.y) - true_track[:, 1])
        pairs.append((t0, msg, predicted, actual, track_error, true_track))
    if not pairs:
        return None, pairs
    errors = np.stack([p[2] - p[3] for p in pairs])
    rmse = np.sqrt(np.mean(errors ** 2, axis=(0, 1)))
    track = np.stack([p[4] for p in pairs])
    per_forecast = track.mean(axis=1)
    horizon = track.shape[1]
    figures = {
        'forecasts_evaluated': len(pairs),
        'horizon_steps': int(pairs[0][1].horizon),
        'rmse': {s: float(v) for s, v in zip(STATES, rmse, strict=True)},
        'trajectory_error_m': {
            'mean': float(track.mean()),
            'ci95': float(1.96 * per_forecast.std(ddof=1) / math.sqrt(len(pairs)))
            if len(pairs) > 1 else None,
            'at_5_min': float(track[:, 299].mean()) if horizon >= 300 else None,
            'at_horizon_end': float(track[:, -1].mean()),
        },
        'model_id': pairs[0][1].model_id,
    }
    return figures, pairs


def plot(pair, path: Path) -> None:
    """Write a PNG of one forecast (hybrid and its physics part) against the truth."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    t0, msg, predicted, actual, _, true_track = pair
    physics = model_states(msg.physics, msg)
    bound = np.asarray(msg.residual_bound)
    minutes = np.arange(1, msg.horizon + 1) / 60.0
    fig = plt.figure(figsize=(13, 8), constrained_layout=True)
    grid = fig.add_gridspec(len(STATES), 2)
    for i, (state, unit) in enumerate(zip(STATES, UNITS, strict=True)):
        ax = fig.add_subplot(grid[i, 1])
        ax.plot(minutes, actual[:, i], 'k', lw=1, label='truth')
        ax.plot(minutes, predicted[:, i], 'C1', lw=1, label='hybrid forecast')
        ax.fill_between(minutes, physics[:, i] - bound[i], physics[:, i] + bound[i],
                        color='C0', alpha=0.2, label='physics part ± LSTM bound')
        ax.set_ylabel(f'{state} ({unit})')
        if i == 0:
            ax.legend(loc='upper right', fontsize=8)
    ax.set_xlabel('minutes after the forecast was made')
    track_ax = fig.add_subplot(grid[:, 0])
    track_ax.plot(true_track[:, 0], true_track[:, 1], 'k', label='true track')
    track_ax.plot(msg.x, msg.y, 'C1', label='forecast track')
    track_ax.set(xlabel='east (m)', ylabel='north (m)', aspect='equal',
                 title=f'forecast made at t = {t0} s, {msg.horizon / 60:g} min ahead')
    track_ax.legend()
    fig.suptitle(f'model {msg.model_id}')
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def online_figures(heard: list[float], kept) -> dict:
    """Return how the online path kept up: forecasts heard and gaps in the inputs (s)."""
    spacing = np.diff(heard) if len(heard) > 1 else np.zeros(1)
    inputs = {}
    for topic, (times, _) in kept.samples.items():
        gaps = np.diff(times) if len(times) > 1 else np.zeros(1)
        inputs[topic] = {'received': len(times), 'largest_gap_s': float(gaps.max())}
    return {'forecasts_heard': len(heard), 'forecast_spacing_s': {
        'median': float(np.median(spacing)), 'max': float(spacing.max())}, 'inputs': inputs}


def re_forecaster(horizon: int, plan_timeout: float):
    """Return a ReForecast of the predictor the demo starts (embedded model, defaults)."""
    from hybrid_models.engine import Forecaster
    from hybrid_predictor.node import default_model_path
    from hybrid_predictor.re_forecast import ReForecast, predictor_defaults
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel

    parameters = dict(predictor_defaults(), horizon=horizon, plan_timeout=plan_timeout)
    return ReForecast(Forecaster.from_checkpoint(default_model_path()),
                      topic_map_for(load_vessel(VESSEL)), parameters)


def recorder_argv(out: Path) -> list[str]:
    """Return the recorder's command line for the demo's topics, timed by /clock."""
    from vessel_bringup.processes import executable
    from vessel_ros_bridge.names import DEFAULT_NAMESPACE

    # The predictor compiles its model before it publishes: wait for it.
    return [str(executable('vessel_recorder', 'record')), '--out', str(out), '--use-sim-time',
            '--wait', '300', '--topics', *(f'{DEFAULT_NAMESPACE}/{t}' for t in RECORDED)]


def main(argv=None) -> int:
    """Run the demo; return the exit code."""
    import json

    from hybrid_predictor.re_forecast import compare

    args = parse_args(argv)
    seconds = args.minutes * 60.0
    print(f'demo: simulator at {args.speed_up:g}x real time with the predictor; '
          f'{args.minutes:g} simulated minutes (about {seconds / args.speed_up:.0f} s)')
    plan = None if args.no_plan else make_plan(args.seed + 1000, int(seconds) + 1000)
    plan_timeout = seconds + 60
    try:
        predictor = node_argv('hybrid_predictor', 'predictor', params={
            'use_sim_time': True, 'plan_timeout': plan_timeout, 'horizon': args.horizon})
        simulator = node_argv('ship_sim_node', 'simulator', '--log-level', 'warn', params={
            'seed': args.seed, 'real_time_factor': args.speed_up, 'publish_truth': True,
            'start_time': START})
        recorder = None if args.record is None else recorder_argv(args.record)
    except FileNotFoundError as exc:
        sys.exit(f'demo: error: {exc}')
    kept = re_forecaster(args.horizon, plan_timeout)
    running = []   # the simulator's process, once started
    with Children() as children:
        if recorder is not None:
            children.start(recorder, 'recorder')
        children.start(predictor, 'predictor')
        truth, forecasts, heard, status = collect(
            seconds, args.speed_up, args.evaluate_every,
            lambda: running.append(children.start(simulator, 'simulator')), plan, kept,
            lambda: [stop_group(process) for process in running])
    figures, pairs = evaluate(truth, forecasts)
    if figures is None:
        print(f'demo: error: no forecast matured ({len(forecasts)} forecasts, {len(truth)} s '
              "of truth); see the nodes' output above", file=sys.stderr)
        return 1
    figures['live_vs_offline'] = compare(kept, [p[1] for p in pairs], since=START + heard[0])
    figures['online'] = online_figures(heard, kept)
    figures['online']['predictor'] = {k: status.get(k) for k in (
        'forecasts_published', 'states_skipped_as_backlog', 'forecasts_before_sample_complete',
        'forecast_latency_p50_ms', 'forecast_latency_p99_ms')}
    how = 'latest controls held' if plan is None else 'following the applied control plan'
    print(f'demo: {figures["forecasts_evaluated"]} forecasts of {figures["horizon_steps"]} '
          f'steps ({how}) against the simulator\'s truth (model {figures["model_id"]})')
    for state, unit in zip(STATES, UNITS, strict=True):
        print(f'  RMSE {state:>3}  {figures["rmse"][state]:.4f} {unit}')
    traj = figures['trajectory_error_m']
    ci = f' ± {traj["ci95"]:.0f}' if traj['ci95'] is not None else ''
    minutes = figures['horizon_steps'] / 60
    at_5 = f'{traj["at_5_min"]:.0f} m after 5 min, ' if traj['at_5_min'] is not None else ''
    print(f'  trajectory error  mean {traj["mean"]:.0f}{ci} m over {minutes:g} min '
          f'({at_5}{traj["at_horizon_end"]:.0f} m after {minutes:g} min)')
    same = figures['live_vs_offline']
    if same['compared']:
        gaps = ', '.join(f'{n} {same["max_abs_difference"][n]:.1e}' for n in STATES)
        print(f'  live = offline    {same["compared"]} forecasts recomputed offline, largest '
              f'|live - offline|: {gaps}; track {same["max_position_difference_m"]:.1e} m '
              f'({"equal" if same["equal"] else "NOT equal"} to float32 precision)')
    if same['not_compared']:
        print(f'  not recomputed    {same["not_compared"]}: '
              f'{next(iter(same["why_not_compared"].values()))}')
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / 'demo.json').write_text(json.dumps(figures, indent=2))
    png = args.out / 'forecast_vs_truth.png'
    plot(pairs[len(pairs) // 2], png)
    print(f'demo: wrote {png} and {args.out / "demo.json"}'
          + (f'; recorded {args.record}' if args.record is not None else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
