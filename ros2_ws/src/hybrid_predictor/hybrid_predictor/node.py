"""
The predictor node: a thin ROS 2 adapter around ``hybrid_models.engine``.

Inputs: the topics of the vessel's topic map (vessel file, ``recordings.topics``; the
patrol boat's are ``/vessel/odom``, ``/vessel/actuators``, ``/vessel/wind``), with the
message types it names, and optionally ``/vessel/control_plan``
(hybrid_predictor_interfaces/ControlPlan).
Outputs: ``/vessel/forecast`` (Forecast: hybrid forecast, its physical part, the
LSTM's bound, the trajectory), ``/vessel/forecast/path`` (nav_msgs/Path),
``/vessel/forecast/skill`` (diagnostic_msgs/DiagnosticStatus: the live skill of the
model, on windows forecast again with the inputs then applied as each scored step
matures, ``hindsight`` and ``skill``) and ``/diagnostics`` (WARN when the vessel departs
from its model). Service ``~/predict`` (Predict): forecasts for candidate control plans,
evaluated as one batch. Window assembly, plan checks, plausibility limits and
health figures live in ROS-free modules of this package; the numerics in
``hybrid_models``.

Threads (a MultiThreadedExecutor, see ``executor_for``): each input topic and the plan
topic has a mutually exclusive callback group of its own (one topic's samples stay in
order) and only reads, checks and stores samples; forecasting runs in a group of its
own, woken by a guard condition; ``~/predict`` is served by a thread of its own in C
(``what_if_c.door``), which admits at most ``service_capacity`` requests at a time and
answers the rest "busy" at once, with the time to come back, without the interpreter;
the admitted ones are answered by a pool of as many Python threads;
/clock, parameters and /diagnostics keep the default group. None of them waits for
another, so no input callback starves: rclpy offers a group's ready subscriptions in a
fixed order, and when the inputs shared one group a state topic the node could not keep
up with won every turn and held the actuators back (a what-if refused for "actuators
silent" behind a simulator at 10x).

Health is judged on two clocks (``health``): message time and a steady wall clock, so a
paused or dead source under use_sim_time, which stops /clock with it, is ERROR too. The
status is one per node and vessel: its name is the node's fully qualified name, its
hardware id the namespace and vessel; every message names the topics as resolved.
"""

from __future__ import annotations

from array import array
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from functools import partial
import gc
import math
import os
from pathlib import Path
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup
from rclpy.clock import Clock, ClockType, JumpThreshold
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from what_if_c.door import open_door

from hybrid_models.bound import loosest
from hybrid_models.checkpoint_format import CheckpointError
from hybrid_models.engine import Forecaster
from hybrid_models.metrics import reported_steps
from hybrid_predictor.health import Health
from hybrid_predictor.held_wind import forecast_holding_wind, holds_wind
from hybrid_predictor.hindsight import Hindsight, Remade, applied_future
from hybrid_predictor.input_window import InputWindow
from hybrid_predictor.middleware import use_service_profile
from hybrid_predictor.plans import (
    PlanError,
    PlanLimits,
    answer_steps,
    answer_stride,
    bound_hit_fraction,
    check_plan_message,
    hold_latest,
    plan_controls,
    plan_rows,
    track,
)
from hybrid_predictor.plausibility import forecast_problem
from hybrid_predictor.schedule import ForecastSchedule
from hybrid_predictor.skill import LiveSkill, Settings
from hybrid_predictor.vessel_source import served_vessel
from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
from hybrid_predictor_interfaces.srv import Predict
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_datasets.topic_messages import channel_reader
from vessel_description import VesselError, load_vessel
from vessel_physics import frames
from vessel_ros_bridge import messages
from vessel_ros_bridge.executors import MultiThreadedExecutor
from vessel_ros_bridge.lifecycle import run_node
from vessel_ros_bridge.names import node_topic
from vessel_ros_bridge.parameters import declare_from_specs, load_specs, package_config

NODE_NAME = 'predictor'
# Relative names: they follow the node's namespace (/vessel/forecast by default).
FORECAST_TOPIC = 'forecast'
PATH_TOPIC = 'forecast/path'
PLAN_TOPIC = 'control_plan'
SKILL_TOPIC = 'forecast/skill'
DEFAULT_MODEL = ('models', 'default', 'model.safetensors')
CLOCK_TOPIC = '/clock'
# Repeated warnings (rejected inputs, plans, withheld forecasts) are said once per this
# many seconds each. Checked here: rclpy's own throttle costs about 0.3 ms a call, which
# a burst of rejected messages pays for every message (measured).
SAY_EVERY_S = 5.0


