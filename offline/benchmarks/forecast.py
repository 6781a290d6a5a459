"""
Forecast speed of the default model, all figures measured in one run.

- engine: p50/p99 latency of one 900-step forecast with the compiled engine (the code
  the predictor node runs);
- baseline: the same model as a naive per-step PyTorch eager loop
  (``HybridModel.forecast``), and the speed-up over it;
- bound: the FLOP count of one forecast divided by the float32 matrix-multiply rate
  measured on this machine now, the time no implementation can beat;
- throughput: forecasts per second for a batch of 64 plans;
- node: from a state message being published to its forecast arriving, over DDS on
  loopback through a predictor process (``--skip-node`` leaves it out);
- start-up: the warm-up a starting predictor runs (every batch size compiled), in a
  new process with an empty compilation cache and in the next one that finds it filled;
- rate: a vehicle at its own rate (the Crazyflie at 100 Hz, its shipped model), one
  forecast per state message, idle and beside a busy core, and the floor: the same
  replay and receiver against a node that answers at once (``node_rate``);
- what-if: a planner's request of 1,000 plans x 100 steps answered by the predictor's
  own code, stage by stage, without DDS (``what_if``), of the default model or another
  (``--what-if-model``, fed from a recording of its vessel with ``--what-if-dataset``);
- gpu: the engine's single and batch figures on the GPU where jax sees one, and the
  largest difference of its forecasts from the CPU's; where it sees none, why;
- precision (``--precision-dataset DIR``): the model's test forecasts of a dataset (its
  model card's protocol) served in float32, as the predictor serves them, against the
  same in float64: the largest difference per state, also as a share of the state's
  test RMSE, and the trajectory error of each.
"""

from __future__ import annotations

import os
from pathlib import Path
import sys
import time

import numpy as np

from .node_rate import confine_dds, measure, simulator_cost
from .what_if import what_if_stages

REPO = Path(__file__).resolve().parents[2]
GOALS = {'engine_p50_ms': '<= 10', 'speedup_vs_naive': '>= 20',
         'batch64_forecasts_per_s': '>= 1000', 'node_p99_ms': '<= 20',
         'start_up_speedup': '>= 3', 'rate_idle_p99_ms': '<= 10',
         'rate_idle_share_forecast_by_node': '>= 0.99',
         'rate_simulator_cpu_ms_per_period': '<= 7', 'what_if_answer_ms': '<= 100'}
WARM_UP = """
import sys, time
from hybrid_models.engine import Forecaster
engine = Forecaster.from_checkpoint(sys.argv[1])
started = time.perf_counter()
engine.warm_up(int(sys.argv[2]), window=engine.window, max_batch=64)
print(time.perf_counter() - started)
"""


# A run that takes seconds to minutes, for CI (`bench.py --quick forecast`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--repeats', '3', '--naive-repeats', '1', '--node-samples', '10',
         '--rate-samples', '20', '--what-if-plans', '20')


def add_arguments(parser) -> None:
    """Declare this suite's options."""
    parser.add_argument('--model', type=Path, default=None,
                        help="checkpoint (default: the predictor's embedded model)")
    parser.add_argument('--horizon', type=int, default=900, help='forecast steps (900)')
    parser.add_argument('--repeats', type=int, default=200,
                        help='timed single forecasts (default 200)')
    parser.add_argument('--naive-repeats', type=int, default=5,
                        help='timed eager-loop forecasts (default 5)')
    parser.add_argument('--node-samples', type=int, default=150,
                        help='state messages timed through the node (default 150)')
    parser.add_argument('--skip-node', action='store_true',
                        help='leave out the end-to-end measurement through the node')
    parser.add_argument('--rate-vehicle', default='crazyflie_brushless',
                        help='vehicle forecast at its own rate (default crazyflie_brushless)')
    parser.add_argument('--rate-model', type=Path, default=None,
                        help='its checkpoint (default: the model shipped for it)')
    parser.add_argument('--rate-samples', type=int, default=1000,
                        help='states timed at its rate, idle and beside a busy core (1000)')
    parser.add_argument('--what-if-plans', type=int, default=1000,
                        help="plans in the what-if request timed in the predictor's code "
                             '(1000; 0 leaves it out)')
    parser.add_argument('--what-if-steps', type=int, default=100,
                        help='steps of each what-if plan (100)')
    parser.add_argument('--what-if-model', type=Path, default=None,
                        help="the what-if's checkpoint (default: --model)")
    parser.add_argument('--what-if-dataset', type=Path, default=None,
                        help='a recording of its vessel that feeds the predictor (needed '
                             'where the simulator has no physics of it, e.g. the snuboat; '
                             'default: a simulated run)')
    parser.add_argument('--precision-dataset', type=Path, default=None,
                        help="a dataset whose test forecasts are compared in float32 and "
                             "float64 (the default model's: data/ship96 of its model card)")
    parser.add_argument('--skip-rate', action='store_true',
                        help="leave out the measurement at the vehicle's rate")


