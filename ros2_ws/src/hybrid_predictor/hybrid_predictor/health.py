"""
The predictor's health in numbers, for /diagnostics (no ROS).

Everything is judged at report time from what actually happened, never from a figure
frozen at the last forecast, on two clocks: the node's own (``now``, which follows
use_sim_time) for message time, and a steady wall clock (``wall``) for "nothing happens
at all", which the node's clock cannot see when it is /clock and /clock stops with its
source.

- ERROR when no forecast was published for ``silence_error`` seconds of message time
  (the message adds why the latest window could not be formed), when the newest
  accepted state is older than ``max_age`` (inputs stale), when no state was accepted
  for ``watchdog`` seconds of wall time, when (with use_sim_time) the node's clock has
  not moved for ``watchdog`` wall seconds, when more than one node publishes /clock,
  when the state topic carries two live time lines (two sources), or when ``~/predict``
  answers no more (``service_stopped``: its door's thread stopped, and why);
- WARN when more than ``rejection_warn_fraction`` of the inputs offered since the
  previous report were rejected, when forecasts were withheld (non-finite or outside
  the vessel limits) since then, when the LSTM keeps hitting its bound, when the source's
  stamps are followed on a line off the node's clock (re-anchored), when the model is
  served unbounded without the user having said so, or when the vessel departs from its
  model (``departure``, set from ``skill``: matured forecasts keep leaving their band);
- STALE before any input arrived; OK otherwise.

The message names every reason found, the worst first.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass
class Health:
    """Running figures of one predictor; ``report`` turns them into level and values."""

    silence_error: float          # s without a published forecast -> ERROR
    max_age: float                # s, newest state older -> ERROR
    watchdog: float = float('inf')  # s of wall time without an accepted state -> ERROR
    rejection_warn_fraction: float = 0.2
    bound_hit_warn: float = 0.2
    latency_window: int = 200
    sim_time: bool = False        # the node's clock is /clock (use_sim_time)
    state_topic: str = 'the state topic'   # as the node resolved it, for messages
    unbounded: str = ''           # why the model is served unbounded unasked; '' otherwise
    departure: str = ''           # how the vessel departs from its model; '' otherwise
    service_stopped: str = ''     # why ~/predict answers no more; '' while it does
    started: float | None = None  # node clock (s) of the first accepted input
    last_state_wall: float | None = None     # wall clock (s) of the latest accepted state
    last_forecast_wall: float | None = None  # wall clock (s) of the latest forecast
    clock_seen: float | None = None          # node clock at the previous report (s)
    clock_moved_wall: float | None = None    # wall clock (s) when it last moved
    latencies_ms: deque = field(default_factory=deque)
    forecasts: int = 0
    withheld: int = 0
    last_withheld_reason: str = ''
    last_forecast_time: float | None = None
    bound_hit_fraction: float = 0.0
    window_status: str = 'incomplete'
    window_reason: str = 'no input yet'
    window_fill: float = 0.0
    _offered_at_last_report: int = 0
    _rejected_at_last_report: int = 0
    _withheld_at_last_report: int = 0

    def record_forecast(self, now: float, latency_ms: float, bound_hit_fraction: float,
                        wall: float | None = None) -> None:
        """Note one published forecast at ``now`` (s, node clock) and ``wall`` (s)."""
        self.latencies_ms.append(latency_ms)
        while len(self.latencies_ms) > self.latency_window:
            self.latencies_ms.popleft()
        self.forecasts += 1
        self.last_forecast_time = now
        self.last_forecast_wall = wall
        self.bound_hit_fraction = bound_hit_fraction

    def record_withheld(self, reason: str) -> None:
        """Note a forecast that was computed but not published, and why."""
        self.withheld += 1
        self.last_withheld_reason = reason

    def record_window(self, status: str, reason: str, fill: float) -> None:
        """Note the outcome of the latest window assembly."""
        self.window_status, self.window_reason, self.window_fill = status, reason, fill

    def record_input(self, now: float, wall: float | None = None,
                     state: bool = False) -> None:
        """Note an accepted input (a ``state`` sample or not) at ``now`` and ``wall`` (s)."""
        if self.started is None:
            self.started = now
        if state and wall is not None:
            self.last_state_wall = wall

    def clock_jumped(self, now: float) -> None:
        """Restart the silence count after the node's clock jumped (e.g. /clock reset)."""
        self.started = now
        self.last_forecast_time = None

    def latency_percentiles(self) -> tuple[float, float] | None:
        """Return (p50, p99) of the recent latencies in ms, or None."""
        if not self.latencies_ms:
            return None
        values = np.fromiter(self.latencies_ms, float)
        return float(np.percentile(values, 50)), float(np.percentile(values, 99))

    def report(self, now: float, newest_state: float | None, accepted: int,
               rejected: dict[str, int], wall: float | None = None, lines=None,
               clock_publishers: list[str] | None = None,
               ) -> tuple[int, str, dict[str, str]]:
        """
        Return (level, message, values) at ``now`` (s, node clock) and ``wall`` (s, steady).

        ``newest_state`` is the stamp of the newest accepted state (s) or None;
        ``accepted`` and ``rejected`` (per reason) are cumulative input counts;
        ``lines`` the window's ``time_line.TimeLines`` (None: stamps judged on the node's
        clock as they are); ``clock_publishers`` the nodes publishing /clock (with
        use_sim_time; None: not looked at).
        """
        since_when = self.started if self.last_forecast_time is None else \
            self.last_forecast_time
        since = 0.0 if since_when is None else now - since_when
        offset = lines.offset if lines is not None else 0.0
        age = None if newest_state is None else now - offset - newest_state
        clock_still = self._clock_still(now, wall)
        values = {
            'window_status': self.window_status,
            'window_fill_percent': f'{100.0 * self.window_fill:.0f}',
            'input_age_s': 'n/a' if age is None else f'{age:.2f}',
            'seconds_since_last_forecast': f'{since:.2f}',
            'forecasts_published': str(self.forecasts),
            'forecasts_withheld': str(self.withheld),
            'lstm_bound_hit_fraction': f'{self.bound_hit_fraction:.3f}',
            'inputs_accepted': str(accepted),
        }
        for key, at in (('wall_s_since_last_state', self.last_state_wall),
                        ('wall_s_since_last_forecast', self.last_forecast_wall)):
            values[key] = 'n/a' if at is None or wall is None else f'{wall - at:.2f}'
        if lines is not None:
            values['clock_offset_s'] = f'{offset:.2f}'
            values['re_anchors'] = str(len(lines.re_anchors))
        if clock_publishers is not None:
            values['clock_publishers'] = str(len(clock_publishers))
        latency = self.latency_percentiles()
        if latency is not None:
            values['forecast_latency_p50_ms'] = f'{latency[0]:.2f}'
            values['forecast_latency_p99_ms'] = f'{latency[1]:.2f}'
        for reason, count in sorted(rejected.items()):
            values[f'rejected_{reason}'] = str(count)
        total_rejected = sum(rejected.values())
        new_rejected = total_rejected - self._rejected_at_last_report
        new_offered = accepted + total_rejected - self._offered_at_last_report
        new_withheld = self.withheld - self._withheld_at_last_report
        self._rejected_at_last_report = total_rejected
        self._offered_at_last_report = accepted + total_rejected
        self._withheld_at_last_report = self.withheld

        errors, warnings = [], []
        if self.service_stopped:
            errors.append(f'~/predict answers no more: {self.service_stopped}')
        if accepted + total_rejected == 0 and not errors:
            return STALE, f'waiting for input: {self.window_reason}', values
        if clock_publishers is not None and len(clock_publishers) > 1:
            errors.append(f'{len(clock_publishers)} publishers on /clock '
                          f'({", ".join(clock_publishers)}): the node\'s clock jumps '
                          f'between their time lines; stop all but one')
        if clock_still is not None and clock_still > self.watchdog:
            errors.append(f'/clock has not moved for {clock_still:.1f} s of wall time (the '
                          f"node's clock stands at {now:.1f} s): its publisher is paused "
                          f'or gone')
        if lines is not None and lines.contested_lag is not None:
            errors.append(f'two time lines on {self.state_topic}: live samples '
                          f'{abs(lines.contested_lag - offset):.1f} s apart, from two '
                          f'sources')
        if age is not None and age > self.max_age:
            errors.append(f'inputs stale: newest state is {age:.1f} s old on '
                          f'{self.state_topic} (max {self.max_age:g} s)')
        elif self.last_state_wall is not None and wall is not None and \
                wall - self.last_state_wall > self.watchdog:
            errors.append(f'no {self.state_topic} accepted for '
                          f'{wall - self.last_state_wall:.1f} s of wall time (max '
                          f'{self.watchdog:g} s)')
        if since > self.silence_error:
            why = '' if errors or self.window_status in ('ok', 'stale') else \
                f': {self.window_reason}'
            errors.append(f'no forecast for {since:.1f} s{why}')
        if new_offered and new_rejected / new_offered > self.rejection_warn_fraction:
            warnings.append(f'{new_rejected} of {new_offered} inputs rejected since the '
                            f'last report')
        if new_withheld:
            warnings.append(f'{new_withheld} forecasts withheld: '
                            f'{self.last_withheld_reason}')
        if lines is not None and lines.shifted():
            ago = now - lines.latest.at if lines.latest is not None else 0.0
            warnings.append(f'{lines.describe(self.state_topic)}, followed for {ago:.0f} s '
                            f'(a source paused, restarted or with its clock off)')
        if self.unbounded:
            warnings.append(self.unbounded)
        if self.departure:
            warnings.append(self.departure)
        if self.bound_hit_fraction > self.bound_hit_warn:
            warnings.append(f'LSTM correction at its bound in '
                            f'{100 * self.bound_hit_fraction:.0f} % of the forecast: the '
                            f'physics is far off')
        if errors:
            return ERROR, '; '.join(errors + warnings), values
        if warnings:
            return WARN, 'forecasting; ' + '; '.join(warnings), values
        return OK, 'forecasting', values

    def _clock_still(self, now: float, wall: float | None) -> float | None:
        """Wall seconds the node's clock has stood still (use_sim_time only), or None."""
        if not self.sim_time or wall is None:
            return None
        if self.clock_seen != now or self.clock_moved_wall is None:
            self.clock_seen, self.clock_moved_wall = now, wall
        return wall - self.clock_moved_wall