def default_model_path(vessel: str = '') -> Path:
    """
    Return the installed model shipped for ``vessel`` (a vessel file's name or path).

    The one in ``models/<vessel name>/`` where this package ships one (the Crazyflie),
    else the default model (the patrol boat; a vessel it does not fit is then refused by
    ``served_vessel`` in one line).
    """
    from ament_index_python.packages import get_package_share_directory

    share = Path(get_package_share_directory('hybrid_predictor'))
    if vessel:
        own = share / 'models' / load_vessel(vessel).name / DEFAULT_MODEL[-1]
        if own.is_file():
            return own
    return share.joinpath(*DEFAULT_MODEL)


@dataclass(frozen=True)
class Pending:
    """A state sample awaiting its forecast."""

    t: float              # its stamp (s, message clock)
    received_ns: int      # when it reached this process (ns, system clock)
    backlogged: bool      # it waited in the queue longer than backlog_skip
    forecast: bool = True  # False: its window is only scored (skill), not forecast


@dataclass(frozen=True)
class Assumed:
    """What a forecast assumed about the future controls (Forecast.controls_assumed)."""

    controls: str = Forecast.CONTROLS_HELD
    plan_id: str = ''
    plan_stamp: object = None   # builtin_interfaces/Time of the plan, None when held


class PredictorNode(Node):
    """Serve forecasts of the vessel's motion from the latest measurement window."""

    def __init__(self, middleware_note: str = '', **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        if middleware_note:
            self.get_logger().info(middleware_note)
        p = declare_from_specs(self, load_specs(package_config('hybrid_predictor',
                                                               'predictor.yaml')))
        self.p = p
        path = Path(p['model_path']) if p['model_path'] else default_model_path(p['vessel'])
        self.engine = Forecaster.from_checkpoint(path, p['relative_threshold'])
        self.spec, vessel_note = served_vessel(p['vessel'], self.engine.spec, str(path))
        self.get_logger().info(f'vessel {self.spec.name}: {vessel_note}')
        self.topic_map = topic_map_for(self.spec)
        self.horizon = p['horizon'] or self.spec.horizon
        self.limits = PlanLimits.of(self.spec)
        self.bands = self.engine.bands
        self.get_logger().info(f'forecast bands: {self.engine.bands_note}')
        self.sim_time = bool(self.get_parameter('use_sim_time').value)
        window = self.engine.window
        check_time_parameters(p)
        # Topics as this node resolves them (namespace, remapping), for every message.
        self.resolved = {topic: self.resolve_topic_name(node_topic(topic))
                         for topic in self.topic_map.topics}
        self.plan_topic = self.resolve_topic_name(PLAN_TOPIC)
        self.window = InputWindow.of_node(self.topic_map, window, self.spec.dt, p,
                                          labels=self.resolved)
        # A threshold schedule (the do-no-harm selection's) is reported by its loosest
        # entry, and the bound by every step's largest: what holds at every step.
        self.step_bounds = self.engine.step_bounds(self.horizon)
        self.residual_bound = self.step_bounds.max(axis=0)
        self.bounded = bool(np.isfinite(self.residual_bound).all())
        threshold = self.engine.relative_threshold
        self.relative_threshold = loosest(threshold)
        unbounded = '' if self.bounded or p['allow_unbounded'] else (
            f'model {self.engine.model_id} is served unbounded (relative threshold '
            f'{threshold}): the LSTM correction has no bound; set allow_unbounded:=true if '
            f'that is meant, or a relative_threshold')
        self.health = Health(silence_error=self._silence_error(p), max_age=p['max_age'],
                             watchdog=p['watchdog_timeout'],
                             rejection_warn_fraction=p['rejection_warn_fraction'],
                             sim_time=self.sim_time,
                             state_topic=self.resolved[self.window.state_topic],
                             unbounded=unbounded)
        self.schedule = ForecastSchedule(p['forecast_period'])
        self.skill = live_skill(self.spec, self.horizon, p)
        # The model is judged on forecasts re-made with the inputs then applied.
        self.hindsight = Hindsight(self.skill, self._remake)
        # The newest row scored (s): hindsight.newest, copied where the input thread reads
        # it without the skill lock.
        self.scored_until: float | None = None
        # Guards the skill tracker, which the forecast and diagnostics threads share.
        self.skill_lock = threading.Lock()
        # Guards the window, the pending state, the plan, the schedule and the health
        # figures, which the input, forecast, service and clock threads share; held only
        # briefly, but a window assembly takes milliseconds under it.
        self.lock = threading.Lock()
        # Guards the counters alone: an answer counts itself without waiting for a window
        # assembly or a forecast in progress.
        self.count_lock = threading.Lock()
        # One what-if batch at a time: the engine already spreads a batch over the cores.
        self.batch_lock = threading.Lock()
        self.input_event = threading.Event()
        self._said: dict[str, float] = {}   # what was said last when (monotonic s)
        self.counts = {'malformed_inputs': 0, 'plans_rejected': 0, 'states_skipped_as_backlog':
                       0, 'clock_resets': 0, 'service_failed': 0,
                       'forecasts_before_sample_complete': 0}
        self.latest_plan: tuple[ControlPlan, dict] | None = None
        self.pending: Pending | None = None
        # A scheduled state whose actuator or wind samples had not arrived when its wait
        # ended (a burst read topic by topic): forecast once they catch up with it.
        self.deferred: Pending | None = None
        self.timeline_changes = 0   # restarts and re-anchors the schedule has seen
        started = time.perf_counter()
        self.engine.warm_up(self.horizon, window=window, max_batch=p['max_plans'])
        # Everything loaded so far (torch, JAX, the compiled forecasts) lives as long as the
        # node: kept out of the cyclic collector, whose full passes over it stalled every
        # thread for up to 120 ms (measured at 100 Hz; forecasts then missed their state).
        gc.collect()
        gc.freeze()
        self.get_logger().info(
            f'model {self.engine.model_id} ({path}); window {window}, horizon '
            f'{self.horizon}, relative threshold {self.engine.relative_threshold}, bound '
            f'{np.round(self.engine.bound, 5).tolist()}; compiled in '
            f'{time.perf_counter() - started:.1f} s')
        if unbounded:
            self.get_logger().warning(unbounded)

        self.forecast_pub = self.create_publisher(Forecast, FORECAST_TOPIC, 10)
        self.path_pub = self.create_publisher(PathMsg, PATH_TOPIC, 10)
        self.skill_pub = self.create_publisher(DiagnosticStatus, SKILL_TOPIC, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        input_qos = QoSProfile(depth=p['input_queue_depth'], reliability=(
            ReliabilityPolicy.RELIABLE if p['reliable_inputs'] else ReliabilityPolicy.BEST_EFFORT))
        self.readers = {}
        for topic, msg_class in messages.message_types(self.topic_map).items():
            self.readers[topic] = channel_reader(self.topic_map, topic)
            self.create_subscription(msg_class, self.resolved[topic],
                                     partial(self._on_input, topic), input_qos,
                                     callback_group=MutuallyExclusiveCallbackGroup())
        self.create_subscription(ControlPlan, PLAN_TOPIC, self._on_plan, 10,
                                 callback_group=MutuallyExclusiveCallbackGroup())
        self.forecast_trigger = self.create_guard_condition(
            self._forecast_worker, callback_group=MutuallyExclusiveCallbackGroup())
        # Every request is answered (success, failure or busy), reliable and keep-all,
        # by the door's thread: a refusal never waits for the interpreter, which the
        # forecasts' Python work holds (docs/predictor.md, "Soak benchmark").
        self.door = open_door(self, '~/predict', p['service_capacity'], p['max_retry_after'])
        self.answering = ThreadPoolExecutor(max_workers=p['service_capacity'],
                                            thread_name_prefix='predict')
        threading.Thread(target=self._take_admitted, name='predict-door', daemon=True).start()
        self.diag_timer = self.create_timer(p['diagnostics_period'], self._publish_diagnostics,
                                            clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.jump_handle = None
        self._watch_clock_jumps(p['restart_span'])
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)

    # ------------------------------------------------------------------ parameters
    def _silence_error(self, p: dict) -> float:
        # A forecast period of 0 forecasts every state: expect one per model step then.
        return p['silence_error_periods'] * max(p['forecast_period'], self.spec.dt)

    def _check_parameters(self, parameters) -> SetParametersResult:
        values = dict(self.p, **{q.name: q.value for q in parameters})
        try:
            check_time_parameters(values)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters) -> None:
        p = dict(self.p, **{q.name: q.value for q in parameters})
        self.p = p
        with self.lock:
            self.window.configure(p['max_gap'], p['max_age'], p['max_future'],
                                  p['restart_span'], p['re_anchor_after'])
            self.window.plausibility.quaternion_tolerance = p['quaternion_tolerance']
            self.health.silence_error = self._silence_error(p)
            self.health.max_age = p['max_age']
            self.health.watchdog = p['watchdog_timeout']
            self.health.rejection_warn_fraction = p['rejection_warn_fraction']
            if self.schedule.period != p['forecast_period']:
                self.schedule = ForecastSchedule(p['forecast_period'])
        self.diag_timer.timer_period_ns = int(p['diagnostics_period'] * 1e9)
        if any(q.name == 'restart_span' for q in parameters):
            self._watch_clock_jumps(p['restart_span'])
        self.get_logger().info('parameters set: ' + ', '.join(
            f'{q.name}={q.value}' for q in parameters))

    def _watch_clock_jumps(self, span: float) -> None:
        # The node's clock (ROS time with use_sim_time) going back more than restart_span
        # means /clock restarted: the window holds samples of another time line.
        threshold = JumpThreshold(min_forward=None, min_backward=Duration(
            nanoseconds=-int(span * 1e9)), on_clock_change=True)
        if self.jump_handle is not None:
            self.jump_handle.unregister()
        self.jump_handle = self.get_clock().create_jump_callback(
            threshold, post_callback=self._on_clock_jump)

    def _on_clock_jump(self, jump) -> None:
        with self.lock:
            self.window.clear()
            self.schedule.reset()
            self.pending = self.deferred = None
            self.health.clock_jumped(self._now())
            self.window.keep_from(None, 0.0)
        with self.skill_lock:
            self.hindsight.reset()
            self.scored_until = None
        with self.count_lock:
            self.counts['clock_resets'] += 1
        self._say('clock_jump', f'clock jumped by {jump.delta.nanoseconds * 1e-9:.1f} s: '
                                f'window cleared ({self._clock_publishers_note()})')

    def _clock_publishers(self) -> list[str] | None:
        """Return the nodes publishing /clock (with use_sim_time), else None."""
        if not self.sim_time:
            return None
        return sorted(f'{i.node_namespace.rstrip("/")}/{i.node_name}'
                      for i in self.get_publishers_info_by_topic(CLOCK_TOPIC))

    def _clock_publishers_note(self) -> str:
        names = self._clock_publishers()
        if names is None:
            return 'wall clock'
        return f'{len(names)} publisher(s) on {CLOCK_TOPIC}: {", ".join(names) or "none"}'

    # ------------------------------------------------------------------ inputs
    def _on_input(self, topic: str, msg, info=None) -> None:
        try:
            values = self.readers[topic](msg)
        except (AttributeError, IndexError, TypeError, ValueError) as exc:
            with self.count_lock:
                self.counts['malformed_inputs'] += 1
            self._say('malformed', f'rejected {self.resolved[topic]}: {exc}')
            return
        # Types without a header are timed on arrival, as offline conversion does.
        header = getattr(msg, 'header', None)
        now = self._now()
        t = messages.seconds_from_stamp(header.stamp) if header is not None else now
        is_state = topic == self.window.state_topic
        wall = time.monotonic()
        with self.lock:
            reason = self.window.push(topic, t, values, now,
                                      None if header is None else header.frame_id, wall)
            changes = self.window.restarts + len(self.window.re_anchors)
            if changes != self.timeline_changes:
                self.timeline_changes = changes
                self.schedule.reset()
                re_anchored = self.window.lines.latest
            else:
                re_anchored = None
            if not reason:
                self.health.record_input(now, wall, is_state)
        if re_anchored is not None and re_anchored.at == now:
            self.get_logger().warning(
                f'{self.window.lines.describe(self.resolved[topic])}: window re-anchored '
                f'(offset {re_anchored.old_offset:.1f} -> {re_anchored.new_offset:.1f} s)')
        if reason:
            self._say('rejected', f'rejected input: {reason}')
            return
        if is_state:
            self._on_state(t, info)
        else:
            self._resume_deferred()
        self.input_event.set()

    def _say(self, key: str, text: str, error: bool = False) -> None:
        """Log ``text`` at most once per SAY_EVERY_S seconds per ``key``."""
        now = time.monotonic()
        if now - self._said.get(key, -math.inf) < SAY_EVERY_S:
            return
        self._said[key] = now
        # One call line per severity: rclpy keys a logging call by its line and raises
        # ValueError when one line logs at two severities (the node died of it).
        if error:
            self.get_logger().error(text)
        else:
            self.get_logger().warning(text)

    def _on_state(self, t: float, info) -> None:
        with self.lock:
            due = self.schedule.due(t)
            # The skill needs every sample: between forecasts further apart than a
            # window, a window is assembled for it alone before its rows fall out.
            if not due and (self.pending is not None or not self._scoring_due(t)):
                return
            received_ns = (info or {}).get('received_timestamp') or time.time_ns()
            # A message that waited in the queue: newer ones are probably behind it.
            backlogged = due and (time.time_ns() - received_ns) * 1e-9 > \
                self.p['backlog_skip']
            self.pending = Pending(t, received_ns, backlogged, forecast=due)
            self.deferred = None
        with self.count_lock:
            self.counts['states_skipped_as_backlog'] += backlogged
        self.forecast_trigger.trigger()

    def _scoring_due(self, t: float) -> bool:
        # Two steps before the oldest unscored row would leave a window of rows ending
        # at t: assembled then, every row reaches the skill (_scoring_window lengthens a
        # window that starts later than the rows already scored).
        fed = self.scored_until
        return fed is None or t - fed >= (self.engine.window - 2) * self.spec.dt

    def _resume_deferred(self) -> None:
        with self.lock:
            if self.deferred is None or not self._synced(self.deferred.t):
                return
            self.pending, self.deferred = self.deferred, None
        self.forecast_trigger.trigger()

    def _on_plan(self, msg: ControlPlan) -> None:
        try:
            matrix = check_plan_message(msg, self.horizon, self.limits, exact=False)
        except PlanError as exc:
            with self.count_lock:
                self.counts['plans_rejected'] += 1
            self._say('plan_rejected', f'rejected {self.plan_topic}: {exc}')
            return
        with self.lock:
            self.latest_plan = (msg, matrix)

    # ------------------------------------------------------------------ forecasting
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _synced(self, t_state: float) -> bool:
        # A sample's actuators and wind may arrive just after its state.
        return all((stream.latest_time or -math.inf) >= t_state
                   for stream in self.window.streams.values())

    def _forecast_worker(self) -> None:
        """Forecast the pending state once its sample is complete or the wait is over."""
        started, started_msg = time.monotonic(), self._now()
        while True:
            with self.lock:
                pending = self.pending
                if pending is None:
                    return
                synced = self._synced(pending.t)
            self.input_event.clear()
            if pending.backlogged:
                # Read a burst through first, then forecast once from the latest window:
                # at the latest one forecast period of message time after the first
                # backlogged state (a wall second is ten periods at 10x simulated time),
                # plus at most one backlog_skip of wall time.
                left = started_msg + self.p['forecast_period'] - self._now()
                if left > 0 and self.input_event.wait(min(self.p['backlog_skip'], left)):
                    continue
            elif not synced:
                wait = started + self.p['sync_timeout'] - time.monotonic()
                if wait > 0:
                    self.input_event.wait(wait)
                    continue
            break
        with self.lock:
            pending, self.pending = self.pending, None
            if pending is None:
                return
            # The scheduled state, whose samples were awaited: not a newer one that
            # arrived meanwhile, perhaps before its actuators and wind.
            result = self._window(until=pending.t)
            scoring = self._scoring_window(result, pending.t)
            plan = self.latest_plan
            synced = self._synced(pending.t)
            if not result.ready and not synced:
                self.deferred = pending
        if result.ready and pending.forecast:
            # From a sample whose actuators or wind had not arrived when the wait was
            # over: an offline re-forecast of the same messages (re_forecast) differs.
            with self.count_lock:
                self.counts['forecasts_before_sample_complete'] += not synced
            self._forecast_and_publish(result, plan, pending.received_ns)
        if scoring.ready:
            self._score(scoring)

    def _scoring_window(self, result, until: float):
        """Return ``result`` lengthened back to the newest row scored, if it falls short."""
        fed = self.scored_until
        if not result.ready or fed is None or \
                result.t_end - fed <= (self.engine.window - 1) * self.spec.dt:
            return result
        longer = self.window.assemble(self._now(), until=until, since=fed)
        return longer if longer.ready else result

    def _window(self, until: float | None = None):
        result = self.window.assemble(self._now(), until)
        self.health.record_window(result.status, result.reason, result.fill)
        return result

    def _future_controls(self, result, plan) -> tuple[np.ndarray, Assumed, bool]:
        """Return the future controls (1, H, n), what they are, whether they hold the wind."""
        if plan is not None:
            msg, matrix = plan
            rows, why = plan_rows(matrix, messages.seconds_from_stamp(msg.header.stamp),
                                  result.t_end, self.spec.dt, self.horizon,
                                  self.p['plan_timeout'])
            if rows is not None:
                return (plan_controls(rows, result.controls[-1])[None], followed(msg),
                        holds_wind(self.spec, rows))
            if why:
                self._say('stale_plan', f'ignoring {self.plan_topic} {why}')
        return (hold_latest(result.controls[-1], self.horizon), Assumed(),
                holds_wind(self.spec, None))

    def _forecast_and_publish(self, result, plan, received_ns: int) -> None:
        future, assumed, held = self._future_controls(result, plan)
        forecast, _ = forecast_holding_wind(self.engine, result.states, result.controls,
                                            future, [held])
        (msg,) = self._forecast_messages(result, forecast.hybrid, forecast.physics,
                                         [assumed])
        problem = self._withheld(forecast.hybrid, msg)
        if problem:
            with self.lock:
                self.health.record_withheld(problem)
            self._say('withheld', f'forecast withheld: {problem}', error=True)
            return
        self.forecast_pub.publish(msg)
        latency_ms = (time.time_ns() - received_ns) * 1e-6
        with self.lock:
            self.health.record_forecast(self._now(), latency_ms, bound_hit_fraction(
                forecast.hybrid, forecast.physics, self.step_bounds), time.monotonic())
        self.path_pub.publish(self._path_message(msg))

    def _score(self, result) -> None:
        """Give the skill tracker, through hindsight, the window's new measurements."""
        dt = self.spec.dt
        times = result.t_end - dt * np.arange(len(result.states) - 1, -1, -1)
        names = self.spec.state_names
        with self.skill_lock:
            fed = self.hindsight.newest   # the newest measurement given so far
            if fed is not None and result.t_end < fed:   # the source restarted or moved
                self.hindsight.reset()
                self.scored_until = None
                fed = None
            new = times > (-math.inf if fed is None else fed + 0.5 * dt)
            states = frames.states_frd_to_flu(result.states[new], names)
            x, y, _ = frames.position_ned_to_enu(result.poses[new, 0], result.poses[new, 1])
            for row in zip(times[new], states, x, y, result.controls[new], strict=True):
                self.hindsight.add_measurement(*row)
            if self.hindsight.wants(result.t_end):
                w = self.engine.window   # the forecast's window: the newest rows
                self.hindsight.keep(result.t_end, replace(
                    result, states=result.states[-w:], controls=result.controls[-w:],
                    poses=result.poses[-w:]))
            self.scored_until = result.t_end
        with self.lock:   # the rows not yet scored are kept, at most one horizon back
            self.window.keep_from(self.scored_until, self.hindsight.delay)

    def _remake(self, result, applied: np.ndarray) -> Remade:
        """Return the forecast from window ``result`` under the ``applied`` controls (S, m)."""
        forecast = self.engine.forecast(result.states, result.controls,
                                        applied_future(applied, self.horizon))
        (msg,) = self._forecast_messages(result, forecast.hybrid, forecast.physics,
                                         [Assumed(Forecast.CONTROLS_PLAN)])
        n, horizon, levels = len(self.spec.state_names), msg.horizon, len(msg.band_levels)
        return Remade(np.reshape(msg.hybrid, (horizon, n)), np.asarray(msg.x),
                      np.asarray(msg.y), tuple(msg.band_levels),
                      np.reshape(msg.band_lower, (levels, horizon, n)),
                      np.reshape(msg.band_upper, (levels, horizon, n)),
                      np.reshape(msg.band_position_radius, (levels, horizon)), msg.band_note)

    def _withheld(self, hybrid: np.ndarray, msg: Forecast) -> str | None:
        return forecast_problem(hybrid, (np.asarray(msg.x), np.asarray(msg.y),
                                         np.asarray(msg.heading), np.asarray(msg.z)),
                                self.spec)

    def _forecast_messages(self, result, hybrid: np.ndarray, physics: np.ndarray,
                           assumed: list[Assumed], stride: int = 1) -> list[Forecast]:
        """
        Return one Forecast per plan of a batch, hybrid and physics (plans, H, n).

        ``stride`` > 1 keeps the steps ending at every ``stride`` steps (a what-if
        request's answer_period; ``plans.answer_steps``) in every array.
        """
        path = track(hybrid, result.pose, self.spec)   # one pass, all plans
        keep = answer_steps(self.horizon, stride)
        x_enu, y_enu, _ = frames.position_ned_to_enu(path.north[..., keep], path.east[..., keep])
        z_enu = None if path.down is None else -path.down[..., keep]
        heading = frames.heading_ned_to_enu(path.heading[..., keep])
        names = self.spec.state_names
        hybrid_flu = frames.states_frd_to_flu(hybrid[:, keep], names)
        physics_flu = frames.states_frd_to_flu(physics[:, keep], names)
        if self.bands is not None:
            lower, upper, radius = self.bands.bounds(hybrid)
            lower, upper = frames.interval_frd_to_flu(lower[..., keep, :],
                                                      upper[..., keep, :], names)
            radius = radius[..., keep]
        out = []
        for i in range(len(hybrid)):
            msg = Forecast()
            msg.header.stamp = messages.stamp_from_seconds(result.t_end)
            msg.header.frame_id = self.p['world_frame']
            msg.child_frame_id = self.p['body_frame']
            msg.step_period = float(self.spec.dt * stride)
            msg.horizon = len(keep)
            msg.state_names = list(self.spec.state_names)
            msg.state_units = list(self.spec.state_units)
            msg.vessel = self.spec.name
            msg.control_names = list(self.spec.control_names)
            msg.control_units = list(self.spec.control_units)
            msg.hybrid, msg.physics = doubles(hybrid_flu[i]), doubles(physics_flu[i])
            msg.residual_bound = doubles(self.residual_bound)
            msg.x, msg.y, msg.heading = doubles(x_enu[i]), doubles(y_enu[i]), doubles(
                heading[i])
            if z_enu is not None:
                msg.z = doubles(z_enu[i])
            msg.band_note = self.engine.bands_note
            if self.bands is not None:
                msg.band_levels = list(self.bands.levels)
                msg.band_lower, msg.band_upper = doubles(lower[i]), doubles(upper[i])
                msg.band_position_radius = doubles(radius)
            msg.model_id = self.engine.model_id
            msg.controls_assumed = assumed[i].controls
            msg.plan_id = assumed[i].plan_id
            if assumed[i].plan_stamp is not None:
                msg.plan_stamp = assumed[i].plan_stamp
            msg.relative_threshold = self.relative_threshold
            msg.bounded = self.bounded
            out.append(msg)
        return out

    def _path_message(self, forecast: Forecast) -> PathMsg:
        path = PathMsg()
        path.header = forecast.header
        t0 = messages.seconds_from_stamp(forecast.header.stamp)
        stride = self.p['path_stride']
        last = len(forecast.x) - 1
        for k in [*range(0, last, stride), last]:
            x, y, yaw = forecast.x[k], forecast.y[k], forecast.heading[k]
            pose = PoseStamped()
            pose.header.frame_id = forecast.header.frame_id
            pose.header.stamp = messages.stamp_from_seconds(t0 + (k + 1) * forecast.step_period)
            pose.pose.position.x, pose.pose.position.y = x, y
            if len(forecast.z):
                pose.pose.position.z = forecast.z[k]
            pose.pose.orientation.z = math.sin(yaw / 2)
            pose.pose.orientation.w = math.cos(yaw / 2)
            path.poses.append(pose)
        return path

    def destroy_node(self) -> None:
        """Close the what-if door first: its service lives on this node."""
        self.door.close()
        self.answering.shutdown(wait=False, cancel_futures=True)
        super().destroy_node()

    def _take_admitted(self) -> None:
        # Until the door closes: each admitted request is answered on the pool.
        while (taken := self.door.take()) is not None:
            try:
                self.answering.submit(self._answer, *taken)
            except RuntimeError:   # the pool shut down: the node is being destroyed
                return
        if self.door.failure:
            self.get_logger().error(f'~/predict stopped: {self.door.failure}')

    def _answer(self, token: int, request) -> None:
        response = Predict.Response()
        try:
            response.success, response.message, response.forecasts = self._predict(
                request.plans, request.answer_period)
        except Exception as exc:  # noqa: BLE001 - a request must never stop the node
            self.get_logger().error(f'~/predict failed: {exc!r}')
            response.success, response.message = False, f'internal error: {exc}'
        if not response.success:
            response.forecasts = []
            with self.count_lock:
                self.counts['service_failed'] += 1
        try:
            self.door.answer(token, response)
        except RuntimeError as exc:   # the door closed meanwhile: the node is stopping
            self.get_logger().info(f'~/predict answer not sent: {exc}')

    def _predict(self, plans, answer_period: float) -> tuple[bool, str, list]:
        """Return (success, message, forecasts) for a request's plans."""
        if not 1 <= len(plans) <= self.p['max_plans']:
            return False, f'send 1 to {self.p["max_plans"]} plans, got {len(plans)}', []
        try:   # every plan, as a whole, before any window or model work
            stride = answer_stride(answer_period, self.spec.dt, self.horizon)
            matrices = [check_plan_message(plan, self.horizon, self.limits, index=i)
                        for i, plan in enumerate(plans)]
        except PlanError as exc:
            return False, str(exc), []
        with self.lock:
            result = self._window()
        if not result.ready:
            return False, f'no forecast: {result.reason}', []
        future = np.stack([plan_controls(m, result.controls[-1]) for m in matrices])
        held = [holds_wind(self.spec, m) for m in matrices]
        with self.batch_lock:
            forecast, _ = forecast_holding_wind(self.engine, result.states, result.controls,
                                                future, held)
        out = self._forecast_messages(result, forecast.hybrid, forecast.physics,
                                      [followed(plan) for plan in plans], stride)
        for i, msg in enumerate(out):
            # Every step's states are checked; a non-finite track between the answer's
            # steps would carry on to its last step, which every answer holds.
            problem = self._withheld(forecast.hybrid[i], msg)
            if problem:
                return False, f'plan {i}: forecast withheld: {problem}', []
        return True, f'{len(plans)} forecasts from the window ending at ' \
                     f'{result.t_end:.3f} s', out

    # ------------------------------------------------------------------ health
    def _publish_diagnostics(self) -> None:
        clock_publishers = self._clock_publishers()
        with self.count_lock:
            counts = dict(self.counts)
        door = self.door.counts()
        # Every refusal is the door's, given without the interpreter: "unread" by Python.
        counts.update(service_requests=door['requests'], service_busy=door['refused'],
                      service_busy_unread=door['refused'])
        with self.skill_lock:
            departure = self.skill.departure()
            departure_line = self.skill.describe(departure)
            summary = self.skill.summary()
            skill_counts = {**self.skill.counts, **self.hindsight.counts}
        with self.lock:
            self.health.departure = departure_line
            self.health.service_stopped = self.door.failure or ''
            rejected = self.window.rejected_counts()
            accepted = sum(s.counts.accepted for s in self.window.streams.values())
            rejected['malformed'] = counts.pop('malformed_inputs')
            newest = self.window.streams[self.window.state_topic].latest_time
            level, message, values = self.health.report(
                self._now(), newest, accepted, rejected, wall=time.monotonic(),
                lines=self.window.lines, clock_publishers=clock_publishers)
            counts['source_restarts'] = self.window.restarts
        values.update({k: str(v) for k, v in counts.items()})
        values.update({'model_id': self.engine.model_id, 'vessel': self.spec.name,
                       'relative_threshold': f'{self.relative_threshold:g}',
                       'bounded': str(self.bounded).lower()})
        status = DiagnosticStatus(level=bytes([level]), name=self.status_name(),
                                  message=message, hardware_id=self.hardware_id())
        status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        diag = DiagnosticArray(status=[status])
        diag.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(diag)
        self.skill_pub.publish(self._skill_status(departure, departure_line, summary,
                                                  skill_counts))

    def _skill_status(self, departure, line: str, summary: dict,
                      counts: dict) -> DiagnosticStatus:
        """Return the rolling skill summary as a status (forecast/skill)."""
        if departure.active:
            level, message = DiagnosticStatus.WARN, line
        elif not departure.judged:
            level, message = DiagnosticStatus.OK, f'scored; departure {departure.note}'
        else:
            level, message = DiagnosticStatus.OK, (
                f'matured forecasts within their {100 * self.p["skill_level"]:g} % band')
        values = {k: str(v) for k, v in counts.items()}
        values['window_s'] = f'{self.p["skill_window"]:g}'
        units = dict(zip(self.spec.state_names, self.spec.state_units, strict=True))
        for step, per in summary.items():
            ahead = f'{step * self.spec.dt:g}s'
            for name, score in per.items():
                unit = units.get(name, 'm')
                values[f'{name}@{ahead}_n'] = str(score['n'])
                values[f'{name}@{ahead}_rmse_{unit}'] = f'{score["rmse"]:.4g}'
                for band, cover in score['coverage'].items():
                    values[f'{name}@{ahead}_in{100 * band:g}'] = f'{cover:.3f}'
        return DiagnosticStatus(level=level, name=f'{self.get_fully_qualified_name()}: skill',
                                message=message, hardware_id=self.hardware_id(),
                                values=[KeyValue(key=k, value=v) for k, v in values.items()])

    def status_name(self) -> str:
        """Return the /diagnostics status name: the node's fully qualified name."""
        return f'{self.get_fully_qualified_name()}: forecast'

    def hardware_id(self) -> str:
        """Return the status's hardware id: the vessel, by its namespace and type."""
        namespace = self.get_namespace().strip('/')
        return f'{namespace}/{self.spec.name}' if namespace else self.spec.name


def check_time_parameters(p: dict) -> None:
    """Raise ValueError unless the time parameters fit together (ranges are the YAML's)."""
    if p['restart_span'] < p['max_age']:
        raise ValueError(f'restart_span ({p["restart_span"]:g} s) must be at least max_age '
                         f'({p["max_age"]:g} s): a fresh sample is never a restart')


def live_skill(spec, horizon: int, p: dict) -> LiveSkill:
    """Return the skill tracker of a vessel's forecasts (``skill_*`` parameters)."""
    settings = Settings(p['skill_forecast_period'], p['skill_window'], p['skill_min_samples'],
                        p['skill_warn_coverage'], p['skill_clear_coverage'],
                        p['skill_sustain'], p['skill_level'])
    return LiveSkill(spec.state_names, reported_steps(horizon), settings, spec.dt)


def doubles(values) -> array:
    """
    Return values as a flat array('d') for a float64[] message field.

    rclpy checks a list element by element, an array('d') at once; filling it from the
    bytes of a NumPy array is a copy, where array('d', ndarray) converts every element.
    """
    out = array('d')
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def followed(plan: ControlPlan) -> Assumed:
    """Return what a forecast following ``plan`` assumed."""
    return Assumed(Forecast.CONTROLS_PLAN, plan.plan_id, plan.header.stamp)


def executor_for(node: PredictorNode) -> MultiThreadedExecutor:
    """Return the executor the predictor spins in, with ``executor_threads(node)``."""
    return MultiThreadedExecutor(num_threads=executor_threads(node))


def executor_threads(node: PredictorNode) -> int:
    """
    Return the threads the node's executor needs so no callback group waits for one.

    One per input topic and the plan topic, and one each for forecasting and the default
    group; ``~/predict`` has threads of its own (the door's and its answering pool).
    """
    return len(node.readers) + 3


def main(args=None) -> int:
    """Run the predictor until interrupted; exit 2 with one line on a bad model or value."""
    note = use_service_profile(os.environ)
    return run_node(partial(PredictorNode, middleware_note=note), NODE_NAME,
                    (CheckpointError, FileNotFoundError, ValueError, VesselError,
                     TopicMapError), args, executor_for)


if __name__ == '__main__':
    sys.exit(main())