def default_model() -> Path:
    """Return the predictor package's embedded model."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory('hybrid_predictor')) / 'models' / 'default' / \
        'model.safetensors'


def inputs(window: int, horizon: int, batch: int, seed: int = 0):
    """Return a plausible cruise window and `batch` plans of rudder/shaft variations."""
    rng = np.random.default_rng(seed)
    z = np.tile([6.0, 0.05, 0.0, 0.002, 0.01], (window, 1)) + rng.normal(0, 0.01, (window, 5))
    c = np.tile([85.0, 0.01, 0.01, 3.0, 0.6, 0.8], (window, 1))
    future = np.tile(c[-1], (batch, horizon, 1))
    future[:, :, 0] += rng.uniform(-20, 20, (batch, 1))
    future[:, :, 1:3] += rng.uniform(-0.1, 0.1, (batch, 1, 1))
    return z, c, future


def percentiles(seconds: list[float]) -> tuple[float, float]:
    """Return (p50, p99) in ms."""
    ms = np.asarray(seconds) * 1e3
    return float(np.percentile(ms, 50)), float(np.percentile(ms, 99))


def forecast_flops(model, window: int, horizon: int) -> float:
    """Multiply-add FLOPs (2 per MAC) of the recurrent stacks and head for one forecast."""
    from hybrid_models.recurrent import step_flops

    def stack(module, steps):
        return steps * step_flops(model.cell, module.input_size, module.hidden_size,
                                  module.num_layers)

    head = 2 * model.head.in_features * model.head.out_features * horizon
    return float(stack(model.init, window) + stack(model.lstm, horizon) + head)


def matmul_rate(size: int = 512, seconds: float = 1.0) -> float:
    """Float32 GEMM rate of this machine now (FLOP/s), best of repeated products."""
    a = np.random.default_rng(0).standard_normal((size, size)).astype(np.float32)
    best, end = 0.0, time.perf_counter() + seconds
    while time.perf_counter() < end:
        started = time.perf_counter()
        a @ a
        best = max(best, 2 * size ** 3 / (time.perf_counter() - started))
    return best


def node_latency(model: Path, samples: int) -> dict:
    """Publish inputs to a predictor process; time state publish -> forecast received."""
    from vessel_bringup.processes import Children

    confine_dds()
    # The predictor is stopped however this ends, SIGINT/SIGTERM/SIGHUP included.
    with Children() as children:
        children.node('hybrid_predictor', 'predictor', '--log-level', 'warn',
                      params={'model_path': model, 'forecast_period': 0.0})
        latencies = timed_states(samples)
    if not latencies:
        return {'error': 'no forecast arrived from the predictor process'}
    p50, p99 = percentiles(latencies)
    return {'node_p50_ms': round(p50, 2), 'node_p99_ms': round(p99, 2),
            'node_forecasts_timed': len(latencies), 'node_states_sent': samples}


def timed_states(samples: int) -> list[float]:
    """Publish a window, then ``samples`` live states; return each one's forecast delay (s)."""
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    import rclpy
    from sensor_msgs.msg import JointState
    from vessel_bringup.processes import rclpy_options

    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_ros_bridge import messages as m
    from vessel_ros_bridge.names import DEFAULT_NAMESPACE

    rclpy.init(**rclpy_options())
    # In the nodes' namespace, so the shared relative topic names resolve as theirs do.
    node = rclpy.create_node('bench_forecast_client', namespace=DEFAULT_NAMESPACE)
    pubs = {'odom': node.create_publisher(Odometry, m.ODOM_TOPIC, 10),
            'act': node.create_publisher(JointState, m.ACTUATORS_TOPIC, 10),
            'wind': node.create_publisher(Vector3Stamped, m.WIND_TOPIC, 10)}
    sent, latencies = {}, []

    def on_forecast(msg):
        t = round(m.seconds_from_stamp(msg.header.stamp), 6)
        if t in sent:
            latencies.append(time.perf_counter() - sent.pop(t))

    node.create_subscription(Forecast, 'forecast', on_forecast, 10)

    def publish(t: float, timed: bool) -> None:
        stamp = m.stamp_from_seconds(t)
        state = {'u': 6.0, 'v': 0.05, 'p': 0.0, 'r': 0.002, 'phi': 0.01,
                 'psi': 0.002 * t, 'x': 6.0 * t, 'y': 0.0}
        pubs['act'].publish(m.joint_state_from_actuators(
            {'n': 85.0, 'delta_port': 0.01, 'delta_stbd': 0.01}, stamp))
        pubs['wind'].publish(m.wind_from_measurement(3.0, 0.6, 0.8, stamp, 'base_link'))
        if timed:
            sent[round(t, 6)] = time.perf_counter()
        pubs['odom'].publish(m.odometry_from_state(state, stamp, 'odom', 'base_link'))

    try:
        deadline = time.monotonic() + 120
        while node.count_subscribers(m.ODOM_TOPIC) == 0 and time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.1)   # the predictor compiles first
        time.sleep(1.0)
        now = time.time()
        for k in range(70):                          # the 60 s window, in one burst
            publish(now - 70 + k, timed=False)
            rclpy.spin_once(node, timeout_sec=0.005)
        for _ in range(samples):                     # live samples, 10 per second
            publish(time.time(), timed=True)
            end = time.monotonic() + 0.1
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.01)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return latencies


