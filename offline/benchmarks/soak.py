"""
Service soak: concurrent what-if clients against a forecasting predictor, over DDS.

Starts the simulator (``--rtf`` times real time) and the predictor as processes, waits
for the first forecast, then for ``--duration`` seconds keeps ``--concurrency``
requests of ``--plans`` plans in flight from each of ``--clients`` clients, while it
listens to /vessel/forecast. Plans hold each row for ``--plan-period`` seconds and
answers carry every ``--answer-period`` seconds' step (10 s each by default over the
patrol boat's 15-minute horizon, what a controller ranking plans needs; 0 sends and
receives every 1 s step, ten times the bytes). A client answered "busy" waits
``--busy-backoff`` seconds before it sends again, as a well-behaved client does, or
(``--busy-backoff retry_after``) the answer's ``retry_after`` and up to a tenth more at
random, as a client that follows the node's hint does.
The clients ask with the what-if client's Fast DDS profile
(``hybrid_predictor.middleware.use_client_profile``), as a controller should. By default
they are C programs over rcl (package what_if_c, ``--client c``), in processes of
their own that write their figures for the soak to merge: what they measure is the node
and the transport. With ``--client python`` they are rclpy clients, in the soak's own
process or (``--client-processes``) spread over processes of their own, and a busy
answer also waits for the client's interpreter, busy converting the 1.65 MB answers it
receives meanwhile (docs/predictor.md, "Soak benchmark").
Figures: the request's and a successful answer's size; requests sent, answered
(success, busy or another failure) and never answered; p50/p99 latency, and for "busy"
answers where it went (``busy_stages_ms``: to the node and through it, back over DDS,
queued in this process, taken, handed to the callback); forecasts
published during the soak and the longest silence between them, in message time
(forecast periods) and wall time; how many /diagnostics reports said ERROR or WARN
meanwhile, and why; the predictor's own service counts from its last report (requests,
busy, busy unread, failed); the predictor's resident memory at the start, after
the warm-up (the first tenth of the soak, at most 60 s: buffers and caches filling),
at the end, and 20 samples in between (growth that levels off, or keeps on).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import json
import os
from pathlib import Path
import random
import threading
import time

import numpy as np

REPO = Path(__file__).resolve().parents[2]
GOALS = {'answered_percent': '== 100', 'longest_silence_periods': '<= 2',
         'rss_growth_percent': '< 5 (over 10 minutes)'}
HORIZON = 900
WINDOW_S = 60.0   # the patrol boat's window: the simulator must run this long first
# Fast DDS hands every client of a service the responses to all of them, each
# client filtering its own: the response queue must hold all requests in flight.
RESPONSE_DEPTH = 1000
RSS_SAMPLES = 20  # evenly spaced over the soak: growth that levels off or keeps on
FOLLOW_HINT = 'retry_after'
SERVICE = '/vessel/predictor/predict'
CLIENT_KINDS = ('python', 'c')


def backoff(text: str) -> float | str:
    """Return ``--busy-backoff``: seconds (>= 0), or FOLLOW_HINT."""
    if text == FOLLOW_HINT:
        return text
    try:
        seconds = float(text)
    except ValueError:
        seconds = -1.0
    if not seconds >= 0:
        raise argparse.ArgumentTypeError(f'takes seconds >= 0 or {FOLLOW_HINT!r}, got {text!r}')
    return seconds


def positive_int(text: str) -> int:
    """Return an integer >= 1 from the command line."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f'takes an integer >= 1, got {text!r}')
    return value


# A run that takes seconds to minutes, for CI (`bench.py --quick soak`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--duration', '20')


