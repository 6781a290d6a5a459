"""
Health under outages: what /diagnostics says, and when, per vessel and clock mode.

Starts ``--vessels`` simulated vessels, a simulator and a predictor each, in namespaces
boat1, boat2, ... With ``--clock sim`` boat1's simulator publishes /clock and every node
follows it (``use_sim_time``; one vessel by default); with ``--clock wall`` no /clock is
published and the nodes run on the wall clock (two vessels by default, as
``two_vessels.launch.py``). Once every predictor forecasts, each case given is done to
boat1 in turn, the next once boat1 forecasts and is OK again:

- ``pause``: its simulator is stopped (SIGSTOP) for ``--outage`` s, then continued;
- ``kill``: its simulator is killed (SIGKILL) and a new one with the same parameters is
  started ``--outage`` s later (under sim time its /clock starts over: a rewind);
- ``second-clock``: a second simulator publishing /clock on another time line runs in
  namespace ``intruder`` for ``--outage`` s from when its /clock publisher is on the
  graph (two /clock publishers; on the wall clock no node reads /clock and nothing may
  change);
- ``none``: nothing (a baseline).

Figures per case, in wall seconds: from the event (for ``second-clock``, the second
publisher's arrival) to boat1's predictor's first ERROR, and that message; from the end
of the outage to its first forecast and to its first OK after it; the worst level the
other vessels' predictors reported meanwhile; every status name and hardware id seen
(one per node and vessel, or shared).
"""

from __future__ import annotations

import contextlib
from functools import partial
import os
from pathlib import Path
import re
import signal
import threading
import time

REPO = Path(__file__).resolve().parents[2]
CASES = ('pause', 'kill', 'second-clock', 'none')
OK, WARN, ERROR, STALE = 0, 1, 2, 3
WINDOW_S = 60.0          # the patrol boat's window: simulated seconds before a forecast
START_TIME = 5000.0      # stamp of simulated t = 0 under sim time (a restart rewinds to it)
INTRUDER_START = 1.0e6   # the second clock's time line, far from the first
SETTLE_S = 5.0           # forecasting steadily this long before the event
INTRUDER_START_UP_S = 120.0   # at most this long for the second clock to be on the graph


# A run that takes seconds to minutes, for CI (`bench.py --quick outage`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--outage', '3', '--watch', '20')


def add_arguments(parser) -> None:
    """Declare this suite's options."""
    parser.add_argument('--case', choices=CASES, nargs='+', default=['pause'],
                        help='what happens to boat1, in turn (default pause)')
    parser.add_argument('--clock', choices=('sim', 'wall'), default='sim',
                        help='sim: nodes follow /clock of boat1; wall: the wall clock')
    parser.add_argument('--vessels', type=int, default=None,
                        help='vessels on the graph (default: 1 with sim, 2 with wall)')
    parser.add_argument('--outage', type=float, default=30.0,
                        help='seconds the outage lasts (default 30)')
    parser.add_argument('--watch', type=float, default=150.0,
                        help='at most this many seconds after the outage (default 150)')
    parser.add_argument('--rtf', type=float, default=None,
                        help='simulators, times real time (default: 10 sim, 1 wall)')
    parser.add_argument('--param', action='append', default=[], metavar='NAME:=VALUE',
                        help='a predictor parameter (repeatable)')
    parser.add_argument('--log-dir', type=Path, default=REPO / 'ros2_ws' / 'log' / 'outage',
                        help="the nodes' logs")


def run(args) -> dict:
    """Run one case with the command line's figures; return the JSON-ready result."""
    params = dict(p.split(':=', 1) for p in args.param)
    return outage(args.case, args.clock, args.vessels, args.outage, args.watch, args.rtf,
                  params, args.log_dir)