def start_up(path: Path, horizon: int) -> dict:
    """Time the warm-up in a new process, with an empty then a filled compilation cache."""
    import subprocess
    import tempfile

    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, 'JAX_COMPILATION_CACHE_DIR': cache}
        cold, cached = (float(subprocess.run(
            [sys.executable, '-c', WARM_UP, str(path), str(horizon)], env=env, check=True,
            capture_output=True, text=True).stdout.split()[-1]) for _ in range(2))
    return {'warm_up_cold_s': round(cold, 2), 'warm_up_cached_s': round(cached, 2),
            'start_up_speedup': round(cold / cached, 1)}


def engine_times(engine, z, c, future, repeats: int) -> tuple[float, float, float, object]:
    """
    Time a warmed-up engine: one plan at a time ``repeats`` times, then the whole batch.

    Returns the single forecast's p50 and p99 (ms), the batch's median (s) over 10 and
    the batch's forecast.
    """
    single = []
    for i in range(repeats):
        started = time.perf_counter()
        engine.forecast(z, c, future[i % len(future):i % len(future) + 1])
        single.append(time.perf_counter() - started)
    batch = []
    for _ in range(10):
        started = time.perf_counter()
        made = engine.forecast(z, c, future)
        batch.append(time.perf_counter() - started)
    return (*percentiles(single), float(np.median(batch)), made)


def gpu_figures(path: Path, cpu_forecast, z, c, future, repeats: int) -> dict:
    """Time the engine on the GPU as on the CPU (same inputs); {'absent': why} without one."""
    from hybrid_models.engine import Forecaster, platform_devices

    try:
        devices = platform_devices('gpu')
    except ValueError as exc:
        return {'absent': str(exc)}
    engine = Forecaster.from_checkpoint(path, platform='gpu')
    engine.warm_up(future.shape[1], window=engine.window, max_batch=future.shape[0])
    p50, p99, batch_s, on_gpu = engine_times(engine, z, c, future, repeats)
    return {'devices': [str(d) for d in devices], 'engine_p50_ms': round(p50, 3),
            'engine_p99_ms': round(p99, 3), 'batch64_ms': round(batch_s * 1e3, 1),
            'batch64_forecasts_per_s': round(len(future) / batch_s, 1),
            'max_abs_difference_from_cpu': float(np.abs(on_gpu.hybrid
                                                        - cpu_forecast.hybrid).max())}


def precision(served, path: Path, dataset_dir: Path) -> dict:
    """
    Forecast the test split of ``dataset_dir`` with ``served`` and in float64; compare.

    ``served`` is the float32 ``Forecaster`` of checkpoint ``path``, as the node serves it.
    """
    from hybrid_models.data import evaluation_protocol, forecast_windows, load_runs
    from hybrid_models.engine import Forecaster
    from hybrid_models.metrics import forecast_metrics
    from vessel_datasets.format import read_dataset

    dataset = read_dataset(dataset_dir)
    dataset.vessel.check_compatible(served.spec, f'checkpoint {path}')
    _, horizon, stride = evaluation_protocol(served.spec, served.window, None, None)
    runs = load_runs(dataset, 'test', served.spec)
    windows = forecast_windows(runs, served.window, horizon, stride, target='true')
    problems = (windows.z_window, windows.c_window, windows.c_future)
    single = served.forecast_each(*problems).hybrid
    double = Forecaster.from_checkpoint(path, dtype=np.float64).forecast_each(*problems).hybrid
    metrics = {name: forecast_metrics(f, windows.z_target, served.spec)
               for name, f in (('float32', single), ('float64', double))}
    difference = np.abs(single - double).max(axis=(0, 1))
    names = served.spec.state_names
    return {
        'dataset': str(dataset_dir), 'test_runs': len(runs), 'forecasts': len(single),
        'horizon': horizon,
        'max_abs_difference': dict(zip(names, difference.tolist(), strict=True)),
        'max_difference_over_rmse': {s: float(d / metrics['float64']['rmse'][s])
                                     for s, d in zip(names, difference, strict=True)},
        'trajectory_m': {k: m['trajectory']['mean'] for k, m in metrics.items()},
        'rmse': {k: m['rmse'] for k, m in metrics.items()}}