def add_arguments(parser) -> None:
    """Declare this suite's options."""
    parser.add_argument('--duration', type=float, default=600.0,
                        help='seconds of load (default 600)')
    parser.add_argument('--clients', type=int, default=4, help='client nodes (default 4)')
    parser.add_argument('--concurrency', type=int, default=8,
                        help='requests each client keeps in flight (default 8)')
    parser.add_argument('--plans', type=int, default=64,
                        help='control plans per request (default 64)')
    parser.add_argument('--steps', type=positive_int, default=HORIZON,
                        help="forecast steps of every plan, the predictor's horizon "
                             f"(default {HORIZON}: the patrol boat's 15 minutes)")
    parser.add_argument('--plan-period', type=float, default=10.0,
                        help='seconds each plan row holds; 0: one row a forecast step '
                             '(default 10)')
    parser.add_argument('--answer-period', type=float, default=10.0,
                        help='seconds between the forecast steps an answer carries; 0: '
                             'every step (default 10)')
    parser.add_argument('--rtf', type=float, default=1.0,
                        help='simulator speed, times real time (default 1: a vessel)')
    parser.add_argument('--forecast-period', type=float, default=1.0,
                        help="the predictor's forecast_period, s of message time (default 1)")
    parser.add_argument('--busy-backoff', type=backoff, default=0.2,
                        help='seconds a client waits after a busy answer, or '
                             f'"{FOLLOW_HINT}": the answer\'s retry_after and up to a '
                             'tenth more at random (default 0.2)')
    parser.add_argument('--client-processes', type=positive_int, default=1,
                        help='processes the clients are spread over (default 1: all in '
                             "one, with --client python the soak's own; --clients of "
                             'them: one each, as controllers are)')
    parser.add_argument('--client', choices=CLIENT_KINDS, default='c',
                        help="the clients' language: c (rcl, package what_if_c; the "
                             "default: no interpreter of the client's own in what is "
                             'measured) or python (rclpy, as a Python controller asks)')
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='another predictor parameter (repeatable)')


def run(args) -> dict:
    """Run the soak with the command line's figures; return the JSON-ready result."""
    shape = RequestShape(args.plans, args.plan_period, args.answer_period, args.steps)
    if args.clients % args.client_processes:
        raise SystemExit(f'soak: error: --clients {args.clients} cannot be spread evenly '
                         f'over --client-processes {args.client_processes}')
    return soak(args.duration, args.clients, args.concurrency, shape, args.rtf,
                args.forecast_period, args.busy_backoff, predictor_params=args.param,
                client_processes=args.client_processes, client=args.client)


@dataclass(frozen=True)
class RequestShape:
    """What every request holds: plans, s a row holds, s between answer steps, steps."""

    plans: int = 64
    plan_period: float = 10.0
    answer_period: float = 10.0
    steps: int = HORIZON


def percentile_ms(seconds, q: float) -> float | None:
    """Return the ``q``-th percentile of latencies in s, in ms to 0.1 (None without any)."""
    latencies = np.asarray(seconds, dtype=float) * 1e3
    return round(float(np.percentile(latencies, q)), 1) if len(latencies) else None


MEMORY_PARTS = ('VmRSS', 'RssAnon', 'RssShmem')


def memory_mb(pid: int) -> dict[str, float]:
    """
    Resident memory of a process (MB), from one read of /proc: all of it and two parts.

    ``VmRSS`` all of it; ``RssAnon`` its private memory (what a leak grows); ``RssShmem``
    the pages of shared memory it has touched: Fast DDS's segments, its own and its
    peers', count as resident as they fill, up to their size.
    """
    found = {}
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        name, _, value = line.partition(':')
        if name in MEMORY_PARTS:
            found[name] = int(value.split()[0]) / 1024.0
    missing = [part for part in MEMORY_PARTS if part not in found]
    if missing:
        raise RuntimeError(f'no {", ".join(missing)} for process {pid}')
    return found


def growth(before: dict[str, float], after: dict[str, float], part: str) -> float:
    """Return the growth of one part of ``memory_mb`` from ``before`` to ``after`` (%)."""
    return round(100.0 * (after[part] - before[part]) / before[part], 2)


def make_plans(count: int, period: float = 0.0, seed: int = 0, steps: int = HORIZON):
    """Return ``count`` ControlPlans of ``steps`` steps of steady shaft and rudder."""
    from hybrid_predictor.plan_message import control_plan
    from hybrid_predictor.plans import plan_length
    from vessel_description import load_vessel

    boat = load_vessel('patrol_boat')
    _, rows = plan_length(steps, period, boat.dt, '--plan-period')
    rng = np.random.default_rng(seed)
    plans = []
    for _ in range(count):
        rudder = float(rng.uniform(-0.2, 0.2))
        row = [float(rng.uniform(60, 100)), rudder, rudder]
        plans.append(control_plan(boat, np.tile(row, (rows, 1)), step_period=period))
    return plans


