"""
The predictor's health in numbers, for /diagnostics (no ROS).

Keeps the latest forecast latencies (from a state message arriving to its forecast
being published) and decides the diagnostic level: OK while forecasts flow, WARN when
inputs are rejected or the LSTM keeps hitting its bound, ERROR when no window can be
formed (stale or incomplete inputs) and STALE before anything arrived. Rejected inputs
warn only while new ones keep coming: the counts in the report are cumulative, the
level looks at what changed since the previous report.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

OK, WARN, ERROR, STALE = 0, 1, 2, 3


@dataclass
class Health:
    """Running figures of one predictor; ``report`` turns them into key/value pairs."""

    latency_window: int = 200
    bound_hit_warn: float = 0.2
    latencies_ms: deque = field(default_factory=deque)
    forecasts: int = 0
    bound_hit_fraction: float = 0.0
    window_status: str = 'incomplete'
    window_reason: str = 'no input yet'
    window_fill: float = 0.0
    input_age_s: float | None = None
    _rejected_at_last_report: int = 0

    def record_forecast(self, latency_ms: float, bound_hit_fraction: float) -> None:
        """Note one published forecast."""
        self.latencies_ms.append(latency_ms)
        while len(self.latencies_ms) > self.latency_window:
            self.latencies_ms.popleft()
        self.forecasts += 1
        self.bound_hit_fraction = bound_hit_fraction

    def record_window(self, status: str, reason: str, fill: float, age: float | None) -> None:
        """Note the outcome of the latest window assembly."""
        self.window_status, self.window_reason = status, reason
        self.window_fill, self.input_age_s = fill, age

    def latency_percentiles(self) -> tuple[float, float] | None:
        """Return (p50, p99) of the recent latencies in ms, or None."""
        if not self.latencies_ms:
            return None
        values = np.fromiter(self.latencies_ms, float)
        return float(np.percentile(values, 50)), float(np.percentile(values, 99))

    def report(self, rejected: dict[str, int]) -> tuple[int, str, dict[str, str]]:
        """Return (level, message, values) given the rejected-input counts per reason."""
        values = {
            'window_status': self.window_status,
            'window_fill_percent': f'{100.0 * self.window_fill:.0f}',
            'input_age_s': 'n/a' if self.input_age_s is None else f'{self.input_age_s:.2f}',
            'forecasts_published': str(self.forecasts),
            'lstm_bound_hit_fraction': f'{self.bound_hit_fraction:.3f}',
        }
        latency = self.latency_percentiles()
        if latency is not None:
            values['forecast_latency_p50_ms'] = f'{latency[0]:.2f}'
            values['forecast_latency_p99_ms'] = f'{latency[1]:.2f}'
        for reason, count in sorted(rejected.items()):
            values[f'rejected_{reason}'] = str(count)
        new_rejections = sum(rejected.values()) - self._rejected_at_last_report
        self._rejected_at_last_report = sum(rejected.values())
        if self.window_status != 'ok':
            if self.forecasts == 0 and self.input_age_s is None:
                return STALE, f'waiting for input: {self.window_reason}', values
            return ERROR, f'no forecast: {self.window_reason}', values
        if self.bound_hit_fraction > self.bound_hit_warn:
            return WARN, (f'LSTM correction at its bound in {100 * self.bound_hit_fraction:.0f}'
                          f' % of the forecast: the physics is far off'), values
        if new_rejections > 0:
            return WARN, f'forecasting; {new_rejections} inputs rejected since last report', \
                values
        return OK, 'forecasting', values