class Watcher:
    """Listens to /diagnostics and every vessel's forecasts (monotonic time of arrival)."""

    def __init__(self, namespaces: list[str]):
        from diagnostic_msgs.msg import DiagnosticArray
        import rclpy
        from vessel_bringup.processes import rclpy_options

        from hybrid_predictor_interfaces.msg import Forecast
        from vessel_ros_bridge.executors import MultiThreadedExecutor

        self.context = rclpy.Context()
        rclpy.init(context=self.context, **rclpy_options())
        self.node = rclpy.create_node(f'outage_watch_{os.getpid()}', context=self.context)
        self.lock = threading.Lock()
        self.statuses: list[tuple[float, object]] = []   # (t, DiagnosticStatus)
        self.forecasts: dict[str, list[float]] = {ns: [] for ns in namespaces}
        self.node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, 100)
        for ns in namespaces:
            self.node.create_subscription(Forecast, f'/{ns}/forecast',
                                          lambda _m, ns=ns: self._on_forecast(ns), 10)
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.executor.add_node(self.node)
        self.thread = threading.Thread(target=self.executor.spin, daemon=True)
        self.thread.start()

    def _on_diag(self, msg) -> None:
        now = time.monotonic()
        with self.lock:
            self.statuses.extend((now, s) for s in msg.status)

    def _on_forecast(self, ns: str) -> None:
        with self.lock:
            self.forecasts[ns].append(time.monotonic())

    def close(self) -> None:
        """Stop listening and leave the graph."""
        import rclpy

        self.executor.shutdown(timeout_sec=5)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)

    def clock_publishers(self) -> int:
        """Return how many publishers of /clock the graph shows."""
        return self.node.count_publishers('/clock')

    def keys(self) -> list[list[str]]:
        """Return every (status name, hardware id) seen."""
        with self.lock:
            return sorted({(s.name, s.hardware_id) for _, s in self.statuses})

    def of(self, ns: str, since: float, attributable: bool) -> list[tuple[float, int, str]]:
        """(t, level, message) of the statuses about ``ns`` after ``since``."""
        with self.lock:
            items = list(self.statuses)
        return [(t, s.level[0], s.message) for t, s in items if t >= since and (
            not attributable or f'/{ns}/' in s.name)]

    def forecasting(self, ns: str, since: float, count: int = 2) -> bool:
        """Whether ``ns`` published ``count`` forecasts after ``since``."""
        with self.lock:
            return sum(t >= since for t in self.forecasts[ns]) >= count


def outage(cases, clock: str = 'sim', vessels: int | None = None,
           outage_s: float = 30.0, watch_s: float = 150.0, rtf: float | None = None,
           params: dict | None = None, log_dir: Path | None = None) -> dict:
    """Run the cases in turn on one graph (see the module docstring); return the figures."""
    from vessel_bringup.processes import Children, say, wait_until

    cases = [cases] if isinstance(cases, str) else list(cases)
    if unknown := [c for c in cases if c not in CASES]:
        raise ValueError(f'cases must be among {CASES}, got {unknown}')
    sim_time = clock == 'sim'
    vessels = vessels or (1 if sim_time else 2)
    rtf = rtf or (10.0 if sim_time else 1.0)
    namespaces = [f'boat{k + 1}' for k in range(vessels)]
    log_dir = Path(log_dir or REPO / 'ros2_ws' / 'log' / 'outage')

    def simulator_params(k: int, clock_source: bool) -> dict:
        return {'seed': k + 1, 'real_time_factor': rtf, 'publish_clock': clock_source,
                'start_time': START_TIME if sim_time else 0.0,
                'world_frame': f'boat{k + 1}/odom', 'body_frame': f'boat{k + 1}/base_link'}

    with Children(log_dir) as children:
        watcher = Watcher(namespaces)
        try:
            sims = {}
            for k, ns in enumerate(namespaces):
                predictor = {'use_sim_time': sim_time, 'world_frame': f'{ns}/odom',
                             **(params or {})}
                children.node('hybrid_predictor', 'predictor', params=predictor,
                              namespace=ns)
                sims[ns] = children.node('ship_sim_node', 'simulator', namespace=ns,
                                         params=simulator_params(k, sim_time and k == 0))
            say(f'outage: {vessels} vessel(s), {clock} clock, {rtf:g}x real time; waiting '
                f'for every predictor to forecast')
            started = time.monotonic()
            ready = wait_until(lambda: all(watcher.forecasting(ns, started, 3)
                                           for ns in namespaces), 240 + WINDOW_S / rtf, 0.5)
            if not ready:
                raise RuntimeError(f'not every predictor forecast within the start-up '
                                   f'time; logs in {log_dir}')
            time.sleep(SETTLE_S)
            keys_before = watcher.keys()
            attributable = all(any(f'/{ns}/' in name for name, _ in keys_before)
                               for ns in namespaces)
            victim = namespaces[0]
            results = []
            for number, case in enumerate(cases):
                say(f'outage: {case} of {victim} for {outage_s:g} s')
                event = time.monotonic()
                if case == 'pause':
                    os.killpg(sims[victim].pid, signal.SIGSTOP)
                    time.sleep(outage_s)
                    os.killpg(sims[victim].pid, signal.SIGCONT)
                elif case == 'kill':
                    os.killpg(sims[victim].pid, signal.SIGKILL)
                    with contextlib.suppress(Exception):
                        sims[victim].wait(5)
                    children.processes.remove(sims[victim])
                    time.sleep(outage_s)
                    sims[victim] = children.node(
                        'ship_sim_node', 'simulator', namespace=victim,
                        params=simulator_params(0, sim_time),
                        label=f'{victim}_simulator_{number}')
                elif case == 'second-clock':
                    clocks = watcher.clock_publishers()
                    intruder = children.node(
                        'ship_sim_node', 'simulator', namespace='intruder',
                        label=f'intruder_simulator_{number}',
                        params={'seed': 9, 'real_time_factor': rtf,
                                'start_time': INTRUDER_START})
                    # The outage is the second clock on the graph, not its start-up, which
                    # on a loaded machine can outlast a short outage.
                    if not wait_until(lambda n=clocks: watcher.clock_publishers() > n,
                                      INTRUDER_START_UP_S, 0.1):
                        raise RuntimeError(f'the intruder published no /clock within '
                                           f'{INTRUDER_START_UP_S:g} s; logs in {log_dir}')
                    event = time.monotonic()
                    time.sleep(outage_s)
                    children.stop(intruder)
                else:
                    time.sleep(outage_s)
                resumed = time.monotonic()
                say('outage: over; watching the recovery')
                wait_until(partial(recovered, watcher, victim, resumed, attributable),
                           watch_s, 0.5)
                time.sleep(2.0)
                results.append(figures(watcher, case, namespaces, event, resumed,
                                       attributable))
            return {'clock': clock, 'vessels': vessels, 'rtf': rtf, 'outage_s': outage_s,
                    'statuses_attributable_to_a_vessel': attributable,
                    'status_keys': [list(k) for k in watcher.keys()],
                    'cases': results}
        finally:
            watcher.close()