def run(args) -> dict:
    """Measure everything; return the figures."""
    import torch

    from hybrid_models.checkpoint import load_model
    from hybrid_models.engine import Forecaster

    torch.set_num_threads(os.cpu_count() or 1)
    path = args.model or default_model()
    engine = Forecaster.from_checkpoint(path)          # served as the predictor serves it
    model, _ = load_model(path)                         # the same weights in torch
    window, horizon = engine.window, args.horizon
    z, c, future = inputs(window, horizon, batch=64)
    engine.warm_up(horizon, window=window, max_batch=64)

    p50, p99, batch_s, on_cpu = engine_times(engine, z, c, future, args.repeats)

    naive = []
    t = lambda a: torch.as_tensor(a[None] if a.ndim == 2 else a, dtype=torch.float32)  # noqa
    with torch.no_grad():
        for i in range(args.naive_repeats):
            started = time.perf_counter()
            model.forecast(t(z), t(c), t(future[i:i + 1]))
            naive.append(time.perf_counter() - started)
    naive_p50 = percentiles(naive)[0]

    flops = forecast_flops(model, window, horizon)
    rate = matmul_rate()
    result = {
        'suite': 'forecast', 'model': engine.model_id, 'horizon': horizon, 'window': window,
        'engine_p50_ms': round(p50, 3), 'engine_p99_ms': round(p99, 3),
        'naive_eager_p50_ms': round(naive_p50, 1),
        'speedup_vs_naive': round(naive_p50 / p50, 1),
        'flops_per_forecast': flops,
        'matmul_gflops_measured': round(rate / 1e9, 1),
        'flop_lower_bound_ms': round(flops / rate * 1e3, 3),
        'engine_vs_lower_bound': round(p50 / (flops / rate * 1e3), 1),
        'batch64_ms': round(batch_s * 1e3, 1),
        'batch64_forecasts_per_s': round(64 / batch_s, 1),
    }
    result['gpu'] = gpu_figures(path, on_cpu, z, c, future, args.repeats)
    if args.precision_dataset is not None:   # last: float64 turns on jax's x64 mode
        result['precision'] = precision(engine, path, args.precision_dataset)
    result.update(start_up(path, horizon))
    if not args.skip_node:
        result.update(node_latency(path, args.node_samples))
    if args.what_if_plans:
        result['what_if'] = what_if_stages(args.what_if_model or path, args.what_if_plans,
                                           args.what_if_steps, dataset=args.what_if_dataset)
        result['what_if_answer_ms'] = result['what_if']['answer_ms']
    if not args.skip_rate:
        from hybrid_predictor.node import default_model_path

        rate_model = args.rate_model or default_model_path(args.rate_vehicle)
        result['rate'] = {
            'idle': measure(rate_model, args.rate_vehicle, args.rate_samples),
            'busy_core': measure(rate_model, args.rate_vehicle, args.rate_samples, busy=True),
            # The same replay and receiver against a node that answers at once.
            'floor': measure(rate_model, args.rate_vehicle, args.rate_samples, stand_in=True),
            'simulator_node': simulator_cost(args.rate_vehicle, args.rate_samples)}
        if 'cpu_ms_per_period' in result['rate']['simulator_node']:
            result['rate_simulator_cpu_ms_per_period'] = \
                result['rate']['simulator_node']['cpu_ms_per_period']
        for key in ('p99_ms', 'share_forecast_by_node'):
            if key in result['rate']['idle']:
                result[f'rate_idle_{key}'] = result['rate']['idle'][key]
        if 'p99_ms' in result['rate']['floor']:
            result['rate_floor_p99_ms'] = result['rate']['floor']['p99_ms']
    met = {}
    for key, goal in GOALS.items():
        if key in result:
            op, value = goal.split()
            met[key] = result[key] <= float(value) if op == '<=' else result[key] >= float(value)
    result['goals'] = GOALS
    result['met'] = met
    print(f'forecast bench: engine p50 {p50:.2f} ms, naive {naive_p50:.0f} ms', file=sys.stderr)
    return result
