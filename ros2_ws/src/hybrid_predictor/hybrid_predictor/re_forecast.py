"""
Re-forecast offline what the predictor node forecast live, and compare the two (no rclpy).

A ``ReForecast`` keeps what a predictor was given -- the messages of its input topics
(the vessel's topic map) and its ControlPlan messages -- and recomputes any of its
published Forecast messages from them: the window the node assembles
(``InputWindow.of_node``, the node's own parameters), then the node's own forecast code
(``forecasting``: the future controls it assumed, the plan the forecast names or the
latest controls held, the same checkpoint's ``Forecaster`` with the wind held over the
earth, the published frames): equal by construction. Messages may be rclpy's (a live
client) or rosbags' (a recorded bag, ``bag_re_forecast``): only their fields are read.

``difference`` gives, for one forecast, the largest absolute difference live minus
offline of every state (the message's units) and of the published track (m). Both run
the same compiled float32 program on the same inputs, so they agree to float32
rounding (``TOLERANCE``); anything larger means the node forecast from other inputs
than the ones it was sent: under load a state's actuators and wind can reach the node
later than its ``sync_timeout``, which then forecasts with the previous ones (it counts
these, ``forecasts_before_sample_complete`` on /diagnostics), or a sample was rejected,
or another plan followed.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right
from dataclasses import dataclass
import math

import numpy as np

from hybrid_models.bound import loosest
from hybrid_models.engine import Forecaster
from hybrid_predictor_interfaces.msg import Forecast
from vessel_datasets.topic_map import TopicMap
from vessel_datasets.topic_messages import channel_reader
from vessel_ros_bridge.messages import seconds_from_stamp

from .forecasting import Future, future_controls
from .forecasting import forecast as forecast_made
from .input_window import InputWindow
from .plans import PlanLimits, check_plan_message

# Live minus offline, relative to each state's largest magnitude in the forecast (plus
# 1e-3 so a state near zero is not judged on its rounding alone): float32 carries ~7
# digits; the node and this module run one compiled program on equal inputs, so equal
# results are expected and 1e-5 leaves room for a different XLA thread schedule only.
TOLERANCE = 1e-5
# The track (m) is dead-reckoned in float64 from those states and the window's pose:
# equal inputs give it to ~1e-9 m; 1 mm is far below any pose difference.
TRACK_TOLERANCE_M = 1e-3
# A gap between kept samples longer than this many times the stream's usual spacing means
# a message was not kept (a subscription matched late, a loss): the node may have had it.
MISSED_SPACINGS = 1.5


class ReForecastError(ValueError):
    """A forecast cannot be recomputed from what was kept; the message says why."""


def predictor_defaults() -> dict:
    """Return the predictor node's default parameters (``config/predictor.yaml``)."""
    from vessel_ros_bridge.parameters import load_specs, package_config

    return {s.name: s.default for s in load_specs(package_config('hybrid_predictor',
                                                                 'predictor.yaml'))}


@dataclass(frozen=True)
class Difference:
    """Live minus offline for one forecast: largest absolute values."""

    t_end: float                 # stamp of the forecast (s)
    states: dict[str, float]     # per state, in the message's units (FLU, REP-103)
    relative: dict[str, float]   # per state, over its largest magnitude + 1e-3
    position_m: float            # of the published track (x, y)