def recovered(watcher: Watcher, ns: str, since: float, attributable: bool) -> bool:
    """Whether ``ns`` forecast again and said OK (or only WARN) after ``since``."""
    return watcher.forecasting(ns, since, 2) and any(
        level in (OK, WARN) for _, level, _ in watcher.of(ns, since, attributable))


def first_distinct(messages, count: int = 8) -> list[str]:
    """Return the first ``count`` distinct messages in order (numbers not compared)."""
    out, keys = [], set()
    for message in messages:
        key = re.sub(r'[0-9.]+', '#', message)
        if key not in keys:
            keys.add(key)
            out.append(message)
    return out[:count]


def figures(watcher: Watcher, case: str, namespaces: list[str], event: float,
            resumed: float, attributable: bool) -> dict:
    """Return the case's figures (wall seconds, relative to the event or the resumption)."""
    victim, others = namespaces[0], namespaces[1:]
    seen = watcher.of(victim, event, attributable)
    errors = [(t, message) for t, level, message in seen if level == ERROR]
    first_forecast = [t for t in watcher.forecasts[victim] if t >= resumed]
    first_ok = [t for t, level, _ in seen if level == OK and t >= resumed]
    first_no_error = [t for t, level, _ in seen if level in (OK, WARN) and t >= resumed]
    during = [(t, level, message) for t, level, message in seen if t < resumed]

    def rounded(value):
        return None if value is None else round(value, 2)

    out = {
        'case': case,
        'time_to_error_s': rounded(errors[0][0] - event if errors else None),
        'error_message': errors[0][1] if errors else None,
        'levels_during_outage': sorted({level for _, level, _ in during}),
        'error_messages': first_distinct(message for _, message in errors),
        'messages_after': first_distinct(message for t, _, message in seen if t >= resumed),
        'recovered_forecast_after_s': rounded(first_forecast[0] - resumed
                                              if first_forecast else None),
        'recovered_ok_after_s': rounded(first_ok[0] - resumed if first_ok else None),
        'recovered_no_error_after_s': rounded(first_no_error[0] - resumed
                                              if first_no_error else None),
        'last_message': seen[-1][2] if seen else None,
    }
    if attributable:
        out['other_vessels_worst_level'] = {
            ns: max((level for _, level, _ in watcher.of(ns, event, True)), default=None)
            for ns in others}
    return out
