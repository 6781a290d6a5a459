"""
Calibrated forecast bands: how far a served hybrid's forecasts are off, per state and step.

A band at level L (e.g. 0.9) of state i at forecast step k is the interval
[forecast + lo, forecast + hi] where lo and hi are the (1 - L) / 2 and (1 + L) / 2
empirical quantiles of the error e = measured - forecast over a set of calibration
forecasts: the validation runs' forecasts of the SERVED model (after the do-no-harm
selection), against the measured states, with the true future controls. The position
band at level L is the L-quantile of the trajectory error (``metrics.trajectory_errors``:
the distance between the dead-reckoned tracks of forecast and measured states, the
model cards' trajectory error): a circle of that radius (m) around the forecast track.

Bands are computed at knot steps (``knot_steps``: every sixteenth of the horizon and a
geometric series below the first) and interpolated linearly between them, so a
checkpoint holds a few hundred numbers; the reported steps (``metrics.reported_steps``,
every quarter of the horizon) are knots. No edge narrows along the horizon (a forecast
further ahead is never claimed to be more certain): the quantiles along the knots are
replaced by the closest non-narrowing sequence (``widening``, isotonic regression).
Beyond the calibrated horizon there is no band (NaN).

The bands hold for forecasts made as the calibration forecasts were: at the relative
threshold they were computed for (``relative_threshold``; the engine serves them only
at that threshold), with the future controls known. A forecast that assumed controls
the vessel did not apply is outside their promise. Numpy only: the predictor serves
them without torch.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import isotonic_regression

from hybrid_models.bound import schedule_of
from hybrid_models.metrics import reported_steps, trajectory_errors

LEVELS = (0.5, 0.9)
KNOTS_PER_HORIZON = 16    # knots at every sixteenth of the horizon ...
EARLY_KNOTS = 6           # ... and a geometric series from step 1 to the first of them
DEFINITION = ('lo, hi: (1 - L)/2 and (1 + L)/2 quantiles of measured - forecast per state '
              'and step over the calibration forecasts; position: L-quantile of the '
              'trajectory error (m); edges never narrow along the horizon')


class BandsError(ValueError):
    """Bands cannot be computed or served; the message says why."""


def knot_steps(horizon: int) -> np.ndarray:
    """Return the steps (1 = the first forecast step) bands are stored at, ascending."""
    if horizon < 1:
        raise BandsError(f'a horizon of at least 1 step is needed, got {horizon}')
    regular = np.round(np.arange(1, KNOTS_PER_HORIZON + 1) * horizon / KNOTS_PER_HORIZON)
    first = max(float(regular[0]), 1.0)
    early = np.round(np.geomspace(1.0, first, EARLY_KNOTS))
    steps = {int(s) for s in (*regular, *early) if s >= 1}
    steps.update(reported_steps(horizon))
    return np.array(sorted(steps), dtype=np.int64)


@dataclass(frozen=True)
class Bands:
    """
    Bands of one served model at knot steps; ``at`` interpolates every step.

    ``lower`` and ``upper`` (levels, knots, states) are offsets from the forecast in the
    states' units (body FRD, as the model forecasts), ``position`` (levels, knots) radii
    in m.
    """

    levels: tuple[float, ...]
    steps: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    position: np.ndarray
    state_names: tuple[str, ...]
    relative_threshold: object = None    # the served threshold (number, None, schedule)
    source: dict = field(default_factory=dict)
    # ``at`` by horizon: a served model asks for the same horizon at every forecast
    # (interpolated anew, 0.2 ms of a 100 Hz vehicle's state).
    _at: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @property
    def horizon(self) -> int:
        """Return the last calibrated step."""
        return int(self.steps[-1])

    def at(self, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """
        Return (lower, upper, position) at steps 1..horizon, interpolated between knots.

        Shapes (levels, horizon, states), (levels, horizon, states), (levels, horizon);
        NaN beyond the calibrated horizon; read-only (shared by every call).
        """
        if horizon not in self._at:
            self._at[horizon] = self._interpolated(horizon)
        return self._at[horizon]

    def _interpolated(self, horizon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        grid = np.arange(1, horizon + 1, dtype=np.float64)
        inside = grid <= self.horizon

        def along(values: np.ndarray) -> np.ndarray:
            out = np.full(grid.shape, np.nan)
            out[inside] = np.interp(grid[inside], self.steps, values)
            return out

        n_levels, _, n_state = self.lower.shape
        lower = np.empty((n_levels, horizon, n_state))
        upper = np.empty_like(lower)
        for li in range(n_levels):
            for i in range(n_state):
                lower[li, :, i] = along(self.lower[li, :, i])
                upper[li, :, i] = along(self.upper[li, :, i])
        position = np.stack([along(self.position[li]) for li in range(n_levels)])
        for a in (lower, upper, position):
            a.flags.writeable = False
        return lower, upper, position

    @property
    def origin(self) -> str:
        """Return what the bands were calibrated on, as one phrase."""
        if self.source.get('note'):
            return str(self.source['note'])
        return (f"{self.source.get('forecasts')} forecasts of {self.source.get('runs')} "
                f"validation runs (one every {self.source.get('stride')} samples)")

    def serves(self, relative_threshold) -> bool:
        """Tell whether these bands hold for forecasts served at ``relative_threshold``."""
        return _same_threshold(self.relative_threshold, relative_threshold)

    def to_dict(self) -> dict:
        """Return the checkpoint config entry (plain JSON types)."""
        return {
            'definition': DEFINITION,
            'levels': list(self.levels),
            'steps': self.steps.tolist(),
            'state_names': list(self.state_names),
            'lower': self.lower.tolist(),
            'upper': self.upper.tolist(),
            'position_m': self.position.tolist(),
            'relative_threshold': self.relative_threshold,
            'source': self.source,
        }

    @classmethod
    def from_dict(cls, data: dict, state_names) -> Bands:
        """Read a checkpoint's ``bands`` entry; refuse one of other states or shapes."""
        try:
            bands = cls(tuple(float(x) for x in data['levels']),
                        np.asarray(data['steps'], dtype=np.int64),
                        np.asarray(data['lower'], dtype=np.float64),
                        np.asarray(data['upper'], dtype=np.float64),
                        np.asarray(data['position_m'], dtype=np.float64),
                        tuple(data['state_names']), data.get('relative_threshold'),
                        dict(data.get('source') or {}))
        except (KeyError, TypeError, ValueError) as exc:
            raise BandsError(f'damaged bands in the checkpoint ({type(exc).__name__}: '
                             f'{exc})') from None
        shape = (len(bands.levels), len(bands.steps), len(state_names))
        if bands.state_names != tuple(state_names) or bands.lower.shape != shape or \
                bands.upper.shape != shape or bands.position.shape != shape[:2]:
            raise BandsError(f'bands of states {list(bands.state_names)} with shape '
                             f"{bands.lower.shape} do not fit the model's states "
                             f'{list(state_names)} (levels, knots, states = {shape})')
        return bands


