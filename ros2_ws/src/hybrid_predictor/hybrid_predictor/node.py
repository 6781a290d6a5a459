"""
The predictor node: a thin ROS 2 adapter around ``hybrid_models.engine``.

Inputs: the topics of the vessel's topic map (vessel file, ``recordings.topics``; the
patrol boat's are ``/vessel/odom``, ``/vessel/actuators``, ``/vessel/wind``), with the
message types it names, and optionally ``/vessel/control_plan``
(hybrid_predictor_interfaces/ControlPlan).
Outputs: ``/vessel/forecast`` (Forecast: hybrid forecast, its physical part, the
LSTM's bound, the trajectory), ``/vessel/forecast/path`` (nav_msgs/Path, made while it
has a subscriber),
``/vessel/forecast/skill`` (diagnostic_msgs/DiagnosticStatus: the live skill of the
model, on windows forecast again with the inputs then applied as each scored step
matures, ``hindsight`` and ``skill``) and ``/diagnostics`` (WARN when the vessel departs
from its model). Service ``~/predict`` (Predict): forecasts for candidate control plans,
evaluated as one batch. Window assembly, plan checks, plausibility limits and
health figures live in ROS-free modules of this package, and the state the node's
threads share in one of them (``core.PredictorCore``); the numerics in ``hybrid_models``.

Threads: one thread (``inputs``) reads, checks and stores the input samples and plans,
taken by ``what_if_c.inlet`` in the order DDS received them, whatever their topic: a
state topic the node cannot keep up with never holds the actuators back (as a callback
group per topic in a multi-threaded executor once did), and no executor's Python runs
per message (rclpy's single-threaded executor, which read in order too, cost a 100 Hz
state about 1 ms of the node's CPU; docs/predictor.md, "Inputs read in C"). One executor
thread (rclpy's single-threaded executor, ``executor_for``) serves /clock, parameters
and /diagnostics. Forecasting runs on a thread of its own (``forecast``),
woken by the inputs: at 100 Hz the multi-threaded executor's dispatch of a guard
condition and of each input to a pool cost a vehicle's state more than the forecast's
own compute (docs/predictor.md, "At the vehicle's rate"). ``~/predict`` is served by
a thread of its own in C (``what_if_c.door``), which admits at most
``service_capacity`` requests at a time and answers the rest "busy" at once, with the
time to come back, without the interpreter; the admitted ones are answered by a pool of
as many Python threads.

Health is judged on two clocks (``health``): message time and a steady wall clock, so a
paused or dead source under use_sim_time, which stops /clock with it, is ERROR too. The
status is one per node and vessel: its name is the node's fully qualified name, its
hardware id the namespace and vessel; every message names the topics as resolved.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from functools import partial
import gc
import math
import os
from pathlib import Path
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Path as PathMsg
import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType, JumpThreshold
from rclpy.duration import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from what_if_c.door import open_door
from what_if_c.inlet import open_inlet
from what_if_c.outlet import Outlet

from hybrid_models.checkpoint_format import CheckpointError
from hybrid_models.engine import Forecaster
from hybrid_predictor.core import PredictorCore, check_time_parameters
from hybrid_predictor.forecast_messages import path_message
from hybrid_predictor.middleware import use_service_profile
from hybrid_predictor.vessel_source import served_vessel
from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
from hybrid_predictor_interfaces.srv import Predict
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_datasets.topic_messages import channel_reader
from vessel_description import VesselError, load_vessel
from vessel_ros_bridge import messages
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
        engine = Forecaster.from_checkpoint(path, p['relative_threshold'],
                                            platform=p['compute_platform'])
        self.engine = engine
        self.spec, vessel_note = served_vessel(p['vessel'], engine.spec, str(path))
        self.get_logger().info(f'vessel {self.spec.name}: {vessel_note}')
        self.topic_map = topic_map_for(self.spec)
        self.get_logger().info(f'forecast bands: {engine.bands_note}')
        self.sim_time = bool(self.get_parameter('use_sim_time').value)
        # Topics as this node resolves them (namespace, remapping), for every message.
        self.resolved = {topic: self.resolve_topic_name(node_topic(topic))
                         for topic in self.topic_map.topics}
        self.plan_topic = self.resolve_topic_name(PLAN_TOPIC)
        self.core = PredictorCore(engine, self.spec, self.topic_map, p, self.resolved,
                                  self.sim_time)
        self._said: dict[str, float] = {}   # what was said last when (monotonic s)
        started = time.perf_counter()
        engine.warm_up(self.core.horizon, window=engine.window, max_batch=p['max_plans'])
        # Everything loaded so far (torch, JAX, the compiled forecasts) lives as long as the
        # node: kept out of the cyclic collector, whose full passes over it stalled every
        # thread for up to 120 ms (measured at 100 Hz; forecasts then missed their state).
        gc.collect()
        gc.freeze()
        self.get_logger().info(
            f'model {engine.model_id} ({path}); window {engine.window}, horizon '
            f'{self.core.horizon}, relative threshold {engine.relative_threshold}, bound '
            f'{np.round(engine.bound, 5).tolist()}; compiled in '
            f'{time.perf_counter() - started:.1f} s')
        if self.core.unbounded:
            self.get_logger().warning(self.core.unbounded)

        # Sent with the interpreter lock released: rclpy's publish held it while rcl handed
        # a quadrotor's forecast to a subscriber (0.5 ms a state), and the inputs waited.
        self.forecast_out = Outlet(self.create_publisher(Forecast, FORECAST_TOPIC, 10))
        self.path_out = Outlet(self.create_publisher(PathMsg, PATH_TOPIC, 10))
        self.skill_pub = self.create_publisher(DiagnosticStatus, SKILL_TOPIC, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        input_types = messages.message_types(self.topic_map)
        self.readers = {topic: channel_reader(self.topic_map, topic) for topic in input_types}
        input_qos = QoSProfile(depth=p['input_queue_depth'], reliability=(
            ReliabilityPolicy.RELIABLE if p['reliable_inputs'] else ReliabilityPolicy.BEST_EFFORT))
        # The plans too: at 100 Hz a plan a state through the executor cost its Python turn.
        self.inlet = open_inlet(self, [(self.resolved[t], c, input_qos)
                                       for t, c in input_types.items()]
                                + [(self.plan_topic, ControlPlan, QoSProfile(depth=10))])
        # Set by the inputs when a state is due a forecast (core.pending holds it).
        self.forecast_due = threading.Event()
        self.stopping = False
        self.forecasting = threading.Thread(target=self._forecast_loop, name='forecast',
                                            daemon=True)
        self.forecasting.start()
        self.reading = threading.Thread(target=self._read_inputs, args=(
            [partial(self._on_input, topic) for topic in input_types]
            + [lambda msg, _received_ns: self._on_plan(msg)],),
            name='inputs', daemon=True)
        self.reading.start()
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
    def _check_parameters(self, parameters) -> SetParametersResult:
        values = dict(self.p, **{q.name: q.value for q in parameters})
        try:
            check_time_parameters(values)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _apply_parameters(self, parameters) -> None:
        self.p = dict(self.p, **{q.name: q.value for q in parameters})
        self.core.configure(self.p)
        self.diag_timer.timer_period_ns = int(self.p['diagnostics_period'] * 1e9)
        if any(q.name == 'restart_span' for q in parameters):
            self._watch_clock_jumps(self.p['restart_span'])
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
        self.core.clock_jumped(self._now())
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
    def _read_inputs(self, readers: list) -> None:
        """Take the inlet's messages in the order received until it closes (``inputs``)."""
        while True:
            try:
                taken = self.inlet.take()
            except RuntimeError as exc:   # rcl failed: the health report then sees silence
                if not self.stopping:
                    self.get_logger().error(f'inputs stopped: {exc}')
                return
            if taken is None:
                return
            for index, msg, received_ns in taken:
                try:
                    readers[index](msg, received_ns)
                except Exception as exc:  # noqa: BLE001 - the next message is read anew
                    self.core.count('input_failures')
                    self._say('input_failed', f'reading an input failed: {exc!r}', error=True)

    def _on_input(self, topic: str, msg, received_ns: int = 0) -> None:
        """Store one input sample; ``received_ns``: its arrival (ns, system clock; 0: now)."""
        try:
            values = self.readers[topic](msg)
        except (AttributeError, IndexError, TypeError, ValueError) as exc:
            self.core.count('malformed_inputs')
            self._say('malformed', f'rejected {self.resolved[topic]}: {exc}')
            return
        # Types without a header are timed on arrival, as offline conversion does.
        header = getattr(msg, 'header', None)
        now = self._now()
        t = messages.seconds_from_stamp(header.stamp) if header is not None else now
        reason, re_anchored = self.core.push(topic, t, values, now, None if header is None
                                             else header.frame_id, time.monotonic())
        if re_anchored is not None and re_anchored.at == now:
            self.get_logger().warning(
                f'{self.core.window.lines.describe(self.resolved[topic])}: window '
                f're-anchored (offset {re_anchored.old_offset:.1f} -> '
                f'{re_anchored.new_offset:.1f} s)')
        if reason:
            self._say('rejected', f'rejected input: {reason}')
            return
        if topic == self.core.window.state_topic:
            if self.core.state_arrived(t, received_ns or time.time_ns()):
                self.forecast_due.set()
        elif self.core.resume_deferred():
            self.forecast_due.set()
        self.core.input_event.set()

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

    def _on_plan(self, msg: ControlPlan) -> None:
        why = self.core.set_plan(msg)
        if why:
            self._say('plan_rejected', f'rejected {self.plan_topic}: {why}')

    # ------------------------------------------------------------------ forecasting
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _forecast_loop(self) -> None:
        """Forecast each pending state until the node is destroyed (the thread ``forecast``)."""
        while True:
            self.forecast_due.wait()
            # Cleared before the work: a state that comes meanwhile sets it again.
            self.forecast_due.clear()
            if self.stopping:
                return
            try:
                self._forecast_worker()
            except Exception as exc:  # noqa: BLE001 - the next state is forecast anew
                if self.stopping or not self.context.ok():   # publishing while stopping
                    return
                self.core.count('forecast_failures')
                self._say('forecast_failed', f'forecast failed: {exc!r}', error=True)

    def _forecast_worker(self) -> None:
        """Forecast the pending state once its sample is complete or the wait is over."""
        job = self.core.next_job(self._now)
        if job is None:
            return
        if job.result.ready and job.pending.forecast:
            outcome = self.core.forecast(job, self._now())
            if outcome.stale_plan:
                self._say('stale_plan', f'ignoring {self.plan_topic} {outcome.stale_plan}')
            if outcome.withheld:
                self._say('withheld', f'forecast withheld: {outcome.withheld}', error=True)
            else:
                self.forecast_out.publish(outcome.message)
                # Made only while someone listens (RViz, a recorder): at 100 Hz the path
                # cost a state 0.7 ms the forecast's next state waited for.
                if self.path_out.publisher.get_subscription_count():
                    self.path_out.publish(path_message(outcome.message, self.p['path_stride']))
        if job.scoring.ready:
            self.core.score(job.scoring)

    def destroy_node(self) -> None:
        """Close the inlet and the what-if door first: they live on this node."""
        self.stopping = True
        self.inlet.destroy()
        self.reading.join(timeout=5.0)
        self.door.close()
        self.answering.shutdown(wait=False, cancel_futures=True)
        self.forecast_due.set()
        self.forecasting.join(timeout=5.0)
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
        try:
            success, message, batch, withheld = self.core.what_if(
                request.plans, request.answer_period, self._now())
        except Exception as exc:  # noqa: BLE001 - a request must never stop the node
            self.get_logger().error(f'~/predict failed: {exc!r}')
            success, message = False, f'internal error: {exc}'
        try:
            if success:   # the Forecasts written in C from the batch's arrays
                self.door.answer_batch(token, message, withheld, batch)
            else:
                self.core.count('service_failed')
                self.door.answer(token, Predict.Response(success=False, message=message))
        except RuntimeError as exc:   # the door closed meanwhile: the node is stopping
            self.get_logger().info(f'~/predict answer not sent: {exc}')
        except Exception as exc:  # noqa: BLE001 - the door told the client; the log says why
            self.get_logger().error(f'~/predict answer could not be written: {exc!r}')

    # ------------------------------------------------------------------ health
    def _publish_diagnostics(self) -> None:
        service = dict(self.door.counts(), failure=self.door.failure or '')
        report = self.core.report(self._now(), time.monotonic(), self._clock_publishers(),
                                  service)
        name = self.get_fully_qualified_name()
        diag = DiagnosticArray(status=[status(report.level, f'{name}: forecast', report.message,
                                              self.hardware_id(), report.values)])
        diag.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(diag)
        self.skill_pub.publish(status(report.skill_level, f'{name}: skill',
                                      report.skill_message, self.hardware_id(),
                                      report.skill_values))

    def status_name(self) -> str:
        """Return the /diagnostics status name: the node's fully qualified name."""
        return f'{self.get_fully_qualified_name()}: forecast'

    def hardware_id(self) -> str:
        """Return the status's hardware id: the vessel, by its namespace and type."""
        namespace = self.get_namespace().strip('/')
        return f'{namespace}/{self.spec.name}' if namespace else self.spec.name


def status(level: int, name: str, message: str, hardware_id: str,
           values: dict) -> DiagnosticStatus:
    """Return a DiagnosticStatus of ``values`` (text)."""
    return DiagnosticStatus(level=bytes([level]), name=name, message=message,
                            hardware_id=hardware_id,
                            values=[KeyValue(key=k, value=v) for k, v in values.items()])


def executor_for(node: PredictorNode) -> SingleThreadedExecutor:
    """Return the executor of the predictor's clock, parameters and diagnostics (module doc)."""
    return SingleThreadedExecutor(context=node.context)


def main(args=None) -> int:
    """Run the predictor until interrupted; exit 2 with one line on a bad model or value."""
    note = use_service_profile(os.environ)
    return run_node(partial(PredictorNode, middleware_note=note), NODE_NAME,
                    (CheckpointError, FileNotFoundError, ValueError, VesselError,
                     TopicMapError), args, executor_for)


if __name__ == '__main__':
    sys.exit(main())
