"""
The predictor node: a thin ROS 2 adapter around ``hybrid_models.engine``.

Inputs: the topics of the vessel's topic map (vessel file, ``recordings.topics``; the
patrol boat's are ``/vessel/odom``, ``/vessel/actuators``, ``/vessel/wind``), with the
message types it names, and optionally ``/vessel/control_plan``
(hybrid_predictor_interfaces/ControlPlan).
Outputs: ``/vessel/forecast`` (Forecast: hybrid forecast, its physical part, the
LSTM's bound, the trajectory), ``/vessel/forecast/path`` (nav_msgs/Path) and
``/diagnostics``. Service ``~/predict`` (Predict): forecasts for candidate control
plans, evaluated as one batch. Window assembly, plan checks and health figures live in
ROS-free modules of this package; the numerics in ``hybrid_models``.
"""

from __future__ import annotations

from array import array
from functools import partial
import importlib
import math
from pathlib import Path
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
import numpy as np
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from hybrid_models.checkpoint import CheckpointError
from hybrid_models.engine import ForecastEngine
from hybrid_predictor.health import Health
from hybrid_predictor.input_window import InputWindow, channel_reader
from hybrid_predictor.plans import (
    ActuatorLimits,
    PlanError,
    bound_hit_fraction,
    hold_latest,
    plan_controls,
    track,
)
from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
from hybrid_predictor_interfaces.srv import Predict
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel
from vessel_physics import frames
from vessel_ros_bridge import messages
from vessel_ros_bridge.lifecycle import run_node
from vessel_ros_bridge.names import node_topic
from vessel_ros_bridge.parameters import declare_from_specs, load_specs, package_config

NODE_NAME = 'predictor'
# Relative names: they follow the node's namespace (/vessel/forecast by default).
FORECAST_TOPIC = 'forecast'
PATH_TOPIC = 'forecast/path'
PLAN_TOPIC = 'control_plan'
DEFAULT_MODEL = ('models', 'default', 'model.safetensors')
PLAN_FIELDS = ('shaft_speed', 'rudder_port', 'rudder_stbd', 'wind_speed', 'wind_direction')
# The controls a ControlPlan message gives (its fields are the patrol boat's).
PLAN_CONTROLS = ('n', 'delta_port', 'delta_stbd', 'wind_speed', 'wind_dir_cos',
                 'wind_dir_sin')


def default_model_path() -> Path:
    """Return the installed path of the model shipped with this package."""
    from ament_index_python.packages import get_package_share_directory

    return Path(get_package_share_directory('hybrid_predictor')).joinpath(*DEFAULT_MODEL)


