"""
Do no harm: the relative threshold a hybrid is served with, chosen on validation runs.

A trained hybrid is forecast on the validation runs at thresholds of a grid that
includes 0, the physics alone (``hybrid_models.bound``). A forecast is admissible when,
at every reported step (``hybrid_models.metrics.StepErrors.profile``: every quarter of
the horizon), neither its position error nor its state error is worse than the physics
alone's. T = 0 is admissible by construction. "Worse" is judged on paired differences
(each forecast against the physics alone's from the same window), averaged per
validation run: the runs are the sampling units, since the forecasts of one run share
its conditions and overlap. The mean of the runs' differences must exceed its standard
error times the one-sided normal quantile of ``confidence`` (0.95: 1.645), so that a
difference the validation runs cannot resolve is not called harm; with one validation
run, or ``confidence`` None, any worse mean counts; the choice's reason then says that
one run judged it (a user with few runs should know the fallback may be noise).

The served threshold is the admissible one of the grid with the lowest validation score
(sum over states of RMSE / std, the score epochs are selected by). When no threshold
above 0 is admissible, the correction may still be admissible from a later reported
step on (a hybrid whose correction helps later but not over the first seconds): the
schedule "the physics alone until s, then T" (``bound.schedule_of``) is tried for s at
each reported step but the last. One threshold for the whole forecast is preferred to a
later start however their scores compare, as the simpler claim that the validation runs
support. If nothing is admissible, the physics alone is served. The checkpoint keeps
every candidate's figures, so the choice can be checked and redone; per-state RMSEs are
reported, not judged: a correction may trade a little of one state for much of the
others.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
import math
from statistics import NormalDist

import numpy as np

from hybrid_models.metrics import StepErrors, trajectory_errors

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


def forecast_figures(pred: np.ndarray, true: np.ndarray, spec, state_std: np.ndarray,
                     runs: np.ndarray) -> dict:
    """
    Return what the selection judges of forecasts (B, H, n_state) against the truth.

    'score' and 'profile' (``metrics.StepErrors``), and per forecast at the reported steps
    (B, steps) its position error ('position') and state error ('state': sum over states
    of squared error / std^2), with the run each came from (``runs``, (B,)), for paired
    comparisons.
    """
    errors = StepErrors.of(pred, true, spec)
    profile = errors.profile(spec, state_std=state_std)
    at = np.asarray(profile['steps']) - 1
    with np.errstate(invalid='ignore', over='ignore'):
        position = trajectory_errors(pred, true, spec)[:, at]
        state = (((np.asarray(pred, np.float64) - true) / state_std) ** 2).sum(axis=-1)[:, at]
    return {'score': errors.score(state_std), 'profile': profile,
            'per_forecast': {'position': position, 'state': state, 'run': np.asarray(runs)}}


def harms(profile: dict, physics: dict, until_step: int | None = None,
          paired: tuple[dict, dict] | None = None, confidence: float | None = None
          ) -> list[str]:
    """
    Return every judged figure of ``profile`` worse than the physics alone's.

    The position error and, where the profiles carry it, the state error (``normalized``)
    at the reported steps up to ``until_step`` (default all). With ``paired``, the
    per-forecast figures of both (``forecast_figures``), and a ``confidence``, worse
    means worse beyond the sampling error (module docstring); otherwise any worse mean
    counts. Empty: the profile is admissible. A diverged figure (None) is always worse.
    """
    z = None if paired is None or confidence is None else NormalDist().inv_cdf(confidence)
    worse = []
    figures = [('position', 'position', profile['position_m'], physics['position_m'])]
    if 'normalized' in profile and 'normalized' in physics:
        figures.append(('state error', 'state', profile['normalized'], physics['normalized']))
    for name, key, got, reference in figures:
        for q, (step, g, r) in enumerate(zip(profile['steps'], got, reference, strict=True)):
            if until_step is not None and step > until_step:
                continue
            if g is None:
                worse.append(f'{name} at step {step}')
            elif r is not None and g > r and (z is None or _resolved(
                    paired[0][key][:, q] - paired[1][key][:, q], paired[1]['run'], z)):
                worse.append(f'{name} at step {step}')
    return worse


def _resolved(differences: np.ndarray, runs: np.ndarray, z: float) -> bool:
    """Tell whether paired differences, averaged per run, are positive beyond z errors."""
    per_run = np.array([differences[runs == r].mean() for r in np.unique(runs)])
    if len(per_run) < 2:
        return True
    return bool(per_run.mean() > z * per_run.std(ddof=1) / np.sqrt(len(per_run)))


def choose_schedule(evaluate: Callable[[list], list], grid: list, physics: dict,
                    dt: float, confidence: float | None = None) -> dict:
    """
    Pick the served threshold (module docstring); return the choice.

    ``evaluate(schedules)`` forecasts the validation runs served at each schedule of a
    list and returns their ``forecast_figures``, in order; ``physics`` is that of the
    physics alone. Returns
    {'relative_threshold' (a number, or a schedule for a later start), 'score', 'reason',
    'candidates'} where every candidate row has its schedule and ``harms``.
    """
    steps = physics['profile']['steps']
    runs = physics.get('per_forecast', {}).get('run')
    n_runs = None if runs is None else int(len(np.unique(runs)))
    caveat = ('; judged on one validation run, where any worse mean counts as harm'
              if n_runs == 1 else '')
    rows: list[dict] = []
    for start in [0.0] + [k * dt for k in steps[:-1]]:
        tried = []
        thresholds = [t for t in grid if t != PHYSICS_ALONE]
        schedules = [[(0.0, t)] if start == 0.0 else [(0.0, PHYSICS_ALONE), (start, t)]
                     for t in thresholds]
        for t, schedule, figures in zip(thresholds, schedules, evaluate(schedules),
                                        strict=True):
            row = {'from_s': start, 'relative_threshold': t, 'schedule': schedule,
                   **figures}
            paired = (row.pop('per_forecast'), physics['per_forecast']) \
                if 'per_forecast' in row and 'per_forecast' in physics else None
            row['harms'] = harms(row['profile'], physics['profile'], None, paired,
                                 confidence)
            tried.append(row)
        rows += tried
        admissible = [r for r in tried if not r['harms'] and math.isfinite(r['score'])
                      and r['score'] < physics['score']]
        best = min(admissible, key=lambda r: (r['score'], _order(r['relative_threshold'])),
                   default=None)
        if best is not None:
            gain = 1 - best['score'] / physics['score']
            when = '' if start == 0.0 else f', the physics alone until {start:g} s'
            return {'relative_threshold': simplest(best['schedule']), 'score': best['score'],
                    'reason': f'lowest validation score not worse than the physics alone at '
                              f'any reported step{when} ({100 * gain:.1f} % below the '
                              f'physics alone){caveat}', 'candidates': rows,
                    'validation_runs': n_runs}
    return {'relative_threshold': PHYSICS_ALONE, 'score': physics['score'],
            'reason': 'no threshold forecasts the validation runs better than the physics '
                      'alone without being worse at a reported step; the physics alone is '
                      f'served{caveat}', 'candidates': rows, 'validation_runs': n_runs}


def simplest(schedule: list[tuple[float, float | None]]):
    """Return a schedule with repeats merged; one entry is returned as its threshold."""
    merged = [schedule[0]]
    for start, t in schedule[1:]:
        if t != merged[-1][1]:
            merged.append((start, t))
    return merged[0][1] if len(merged) == 1 else [list(entry) for entry in merged]


def _order(threshold: float | None) -> float:
    return math.inf if threshold is None else threshold
