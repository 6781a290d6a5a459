"""
Cross-validated forecast bands, for a vessel recorded in too few runs to hold some out.

Bands from a handful of validation runs are only as good as those runs stand for the
others (docs/results/real/bands.md). A cross-validated study (``studies.crossval``)
holds every recording out once: each fold's test runs forecast by that fold's models,
all served at ONE relative threshold, are out-of-fold forecasts of every recording.
Pooled over the folds they calibrate the bands (``bands.calibrate``, cross-conformal),
which then hold for a model of the same recipe trained on all runs, at that threshold.

Their honest coverage is measured leave-one-fold-out: bands calibrated on the other
folds' out-of-fold forecasts, measured on this fold's, pooled over the folds. Numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hybrid_models.bands import LEVELS, Bands, BandsError, calibrate, coverage


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


def cross_calibrate(held_out: list[HeldOut], spec, relative_threshold, levels=LEVELS,
                    source: dict | None = None) -> Bands:
    """
    Return the bands of all folds' out-of-fold forecasts pooled (see module doc).

    ``relative_threshold`` is the one every fold's model was served at; the note stored
    with the bands (``source['note']``) names the folds, forecasts and runs.
    """
    _enough_folds(held_out)
    pred, true = _pooled(held_out)
    return calibrate(pred, true, spec, relative_threshold, levels, source={
        'split': 'out-of-fold', 'folds': len(held_out),
        'runs': _runs(held_out),
        'note': note_of(held_out, relative_threshold), **(source or {})})


def held_out_coverage(held_out: list[HeldOut], spec, relative_threshold,
                      levels=LEVELS) -> dict:
    """
    Return the leave-one-fold-out coverage of the cross-validated bands.

    For each fold, bands calibrated on the other folds' out-of-fold forecasts are
    measured on this fold's (``bands.coverage``, at the reported steps); the fractions
    are pooled over the folds, weighted by their forecasts. Same keys as
    ``bands.coverage``, plus 'per_fold' (each fold's own).
    """
    _enough_folds(held_out)
    per_fold = []
    for k, fold in enumerate(held_out):
        others = held_out[:k] + held_out[k + 1:]
        bands = calibrate(*_pooled(others), spec, relative_threshold, levels)
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
