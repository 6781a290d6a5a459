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

from builtin_interfaces.msg import Time
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


@dataclass(frozen=True)
class ForecastBatch:
    """
    A batch's Forecast messages as arrays: what they share, and each one's own.

    ``messages()`` builds them in Python; the what-if door writes the same messages
    straight from these arrays in C (``what_if_c.door``), which is where a thousand-plan
    answer spent a third of its time. Read-only: both share ``template``.
    """

    template: Forecast               # every field the messages share; no step rows
    rows: dict                       # STEP_ROWS name -> (B, k) float64, C-contiguous
    plan_ids: list                   # (B,) str
    controls_assumed: list           # (B,) str
    plan_stamps: np.ndarray          # (B, 2) int64 sec, nanosec; 0, 0 when held
    emptied: np.ndarray              # (B,) bool: withheld, sent without steps (no_steps)

    def __len__(self) -> int:
        """Return the number of forecasts."""
        return len(self.emptied)

    def messages(self) -> list[Forecast]:
        """Return the Forecast messages, each a shallow copy of the template (never edit)."""
        # A shallow copy of one filled message is a third of a message built field by
        # field; each row is read from the batch's bytes at one copy.
        views = {name: (memoryview(rows).cast('B'), rows[0].nbytes)
                 for name, rows in self.rows.items()}
        out = []
        for i in range(len(self)):
            msg = copy.copy(self.template)
            msg.controls_assumed, msg.plan_id = self.controls_assumed[i], self.plan_ids[i]
            if self.plan_stamps[i].any():
                msg.plan_stamp = Time(sec=int(self.plan_stamps[i, 0]),
                                      nanosec=int(self.plan_stamps[i, 1]))
            if self.emptied[i]:
                no_steps(msg)
            else:
                for name, (view, size) in views.items():
                    row = array('d')
                    row.frombytes(view[i * size:(i + 1) * size])
                    setattr(msg, name, row)
            out.append(msg)
        return out


def forecast_batch(served: Served, t_end: float, forecasts: Published, assumed: list[Assumed],
                   stride: int = 1, emptied=None) -> ForecastBatch:
    """
    Return the batch's Forecasts from the window ending at ``t_end`` (s), as arrays.

    ``emptied``: (B,) bool, the forecasts withheld, sent without steps (none by default).
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
    count = len(forecasts.hybrid)
    rows = {name: np.ascontiguousarray(getattr(forecasts, name), dtype=np.float64
                                       ).reshape(count, -1)
            for name in STEP_ROWS if getattr(forecasts, name) is not None}
    stamps = np.zeros((count, 2), dtype=np.int64)
    for i, a in enumerate(assumed):
        if a.plan_stamp is not None:
            stamps[i] = a.plan_stamp.sec, a.plan_stamp.nanosec
    return ForecastBatch(
        Forecast(**alike), rows, [a.plan_id for a in assumed], [a.controls for a in assumed],
        stamps, np.zeros(count, dtype=bool) if emptied is None else np.asarray(emptied, bool))


def forecast_messages(served: Served, t_end: float, forecasts: Published,
                      assumed: list[Assumed], stride: int = 1) -> list[Forecast]:
    """Return one Forecast per forecast of the batch (``forecast_batch(...).messages()``)."""
    return forecast_batch(served, t_end, forecasts, assumed, stride).messages()


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
