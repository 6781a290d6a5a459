"""
Do no harm: the relative threshold a hybrid is served with, chosen on validation runs.

A trained hybrid is forecast on the validation runs at thresholds of a grid that
includes 0, the physics alone (``hybrid_models.bound``). A forecast is admissible when,
at every reported step (``hybrid_models.metrics.StepErrors.profile``: every quarter of
the horizon), neither its mean position error nor its state error (sum over states of
RMSE / std) is worse than the physics alone's. T = 0 is admissible by construction.

The threshold may change along the forecast, once per reported step (a schedule,
``bound.schedule_of``), chosen quarter by quarter: for the first quarter, the threshold
(later quarters continuing with it) with the lowest validation score among those
admissible up to the quarter's end; then, with it fixed, the next quarter's; and so on.
The first quarter of a hybrid whose correction helps later but not at first is served
by the physics alone. If no threshold is admissible in some quarter, the physics alone
is served throughout. The checkpoint keeps every candidate's figures, so the choice can
be checked and redone; per-state RMSEs are reported, not judged: a correction may trade
a little of one state for much of the others.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math

PHYSICS_ALONE = 0.0


def threshold_grid(thresholds: Sequence[float | None], cap: float | None) -> list:
    """
    Return the candidate thresholds, ascending (None, unbounded, last).

    The grid's values up to ``cap`` (the config's relative threshold; None: no cap), the
    cap itself, and always 0, the physics alone.
    """
    grid = {PHYSICS_ALONE}
    for t in thresholds:
        if t is not None and not t >= 0:
            raise ValueError(f'selection thresholds must be >= 0 or null, got {t}')
        if cap is None or (t is not None and t <= cap):
            grid.add(t)
    if cap is not None:
        grid.add(float(cap))
    finite = sorted(t for t in grid if t is not None)
    return finite + ([None] if None in grid else [])


def harms(profile: dict, physics: dict, until_step: int | None = None) -> list[str]:
    """
    Return every judged figure of ``profile`` worse than the physics alone's.

    The position error and, where the profiles carry it, the state error (``normalized``)
    at the reported steps up to ``until_step`` (default all). Empty: the profile is
    admissible. A diverged figure (None) is always worse.
    """
    worse = []
    figures = [('position', profile['position_m'], physics['position_m'])]
    if 'normalized' in profile and 'normalized' in physics:
        figures.append(('state error', profile['normalized'], physics['normalized']))
    for name, got, reference in figures:
        for step, g, r in zip(profile['steps'], got, reference, strict=True):
            if until_step is not None and step > until_step:
                continue
            if g is None or (r is not None and g > r):
                worse.append(f'{name} at step {step}')
    return worse


def choose_schedule(evaluate: Callable[[list], dict], grid: list, physics: dict,
                    dt: float) -> dict:
    """
    Pick the served threshold, quarter by quarter (module docstring); return the choice.

    ``evaluate(schedule)`` forecasts the validation runs served at a schedule and returns
    {'score', 'profile'}; ``physics`` is that of the physics alone. Returns
    {'relative_threshold' (a number, or a schedule when it changes), 'score', 'reason',
    'candidates'} where every candidate row has its schedule and ``harms``.
    """
    steps = physics['profile']['steps']
    starts = [0.0] + [k * dt for k in steps[:-1]]
    chosen: list[tuple[float, float | None]] = []
    rows: list[dict] = []
    best = None
    for start, end in zip(starts, steps, strict=True):
        tried = []
        for t in grid:
            schedule = chosen + [(start, t)]
            row = {'quarter_from_s': start, 'relative_threshold': t, 'schedule': schedule,
                   **evaluate(schedule)}
            row['harms'] = harms(row['profile'], physics['profile'], end)
            tried.append(row)
        rows += tried
        admissible = [r for r in tried if not r['harms'] and math.isfinite(r['score'])]
        best = min(admissible, key=lambda r: (r['score'], _order(r['relative_threshold'])),
                   default=None)
        if best is None:
            break
        chosen = best['schedule']
    if best is None or best['score'] >= physics['score']:
        reason = ('no threshold forecasts the validation runs better than the physics alone '
                  'without being worse at a reported step; the physics alone is served')
        return {'relative_threshold': PHYSICS_ALONE, 'score': physics['score'],
                'reason': reason, 'candidates': rows}
    served = simplest(chosen)
    gain = 1 - best['score'] / physics['score']
    reason = (f'lowest validation score not worse than the physics alone at any reported '
              f'step ({100 * gain:.1f} % below the physics alone)')
    return {'relative_threshold': served, 'score': best['score'], 'reason': reason,
            'candidates': rows}


def simplest(schedule: list[tuple[float, float | None]]):
    """Return a schedule with repeats merged; one entry is returned as its threshold."""
    merged = [schedule[0]]
    for start, t in schedule[1:]:
        if t != merged[-1][1]:
            merged.append((start, t))
    return merged[0][1] if len(merged) == 1 else [list(entry) for entry in merged]


def _order(threshold: float | None) -> float:
    return math.inf if threshold is None else threshold
