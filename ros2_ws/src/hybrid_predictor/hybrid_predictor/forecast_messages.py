"""
The predictor's Forecast and nav_msgs/Path messages, built from published forecasts.

``forecasting.published`` gives the arrays (FLU states, ENU track); this module only
fills messages from them, for the forecast topic, the what-if service's answers and the
path topic. No node is needed: the messages are plain interface classes.
"""

from __future__ import annotations

from array import array
from dataclasses import dataclass
import math

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
import numpy as np

from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
from vessel_ros_bridge import messages

from .forecasting import Published


@dataclass(frozen=True)
class Assumed:
    """What a forecast assumed about the future controls (Forecast.controls_assumed)."""

    controls: str = Forecast.CONTROLS_HELD
    plan_id: str = ''
    plan_stamp: object = None   # builtin_interfaces/Time of the plan, None when held


def followed(plan: ControlPlan) -> Assumed:
    """Return what a forecast following ``plan`` assumed."""
    return Assumed(Forecast.CONTROLS_PLAN, plan.plan_id, plan.header.stamp)


@dataclass(frozen=True)
class Served:
    """What every Forecast message of one node says of its vessel, model and frames."""

    spec: object                  # the vessel served (vessel_description)
    world_frame: str
    body_frame: str
    model_id: str
    residual_bound: np.ndarray    # (n_state,) the LSTM correction's largest bound, FRD
    relative_threshold: float     # the loosest of the model's thresholds
    bounded: bool
    band_levels: tuple = ()
    band_note: str = ''


def doubles(values) -> array:
    """
    Return values as a flat array('d') for a float64[] message field.

    rclpy checks a list element by element, an array('d') at once; filling it from the
    bytes of a NumPy array is a copy, where array('d', ndarray) converts every element.
    """
    out = array('d')
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


def forecast_messages(served: Served, t_end: float, forecasts: Published,
                      assumed: list[Assumed], stride: int = 1) -> list[Forecast]:
    """Return one Forecast per forecast of the batch, from the window ending at ``t_end`` (s)."""
    spec = served.spec
    out = []
    for i in range(len(forecasts.hybrid)):
        msg = Forecast()
        msg.header.stamp = messages.stamp_from_seconds(t_end)
        msg.header.frame_id = served.world_frame
        msg.child_frame_id = served.body_frame
        msg.step_period = float(spec.dt * stride)
        msg.horizon = len(forecasts.steps)
        msg.state_names = list(spec.state_names)
        msg.state_units = list(spec.state_units)
        msg.vessel = spec.name
        msg.control_names = list(spec.control_names)
        msg.control_units = list(spec.control_units)
        msg.hybrid, msg.physics = doubles(forecasts.hybrid[i]), doubles(forecasts.physics[i])
        msg.residual_bound = doubles(served.residual_bound)
        msg.x, msg.y = doubles(forecasts.x[i]), doubles(forecasts.y[i])
        msg.heading = doubles(forecasts.heading[i])
        if forecasts.z is not None:
            msg.z = doubles(forecasts.z[i])
        msg.band_note = served.band_note
        if forecasts.band_lower is not None:
            msg.band_levels = list(served.band_levels)
            msg.band_lower = doubles(forecasts.band_lower[i])
            msg.band_upper = doubles(forecasts.band_upper[i])
            msg.band_position_radius = doubles(forecasts.band_radius)
        msg.model_id = served.model_id
        msg.controls_assumed = assumed[i].controls
        msg.plan_id = assumed[i].plan_id
        if assumed[i].plan_stamp is not None:
            msg.plan_stamp = assumed[i].plan_stamp
        msg.relative_threshold = served.relative_threshold
        msg.bounded = served.bounded
        out.append(msg)
    return out


def no_steps(msg: Forecast) -> None:
    """Empty a withheld forecast's steps in place (horizon 0); its names and ids stay."""
    msg.horizon = 0
    for name in ('hybrid', 'physics', 'x', 'y', 'heading', 'z', 'band_lower', 'band_upper',
                 'band_position_radius'):
        setattr(msg, name, array('d'))


def path_message(forecast: Forecast, stride: int) -> PathMsg:
    """Return the forecast's track as a Path: every ``stride``-th step and the last."""
    path = PathMsg()
    path.header = forecast.header
    t0 = messages.seconds_from_stamp(forecast.header.stamp)
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
