"""
A predictor process at its vehicle's own rate: one forecast per state message, timed.

A simulated flight (or voyage) of the vehicle is published over DDS as the vehicle's own
messages at its rate (``hybrid_predictor.replay``), into a predictor started with
``forecast_period`` 0, so that every state is due a forecast. With ``plans``, each state
is preceded by the run's own next controls as a plan on the predictor's plan topic, as
a model-predictive controller sends them: a multirotor's rotor speeds held for a second
overturn it, and such forecasts are withheld as beyond the vehicle's limits. A receiving
thread takes every forecast as it arrives (a subscriber that lags would lose forecasts
the node made) in a process of its own (``rate_receiver.py``, as a controller is apart
from its vehicle), and each is timed from the moment its state was due to be published
to its arrival: the publisher's own lateness counts against the node. Arrival is when the
receiver's callback runs (``p50_ms``, ``p99_ms``) and, beside it, when DDS received the
forecast in that process (``p50_ms_at_receipt``, ``p99_ms_at_receipt``: the receiver's
executor and its conversion to Python left out, as a controller in C++ would not pay
them). Figures: the share of states forecast, p50/p99 of that delay, the node's own
count of forecasts, and, with ``busy_core``, the same beside a process that keeps one
core busy. ``simulator_cost`` measures the simulator node flying the vehicle at its rate:
CPU per period, and the rate its state messages arrive at.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np

# Steps a plan reaches past the horizon: a forecast that finds the previous state's plan
# (the newest not yet taken) still has a whole horizon of it.
PLAN_MARGIN = 10


def simulated_run(vehicle: str, seconds: float, seed: int = 0):
    """Return one simulated run of ``vehicle`` as a table (model frames, one row a sample)."""
    from vessel_datasets.format import read_dataset
    from vessel_datasets.simulate import main as simulate

    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):
        out = Path(tmp) / 'run'
        code = simulate(['--vessel', vehicle, '--runs', '1', '--seconds', f'{seconds:g}',
                         '--seed', str(seed), '--out', str(out), '--quiet'])
        if code:
            raise RuntimeError(f'simulating {vehicle} failed (exit {code})')
        ds = read_dataset(out)
        (run,) = [r for s in ('train', 'val', 'test') for r in ds.run_ids(s)]
        return ds.load(run)


def confine_dds() -> None:
    """Keep DDS traffic on this host, in the caller's domain or one of this process's own."""
    os.environ.update(ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST', ROS_DOMAIN_ID=os.environ.get(
        'ROS_DOMAIN_ID', str(180 + os.getpid() % 40)))


def _spin(executor) -> None:
    from rclpy.executors import ExternalShutdownException

    try:
        executor.spin()
    except ExternalShutdownException:   # the measurement is over
        pass


def cpu_seconds(pid: int) -> float:
    """Return the CPU time (user + system, s) a process and its threads have used."""
    fields = Path(f'/proc/{pid}/stat').read_text().rpartition(')')[2].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def busy_core() -> subprocess.Popen:
    """Start a process that keeps one core busy until it is killed."""
    return subprocess.Popen([sys.executable, '-c', 'while True: pass'])


def measure(model: Path, vehicle: str, samples: int, busy: bool = False,
            plans: bool = True, stand_in: bool = False) -> dict:
    """
    Publish a window and ``samples`` states more at the vehicle's rate; time the forecasts.

    ``stand_in``: time ``stand_in.py`` instead of the predictor, a node that answers each
    state at once with an empty Forecast: the floor of the same replay and receiver.
    """
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from vessel_bringup.processes import Children, rclpy_options

    from hybrid_models.engine import Forecaster
    from hybrid_predictor.node import FORECAST_TOPIC, PLAN_TOPIC
    from hybrid_predictor.replay import RunReplay
    from hybrid_predictor_interfaces.msg import ControlPlan
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel
    from vessel_ros_bridge import messages as m
    from vessel_ros_bridge.names import DEFAULT_NAMESPACE

    spec = load_vessel(vehicle)
    topic_map = topic_map_for(spec)
    window = Forecaster.from_checkpoint(model).window
    rows = window + samples
    flight = simulated_run(vehicle, (rows + spec.horizon + PLAN_MARGIN) / spec.rate_hz + 1.0)
    table = flight.iloc[:rows]
    controls = flight[list(spec.control_names)].to_numpy(float)
    confine_dds()
    health: dict[str, str] = {}     # the predictor's latest /diagnostics values
    spinner = busy_process = None
    logs = Path(tempfile.mkdtemp(prefix='bench_rate_'))
    with Children(logs) as children:
        if stand_in:   # logged as the predictor's, whose log is read below
            predictor = children.start([sys.executable, str(Path(__file__).with_name(
                'stand_in.py')), vehicle], 'predictor')
        else:
            predictor = children.node('hybrid_predictor', 'predictor', '--log-level', 'warn',
                                      params={'model_path': str(model), 'vessel': vehicle,
                                              'forecast_period': 0.0})
        received = logs / 'received.json'
        receiver_process = children.start([sys.executable, str(Path(__file__).with_name(
            'rate_receiver.py')), str(received), str(rows)], 'receiver')
        rclpy.init(**rclpy_options())
        try:
            node = rclpy.create_node('bench_rate_client')
            replay = RunReplay(node, topic_map, m.message_types(topic_map))

            # In the nodes' namespace, where the predictor's relative topics resolve.
            watcher = rclpy.create_node('bench_rate_watcher', namespace=DEFAULT_NAMESPACE)
            plan_pub = watcher.create_publisher(ControlPlan, PLAN_TOPIC, 10)

            # Made before the run, as the replay makes each row's messages before it is
            # due: what is timed is the node, not this process making messages.
            plan_messages = [ControlPlan(
                control_names=list(spec.control_names), control_units=list(
                    spec.control_units), values=controls[
                        k:k + spec.horizon + PLAN_MARGIN].ravel().tolist(),
                step_period=spec.dt) for k in range(rows if plans else 0)]

            def send_plan(k: int, stamp: float) -> None:
                plan = plan_messages[k]
                plan.header.stamp = m.stamp_from_seconds(stamp)
                plan_pub.publish(plan)

            watcher.create_subscription(
                DiagnosticArray, '/diagnostics', lambda msg: health.update(
                    {v.key: v.value for s in msg.status if 'predictor' in s.name
                     for v in s.values}), 10)
            executor = SingleThreadedExecutor()
            executor.add_node(watcher)
            spinner = threading.Thread(target=_spin, args=(executor,), daemon=True)
            spinner.start()
            deadline = time.monotonic() + 180
            while watcher.count_publishers(FORECAST_TOPIC) == 0 or \
                    watcher.count_subscribers(FORECAST_TOPIC) == 0 or \
                    node.count_subscribers(replay.writer.topics[-1]) == 0:
                if time.monotonic() > deadline:
                    return {'error': 'the predictor did not start within 180 s'}
                time.sleep(0.1)
            time.sleep(2.0)                        # its warm-up compiles every batch size
            if busy:
                busy_process = busy_core()
            cpu = cpu_seconds(predictor.pid)
            start = time.time()
            replay.play(table, start, time.sleep, before_row=send_plan if plans else None)
            time.sleep(1.0)                        # the last forecasts in flight
            cpu = cpu_seconds(predictor.pid) - cpu
            time.sleep(1.5)                        # its next /diagnostics
            children.stop(receiver_process)        # writes what it received
        finally:
            if busy_process is not None:
                busy_process.kill()
                busy_process.wait()
            rclpy.try_shutdown()
            if spinner is not None:
                spinner.join(timeout=5)
    # Due a forecast: every state from the one that completes the first window (row
    # window - 1) on; the node counts its forecasts from there too.
    stamps = [round(start + k / spec.rate_hz, 6) for k in range(window - 1, rows)]
    noted = json.loads(received.read_text()) if received.is_file() else {}
    arrivals, receipts = ({float(s): t for s, t in noted.get(kind, {}).items()}
                          for kind in ('arrivals', 'receipts'))
    # Each forecast's delay (ms) to its callback and to its receipt by DDS.
    waits = {suffix: np.array([times[s] - s for s in stamps if s in times]) * 1e3
             for suffix, times in (('', arrivals), ('_at_receipt', receipts))}
    delays = waits['']
    out = {'vehicle': vehicle, 'rate_hz': spec.rate_hz, 'states_timed': len(stamps),
           'forecasts_received': int(len(delays)),
           'share_received': round(len(delays) / len(stamps), 3), 'busy_core': busy,
           'plans': plans, 'stand_in': stand_in,
           'predictor_cpu_ms_per_state': round(cpu / rows * 1e3, 2)}
    counts = {k: int(health.get(k, 0)) for k in (
        'forecasts_published', 'forecasts_withheld', 'states_skipped_as_backlog')}
    # Withheld forecasts were made and refused on their content (a state beyond the
    # vehicle's limits: a multirotor's rotor speeds held for a second overturn it).
    out.update(predictor_counts=counts, share_forecast_by_node=round(
        (counts['forecasts_published'] + counts['forecasts_withheld']) / len(stamps), 3))
    # The node's own view: a state's arrival in the node to its forecast made, over its
    # last forecasts (health.latency_window); the rest of the delay is transport.
    out['predictor_latency_ms'] = {k: float(health[f'forecast_latency_{k}_ms'])
                                   for k in ('p50', 'p99') if f'forecast_latency_{k}_ms' in health}
    said = (logs / 'predictor.log').read_text(errors='replace').splitlines()
    out['predictor_warnings'] = sorted({line.split(': ', 1)[-1][:160] for line in said
                                        if 'WARN' in line or 'ERROR' in line})[:10]
    for suffix, waited in waits.items():
        if len(waited):
            out[f'p50_ms{suffix}'] = round(float(np.percentile(waited, 50)), 2)
            out[f'p99_ms{suffix}'] = round(float(np.percentile(waited, 99)), 2)
    return out


def simulator_cost(vehicle: str, periods: int) -> dict:
    """Run the simulator node of ``vehicle``; return its CPU per period and arrival rate."""
    from nav_msgs.msg import Odometry
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile
    from vessel_bringup.processes import Children, rclpy_options

    from vessel_description import load_vessel

    spec = load_vessel(vehicle)
    confine_dds()
    arrivals: list[float] = []
    with Children(Path(tempfile.mkdtemp(prefix='bench_sim_'))) as children:
        sim = children.node('ship_sim_node', 'simulator', '--log-level', 'warn',
                            params={'vessel': vehicle})
        rclpy.init(**rclpy_options())
        try:
            node = rclpy.create_node('bench_sim_receiver')
            node.create_subscription(Odometry, '/vessel/odom',
                                     lambda msg: arrivals.append(time.monotonic()),
                                     QoSProfile(depth=1000))
            executor = SingleThreadedExecutor()
            executor.add_node(node)
            deadline = time.monotonic() + 120
            while len(arrivals) < spec.rate_hz * 2:           # two seconds flown
                if time.monotonic() > deadline or sim.poll() is not None:
                    return {'error': 'the simulator published no state within 120 s'}
                executor.spin_once(timeout_sec=0.1)
            cpu, first = cpu_seconds(sim.pid), len(arrivals)
            while len(arrivals) < first + periods and time.monotonic() < deadline + 120:
                executor.spin_once(timeout_sec=0.1)
            cpu, count = cpu_seconds(sim.pid) - cpu, len(arrivals) - first
        finally:
            rclpy.try_shutdown()
    span = arrivals[-1] - arrivals[first]
    return {'vehicle': vehicle, 'rate_hz': spec.rate_hz, 'periods': count,
            'cpu_ms_per_period': round(cpu / max(count, 1) * 1e3, 2),
            'received_hz': round((count - 1) / span, 1) if span > 0 else None}
