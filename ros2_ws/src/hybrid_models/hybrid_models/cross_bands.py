"""
Cross-validated forecast bands, for a vessel recorded in too few runs to hold some out.

Bands from a handful of validation runs are only as good as those runs stand for the
others (docs/results/real/bands.md). A cross-validated study (``studies.crossval``)
holds every recording out once: each fold's test runs forecast by that fold's models,
all served at ONE relative threshold, are out-of-fold forecasts of every recording.
Pooled over the folds they calibrate the bands (``bands.calibrate``, cross-conformal),
which then hold for a model of the same recipe trained on all runs, at that threshold.

Their honest coverage is measured leave-one-fold-out: bands calibrated on the other
folds' out-of-fold forecasts, measured on this fold's, pooled over the folds.

Pooled quantiles assume every forecast is like every other. Recordings are not: a few
runs a model mispredicts with an offset make whole folds fall short of the level while
the pooled band looks right in sample. ``fold-robust`` calibration (the default) takes
each band's edges, per knot and state, at the quantile level whose leave-one-fold-out
coverage over the calibration folds reaches the nominal level (``fold_robust_levels``):
wider where the folds disagree, narrower where they agree better than pooled quantiles
admit. Its honest coverage is measured the same way, one level further out: each fold
is held out from the whole calibration, level choice included. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_models.bands import LEVELS, Bands, BandsError, calibrate, coverage, knot_steps
from hybrid_models.metrics import trajectory_errors

CALIBRATIONS = ('fold-robust', 'pooled')
# Quantile levels a fold-robust band may be taken at: 0.01 to 0.995 in steps of 0.005.
LEVEL_GRID = np.round(np.arange(2, 200) * 0.005, 3)


@dataclass(frozen=True)
class HeldOut:
    """
    One fold's out-of-fold forecasts of its test runs, by that fold's model(s).

    ``pred`` and ``true`` (B, H, n_state): forecasts and the measured states, in the
    states' units (body FRD); ``runs`` the ids of the runs forecast.
    """

    fold: int
    runs: tuple[str, ...]
    pred: np.ndarray
    true: np.ndarray


def note_of(held_out: list[HeldOut], relative_threshold) -> str:
    """Return what the cross-validated bands were calibrated on, as one phrase."""
    forecasts = sum(len(h.pred) for h in held_out)
    return (f'cross-validated over {len(held_out)} folds, {forecasts} forecasts of '
            f'{_runs(held_out)} runs at relative threshold {relative_threshold}')


def _runs(held_out: list[HeldOut]) -> int:
    return len({run for h in held_out for run in h.runs})


def _pooled(held_out: list[HeldOut]) -> tuple[np.ndarray, np.ndarray]:
    return (np.concatenate([h.pred for h in held_out]),
            np.concatenate([h.true for h in held_out]))


def _enough_folds(held_out: list[HeldOut]) -> None:
    if len(held_out) < 2:
        raise BandsError(f'cross-validated bands need a study of at least 2 folds, got '
                         f'{len(held_out)}')


def _check_calibration(calibration: str) -> None:
    if calibration not in CALIBRATIONS:
        raise BandsError(f'calibration must be one of {CALIBRATIONS}, got {calibration!r}')


def fold_robust_levels(held_out: list[HeldOut], spec, levels=LEVELS) -> np.ndarray:
    """
    Return the quantile level of every band edge, chosen leave-one-fold-out.

    For each nominal level, knot (``bands.knot_steps``) and state (and the position, last
    column): the smallest level of ``LEVEL_GRID`` whose bands, calibrated on all folds
    but one and measured on that one, hold at least the nominal fraction of the
    forecasts pooled over the folds (weighted by their forecasts); the grid's largest
    where none does. Shape (levels, knots, n_state + 1).
    """
    _enough_folds(held_out)
    levels = sorted(float(level) for level in levels)
    at = knot_steps(held_out[0].pred.shape[1]) - 1
    errors = [(h.true - h.pred)[:, at] for h in held_out]
    distances = [trajectory_errors(h.pred, h.true, spec)[:, at] for h in held_out]
    total = sum(len(e) for e in errors)
    held = 0.0
    for k in range(len(held_out)):
        error = np.concatenate(errors[:k] + errors[k + 1:])
        distance = np.concatenate(distances[:k] + distances[k + 1:])
        # Both edges at every grid level in one call: the errors are sorted once.
        lo, hi = np.split(np.quantile(error, np.concatenate(
            [(1 - LEVEL_GRID) / 2, (1 + LEVEL_GRID) / 2]), axis=0), 2)   # (G, K, n) each
        mine = errors[k][None]
        inside = ((mine >= lo[:, None]) & (mine <= hi[:, None])).sum(axis=1)
        radius = np.quantile(distance, LEVEL_GRID, axis=0)              # (G, K)
        near = (distances[k][None] <= radius[:, None]).sum(axis=1)
        held = held + np.concatenate([inside, near[..., None]], axis=-1) / total
    out = []
    for level in levels:
        enough = held >= level - 1e-12                                  # (G, K, n + 1)
        first = np.where(enough.any(axis=0), enough.argmax(axis=0), len(LEVEL_GRID) - 1)
        out.append(LEVEL_GRID[first])
    return np.stack(out)


def cross_calibrate(held_out: list[HeldOut], spec, relative_threshold, levels=LEVELS,
                    source: dict | None = None, calibration: str = 'fold-robust') -> Bands:
    """
    Return the bands of all folds' out-of-fold forecasts pooled (see module doc).

    ``relative_threshold`` is the one every fold's model was served at; ``calibration``
    'fold-robust' (quantile levels chosen leave-one-fold-out) or 'pooled' (at the
    nominal levels). The note stored with the bands (``source['note']``) names the
    folds, forecasts and runs; a fold-robust band's source holds the levels taken.
    """
    _enough_folds(held_out)
    _check_calibration(calibration)
    pred, true = _pooled(held_out)
    levels = tuple(sorted(float(level) for level in levels))
    taken_at = fold_robust_levels(held_out, spec, levels) if calibration == 'fold-robust' \
        else None
    note = note_of(held_out, relative_threshold) + (
        ', quantile levels chosen leave-one-fold-out' if taken_at is not None else '')
    extra = {} if taken_at is None else {'quantile_levels': taken_at.tolist()}
    return calibrate(pred, true, spec, relative_threshold, levels, source={
        'split': 'out-of-fold', 'folds': len(held_out), 'runs': _runs(held_out),
        'calibration': calibration, **extra, 'note': note, **(source or {})},
        taken_at=taken_at)


def held_out_coverage(held_out: list[HeldOut], spec, relative_threshold,
                      levels=LEVELS, calibration: str = 'fold-robust') -> dict:
    """
    Return the leave-one-fold-out coverage of the cross-validated bands.

    For each fold, bands calibrated on the other folds' out-of-fold forecasts (the
    fold-robust levels chosen among those folds alone: 3 folds at least) are measured on
    this fold's (``bands.coverage``, at the reported steps); the fractions are pooled
    over the folds, weighted by their forecasts. Same keys as ``bands.coverage``, plus
    'per_fold' (each fold's own).
    """
    _check_calibration(calibration)
    if calibration == 'fold-robust' and len(held_out) == 2:
        raise BandsError('the coverage of fold-robust bands needs a study of at least 3 '
                         'folds (each held out, levels chosen on 2 others); calibration '
                         "'pooled' needs 2")
    _enough_folds(held_out)
    per_fold = []
    for k, fold in enumerate(held_out):
        others = held_out[:k] + held_out[k + 1:]
        bands = cross_calibrate(others, spec, relative_threshold, levels,
                                calibration=calibration) if calibration == 'fold-robust' \
            else calibrate(*_pooled(others), spec, relative_threshold, levels)
        per_fold.append({'fold': fold.fold, **coverage(bands, fold.pred, fold.true, spec)})
    weights = np.array([c['forecasts'] for c in per_fold], np.float64)
    weights /= weights.sum()

    def mean(key) -> list:
        return np.tensordot(weights, np.array([key(c) for c in per_fold]), axes=1).tolist()

    first = per_fold[0]
    return {'steps': first['steps'], 'levels': first['levels'],
            'states': {name: mean(lambda c, n=name: c['states'][n]) for name in first['states']},
            'position': mean(lambda c: c['position']),
            'forecasts': int(sum(c['forecasts'] for c in per_fold)), 'per_fold': per_fold}


def least_covered(cover: dict, level: float) -> tuple[float, str, int]:
    """
    Return where the band at ``level`` held the fewest forecasts: (fraction, name, step).

    Over the states and the position ('position') at the steps of a coverage
    (``bands.coverage``, ``held_out_coverage`` or one of its 'per_fold').
    """
    li = cover['levels'].index(level)
    series = {**cover['states'], 'position': cover['position']}
    return min((fraction[li][si], name, step) for name, fraction in series.items()
               for si, step in enumerate(cover['steps']))
