"""
The predictor between its messages and its forecasts (no ROS): tested without a graph.

``PredictorCore`` holds what the node's threads share: the input window, the forecast
schedule, the state awaiting its forecast (pending) or its late actuators and wind
(deferred), the latest control plan, the live skill with its hindsight, and the health
figures. The node (``node``) only turns messages into calls and results into messages:
an input sample is ``push``-ed, a state ``arrived``; the forecast thread takes the
``next_job`` and ``forecast``-s it and ``score``-s its window; the what-if service asks
``what_if``; the diagnostics timer asks ``report``. Forecasts are made by ``forecasting``
and filled into messages by ``forecast_messages``, as the offline re-forecast does.

Locks: ``lock`` guards the window, the pending state, the plan, the schedule and the
health figures (input, forecast, service and clock threads; held briefly, but a window
assembly takes milliseconds under it); ``skill_lock`` the skill tracker (forecast and
diagnostics threads); ``count_lock`` the counters alone, so an answer counts itself
without waiting for a window; ``batch_lock`` keeps one what-if batch at a time (the
engine already spreads a batch over the cores).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
import math
import threading
import time

import numpy as np

from hybrid_models.bound import loosest
from hybrid_models.engine import Forecaster
from hybrid_models.metrics import reported_steps
from vessel_datasets.topic_map import TopicMap
from vessel_physics import frames
from vessel_ros_bridge.messages import seconds_from_stamp

from .forecast_messages import (
    Assumed,
    ForecastBatch,
    Served,
    followed,
    forecast_batch,
    forecast_messages,
)
from .forecasting import forecast, future_controls, plan_futures, published
from .health import OK, WARN, Health
from .hindsight import Hindsight, Remade, applied_future
from .input_window import InputWindow
from .plans import (
    PlanError,
    PlanLimits,
    answer_stride,
    bound_hit_fraction,
    check_plan_message,
    check_plan_messages,
)
from .plausibility import forecast_problems
from .schedule import ForecastSchedule
from .skill import LiveSkill, Settings


@dataclass(frozen=True)
class Pending:
    """A state sample awaiting its forecast."""

    t: float              # its stamp (s, message clock)
    received_ns: int      # when it reached this process (ns, system clock)
    backlogged: bool      # it waited in the queue longer than backlog_skip
    forecast: bool = True  # False: its window is only scored (skill), not forecast


@dataclass(frozen=True)
class Job:
    """What the forecast thread does for one pending state: forecast and/or score."""

    pending: Pending
    result: object        # InputWindow.assemble's, ending at the pending state
    scoring: object       # the same, lengthened back to the newest row scored
    plan: tuple | None    # the latest ControlPlan and its checked matrix
    synced: bool          # the state's actuators and wind had arrived


@dataclass(frozen=True)
class Outcome:
    """A forecast made for the forecast topic: its message, or why it was withheld."""

    message: object | None
    withheld: str = ''
    stale_plan: str = ''   # why the latest plan was not followed ('' if it was or none)


@dataclass(frozen=True)
class Report:
    """Health (/diagnostics) and skill (forecast/skill): levels as health's, values as text."""

    level: int
    message: str
    values: dict
    skill_level: int
    skill_message: str
    skill_values: dict


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


def remade(engine: Forecaster, spec, horizon: int, states: np.ndarray,
           controls: np.ndarray, pose, applied: np.ndarray) -> Remade:
    """
    Return a window's forecast re-made under the controls then ``applied`` (S, m).

    The window's ``states``, ``controls`` (window, n) and ``pose`` as ``InputWindow``
    gives them; the forecast in the published frames (FLU, ENU), as the skill scores it.
    """
    made = engine.forecast(states, controls, applied_future(applied, horizon))
    arrays = published(spec, pose, made.hybrid, made.physics, engine.bands)
    if arrays.band_lower is None:
        return Remade(arrays.hybrid[0], arrays.x[0], arrays.y[0], band_note=engine.bands_note)
    return Remade(arrays.hybrid[0], arrays.x[0], arrays.y[0], tuple(engine.bands.levels),
                  arrays.band_lower[0], arrays.band_upper[0], arrays.band_radius,
                  engine.bands_note)


