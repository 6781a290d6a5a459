"""
The predictor's Forecast and nav_msgs/Path messages, built from published forecasts.

``forecasting.published`` gives the arrays (FLU states, ENU track); this module only
fills messages from them, for the forecast topic, the what-if service's answers and the
path topic. No node is needed: the messages are plain interface classes.
"""

from __future__ import annotations

from array import array
import copy
from dataclasses import dataclass
import math

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
import numpy as np
from std_msgs.msg import Header

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


# The fields a Forecast holds a row of per step, named as ``forecasting.Published``'s.
STEP_ROWS = ('hybrid', 'physics', 'x', 'y', 'heading', 'z', 'band_lower', 'band_upper',
             'bound_available')


def doubles(values) -> array:
    """
    Return values as a flat array('d') for a float64[] message field.

    rclpy checks a list element by element, an array('d') at once; filling it from the
    bytes of a NumPy array is a copy, where array('d', ndarray) converts every element.
    """
    out = array('d')
    out.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
    return out


class _Rows:
    """A batch array's rows (one per forecast) as float64 bytes, each read at one copy."""

    def __init__(self, values):
        batch = np.ascontiguousarray(values, dtype=np.float64)
        self._bytes = memoryview(batch).cast('B')
        self._size = batch[0].nbytes if len(batch) else 0

    def __getitem__(self, i: int) -> array:
        out = array('d')
        out.frombytes(self._bytes[i * self._size:(i + 1) * self._size])
        return out


def forecast_messages(served: Served, t_end: float, forecasts: Published,
                      assumed: list[Assumed], stride: int = 1) -> list[Forecast]:
    """
    Return one Forecast per forecast of the batch, from the window ending at ``t_end`` (s).

    What every message of the batch says alike (header, names, units, bound, band levels
    and radii) is made once and shared by the messages: replace a message's field (as
    ``no_steps`` does), never change one in place.
    """
    spec = served.spec
    header = Header(stamp=messages.stamp_from_seconds(t_end), frame_id=served.world_frame)
    alike = dict(
        header=header, child_frame_id=served.body_frame, step_period=float(spec.dt * stride),
        horizon=len(forecasts.steps), state_names=list(spec.state_names),
        state_units=list(spec.state_units), vessel=spec.name,
        control_names=list(spec.control_names), control_units=list(spec.control_units),
        residual_bound=doubles(served.residual_bound), band_note=served.band_note,
        model_id=served.model_id, relative_threshold=served.relative_threshold,
        bounded=served.bounded)
    if forecasts.band_lower is not None:
        alike.update(band_levels=list(served.band_levels),
                     band_position_radius=doubles(forecasts.band_radius))
    rows = {name: _Rows(getattr(forecasts, name))
            for name in STEP_ROWS if getattr(forecasts, name) is not None}
    # A shallow copy of one filled message is a third of a message built field by field.
    template = Forecast(**alike)
    out = []
    for i in range(len(forecasts.hybrid)):
        msg = copy.copy(template)
        for name, row in rows.items():
            setattr(msg, name, row[i])
        msg.controls_assumed, msg.plan_id = assumed[i].controls, assumed[i].plan_id
        if assumed[i].plan_stamp is not None:
            msg.plan_stamp = assumed[i].plan_stamp
        out.append(msg)
    return out


def no_steps(msg: Forecast) -> None:
    """Empty a withheld forecast's steps in place (horizon 0); its names and ids stay."""
    msg.horizon = 0
    for name in (*STEP_ROWS, 'band_position_radius'):
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