def make_request(shape: RequestShape):
    """Return the Predict.Request every soak client sends."""
    from hybrid_predictor_interfaces.srv import Predict

    return Predict.Request(plans=make_plans(shape.plans, shape.plan_period,
                                            steps=shape.steps),
                           answer_period=shape.answer_period)


class Load:
    """Clients that keep requests in flight and count what comes back."""

    def __init__(self, node, clients: int, concurrency: int, shape: RequestShape,
                 busy_backoff: float | str):
        from rclpy.qos import QoSProfile

        from hybrid_predictor.what_if_client import is_busy
        from hybrid_predictor_interfaces.srv import Predict

        qos = QoSProfile(depth=max(RESPONSE_DEPTH, 2 * clients * concurrency))
        self.busy_backoff = busy_backoff
        self.is_busy = is_busy
        self.clients = [node.create_client(Predict, SERVICE, qos_profile=qos)
                        for _ in range(clients)]
        self.request = make_request(shape)
        self.concurrency = concurrency
        self.lock = threading.Lock()
        self.sent = self.success = self.busy = self.failed = 0
        self.latencies: list[float] = []
        self.success_latencies: list[float] = []
        self.busy_latencies: list[float] = []
        # (sent, response written by the node, received by DDS here, taken, done), ns
        self.busy_stages: list[tuple[int, ...]] = []
        self.failures: dict[str, int] = {}
        self.deadline = 0.0
        self.first_success = None   # a successful answer, kept to give its size

    def begin(self, seconds: float) -> None:
        """Start every client's requests; new ones are sent for ``seconds``."""
        self.deadline = time.monotonic() + seconds
        for client in self.clients:
            for _ in range(self.concurrency):
                self._send(client)

    def _send(self, client) -> None:
        # A back-off timer may fire after the load ended (retry_after can be seconds):
        # its request would go out after the soak stopped waiting for answers.
        if time.monotonic() >= self.deadline:
            return
        with self.lock:
            self.sent += 1
        sent_at = time.monotonic()
        sent_ns = time.time_ns()
        future = client.call_async(self.request)
        future.add_done_callback(lambda f: self._answered(client, f, sent_at, sent_ns))

    def _answered(self, client, future, sent_at: float, sent_ns: int) -> None:
        done_ns = time.time_ns()
        response = future.result()
        busy = self.is_busy(response)
        with self.lock:
            self.latencies.append(time.monotonic() - sent_at)
            if response.success:
                self.success += 1
                self.success_latencies.append(time.monotonic() - sent_at)
                if self.first_success is None:
                    self.first_success = response
            elif busy:
                self.busy += 1
                self.busy_latencies.append(time.monotonic() - sent_at)
                stages = getattr(future, 'stages_ns', None)
                if stages is not None:
                    self.busy_stages.append((sent_ns, *stages, done_ns))
            else:
                self.failed += 1
                key = response.message[:60]
                self.failures[key] = self.failures.get(key, 0) + 1
        if time.monotonic() >= self.deadline:
            return
        wait = self.wait_after_busy(response) if busy else 0.0
        if wait > 0:
            threading.Timer(wait, self._send, [client]).start()
        else:
            self._send(client)

    def wait_after_busy(self, response) -> float:
        """Return the seconds to wait after a busy answer before sending again."""
        if self.busy_backoff == FOLLOW_HINT:
            # Jitter, so clients given one time do not come back in one burst.
            return response.retry_after * (1.0 + 0.1 * random.random())
        return self.busy_backoff

    def settle(self, seconds: float) -> None:
        """Wait up to ``seconds`` for every request sent to be answered."""
        settle = time.monotonic() + seconds
        while self.answered < self.sent and time.monotonic() < settle:
            time.sleep(0.1)

    def figures(self) -> Load:
        """Return what the soak reports from: this load itself."""
        return self

    def raw(self) -> dict:
        """Return the counts and every latency, JSON-ready (``Merged`` reads them back)."""
        return {'sent': self.sent, 'success': self.success, 'busy': self.busy,
                'failed': self.failed, 'failures': self.failures,
                'latencies': self.latencies, 'success_latencies': self.success_latencies,
                'busy_latencies': self.busy_latencies, 'busy_stages': self.busy_stages,
                'request_kb': self.request_kb, 'success_answer_kb': self.success_answer_kb}

    @property
    def request_kb(self) -> float | None:
        """Return a request's size as it crosses DDS (kB)."""
        return self.kb(self.request)

    @property
    def success_answer_kb(self) -> float | None:
        """Return the first successful answer's size as it crosses DDS (kB)."""
        return self.kb(self.first_success)

    @staticmethod
    def kb(message) -> float | None:
        """Return a message's size as it crosses DDS (kB, serialized); None for none."""
        from rclpy.serialization import serialize_message

        return None if message is None else round(len(serialize_message(message)) / 1e3, 1)

    @property
    def answered(self) -> int:
        """Return the number of requests answered in any way."""
        return self.success + self.busy + self.failed


