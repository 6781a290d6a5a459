"""
Forecasts that hold the wind constant over the earth, not relative to a turning bow (no ROS).

The model's wind columns give the angle the wind comes from relative to the bow
(``wind_dir_cos``, ``wind_dir_sin``; docs/conventions.md). A forecast that holds the
latest measured wind (no plan, or a plan without wind columns) used to hold that
relative angle, as if the wind turned with the vessel: through a 90 degree turn a head
wind stayed a head wind. Wind is steady over the earth on a forecast's time scale, so
the held direction is turned against the forecast's own heading change instead:

    gamma_k = gamma_0 - (psi_k - psi_0)

with psi_k the heading at the start of step k, integrated from the forecast's own states
as the dead reckoning does (``hybrid_models.metrics.heading_rate``). The compiled
forecaster turns it step by step inside its one pass (``Forecaster.forecast``'s
``hold_wind``), so the wind each step sees is the one over the earth at the heading the
forecast itself reaches. It replaced two passes, a first forecast with the wind held at
the bow whose heading turned the wind of a second: the same formula on the first
forecast's heading instead of the forecast's own, and twice the compute (1,000 what-if
plans: 189 -> 110 ms, docs/predictor.md). Measured over 32 runs of the demo's scenario
(docs/results/demo_gap): the mean trajectory error of 15-minute forecasts 176 m with the
wind held at the bow, 132 m with this hold (133 m with the two passes), 125 m with the
measured future wind.
"""

from __future__ import annotations

import numpy as np

from hybrid_models.engine import Forecast, Forecaster, wind_direction_columns


def forecast_holding_wind(engine: Forecaster, states: np.ndarray, controls: np.ndarray,
                          future: np.ndarray, held: np.ndarray) -> tuple[Forecast, np.ndarray]:
    """
    Return the forecast of B plans and the future controls it used (B, H, n_control).

    ``held`` (B,) marks the plans whose wind is the latest measurement held (every step
    the same, from ``plans.plan_controls`` or ``plans.hold_latest``); their wind is held
    over the earth (module docstring). Other plans, and vessels without wind, are
    forecast as given. One pass of the engine either way.
    """
    held = np.asarray(held, bool)
    made = engine.forecast(states, controls, future, hold_wind=held)
    if made.wind is None:
        return made, future
    used = np.array(future, dtype=float)
    for j, column in enumerate(wind_direction_columns(engine.spec)):
        used[held, :, column] = made.wind[held, :, j]
    return made, used


def holds_wind(spec, rows: np.ndarray | None) -> bool:
    """Return whether a forecast following plan ``rows`` (None: no plan) holds the wind."""
    if rows is None:
        return wind_direction_columns(spec) is not None
    return bool(holds_wind_each(spec, rows[None])[0])


def holds_wind_each(spec, plans: np.ndarray) -> np.ndarray:
    """Return (B,) whether each checked plan of ``plans`` (B, H, n_control) holds the wind."""
    columns = wind_direction_columns(spec)
    if columns is None:
        return np.zeros(len(plans), bool)
    return np.isnan(plans[:, :, columns[0]]).all(axis=1)   # the plan leaves the wind out
