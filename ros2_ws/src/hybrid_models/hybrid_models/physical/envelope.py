"""
Does a fitted physical model stay inside the vessel's envelope? A check at fit time.

A regression physics fitted on one-step pairs can be unstable where the recordings never
went (a turn at a speed that was only run straight): its forecasts then diverge, and
neither the correction's bound (relative to the physics' own output) nor the do-no-harm
selection (against the physics alone) can hold them. So, from start rows of the
training runs, the physics is rolled out over the horizon with the row's controls held
(a held order is what a forecast without a plan assumes). A roll-out that leaves the
vessel file's state limits, or stops being finite, escapes. (Actuators held at the ends
of their ranges were tried and dropped: full astern on both shafts legitimately takes a
model boat past its plausible astern speed, so the ends flag sound physics.)
An escape is a warning for the user, not a refusal: a course-unstable hull may leave
its limits in a hard turn held long enough, and the recordings decide what is true.
Numpy only.
"""

from __future__ import annotations

import numpy as np

from vessel_description import Vessel

MAX_STARTS = 64   # training rows the roll-outs start from, evenly spread over the rows


def envelope_escapes(physical, spec: Vessel, z: np.ndarray, c: np.ndarray,
                     horizon: int, max_starts: int = MAX_STARTS) -> dict:
    """
    Roll ``physical`` (its numpy ``predict``) out from rows of (z, c); count escapes.

    z (N, n_state), c (N, n_control): training rows in the vessel's units, each row's
    controls held. Return {'checked', 'rollouts', 'escaped', 'horizon_s', 'example' (the
    earliest escape: start state, state left, value, limits, after seconds)}, or
    {'checked': False, 'reason'} when the vessel file gives no state limits.
    """
    limited = [i for i, name in enumerate(spec.state_names) if name in spec.limits]
    if not limited:
        return {'checked': False, 'reason': 'the vessel file gives no state limits'}
    if len(z) == 0:
        return {'checked': False, 'reason': 'no rows to start from'}
    pick = np.unique(np.linspace(0, len(z) - 1, min(max_starts, len(z))).round().astype(int))
    z0 = np.asarray(z, np.float64)[pick]
    controls = np.asarray(c, np.float64)[pick]
    state, escaped, example = z0.copy(), np.zeros(len(z0), bool), None
    with np.errstate(all='ignore'):
        for k in range(1, horizon + 1):
            state = physical.predict(state, controls)
            out = beyond_limits(state, spec)
            new = out & ~escaped
            if new.any() and example is None:
                example = _example(spec, z0, state, limited, int(np.flatnonzero(new)[0]), k)
            escaped |= out
            # Escaped roll-outs restart from their start so nothing overflows.
            state[out] = z0[out]
    return {'checked': True, 'rollouts': len(z0), 'escaped': int(escaped.sum()),
            'horizon_s': horizon * spec.dt, 'example': example}


def beyond_limits(states: np.ndarray, spec: Vessel) -> np.ndarray:
    """
    Tell where state vectors (..., n_state) are not finite or leave the vessel's limits.

    Returns a boolean array of the leading shape; states without limits count only when
    not finite.
    """
    states = np.asarray(states, np.float64)
    out = ~np.isfinite(states).all(axis=-1)
    with np.errstate(invalid='ignore'):
        for i, name in enumerate(spec.state_names):
            if name in spec.limits:
                lo, hi = spec.limits[name]
                out |= (states[..., i] < lo) | (states[..., i] > hi)
    return out


def _example(spec, z0, state, limited, row, step) -> dict:
    def leaves(i: int) -> bool:
        lo, hi = spec.limits[spec.state_names[i]]
        return not np.isfinite(state[row, i]) or not lo <= state[row, i] <= hi

    i = next((i for i in limited if leaves(i)), limited[0])
    name = spec.state_names[i]
    return {'after_s': round(step * spec.dt, 3),
            'start': {s: round(float(v), 4) for s, v in zip(spec.state_names, z0[row],
                                                              strict=True)},
            'state': name, 'value': float(state[row, i]), 'limits': list(spec.limits[name])}


def escape_warning(result: dict, remedy: str | None = None) -> str | None:
    """Return the one-line warning for ``envelope_escapes``' result (and ``remedy``), or None."""
    if not result.get('checked') or not result['escaped']:
        return None
    ex = result['example']
    start = ', '.join(f'{k} {v:g}' for k, v in ex['start'].items())
    return (f"physics check: the fitted physics leaves the vessel's limits in "
            f"{result['escaped']} of {result['rollouts']} roll-outs of "
            f"{result['horizon_s']:g} s with controls held (first: {ex['state']} "
            f"{ex['value']:.4g} outside {ex['limits']} after {ex['after_s']:g} s from "
            f"{start}); its forecasts, and the hybrid's, may diverge on "
            f'manoeuvres unlike the training runs' + (f'; {remedy}' if remedy else ''))