class Merged:
    """The figures of several client processes' ``Load.raw()``, as one Load gives them."""

    def __init__(self, raws: list[dict]):
        self.sent = sum(r['sent'] for r in raws)
        self.success = sum(r['success'] for r in raws)
        self.busy = sum(r['busy'] for r in raws)
        self.failed = sum(r['failed'] for r in raws)
        self.failures: dict[str, int] = {}
        for r in raws:
            for key, count in r['failures'].items():
                self.failures[key] = self.failures.get(key, 0) + count
        for name in ('latencies', 'success_latencies', 'busy_latencies', 'busy_stages'):
            setattr(self, name, [x for r in raws for x in r[name]])
        self.request_kb = next((r['request_kb'] for r in raws), None)
        self.success_answer_kb = next((r['success_answer_kb'] for r in raws
                                       if r['success_answer_kb'] is not None), None)

    @property
    def answered(self) -> int:
        """Return the number of requests answered in any way."""
        return self.success + self.busy + self.failed


class ProcessLoads:
    """
    The clients spread over processes of their own, started now, loaded on ``begin``.

    Each process holds ``clients // processes`` clients, says it is ready once its
    service is there, starts when told, and writes its ``Load.raw()``: a Python one
    (``client_main``) or, with ``kind`` 'c', one of package what_if_c, which sends
    the soak's request (or ``request``, a Predict.Request of any vessel) from its
    serialized bytes.
    """

    clients = ()   # none here: each process waits for the service itself

    def __init__(self, children, log_dir: Path, processes: int, clients: int,
                 concurrency: int, shape: RequestShape, busy_backoff: float | str,
                 kind: str = 'python', request=None):
        import sys

        self.dir = log_dir / 'clients'
        self.dir.mkdir(parents=True, exist_ok=True)
        for old in self.dir.iterdir():
            old.unlink()
        each = ['--clients', str(clients // processes), '--concurrency', str(concurrency),
                '--busy-backoff', str(busy_backoff), '--dir', str(self.dir)]
        if kind == 'c':
            from rclpy.serialization import serialize_message

            sent = self.dir / 'request.cdr'
            sent.write_bytes(serialize_message(request or make_request(shape)))
            command = [sys.executable, '-m', 'what_if_c.load', '--service', SERVICE,
                       '--request', str(sent), *each]
        else:
            command = [sys.executable, str(Path(__file__).resolve()), 'client', *each,
                       '--plans', str(shape.plans), '--plan-period', str(shape.plan_period),
                       '--answer-period', str(shape.answer_period),
                       '--steps', str(shape.steps)]
        self.processes = [children.start([*command, '--name', f'client{k}'], f'soak_client{k}')
                          for k in range(processes)]
        self.merged: Merged | None = None

    def begin(self, seconds: float, ready_within: float = 120.0) -> None:
        """Wait until every process is ready, then start them all for ``seconds``."""
        self.wait_ready(ready_within)
        (self.dir / 'start.tmp').write_text(f'{seconds}')
        (self.dir / 'start.tmp').rename(self.dir / 'start')

    def wait_ready(self, ready_within: float = 120.0) -> None:
        """Wait until every process has found the service (at once when they have)."""
        deadline = time.monotonic() + ready_within
        while len(list(self.dir.glob('*.ready'))) < len(self.processes):
            if any(p.poll() is not None for p in self.processes):
                raise RuntimeError(f'a soak client exited; see {self.dir.parent}')
            if time.monotonic() > deadline:
                raise RuntimeError(f'soak clients not ready within {ready_within:.0f} s')
            time.sleep(0.1)

    def settle(self, seconds: float) -> None:
        """Wait for every process to finish (each waits ``seconds`` for its answers)."""
        for process in self.processes:
            process.wait(timeout=seconds + 30)
        results = sorted(self.dir.glob('*.json'))
        if len(results) < len(self.processes):   # a process's figures would be lost
            raise RuntimeError(f'{len(self.processes) - len(results)} soak clients wrote no '
                               f'figures; see {self.dir.parent}/soak_client*.log')
        self.merged = Merged([json.loads(f.read_text()) for f in results])

    def figures(self) -> Merged:
        """Return the processes' figures together (after ``settle``)."""
        if self.merged is None:
            raise RuntimeError('soak clients not settled yet')
        return self.merged


def client_main(argv: list[str]) -> int:
    """One soak client process: ``python soak.py client --help``."""
    import rclpy
    from vessel_bringup.processes import rclpy_options

    from hybrid_predictor.middleware import use_client_profile

    parser = argparse.ArgumentParser(prog='soak.py client',
                                     description="One process of the soak's clients.")
    parser.add_argument('--clients', type=positive_int, required=True)
    parser.add_argument('--concurrency', type=positive_int, required=True)
    parser.add_argument('--plans', type=positive_int, required=True)
    parser.add_argument('--plan-period', type=float, required=True)
    parser.add_argument('--answer-period', type=float, required=True)
    parser.add_argument('--steps', type=positive_int, required=True)
    parser.add_argument('--busy-backoff', type=backoff, required=True)
    parser.add_argument('--dir', type=Path, required=True, help='where to meet the soak')
    parser.add_argument('--name', required=True)
    args = parser.parse_args(argv)
    use_client_profile(os.environ)
    context = rclpy.Context()
    rclpy.init(context=context, **rclpy_options())
    node = rclpy.create_node(f'soak_{args.name}', context=context)
    executor = staged_executor(2, context)
    executor.add_node(node)
    load = Load(node, args.clients, args.concurrency,
                RequestShape(args.plans, args.plan_period, args.answer_period, args.steps),
                args.busy_backoff)
    threading.Thread(target=executor.spin, daemon=True).start()
    try:
        for client in load.clients:
            client.wait_for_service(timeout_sec=30)
        (args.dir / f'{args.name}.ready').touch()
        while not (args.dir / 'start').exists():
            time.sleep(0.01)
        seconds = float((args.dir / 'start').read_text())
        load.begin(seconds)
        time.sleep(seconds)
        load.settle(30)
        out = args.dir / f'{args.name}.json.tmp'
        out.write_text(json.dumps(load.raw()))
        out.rename(args.dir / f'{args.name}.json')
    finally:
        executor.shutdown(timeout_sec=5)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    return 0


STAGES = ('to the node and through it', 'back over DDS', 'queued in the client',
          'taken (deserialized)', 'to the done callback')


def stage_figures(stages: list[tuple[int, ...]]) -> dict:
    """
    Return p50/p99 (ms) of each stage of the answers, and of the stages of the slowest 1 %.

    ``stages`` rows: (sent, written by the node, received, take begun, taken, done), ns.
    A take begun while DDS is still delivering the answer waits for it: "queued in the
    client" is then a few tens of microseconds below zero.
    """
    if not stages:
        return {}
    times = np.diff(np.asarray(stages, dtype=np.int64), axis=1) / 1e6
    total = times.sum(axis=1)
    slow = times[total >= np.percentile(total, 99)]
    return {name: {'p50': round(float(np.percentile(times[:, i], 50)), 1),
                   'p99': round(float(np.percentile(times[:, i], 99)), 1),
                   'mean_in_slowest_1_percent': round(float(slow[:, i].mean()), 1)}
            for i, name in enumerate(STAGES)}


def staged_executor(threads: int, context):
    """
    Return the soak's executor: it marks each answer's future with ``stages_ns``.

    (response written by the node, received by DDS in this process, take begun, taken),
    ns of the system clock DDS stamps with: where a slow answer spent its time.
    """
    from rclpy.executors import InvalidHandle

    from vessel_ros_bridge.executors import MultiThreadedExecutor

    class StagedExecutor(MultiThreadedExecutor):
        def _take_client(self, client):
            begun = time.time_ns()
            try:
                with client.handle:
                    header, response = client.handle.take_response(client.srv_type.Response)
            except InvalidHandle:
                return None
            taken = time.time_ns()

            async def _execute():
                if header is None:
                    return
                try:
                    future = client.get_pending_request(header.request_id.sequence_number)
                except KeyError:   # cancelled
                    return
                future.stages_ns = (header.source_timestamp, header.received_timestamp,
                                    begun, taken)
                future._set_executor(self)
                future.set_result(response)
            return _execute

    return StagedExecutor(num_threads=threads, context=context)


def soak(duration: float, clients: int, concurrency: int, shape: RequestShape, rtf: float,
         forecast_period: float = 1.0, busy_backoff: float | str = 0.2,
         log_dir: Path | None = None, predictor_params: tuple = (),
         client_processes: int = 1, client: str = 'c') -> dict:
    """Run the soak (see the module docstring) and return its figures."""
    from vessel_bringup.processes import Children

    log_dir = Path(log_dir or REPO / 'ros2_ws' / 'log' / 'soak')
    # The nodes are stopped however the soak ends: normally, by an error, or by SIGINT,
    # SIGTERM or SIGHUP of this process (a `timeout` around it).
    with Children(log_dir) as children:
        return _soak(children, log_dir, duration, clients, concurrency, shape, rtf,
                     forecast_period, busy_backoff, predictor_params, client_processes, client)


def _soak(children, log_dir: Path, duration: float, clients: int, concurrency: int,
          shape: RequestShape, rtf: float, forecast_period: float, busy_backoff: float | str,
          predictor_params, client_processes: int, client_kind: str) -> dict:
    from diagnostic_msgs.msg import DiagnosticArray
    import rclpy
    from vessel_bringup.processes import rclpy_options

    from hybrid_predictor.middleware import use_client_profile
    from hybrid_predictor_interfaces.msg import Forecast
    from vessel_ros_bridge.messages import seconds_from_stamp

    children.node('ship_sim_node', 'simulator', params={'seed': 5, 'real_time_factor': rtf})
    extra = [arg for p in predictor_params for arg in ('-p', p)]
    predictor = children.node('hybrid_predictor', 'predictor', *extra, params={
        'use_sim_time': True, 'max_plans': max(shape.plans, 1), 'horizon': shape.steps,
        'forecast_period': forecast_period})
    # This process asks as a controller would, with the what-if client's profile: set
    # after the nodes started, so they keep their own.
    client_middleware = use_client_profile(os.environ)
    context = rclpy.Context()
    rclpy.init(context=context, **rclpy_options())
    node = rclpy.create_node('soak_client', context=context)
    executor = staged_executor(4, context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    forecasts: list[tuple[float, float]] = []   # (wall s, stamp s)
    node.create_subscription(Forecast, '/vessel/forecast', lambda m: forecasts.append(
        (time.monotonic(), seconds_from_stamp(m.header.stamp))), 50)
    reports: list[tuple[float, int, str]] = []   # (wall s, level, message)
    service_counts: dict[str, str] = {}   # the node's own, from its newest report

    def on_diagnostics(msg) -> None:
        reports.extend((time.monotonic(), s.level[0], s.message) for s in msg.status)
        service_counts.update({kv.key: kv.value for s in msg.status for kv in s.values
                               if kv.key.startswith('service_')})

    node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 50)
    if client_processes > 1 or client_kind != 'python':
        load = ProcessLoads(children, log_dir, client_processes, clients, concurrency, shape,
                            busy_backoff, client_kind)
    else:
        load = Load(node, clients, concurrency, shape, busy_backoff)
    spinner.start()
    try:
        deadline = time.monotonic() + 180 + WINDOW_S / rtf
        while not forecasts and time.monotonic() < deadline:
            if predictor.poll() is not None:
                raise RuntimeError(f'predictor exited; see {log_dir / "predictor.log"}')
            time.sleep(0.2)
        if not forecasts:
            raise RuntimeError('no forecast within 180 s after the first window')
        for client in load.clients:
            client.wait_for_service(timeout_sec=30)
        memory_start = memory_mb(predictor.pid)
        load.begin(duration)   # client processes: once all are ready
        started = time.monotonic()
        warm_at, memory_warm = started + min(0.1 * duration, 60.0), None
        trace_every, rss_trace = duration / RSS_SAMPLES, []
        while time.monotonic() < started + duration:
            time.sleep(0.2)
            if memory_warm is None and time.monotonic() >= warm_at:
                memory_warm = memory_mb(predictor.pid)
            if time.monotonic() >= started + trace_every * len(rss_trace):
                rss_trace.append(round(memory_mb(predictor.pid)['VmRSS'], 1))
        ended = time.monotonic()
        memory_end = memory_mb(predictor.pid)
        memory_warm = memory_warm or memory_end
        # Every request sent must come back; give the last ones time to.
        load.settle(30)
        # One report more, so the node's counts include the last answers.
        settled = time.monotonic()
        while time.monotonic() < settled + 5 and not (reports and reports[-1][0] > settled):
            time.sleep(0.1)
        alive = predictor.poll() is None
    finally:
        executor.shutdown(timeout_sec=5)
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    during = [(w, s) for w, s in forecasts if started <= w <= ended]
    walls = np.array([w for w, _ in during] or [started])
    stamps = np.array([s for _, s in during])
    wall_gaps = np.diff(np.concatenate([[started], walls, [ended]]))
    stamp_gaps = np.diff(stamps) if len(stamps) > 1 else np.array([np.inf])
    during_reports = [(level, message) for w, level, message in reports
                      if started <= w <= ended]
    counted = load.figures()
    return {
        'duration_s': round(ended - started, 1),
        'busy_stages_ms': stage_figures(counted.busy_stages),
        'clients': clients, 'concurrency': concurrency, 'plans_per_request': shape.plans,
        'steps_per_plan': shape.steps,
        'plan_period_s': shape.plan_period, 'answer_period_s': shape.answer_period,
        'request_kb': counted.request_kb,
        'success_answer_kb': counted.success_answer_kb,
        'simulator_rtf': rtf, 'busy_backoff': busy_backoff,
        'client_middleware': client_middleware, 'client_processes': client_processes,
        'client': client_kind,
        'requests_sent': counted.sent,
        'requests_answered': counted.answered,
        'requests_success': counted.success,
        'requests_busy': counted.busy,
        'requests_failed_other': counted.failed,
        'failures': counted.failures,
        'requests_unanswered': counted.sent - counted.answered,
        'answered_percent': round(100.0 * counted.answered / max(counted.sent, 1), 3),
        'latency_p50_ms': percentile_ms(counted.latencies, 50),
        'latency_p99_ms': percentile_ms(counted.latencies, 99),
        'success_latency_p50_ms': percentile_ms(counted.success_latencies, 50),
        'success_latency_p99_ms': percentile_ms(counted.success_latencies, 99),
        'busy_latency_p50_ms': percentile_ms(counted.busy_latencies, 50),
        'busy_latency_p99_ms': percentile_ms(counted.busy_latencies, 99),
        'forecasts_published': len(during),
        'longest_silence_periods': round(float(stamp_gaps.max()) / forecast_period, 2),
        'longest_silence_wall_s': round(float(wall_gaps.max()), 3),
        'forecast_period_wall_s': round(forecast_period / rtf, 3),
        'rss_start_mb': round(memory_start['VmRSS'], 1),
        'rss_after_warm_up_mb': round(memory_warm['VmRSS'], 1),
        'rss_end_mb': round(memory_end['VmRSS'], 1),
        'rss_trace_mb': rss_trace,
        'rss_private_start_mb': round(memory_start['RssAnon'], 1),
        'rss_private_after_warm_up_mb': round(memory_warm['RssAnon'], 1),
        'rss_private_end_mb': round(memory_end['RssAnon'], 1),
        'rss_private_growth_after_warm_up_percent': growth(memory_warm, memory_end, 'RssAnon'),
        'rss_shared_memory_end_mb': round(memory_end['RssShmem'], 1),
        'rss_growth_percent': growth(memory_start, memory_end, 'VmRSS'),
        'rss_growth_after_warm_up_percent': growth(memory_warm, memory_end, 'VmRSS'),
        'diagnostics_reports': len(during_reports),
        'diagnostics_error_reports': sum(level == 2 for level, _ in during_reports),
        'diagnostics_warn_reports': sum(level == 1 for level, _ in during_reports),
        'diagnostics_error_messages': sorted({m for level, m in during_reports
                                              if level == 2})[:5],
        'predictor_service_counts': {k: int(v) for k, v in sorted(service_counts.items())},
        'predictor_alive': alive,
        'goals': GOALS,
    }


if __name__ == '__main__':
    import sys

    if sys.argv[1:2] != ['client']:
        sys.exit('usage: python soak.py client --help (the soak itself: offline/bench.py soak)')
    sys.exit(client_main(sys.argv[2:]))
