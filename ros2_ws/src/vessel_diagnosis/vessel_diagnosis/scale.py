"""
Check that the recordings move like a vessel of the vessel file's size.

Run before anything is fitted. A model-scale recording diagnosed with a full-scale vessel
file (or the reverse) would otherwise be "explained" by absurd corrections. Three
dimensionless figures of the recordings against thresholds of the settings
(``scale_check`` in config/diagnosis.yaml):

- Froude number Fn = U / sqrt(g L) of a high quantile of the measured speed
  U = |(u, v)| (m/s), with L = ``particulars.length_m`` (m): no hull, displacement or
  planing, reaches ``max_froude``;
- non-dimensional turning rate r' = |r| L / U (= L / turning radius) at speeds above a
  share of the recordings' typical speed: no ship turns on a radius much smaller than
  its length, so r' above ``max_turning_rate`` means L is too large for the recordings;
- the vessel file's ``limits``: a state whose high quantile lies beyond its limit by more
  than ``limits_margin`` times the limit span.

A 6-DOF vehicle (``Vessel.is_spatial``: a multirotor) has no hull whose speed and
turning radius its length bounds: it hovers, turns on the spot and flies sideways. Only
its limits are checked; its Froude number and turning rate are None.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from vessel_description import Vessel
from vessel_diagnosis.recordings import Run

GRAVITY = 9.81   # m/s^2


class ScaleError(ValueError):
    """The recordings do not fit the vessel file's scale; the message is one line."""


def scale_figures(runs: Sequence[Run], vessel: Vessel, cfg) -> dict:
    """Return the recordings' Froude number, turning rate and limit excesses (findings)."""
    states = vessel.state_names
    z = np.concatenate([r.z for r in runs])
    length = vessel.length_m
    speed = np.hypot(z[:, states.index('u')], z[:, states.index('v')])
    top_speed = float(np.quantile(speed, cfg.quantile))
    moving = speed >= cfg.turning_speed_share * top_speed
    yaw_rate = z[moving, states.index('r')]
    turning = (float(np.quantile(np.abs(yaw_rate) * length / speed[moving], cfg.quantile))
               if moving.any() and top_speed > 0 else 0.0)
    if vessel.is_spatial:      # no hull: the figure would judge nothing (module doc)
        turning = None
    excess = {}
    for state, (low, high) in vessel.limits.items():
        if state not in states:
            continue
        values = z[:, states.index(state)]
        hi = float(np.quantile(values, cfg.quantile))
        lo = float(np.quantile(values, 1.0 - cfg.quantile))
        excess[state] = max(hi - high, low - lo, 0.0) / (high - low)
    return {'length_m': length, 'speed_mps': top_speed,
            'froude': None if vessel.is_spatial else top_speed / np.sqrt(GRAVITY * length),
            'turning_rate': turning, 'limit_excess': excess, 'quantile': cfg.quantile}


def scale_problems(figures: dict, vessel: Vessel, cfg) -> list[str]:
    """Return what is implausible about the figures (empty when the scales agree)."""
    out = []
    length = figures['length_m']
    if figures['froude'] is not None and figures['froude'] > cfg.max_froude:
        out.append(f'speeds up to {figures["speed_mps"]:.2f} m/s give Froude number '
                   f'{figures["froude"]:.2f} for length_m {length:g} (no hull exceeds '
                   f'{cfg.max_froude:g})')
    if figures['turning_rate'] is not None and figures['turning_rate'] > cfg.max_turning_rate:
        out.append(f'turns of {figures["turning_rate"]:.2f} ship lengths per radius '
                   f'(r L / U) for length_m {length:g} (no ship exceeds '
                   f'{cfg.max_turning_rate:g})')
    for state, excess in figures['limit_excess'].items():
        if excess > cfg.limits_margin:
            low, high = vessel.limits[state]
            out.append(f'{state} leaves its limits [{low:g}, {high:g}] by {excess:.1f} times '
                       f'their span (more than {cfg.limits_margin:g})')
    return out


def check_scale(runs: Sequence[Run], vessel: Vessel, cfg) -> dict:
    """Return the scale figures; raise ScaleError (one line) when they are implausible."""
    figures = scale_figures(runs, vessel, cfg)
    problems = scale_problems(figures, vessel, cfg)
    if problems:
        raise ScaleError(f'the recordings do not fit the scale of vessel {vessel.name!r} '
                         f'({vessel.source}): {"; ".join(problems)}; check the vessel file, '
                         f'or pass --skip-scale-check')
    return figures