def _same_threshold(a, b) -> bool:
    try:
        return schedule_of(a) == schedule_of(b)
    except (TypeError, ValueError):
        return False


def calibrate(pred: np.ndarray, true: np.ndarray, spec, relative_threshold,
              levels=LEVELS, source: dict | None = None,
              taken_at: np.ndarray | None = None) -> Bands:
    """
    Return the bands of forecasts ``pred`` against ``true`` (B, H, n_state), see module doc.

    ``relative_threshold`` is the threshold the forecasts were served at. ``taken_at``
    (levels, knots, n_state + 1; last column the position): the quantile level each
    band's edges are taken at, per knot and state, where it differs from the band's
    nominal level (``cross_bands.fold_robust_levels``); default the nominal level.
    Refuse fewer forecasts than a level needs to have an error outside its band at both
    ends (2 / (1 - L)), and non-finite forecasts.
    """
    pred = np.asarray(pred, np.float64)
    true = np.asarray(true, np.float64)
    levels = tuple(sorted(float(level) for level in levels))
    if not levels or not all(0.0 < level < 1.0 for level in levels):
        raise BandsError(f'band levels must lie in (0, 1), got {list(levels)}')
    need = int(np.ceil(2.0 / (1.0 - levels[-1])))
    if len(pred) < need:
        raise BandsError(f'{len(pred)} calibration forecasts are too few for a '
                         f'{levels[-1]:g} band (at least {need}); use a shorter stride or '
                         f'more validation runs')
    if not np.isfinite(pred).all():
        raise BandsError('the calibration forecasts are not finite (a diverged model)')
    steps = knot_steps(pred.shape[1])
    at = steps - 1
    error = (true - pred)[:, at]                                   # (B, K, n)
    distance = trajectory_errors(pred, true, spec)[:, at]          # (B, K)
    if taken_at is None:
        taken_at = np.broadcast_to(np.asarray(levels)[:, None, None],
                                   (len(levels), len(steps), error.shape[-1] + 1))
    elif np.shape(taken_at) != (len(levels), len(steps), error.shape[-1] + 1):
        raise BandsError(f'quantile levels of shape {np.shape(taken_at)} do not fit '
                         f'{len(levels)} levels, {len(steps)} knots and '
                         f'{error.shape[-1]} states plus the position')
    ordered, ordered_distance = np.sort(error, axis=0), np.sort(distance, axis=0)
    lower, upper, position = [], [], []
    for at_level in np.asarray(taken_at, np.float64):
        states, radius = at_level[:, :-1], at_level[:, -1]
        lower.append(-widening(-quantile_each(ordered, (1 - states) / 2)))
        upper.append(widening(quantile_each(ordered, (1 + states) / 2)))
        position.append(widening(quantile_each(ordered_distance, radius)))
    return Bands(levels, steps, np.stack(lower), np.stack(upper), np.stack(position),
                 tuple(spec.state_names), relative_threshold,
                 {'forecasts': int(len(pred)), **(source or {})})


