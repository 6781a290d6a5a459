"""
Forecasts that hold the wind constant over the earth, not relative to a turning bow (no ROS).

The model's wind columns give the angle the wind comes from relative to the bow
(``wind_dir_cos``, ``wind_dir_sin``; docs/conventions.md). A forecast that holds the
latest measured wind (no plan, or a plan without wind columns) used to hold that
relative angle, as if the wind turned with the vessel: through a 90 degree turn a head
wind stayed a head wind. Wind is steady over the earth on a forecast's time scale, so
the held direction is turned against the forecast's own heading change instead:

    gamma_k = gamma_0 - (psi_k - psi_0)

with psi_k the heading at the start of step k (``hybrid_models.metrics.dead_reckoning``
of a first forecast with the wind held relative to the bow). One such pass is used: the
heading of the second forecast differs from the first's by the effect of the turned
wind alone. Measured over 32 runs of the demo's scenario (docs/results/demo_gap): the
mean trajectory error of 15-minute forecasts 176 m with the wind held at the bow, 133 m
with this hold, 125 m with the measured future wind.
"""

from __future__ import annotations

import numpy as np

from hybrid_models.engine import Forecast, Forecaster
from hybrid_models.metrics import dead_reckoning
from vessel_description.vocabulary import ENVIRONMENT_DIRECTIONS


def wind_direction_columns(spec) -> tuple[int, int] | None:
    """Return the control indices of the wind's (cos, sin) relative to the bow, or None."""
    pair = ENVIRONMENT_DIRECTIONS['wind']
    if 'wind' not in spec.environment:
        return None
    return spec.control_index(pair[0]), spec.control_index(pair[1])


def turned_wind(future: np.ndarray, heading_change: np.ndarray, columns: tuple[int, int],
                ) -> np.ndarray:
    """
    Return ``future`` (B, H, n_control) with its held wind direction turned.

    ``heading_change`` (B, H) is psi_k - psi_0 (rad, NED, positive to starboard) at the
    start of each step k; the wind's angle relative to the bow becomes gamma_0 minus it.
    """
    out = np.array(future, dtype=float)
    i_cos, i_sin = columns
    gamma = np.arctan2(out[:, :1, i_sin], out[:, :1, i_cos]) - heading_change
    out[..., i_cos], out[..., i_sin] = np.cos(gamma), np.sin(gamma)
    return out


def forecast_holding_wind(engine: Forecaster, states: np.ndarray, controls: np.ndarray,
                          future: np.ndarray, held: np.ndarray) -> tuple[Forecast, np.ndarray]:
    """
    Return the forecast of B plans and the future controls it used (B, H, n_control).

    ``held`` (B,) marks the plans whose wind is the latest measurement held (every step
    the same, from ``plans.plan_controls`` or ``plans.hold_latest``); their wind is held
    over the earth (module docstring). Other plans, and vessels without wind, are
    forecast as given, in one pass.
    """
    columns = wind_direction_columns(engine.spec)
    first = engine.forecast(states, controls, future)
    held = np.asarray(held, bool)
    if columns is None or not held.any():
        return first, future
    _, heading = dead_reckoning(np.asarray(first.hybrid, np.float64), engine.spec)
    start = np.concatenate([np.zeros((len(heading), 1)), heading[:, :-1]], axis=1)
    turned = np.where(held[:, None, None], turned_wind(future, start, columns), future)
    return engine.forecast(states, controls, turned), turned


def holds_wind(spec, rows: np.ndarray | None) -> bool:
    """Return whether a forecast following plan ``rows`` (None: no plan) holds the wind."""
    columns = wind_direction_columns(spec)
    return columns is not None and (rows is None or bool(np.isnan(rows[:, columns[0]]).all()))
