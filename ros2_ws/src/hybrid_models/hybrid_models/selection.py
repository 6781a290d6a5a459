"""
Do no harm: the relative threshold a hybrid is served with, chosen on validation runs.

A trained hybrid is forecast on the validation runs at every threshold of a grid that
includes 0, the physics alone (``hybrid_models.bound``). A threshold is admissible when
no figure of its horizon profile (``hybrid_models.metrics.StepErrors.profile``: the
position error and every state's RMSE at every reported step) is worse than the
physics alone's; T = 0 is admissible by construction. The served threshold is the
admissible one with the lowest validation score (sum over states of RMSE / std, the
score epochs are selected by), the smallest on ties. The checkpoint keeps every
candidate's figures, so the choice can be checked and redone.
"""

from __future__ import annotations

from collections.abc import Sequence
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


def harms(profile: dict, physics: dict) -> list[str]:
    """
    Return every reported figure of ``profile`` worse than the physics alone's.

    Empty: the profile is admissible. A diverged figure (None) is always worse.
    """
    worse = []
    figures = [('position', profile['position_m'], physics['position_m'])] + [
        (state, values, physics['rmse'][state]) for state, values in profile['rmse'].items()]
    for name, got, reference in figures:
        for step, g, r in zip(profile['steps'], got, reference, strict=True):
            if g is None or (r is not None and g > r):
                worse.append(f'{name} at step {step}')
    return worse


def choose(candidates: list[dict], physics: dict) -> dict:
    """
    Pick the served threshold; return the choice with its reason.

    ``candidates``: rows {'relative_threshold', 'score', 'profile'}; ``physics``: the
    same for the physics alone. Returns {'relative_threshold', 'score', 'reason',
    'candidates'} where every candidate row gains its list of ``harms``.
    """
    rows = [{**row, 'harms': harms(row['profile'], physics['profile'])} for row in candidates]
    admissible = [r for r in rows if not r['harms'] and math.isfinite(r['score'])]
    best = min(admissible, key=lambda r: (r['score'], _order(r['relative_threshold'])),
               default=None)
    if best is None or best['score'] >= physics['score']:
        reason = ('no threshold forecasts the validation runs better than the physics alone '
                  'without being worse at a reported step; the physics alone is served')
        return {'relative_threshold': PHYSICS_ALONE, 'score': physics['score'],
                'reason': reason, 'candidates': rows}
    gain = 1 - best['score'] / physics['score']
    reason = (f'lowest validation score among the thresholds not worse than the physics '
              f'alone at any reported step ({100 * gain:.1f} % below the physics alone)')
    return {'relative_threshold': best['relative_threshold'], 'score': best['score'],
            'reason': reason, 'candidates': rows}


def _order(threshold: float | None) -> float:
    return math.inf if threshold is None else threshold
