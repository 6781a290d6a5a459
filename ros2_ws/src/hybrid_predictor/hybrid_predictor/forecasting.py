"""
One forecast from an assembled window, as the predictor publishes it (no ROS).

The predictor node, its what-if service, its hindsight scoring and the offline
re-forecast (``re_forecast``) all forecast through these functions: the future controls
a forecast assumes (``future_controls``), the forecast with the wind held over the earth
(``held_wind``), and its states, track and bands in the published frames
(``published``: FLU states, ENU track, REP-103). Live and offline forecasts are therefore
equal by construction, not by a copy kept in step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_models.engine import Forecaster
from vessel_physics import frames

from .held_wind import forecast_holding_wind, holds_wind, holds_wind_each
from .plans import answer_slice, answer_steps, hold_latest, plan_controls, plan_rows, track


@dataclass(frozen=True)
class Future:
    """The future controls of one forecast (1, H, n_control) and what they are."""

    controls: np.ndarray
    holds_wind: bool      # the latest wind is held (over the earth, ``held_wind``)
    follows_plan: bool    # False: the latest controls held
    why_not: str = ''     # why a plan given was not followed ('' if it starts later)


def future_controls(spec, result, horizon: int, plan: np.ndarray | None = None,
                    plan_start: float = 0.0, plan_timeout: float = np.inf) -> Future:
    """
    Return the future controls a forecast from window ``result`` assumes.

    ``plan`` (steps, n_control) is a checked plan (``plans.check_plan``) stamped
    ``plan_start`` (s): followed from the window's end if it covers the horizon there and
    is at most ``plan_timeout`` s old; otherwise the latest controls are held.
    """
    latest = result.controls[-1]
    why = ''
    if plan is not None:
        rows, why = plan_rows(plan, plan_start, result.t_end, spec.dt, horizon, plan_timeout)
        if rows is not None:
            return Future(plan_controls(rows, latest)[None], holds_wind(spec, rows), True)
    return Future(hold_latest(latest, horizon), holds_wind(spec, None), False, why)


def plan_futures(spec, matrices: np.ndarray, latest: np.ndarray) -> list[Future]:
    """
    Return the futures of a what-if request's checked plans (B, H, n_control), made at once.

    ``latest`` holds the columns a plan leaves out (``plans.plan_controls``).
    """
    controls = plan_controls(matrices, latest)
    return [Future(controls[i:i + 1], bool(held), True)
            for i, held in enumerate(holds_wind_each(spec, matrices))]


@dataclass(frozen=True)
class Published:
    """
    A batch of B forecasts in the published frames, at the K steps kept.

    States FLU (B, K, n_state) in the vessel's units; track x, y (and z of a 6-DOF
    vehicle, else None), heading (B, K) in m and rad, ENU; bands (B, L, K, n_state) and
    their position radii (L, K) m, None when the model has none.
    """

    steps: np.ndarray
    hybrid: np.ndarray
    physics: np.ndarray
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    z: np.ndarray | None
    band_lower: np.ndarray | None = None
    band_upper: np.ndarray | None = None
    band_radius: np.ndarray | None = None
    bound_available: np.ndarray | None = None   # (B, K) the bound's share (with the fade)


def published(spec, pose, hybrid: np.ndarray, physics: np.ndarray, bands=None,
              stride: int = 1, available: np.ndarray | None = None) -> Published:
    """
    Return forecasts (B, H, n_state) FRD from the window's ``pose`` in the published frames.

    ``stride`` > 1 keeps the steps ending at every ``stride`` steps (a what-if request's
    answer_period; ``plans.answer_steps``); ``bands`` is the model's (``engine.bands``);
    ``available`` (B, H) the share of the bound each step had (``engine.Forecast``).
    """
    path = track(hybrid, pose, spec)   # one pass, all plans
    keep = answer_slice(stride)
    x, y, _ = frames.position_ned_to_enu(path.north[..., keep], path.east[..., keep])
    z = None if path.down is None else -path.down[..., keep]
    names = spec.state_names
    out = dict(steps=answer_steps(hybrid.shape[1], stride),
               hybrid=frames.states_frd_to_flu(hybrid[:, keep], names),
               physics=frames.states_frd_to_flu(physics[:, keep], names), x=x, y=y,
               heading=frames.heading_ned_to_enu(path.heading[..., keep]), z=z,
               bound_available=None if available is None else available[:, keep])
    if bands is not None:
        # The bands are the forecast plus offsets a level and step share: the offsets are
        # turned into FLU (levels, K, n) and added to the FLU forecast, the same numbers
        # as the bands turned whole, in a third of the passes over the batch.
        lower, upper, radius = bands.at(hybrid.shape[1])
        lower, upper = frames.interval_frd_to_flu(lower[:, keep], upper[:, keep], names)
        around = out['hybrid'][:, None]
        out['band_lower'], out['band_upper'] = around + lower, around + upper
        out['band_radius'] = radius[..., keep]
    return Published(**out)


def forecast(engine: Forecaster, spec, result, futures: list[Future], stride: int = 1):
    """
    Return (hybrid, physics, Published) of one forecast per future from window ``result``.

    hybrid and physics (B, H, n_state) FRD, as the model gives them; every future with
    ``holds_wind`` has its wind held over the earth (``held_wind``). ``spec`` is the
    vessel served.
    """
    plans = np.concatenate([f.controls for f in futures])
    made, _ = forecast_holding_wind(engine, result.states, result.controls, plans,
                                    [f.holds_wind for f in futures])
    return made.hybrid, made.physics, published(spec, result.pose, made.hybrid,
                                                made.physics, engine.bands, stride,
                                                made.available)