class PredictorNode(Node):
    """Serve forecasts of the vessel's motion from the latest measurement window."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        p = declare_from_specs(self, load_specs(package_config('hybrid_predictor',
                                                               'predictor.yaml')))
        self.p = p
        path = Path(p['model_path']) if p['model_path'] else default_model_path()
        self.engine = ForecastEngine.from_checkpoint(path)
        model = self.engine.model
        if p['relative_threshold'] > 0:
            model.set_threshold(p['relative_threshold'])
            self.engine = ForecastEngine(model, model_id=self.engine.model_id,
                                         config=self.engine.config)
        self.spec = model.spec
        if p['vessel']:
            load_vessel(p['vessel']).check_compatible(self.spec, f'model {path}')
        self.topic_map = topic_map_for(self.spec)
        self.horizon = p['horizon'] or self.spec.horizon
        self.limits = plan_limits(self.spec)
        window = self.engine.window
        self.window = InputWindow(self.topic_map, window, self.spec.dt, p['max_gap'],
                                  p['max_age'])
        self.health = Health()
        self.rejected = {'malformed': 0}
        self.last_forecast_t = -math.inf
        self.latest_plan: ControlPlan | None = None
        self.pending_ns: int | None = None   # arrival of a state awaiting its forecast
        self.skipped_backlog = 0
        self.sync_timer = None
        started = time.perf_counter()
        self.engine.warm_up(self.horizon, window=window, max_batch=p['max_plans'])
        self.get_logger().info(
            f'model {self.engine.model_id} ({path}); window {window}, horizon '
            f'{self.horizon}, bound {np.round(self.engine.bound, 5).tolist()}; compiled in '
            f'{time.perf_counter() - started:.1f} s')

        self.forecast_pub = self.create_publisher(Forecast, FORECAST_TOPIC, 10)
        self.path_pub = self.create_publisher(PathMsg, PATH_TOPIC, 10)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', 10)
        depth = p['input_queue_depth']
        self.readers = {}
        for topic, msg_class in input_types(self.topic_map).items():
            self.readers[topic] = channel_reader(self.topic_map, topic)
            self.create_subscription(msg_class, node_topic(topic),
                                     partial(self._on_input, topic), depth)
        self.create_subscription(ControlPlan, PLAN_TOPIC, self._on_plan, 10)
        self.create_service(Predict, '~/predict', self._on_predict)
        self.create_timer(p['diagnostics_period'], self._publish_diagnostics,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------------ inputs
    def _push(self, stream: str, stamp, values) -> bool:
        reason = self.window.push(stream, messages.seconds_from_stamp(stamp), values)
        if reason:
            self.get_logger().warning(f'rejected input: {reason}', throttle_duration_sec=5.0)
        return reason is None

    def _on_input(self, topic: str, msg, info=None) -> None:
        try:
            values = self.readers[topic](msg)
        except (AttributeError, IndexError, TypeError, ValueError) as exc:
            self.rejected['malformed'] += 1
            self.get_logger().warning(f'rejected {topic}: {exc}', throttle_duration_sec=5.0)
            return
        # Types without a header are timed on arrival, as offline conversion does.
        stamp = msg.header.stamp if hasattr(msg, 'header') else \
            self.get_clock().now().to_msg()
        if not self._push(topic, stamp, values):
            return
        if topic == self.window.state_topic:
            self._on_state(messages.seconds_from_stamp(stamp), info)
        else:
            self._forecast_when_synced()

    def _on_state(self, t: float, info) -> None:
        if t - self.last_forecast_t < self.p['forecast_period']:
            return
        received_ns = (info or {}).get('received_timestamp') or time.time_ns()
        self.pending_ns = received_ns
        if (time.time_ns() - received_ns) * 1e-9 > self.p['backlog_skip']:
            # A message that waited in the queue: newer ones are probably behind it.
            # Read on, and forecast once from the latest window when the queue is empty.
            self.skipped_backlog += 1
            self._arm_timer(self.p['backlog_skip'])
            return
        self._forecast_when_synced()

    def _forecast_when_synced(self) -> None:
        # A sample's actuators and wind may arrive just after its state: wait for them
        # (up to sync_timeout) so the forecast never holds the previous second's controls.
        if self.pending_ns is None:
            return
        t_state = self.window.streams[self.window.state_topic].latest_time
        if all((stream.latest_time or -math.inf) >= t_state
               for stream in self.window.streams.values()):
            self._forecast_pending()
        else:
            self._arm_timer(self.p['sync_timeout'])

    def _arm_timer(self, seconds: float) -> None:
        if self.sync_timer is None:
            self.sync_timer = self.create_timer(seconds, self._forecast_pending,
                                                clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _forecast_pending(self) -> None:
        if self.sync_timer is not None:
            self.destroy_timer(self.sync_timer)
            self.sync_timer = None
        received_ns, self.pending_ns = self.pending_ns, None
        if received_ns is not None:
            self._forecast_and_publish(received_ns)

    def _on_plan(self, msg: ControlPlan) -> None:
        self.latest_plan = msg

    # ------------------------------------------------------------------ forecasting
    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _window(self):
        result = self.window.assemble(self._now())
        self.health.record_window(result.status, result.reason, result.fill, result.age)
        return result

    def _future_controls(self, result) -> np.ndarray:
        plan = self.latest_plan
        if plan is not None and self.limits is None:
            self.get_logger().warning(f'ignoring {PLAN_TOPIC}: {self._no_plans()}',
                                      throttle_duration_sec=5.0)
        elif plan is not None:
            age = result.t_end - messages.seconds_from_stamp(plan.header.stamp)
            if 0.0 <= age <= self.p['plan_timeout']:
                shift = int(round(age / self.spec.dt))
                fields = {f: np.asarray(getattr(plan, f))[shift:shift + self.horizon]
                          for f in PLAN_FIELDS}
                try:
                    return plan_controls(fields, result.controls[-1], self.horizon,
                                         self.limits)[None]
                except PlanError as exc:
                    self.get_logger().warning(f'ignoring {PLAN_TOPIC}: {exc}',
                                              throttle_duration_sec=5.0)
        return hold_latest(result.controls[-1], self.horizon)

    def _forecast_and_publish(self, received_ns: int) -> None:
        result = self._window()
        if not result.ready:
            return
        forecast = self.engine.forecast(result.states, result.controls,
                                        self._future_controls(result))
        msg = self._forecast_message(result, forecast.hybrid[0], forecast.physics[0])
        self.forecast_pub.publish(msg)
        self.last_forecast_t = result.t_end
        latency_ms = (time.time_ns() - received_ns) * 1e-6
        self.health.record_forecast(latency_ms, bound_hit_fraction(
            forecast.hybrid, forecast.physics, self.engine.bound))
        self.path_pub.publish(self._path_message(msg))

    def _forecast_message(self, result, hybrid: np.ndarray, physics: np.ndarray) -> Forecast:
        north, east, psi = track(hybrid, result.pose, self.spec)
        x_enu, y_enu, _ = frames.position_ned_to_enu(north, east)
        msg = Forecast()
        msg.header.stamp = messages.stamp_from_seconds(result.t_end)
        msg.header.frame_id = self.p['world_frame']
        msg.step_period = float(self.spec.dt)
        msg.horizon = self.horizon
        msg.state_names = list(self.spec.state_names)
        msg.state_units = list(self.spec.state_units)
        msg.vessel = self.spec.name
        msg.control_names = list(self.spec.control_names)
        # Typed arrays: rclpy checks a list element by element, an array('d') at once.
        msg.hybrid = array('d', hybrid.ravel())
        msg.physics = array('d', physics.ravel())
        msg.residual_bound = array('d', self.engine.bound)
        msg.x, msg.y = array('d', x_enu), array('d', y_enu)
        msg.heading = array('d', frames.heading_ned_to_enu(psi))
        msg.model_id = self.engine.model_id
        return msg

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
            pose.pose.orientation.z = math.sin(yaw / 2)
            pose.pose.orientation.w = math.cos(yaw / 2)
            path.poses.append(pose)
        return path

    def _no_plans(self) -> str:
        return (f'control plans give {list(PLAN_CONTROLS)}; vessel {self.spec.name!r} has '
                f'controls {list(self.spec.control_names)}, so only forecasts that hold the '
                f'latest controls are made')

    def _on_predict(self, request, response):
        plans = request.plans
        if not 1 <= len(plans) <= self.p['max_plans']:
            response.success = False
            response.message = f'send 1 to {self.p["max_plans"]} plans, got {len(plans)}'
            return response
        if self.limits is None:
            response.success = False
            response.message = self._no_plans()
            return response
        result = self._window()
        if not result.ready:
            response.success = False
            response.message = f'no forecast: {result.reason}'
            return response
        try:
            future = np.stack([
                plan_controls({f: np.asarray(getattr(plan, f)) for f in PLAN_FIELDS},
                              result.controls[-1], self.horizon, self.limits, index=i)
                for i, plan in enumerate(plans)])
        except PlanError as exc:
            response.success = False
            response.message = str(exc)
            return response
        forecast = self.engine.forecast(result.states, result.controls, future)
        response.forecasts = [self._forecast_message(result, forecast.hybrid[i],
                                                     forecast.physics[i])
                              for i in range(len(plans))]
        response.success = True
        response.message = f'{len(plans)} forecasts from the window ending at ' \
                           f'{result.t_end:.3f} s'
        return response

    # ------------------------------------------------------------------ health
    def _publish_diagnostics(self) -> None:
        rejected = dict(self.rejected)
        for stream in self.window.streams.values():
            counts = stream.counts
            for reason in ('non_finite', 'duplicate', 'out_of_order', 'incomplete'):
                value = getattr(counts, reason)
                rejected[reason] = rejected.get(reason, 0) + value
        level, message, values = self.health.report(rejected)
        values['states_skipped_as_backlog'] = str(self.skipped_backlog)
        status = DiagnosticStatus(level=bytes([level]), name=f'{self.get_name()}: forecast',
                                  message=message, hardware_id=self.engine.model_id)
        status.values = [KeyValue(key=k, value=v) for k, v in values.items()]
        diag = DiagnosticArray(status=[status])
        diag.header.stamp = self.get_clock().now().to_msg()
        self.diag_pub.publish(diag)


def input_types(topic_map) -> dict:
    """Message class of every input topic, from the ``type`` its map entries name."""
    out = {}
    for topic in topic_map.topics:
        names = {e.msgtype for e in topic_map.entries if e.topic == topic and e.msgtype}
        if len(names) != 1:
            raise TopicMapError(f'vessel {topic_map.vessel.name!r}: topic {topic} needs one '
                                f'type (type: pkg/msg/Name on one of its entries) for the '
                                f'predictor to subscribe; got {sorted(names) or "none"}')
        package, _, name = names.pop().split('/')
        try:
            out[topic] = getattr(importlib.import_module(f'{package}.msg'), name)
        except (ImportError, AttributeError):
            raise TopicMapError(f'topic {topic}: message type {package}/msg/{name} is not '
                                f'installed (build and source its interface package)') \
                from None
    return out


def plan_limits(vessel) -> ActuatorLimits | None:
    """Limits of control plans, for vessels with the plan message's actuators; else None."""
    if vessel.control_names != PLAN_CONTROLS:
        return None
    return ActuatorLimits(vessel.actuator('n').high, vessel.actuator('delta_port').high)


def main(args=None) -> int:
    """Run the predictor until interrupted; exit 2 with one line on a bad model or value."""
    return run_node(PredictorNode, NODE_NAME, (CheckpointError, FileNotFoundError,
                                               ValueError, VesselError, TopicMapError), args)


if __name__ == '__main__':
    sys.exit(main())