class PredictorCore:
    """A predictor's shared state and the work done on it (module docstring)."""

    def __init__(self, engine: Forecaster, spec, topic_map: TopicMap, p: dict,
                 labels: dict[str, str], sim_time: bool):
        """
        Make the core of a predictor serving ``engine`` for vessel ``spec``.

        ``p``: the node's parameters (config/predictor.yaml); ``labels``: each input topic
        as the node resolved it, for messages.
        """
        check_time_parameters(p)
        self.engine, self.spec, self.p = engine, spec, p
        self.horizon = p['horizon'] or spec.horizon
        self.limits = PlanLimits.of(spec)
        self.window = InputWindow.of_node(topic_map, engine.window, spec.dt, p, labels=labels)
        # A threshold schedule (the do-no-harm selection's) is reported by its loosest
        # entry, and the bound by every step's largest: what holds at every step.
        self.step_bounds = engine.step_bounds(self.horizon)
        residual_bound = self.step_bounds.max(axis=0)
        self.served = Served(spec, p['world_frame'], p['body_frame'], engine.model_id,
                             residual_bound, loosest(engine.relative_threshold),
                             bool(np.isfinite(residual_bound).all()),
                             tuple(engine.bands.levels) if engine.bands is not None else (),
                             engine.bands_note)
        # Why the model is served unbounded without allow_unbounded ('' otherwise).
        self.unbounded = '' if self.served.bounded or p['allow_unbounded'] else (
            f'model {engine.model_id} is served unbounded (relative threshold '
            f'{engine.relative_threshold}): the LSTM correction has no bound; set '
            f'allow_unbounded:=true if that is meant, or a relative_threshold')
        self.health = Health(silence_error=self.silence_error(p), max_age=p['max_age'],
                             watchdog=p['watchdog_timeout'],
                             rejection_warn_fraction=p['rejection_warn_fraction'],
                             sim_time=sim_time, state_topic=labels[self.window.state_topic],
                             unbounded=self.unbounded)
        self.schedule = ForecastSchedule(p['forecast_period'])
        self.skill = live_skill(spec, self.horizon, p)
        # The model is judged on forecasts re-made with the inputs then applied.
        self.hindsight = Hindsight(self.skill, self.remake)
        # The newest row scored (s): hindsight.newest, copied where the input thread reads
        # it without the skill lock.
        self.scored_until: float | None = None
        self.lock, self.skill_lock = threading.Lock(), threading.Lock()
        self.count_lock, self.batch_lock = threading.Lock(), threading.Lock()
        self.input_event = threading.Event()
        self.counts = {'malformed_inputs': 0, 'plans_rejected': 0, 'states_skipped_as_backlog':
                       0, 'clock_resets': 0, 'service_failed': 0,
                       'forecasts_before_sample_complete': 0, 'forecast_failures': 0,
                       'input_failures': 0}
        self.latest_plan: tuple | None = None
        self.pending: Pending | None = None
        # A scheduled state whose actuator or wind samples had not arrived when its wait
        # ended (a burst read topic by topic): forecast once they catch up with it.
        self.deferred: Pending | None = None
        self.timeline_changes = 0   # restarts and re-anchors the schedule has seen

    # ------------------------------------------------------------------ parameters
    def silence_error(self, p: dict) -> float:
        """Return the seconds without a forecast that are an ERROR."""
        # A forecast period of 0 forecasts every state: expect one per model step then.
        return p['silence_error_periods'] * max(p['forecast_period'], self.spec.dt)

    def configure(self, p: dict) -> None:
        """Take changed parameters (checked by ``check_time_parameters`` first)."""
        self.p = p
        with self.lock:
            self.window.configure(p['max_gap'], p['max_age'], p['max_future'],
                                  p['restart_span'], p['re_anchor_after'])
            self.window.plausibility.quaternion_tolerance = p['quaternion_tolerance']
            self.health.silence_error = self.silence_error(p)
            self.health.max_age = p['max_age']
            self.health.watchdog = p['watchdog_timeout']
            self.health.rejection_warn_fraction = p['rejection_warn_fraction']
            if self.schedule.period != p['forecast_period']:
                self.schedule = ForecastSchedule(p['forecast_period'])

    def count(self, name: str, n: int = 1) -> None:
        """Add ``n`` to counter ``name`` (reported on /diagnostics)."""
        with self.count_lock:
            self.counts[name] += n

    def clock_jumped(self, now: float) -> None:
        """Forget every sample and score: the clock went back, to another time line."""
        with self.lock:
            self.window.clear()
            self.schedule.reset()
            self.pending = self.deferred = None
            self.health.clock_jumped(now)
            self.window.keep_from(None, 0.0)
        with self.skill_lock:
            self.hindsight.reset()
            self.scored_until = None
        self.count('clock_resets')

    # ------------------------------------------------------------------ inputs
    def push(self, topic: str, t: float, values: dict, now: float, frame_id: str | None,
             wall: float):
        """
        Take one input sample (s, the message clock); return (reason, re-anchored line).

        ``reason`` is why it was rejected (None if taken); the line (``time_line``) is the
        state topic's new one when this sample re-anchored it, else None.
        """
        with self.lock:
            reason = self.window.push(topic, t, values, now, frame_id, wall)
            changes = self.window.restarts + len(self.window.re_anchors)
            re_anchored = None
            if changes != self.timeline_changes:
                self.timeline_changes = changes
                self.schedule.reset()
                re_anchored = self.window.lines.latest
            if not reason:
                self.health.record_input(now, wall, topic == self.window.state_topic)
        return reason, re_anchored

    def state_arrived(self, t: float, received_ns: int) -> bool:
        """Note a state taken at ``t`` (s); return whether the forecast thread has work."""
        with self.lock:
            due = self.schedule.due(t)
            # The skill needs every sample: between forecasts further apart than a
            # window, a window is assembled for it alone before its rows fall out.
            if not due and (self.pending is not None or not self._scoring_due(t)):
                return False
            # A message that waited in the queue: newer ones are probably behind it.
            backlogged = due and (time.time_ns() - received_ns) * 1e-9 > \
                self.p['backlog_skip']
            self.pending = Pending(t, received_ns, backlogged, forecast=due)
            self.deferred = None
        self.count('states_skipped_as_backlog', backlogged)
        return True

    def _scoring_due(self, t: float) -> bool:
        # Two steps before the oldest unscored row would leave a window of rows ending
        # at t: assembled then, every row reaches the skill (_scoring_window lengthens a
        # window that starts later than the rows already scored).
        fed = self.scored_until
        return fed is None or t - fed >= (self.engine.window - 2) * self.spec.dt

    def resume_deferred(self) -> bool:
        """Return whether a deferred state's sample is complete now (it becomes pending)."""
        with self.lock:
            if self.deferred is None or not self.synced(self.deferred.t):
                return False
            self.pending, self.deferred = self.deferred, None
        return True

    def set_plan(self, msg) -> str:
        """Take a ControlPlan message; return why it was rejected ('' if taken)."""
        try:
            matrix = check_plan_message(msg, self.horizon, self.limits, exact=False)
        except PlanError as exc:
            self.count('plans_rejected')
            return str(exc)
        with self.lock:
            self.latest_plan = (msg, matrix)
        return ''

    def synced(self, t_state: float) -> bool:
        """Return whether every input has a sample as new as the state at ``t_state``."""
        # A sample's actuators and wind may arrive just after its state.
        return all((stream.latest_time or -math.inf) >= t_state
                   for stream in self.window.streams.values())

    # ------------------------------------------------------------------ forecasting
    def next_job(self, now: Callable[[], float]) -> Job | None:
        """
        Wait until the pending state's sample is complete or its wait is over; take it.

        ``now`` returns the node's clock (s). Return None when nothing is pending.
        """
        started, started_msg = time.monotonic(), now()
        while True:
            with self.lock:
                pending = self.pending
                if pending is None:
                    return None
                synced = self.synced(pending.t)
            self.input_event.clear()
            if pending.backlogged:
                # Read a burst through first, then forecast once from the latest window:
                # at the latest one forecast period of message time after the first
                # backlogged state (a wall second is ten periods at 10x simulated time),
                # plus at most one backlog_skip of wall time.
                left = started_msg + self.p['forecast_period'] - now()
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
                return None
            # The scheduled state, whose samples were awaited: not a newer one that
            # arrived meanwhile, perhaps before its actuators and wind.
            result = self.assemble(now(), until=pending.t)
            scoring = self._scoring_window(result, pending.t, now())
            synced = self.synced(pending.t)
            if not result.ready and not synced:
                self.deferred = pending
            return Job(pending, result, scoring, self.latest_plan, synced)

    def _scoring_window(self, result, until: float, now: float):
        """Return ``result`` lengthened back to the newest row scored, if it falls short."""
        fed = self.scored_until
        if not result.ready or fed is None or \
                result.t_end - fed <= (self.engine.window - 1) * self.spec.dt:
            return result
        longer = self.window.assemble(now, until=until, since=fed)
        return longer if longer.ready else result

    def assemble(self, now: float, until: float | None = None):
        """Return the window ending at ``until`` (the newest state if None); hold ``lock``."""
        result = self.window.assemble(now, until)
        self.health.record_window(result.status, result.reason, result.fill)
        return result

    def forecast(self, job: Job, now: float) -> Outcome:
        """Return the forecast of a job's window as a Forecast message, or why withheld."""
        # From a sample whose actuators or wind had not arrived when the wait was over:
        # an offline re-forecast of the same messages (re_forecast) differs.
        self.count('forecasts_before_sample_complete', not job.synced)
        result = job.result
        plan, matrix, start = (None, None, 0.0) if job.plan is None else (
            job.plan[0], job.plan[1], seconds_from_stamp(job.plan[0].header.stamp))
        # Held latest controls where there is no plan or it does not cover the window.
        future = future_controls(self.spec, result, self.horizon, matrix, start,
                                 self.p['plan_timeout'])
        assumed = followed(plan) if future.follows_plan else Assumed()
        stale = future.why_not
        hybrid, physics, arrays = forecast(self.engine, self.spec, result, [future])
        (problem,) = self.withheld(hybrid, arrays)
        if problem:
            with self.lock:
                self.health.record_withheld(problem)
            return Outcome(None, problem, stale)
        (msg,) = forecast_messages(self.served, result.t_end, arrays, [assumed])
        latency_ms = (time.time_ns() - job.pending.received_ns) * 1e-6
        with self.lock:
            self.health.record_forecast(now, latency_ms, bound_hit_fraction(
                hybrid, physics, self.step_bounds), time.monotonic())
        return Outcome(msg, '', stale)

    def withheld(self, hybrid: np.ndarray, arrays) -> list[str | None]:
        """Return why each forecast (FRD ``hybrid`` (B, H, n), its arrays) is withheld, or None."""
        z = arrays.z if arrays.z is not None else np.zeros(0)
        return forecast_problems(hybrid, (arrays.x, arrays.y, arrays.heading, z), self.spec)

    def score(self, result) -> None:
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

    def remake(self, result, applied: np.ndarray) -> Remade:
        """Return the forecast from window ``result`` under the ``applied`` controls (S, m)."""
        return remade(self.engine, self.spec, self.horizon, result.states, result.controls,
                      result.pose, applied)

    # ------------------------------------------------------------------ what if
    def what_if(self, plans, answer_period: float, now: float
                ) -> tuple[bool, str, ForecastBatch | None, list[str]]:
        """
        Return (success, message, forecasts, withheld) for a Predict request.

        ``forecasts`` is the answer's Forecasts as a batch of arrays (None on failure;
        ``messages()`` gives the messages). ``withheld`` gives per plan why its forecast
        was withheld ('' if served); such a plan's Forecast carries no steps, and the
        others are answered all the same.
        """
        if not 1 <= len(plans) <= self.p['max_plans']:
            return False, f'send 1 to {self.p["max_plans"]} plans, got {len(plans)}', None, []
        try:   # every plan, as a whole, before any window or model work
            stride = answer_stride(answer_period, self.spec.dt, self.horizon)
            matrices = check_plan_messages(plans, self.horizon, self.limits)   # (B, H, m)
        except PlanError as exc:
            return False, str(exc), None, []
        with self.lock:
            result = self.assemble(now)
        if not result.ready:
            return False, f'no forecast: {result.reason}', None, []
        futures = plan_futures(self.spec, matrices, result.controls[-1])
        with self.batch_lock:
            hybrid, _, arrays = forecast(self.engine, self.spec, result, futures, stride)
        # Every step's states are checked; a non-finite track between the answer's steps
        # would carry on to its last step, which every answer holds.
        withheld = [why or '' for why in self.withheld(hybrid, arrays)]
        count = sum(bool(why) for why in withheld)
        first = next((f'plan {i}: forecast withheld: {why}'
                      for i, why in enumerate(withheld) if why), '')
        if count == len(plans):
            return False, f'every forecast withheld; {first}', None, []
        batch = forecast_batch(self.served, result.t_end, arrays,
                               [followed(plan) for plan in plans], stride,
                               emptied=[bool(why) for why in withheld])
        note = f' ({count} withheld; {first})' if count else ''
        return True, f'{len(plans) - count} forecasts from the window ending at ' \
                     f'{result.t_end:.3f} s{note}', batch, withheld

    # ------------------------------------------------------------------ health
    def report(self, now: float, wall: float, clock_publishers: list[str] | None,
               service: dict) -> Report:
        """
        Return the health and skill reports for /diagnostics and forecast/skill.

        ``service``: the what-if door's ``requests`` and ``refused`` counts and its
        ``failure`` ('' while it answers); ``clock_publishers``: the nodes on /clock with
        use_sim_time, else None.
        """
        with self.count_lock:
            counts = dict(self.counts)
        # Every refusal is the door's, given without the interpreter: "unread" by Python.
        counts.update(service_requests=service['requests'], service_busy=service['refused'],
                      service_busy_unread=service['refused'])
        with self.skill_lock:
            departure = self.skill.departure()
            line = self.skill.describe(departure)
            summary = self.skill.summary()
            skill_counts = {**self.skill.counts, **self.hindsight.counts}
        with self.lock:
            self.health.departure = line
            self.health.service_stopped = service['failure']
            rejected = self.window.rejected_counts()
            accepted = sum(s.counts.accepted for s in self.window.streams.values())
            rejected['malformed'] = counts.pop('malformed_inputs')
            newest = self.window.streams[self.window.state_topic].latest_time
            level, message, values = self.health.report(
                now, newest, accepted, rejected, wall=wall, lines=self.window.lines,
                clock_publishers=clock_publishers)
            counts['source_restarts'] = self.window.restarts
        values.update({k: str(v) for k, v in counts.items()})
        values.update({'model_id': self.engine.model_id, 'vessel': self.spec.name,
                       'relative_threshold': f'{self.served.relative_threshold:g}',
                       'bounded': str(self.served.bounded).lower()})
        return Report(level, message, values,
                      *self._skill_report(departure, line, summary, skill_counts))

    def _skill_report(self, departure, line: str, summary: dict, counts: dict):
        """Return the rolling skill summary: level, message and values (forecast/skill)."""
        if departure.active:
            level, message = WARN, line
        elif not departure.judged:
            level, message = OK, f'scored; departure {departure.note}'
        else:
            level, message = OK, (
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
        return level, message, values