def quantile_each(ordered: np.ndarray, q: np.ndarray) -> np.ndarray:
    """
    Return the quantile of each column of ``ordered`` (B, ...) at its own level ``q`` (...).

    ``ordered`` is sorted along axis 0; numpy's default (linear) quantile, column by column.
    """
    place = np.asarray(q, np.float64) * (len(ordered) - 1)
    below = np.floor(place).astype(np.int64)
    above = np.minimum(below + 1, len(ordered) - 1)
    low = np.take_along_axis(ordered, below[None], axis=0)[0]
    high = np.take_along_axis(ordered, above[None], axis=0)[0]
    return low + (place - below) * (high - low)


def widening(values: np.ndarray) -> np.ndarray:
    """
    Return the non-decreasing sequence (along axis 0) closest to ``values`` in least squares.

    Isotonic regression (pool adjacent violators, per column): where the error's
    quantile stays level along the horizon, its estimates are pooled instead of being
    ratcheted up by their noise, which a running maximum would do (measured on the
    default model: 95 % coverage of the 90 % band where the estimates are 89 %).
    """
    values = np.asarray(values, np.float64)
    flat = values.reshape(len(values), -1)
    out = np.column_stack([isotonic_regression(flat[:, j]).x for j in range(flat.shape[1])])
    return out.reshape(values.shape)


def coverage(bands: Bands, pred: np.ndarray, true: np.ndarray, spec,
             steps=None) -> dict:
    """
    Return the fraction of forecasts inside each band at ``steps`` (default reported).

    {'steps': [...], 'levels': [...], 'states': {name: [[per step] per level]},
    'position': [[per step] per level], 'forecasts': B}.
    """
    pred = np.asarray(pred, np.float64)
    true = np.asarray(true, np.float64)
    horizon = pred.shape[1]
    steps = list(steps or reported_steps(horizon))
    lower, upper, position = bands.at(horizon)
    at = np.asarray(steps) - 1
    error = (true - pred)[:, at]                                   # (B, S, n)
    distance = trajectory_errors(pred, true, spec)[:, at]          # (B, S)
    states = {name: [] for name in spec.state_names}
    inside_position = []
    for li in range(len(bands.levels)):
        inside = (error >= lower[li, at]) & (error <= upper[li, at])
        for i, name in enumerate(spec.state_names):
            states[name].append(inside[:, :, i].mean(axis=0).tolist())
        inside_position.append((distance <= position[li, at]).mean(axis=0).tolist())
    return {'steps': steps, 'levels': list(bands.levels), 'states': states,
            'position': inside_position, 'forecasts': int(len(pred))}


def coverage_table(bands: Bands, cover: dict, spec) -> list[str]:
    """
    Return the Markdown table of the bands at ``cover``'s steps and their coverage there.

    One row per level and reported step: the width of each state's band (upper - lower)
    and the position band's radius (m), each with the fraction of forecasts it held in
    brackets (``coverage`` or ``cross_bands.held_out_coverage``).
    """
    steps = cover['steps']
    lower, upper, position = bands.at(max(steps))
    lines = ['| level | after [s] | position [m] | '
             + ' | '.join(f'{s} [{u}]' for s, u in zip(spec.state_names, spec.state_units,
                                                     strict=True)) + ' |',
             '|' + '---|' * (3 + spec.n_state)]
    for li, level in enumerate(bands.levels):
        for si, step in enumerate(steps):
            cells = [f'{level:g}', f'{step * spec.dt:g}',
                     f"{position[li, step - 1]:.4g} ({cover['position'][li][si]:.2f})"]
            cells += [f"{upper[li, step - 1, i] - lower[li, step - 1, i]:.4g} "
                      f"({cover['states'][name][li][si]:.2f})"
                      for i, name in enumerate(spec.state_names)]
            lines.append('| ' + ' | '.join(cells) + ' |')
    return lines