class ReForecast:
    """What a predictor was given, and its forecasts recomputed from it (module doc)."""

    def __init__(self, engine: Forecaster, topic_map: TopicMap, parameters: dict):
        self.engine, self.topic_map, self.p = engine, topic_map, dict(parameters)
        self.spec = engine.spec
        self.limits = PlanLimits.of(topic_map.vessel)
        self.readers = {topic: channel_reader(topic_map, topic) for topic in topic_map.topics}
        self.samples: dict[str, tuple[list[float], list[dict]]] = {
            topic: ([], []) for topic in topic_map.topics}
        self.plans: dict[tuple[float, str], object] = {}
        # A window needs samples this far back (s) from its last one (the node's keep_s).
        self.span = (engine.window + 1) * self.spec.dt + self.p['max_gap']

    @property
    def topics(self) -> list[str]:
        """Return the input topics kept (the topic map's)."""
        return list(self.samples)

    def add_input(self, topic: str, msg) -> None:
        """Keep one input message of ``topic`` (a message without mapped fields is skipped)."""
        try:
            values = self.readers[topic](msg)
        except (AttributeError, IndexError, TypeError, ValueError):
            return   # the node rejects it as malformed too
        self.add_sample(topic, seconds_from_stamp(msg.header.stamp), values)

    def add_sample(self, topic: str, t: float, values: dict) -> None:
        """
        Keep one sample of ``topic`` read already (its channel values) at time ``t`` (s).

        For messages without a header, which the node stamps on arrival: ``t`` is when
        they were sent (see ``offline``'s ``arrival_slack``).
        """
        times, rows = self.samples[topic]
        at = bisect_right(times, t)
        times.insert(at, t)
        rows.insert(at, values)

    def add_plan(self, msg) -> None:
        """Keep a ControlPlan message (the latest one of each stamp and plan id)."""
        self.plans[(seconds_from_stamp(msg.header.stamp), str(msg.plan_id))] = msg

    def window_at(self, t_end: float, arrival_slack: float = 0.0):
        """
        Return the assembled window (``InputWindow.assemble``) the node had at ``t_end``.

        ``t_end`` is a forecast's stamp: its newest state sample's time minus the topic
        map's delay (``InputWindow.lag``), so samples up to that newest one are taken, and
        ``arrival_slack`` (s) later for samples timed when sent rather than stamped.
        Raise ReForecastError when a stream's kept samples have a gap there longer than
        MISSED_SPACINGS of its usual spacing: a message was missed here, not perhaps there.
        """
        window = InputWindow.of_node(self.topic_map, self.engine.window, self.spec.dt,
                                     self.p)
        newest = t_end + window.lag + arrival_slack
        for topic, (times, rows) in self.samples.items():
            first = max(bisect_left(times, newest - self.span) - 1, 0)
            last = bisect_right(times, newest)
            spacing = np.diff(times[first:last])
            if len(spacing) and spacing.max() > MISSED_SPACINGS * np.median(np.diff(times)):
                raise ReForecastError(f'{topic}: a gap of {spacing.max():.3g} s in the kept '
                                      f'samples before {t_end:.3f} s (a message missed)')
            for k in range(first, last):
                window.push(topic, times[k], rows[k])
        return window.assemble(now=newest, until=newest)

    def future(self, forecast, result) -> Future:
        """Return the future controls ``forecast`` assumed (``forecasting.future_controls``)."""
        horizon = int(forecast.horizon)
        if str(forecast.controls_assumed) != Forecast.CONTROLS_PLAN:
            return future_controls(self.spec, result, horizon)
        key = (seconds_from_stamp(forecast.plan_stamp), str(forecast.plan_id))
        plan = self.plans.get(key)
        if plan is None:
            raise ReForecastError(f'the plan it followed (stamp {key[0]:.3f} s, id '
                                  f'{key[1]!r}) was not kept')
        matrix = check_plan_message(plan, horizon, self.limits, exact=False)
        future = future_controls(self.spec, result, horizon, matrix, key[0])
        if not future.follows_plan:
            raise ReForecastError(f'its plan does not cover it: '
                                  f'{future.why_not or "starts later"}')
        return future

    def offline(self, forecast, arrival_slack: float = 0.0
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """
        Recompute a Forecast message offline; return hybrid (H, n) FLU, x, y, z (m, ENU).

        z is the height of a 6-DOF vehicle's track, zeros for a vessel in the plane.

        ``arrival_slack`` (s): how much later than the kept time the node may have stamped
        a sample (messages without a header, timed here when sent); 0 for stamped ones.
        Raise ReForecastError when its model differs or its inputs were not all kept.
        """
        if str(forecast.model_id) != self.engine.model_id:
            raise ReForecastError(f'forecast of model {forecast.model_id}, not of '
                                  f'{self.engine.model_id}')
        served = self.engine.relative_threshold
        sent = float(forecast.relative_threshold)
        if math.isfinite(sent) and not math.isclose(sent, loosest(served), rel_tol=1e-9):
            raise ReForecastError(f'forecast at relative threshold {sent:g}, the offline '
                                  f'engine serves {served}')
        t_end = seconds_from_stamp(forecast.header.stamp)
        result = self.window_at(t_end, arrival_slack)
        if not result.ready:
            raise ReForecastError(f'no window at {t_end:.3f} s: {result.reason}')
        if not math.isclose(result.t_end, t_end, abs_tol=max(arrival_slack, 1e-6)):
            raise ReForecastError(f'the kept states end at {result.t_end:.3f} s, the '
                                  f'forecast at {t_end:.3f} s')
        _, _, arrays = forecast_made(self.engine, self.spec, result,
                                     [self.future(forecast, result)])
        x, y = arrays.x[0], arrays.y[0]
        z = np.zeros_like(x) if arrays.z is None else arrays.z[0]
        return arrays.hybrid[0], x, y, z

    def difference(self, forecast, arrival_slack: float = 0.0) -> Difference:
        """Return live minus offline for one Forecast message (``Difference``)."""
        offline, x, y, z = self.offline(forecast, arrival_slack)
        names = list(forecast.state_names)
        if names != list(self.spec.state_names):
            raise ReForecastError(f"forecast states {names}, the model's "
                                  f'{list(self.spec.state_names)}')
        live = np.reshape(np.asarray(forecast.hybrid, float), offline.shape)
        gap = np.abs(live - offline).max(axis=0)
        scale = np.abs(offline).max(axis=0) + 1e-3
        live_z = np.asarray(forecast.z) if len(forecast.z) else np.zeros_like(z)
        position = float(np.sqrt((np.asarray(forecast.x) - x) ** 2
                                 + (np.asarray(forecast.y) - y) ** 2 + (live_z - z) ** 2).max())
        return Difference(seconds_from_stamp(forecast.header.stamp),
                          dict(zip(names, gap.tolist(), strict=True)),
                          dict(zip(names, (gap / scale).tolist(), strict=True)), position)


def summarize(differences: list[Difference], skipped: dict[str, str]) -> dict:
    """Return the largest differences over forecasts, and which were not compared, as JSON."""
    out = {'compared': len(differences), 'not_compared': len(skipped),
           'why_not_compared': dict(list(skipped.items())[:5]), 'tolerance_relative': TOLERANCE,
           'tolerance_track_m': TRACK_TOLERANCE_M}
    if differences:
        names = list(differences[0].states)
        out['max_abs_difference'] = {n: max(d.states[n] for d in differences) for n in names}
        out['max_relative_difference'] = {n: max(d.relative[n] for d in differences)
                                          for n in names}
        out['max_position_difference_m'] = max(d.position_m for d in differences)
        unequal = [d for d in differences if max(d.relative.values()) > TOLERANCE
                   or d.position_m > TRACK_TOLERANCE_M]
        out['equal'] = not unequal
        out['unequal_count'] = len(unequal)
        out['unequal'] = {f'{d.t_end:.3f}': {'relative': max(d.relative.values()),
                                             'track_m': d.position_m} for d in unequal[:5]}
    return out


def compare(re_forecast: ReForecast, forecasts, since: float | None = None) -> dict:
    """
    Recompute every Forecast message of ``forecasts``; return ``summarize``'s JSON.

    With ``since`` (s; e.g. the stamp of the node's first forecast) only forecasts whose
    window begins at or after it are compared: until its first forecast, the node's
    subscriptions may match its sources one by one, and a sample it missed then, inside
    the tolerated ``max_gap``, is one the keeper may have had. Once every subscription
    has matched, reliable delivery loses nothing.
    """
    stamps = [seconds_from_stamp(msg.header.stamp) for msg in forecasts]
    since = -math.inf if since is None else since
    reach = (re_forecast.engine.window - 1) * re_forecast.spec.dt
    differences, skipped = [], {}
    for t_end, msg in zip(stamps, forecasts, strict=True):
        if t_end - reach < since - 1e-9:
            skipped[f'{t_end:.3f}'] = (f'its window began before {since:.3f} s, the '
                                       f"predictor's first forecast")
            continue
        try:
            differences.append(re_forecast.difference(msg))
        except ReForecastError as exc:
            skipped[f'{t_end:.3f}'] = str(exc)
    return summarize(differences, skipped)
