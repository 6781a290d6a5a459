"""
What a peer adapter reads and writes: one forecasting problem in an .npz, its answer in another.

Pure numpy, importable in the bench-only environment (``.venv-bench``) and in the
product's alike. The product's peer study (``hybrid_models.studies.peers``) writes the
problem from our own datasets, windows and protocol; an adapter (``offline/peers/*.py``,
run with ``.venv-bench/bin/python``) fits its peer on the training runs, tunes it on the
validation windows, forecasts the test windows and writes the answer; the study scores
the answer against the truth it kept (the problem holds no test targets).

Indexing (``hybrid_models.data``): a forecast starts at t0; its window is z[t0-W:t0] and
c[t0-W:t0]; it predicts z[t0:t0+H], step k from z[t0+k-1] and the control held over that
step, c[t0+k-1], so ``c_future`` = c[t0-1:t0-1+H] and c_future[:, 0] = c_window[:, -1].
In the runs, row t's control acts over the step that ends at row t+1.

Problem keys: ``state_names``, ``control_names`` (str arrays), ``dt`` (s), ``window``,
``horizon``, ``seeds`` (int array: one forecast set per seed for a stochastic peer),
``train_count`` / ``val_count`` and ``{train,val}_{z,c}_{i}`` (whole runs, (T, n_state),
(T, n_control)), ``val_{z_window,c_window,c_future,z_target}`` (the validation
forecasts, measured targets) and ``test_{z_window,c_window,c_future}``.

Answer keys: ``pred`` (S, B, H, n_state), ``seeds`` (S,), ``fit_seconds`` (S,),
``forecast_seconds`` (S,), ``meta`` (a JSON string: the peer, its version, the grid
with each point's validation score, the point chosen, notes).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
import json
from pathlib import Path
import sys
import time

import numpy as np

WINDOW_FIELDS = ('z_window', 'c_window', 'c_future')


class PeerError(Exception):
    """A failure the adapter reports in one line."""


@dataclass
class Problem:
    """One forecasting problem as an adapter sees it."""

    state_names: list
    control_names: list
    dt: float
    window: int
    horizon: int
    seeds: list
    train: list       # [(z, c)] whole runs
    val: list
    val_windows: dict  # z_window, c_window, c_future, z_target
    test_windows: dict  # z_window, c_window, c_future

    @property
    def n_state(self) -> int:
        """Return the number of states."""
        return len(self.state_names)


def write_problem(path, *, state_names, control_names, dt, window, horizon, seeds, train,
                  val, val_windows, test_windows) -> None:
    """Write a problem (see the module docstring); runs as [(z, c)]."""
    arrays = {'state_names': np.asarray(state_names, dtype=str),
              'control_names': np.asarray(control_names, dtype=str),
              'dt': np.float64(dt), 'window': np.int64(window), 'horizon': np.int64(horizon),
              'seeds': np.asarray(seeds, dtype=np.int64),
              'train_count': np.int64(len(train)), 'val_count': np.int64(len(val))}
    for split, runs in (('train', train), ('val', val)):
        for i, (z, c) in enumerate(runs):
            arrays[f'{split}_z_{i}'] = np.asarray(z, np.float64)
            arrays[f'{split}_c_{i}'] = np.asarray(c, np.float64)
    for key in WINDOW_FIELDS + ('z_target',):
        arrays[f'val_{key}'] = np.asarray(val_windows[key], np.float64)
    for key in WINDOW_FIELDS:
        arrays[f'test_{key}'] = np.asarray(test_windows[key], np.float64)
    np.savez(path, **arrays)


def read_problem(path) -> Problem:
    """Read a problem; a file that is not one raises PeerError."""
    try:
        with np.load(path) as f:
            data = {k: f[k] for k in f.files}
    except (OSError, ValueError) as exc:
        raise PeerError(f'cannot read problem {path}: {exc}') from None
    try:
        runs = {split: [(data[f'{split}_z_{i}'], data[f'{split}_c_{i}'])
                        for i in range(int(data[f'{split}_count']))]
                for split in ('train', 'val')}
        return Problem(
            [str(s) for s in data['state_names']], [str(s) for s in data['control_names']],
            float(data['dt']), int(data['window']), int(data['horizon']),
            [int(s) for s in data['seeds']], runs['train'], runs['val'],
            {k: data[f'val_{k}'] for k in WINDOW_FIELDS + ('z_target',)},
            {k: data[f'test_{k}'] for k in WINDOW_FIELDS})
    except KeyError as exc:
        raise PeerError(f'{path} is not a peer problem (no {exc})') from None


def write_answer(path, pred, seeds, fit_seconds, forecast_seconds, meta: dict) -> None:
    """Write an adapter's answer (see the module docstring)."""
    np.savez(path, pred=np.asarray(pred, np.float64), seeds=np.asarray(seeds, np.int64),
             fit_seconds=np.asarray(fit_seconds, np.float64),
             forecast_seconds=np.asarray(forecast_seconds, np.float64),
             meta=np.asarray(json.dumps(meta)))


def read_answer(path) -> dict:
    """Read an answer: pred, seeds, fit_seconds, forecast_seconds and meta (a dict)."""
    with np.load(path) as f:
        out = {k: f[k] for k in f.files}
    out['meta'] = json.loads(str(out['meta']))
    return out


def history(windows: dict) -> tuple[np.ndarray, np.ndarray]:
    """
    Return each window's states and controls on one time axis: (B, W, n), (B, W + H - 1, m).

    Control row j acts over the step from state row j to j + 1, as in the runs: the
    window's controls, then c_future[:, 1:] (c_future[:, 0] is the window's last).
    """
    z = np.asarray(windows['z_window'], np.float64)
    c = np.concatenate([windows['c_window'], windows['c_future'][:, 1:]], axis=1)
    return z, np.asarray(c, np.float64)


def one_step_pairs(runs: list) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (z_t, c_t, z_{t+1}) of the runs, stacked (no pair crosses two runs)."""
    return (np.concatenate([z[:-1] for z, _ in runs]),
            np.concatenate([c[:-1] for _, c in runs]),
            np.concatenate([z[1:] for z, _ in runs]))


def state_scale(runs: list) -> np.ndarray:
    """Return the standard deviation of each state over the runs (1 where a state is constant)."""
    sd = np.concatenate([z for z, _ in runs]).std(axis=0)
    return np.where(sd > 0, sd, 1.0)


def validation_score(pred: np.ndarray, target: np.ndarray, scale: np.ndarray) -> float:
    """Sum over states of RMSE / scale over every step; inf when not finite (diverged)."""
    with np.errstate(invalid='ignore', over='ignore'):
        rmse = np.sqrt(((pred - target) ** 2).reshape(-1, target.shape[-1]).mean(axis=0))
        score = float((rmse / scale).sum())
    return score if np.isfinite(score) else float('inf')


def limited(pred: np.ndarray, bound: float = 1e6) -> np.ndarray:
    """Mark forecasts that left any sane range as diverged (NaN) from there on."""
    pred = np.array(pred, np.float64)
    with np.errstate(invalid='ignore'):
        bad = ~np.isfinite(pred) | (np.abs(pred) > bound)
    bad = np.maximum.accumulate(bad.any(axis=-1), axis=-1)
    pred[bad] = np.nan
    return pred


def timed(fn, *args):
    """Return ``fn(*args)`` and the seconds it took."""
    t0 = time.monotonic()
    out = fn(*args)
    return out, time.monotonic() - t0


@dataclass
class Tuned:
    """The grid point chosen by validation score, its model and how the grid went."""

    point: dict
    model: object
    fit_seconds: float       # the chosen point's fit
    grid: list[dict]         # every point with its notes, val_score and fit_seconds
    seconds: float           # the whole tuning


def tune(grid: list[dict], fit, forecast, problem: Problem, say) -> Tuned:
    """
    Fit every grid point on the training runs; keep the one of lowest validation score.

    ``fit(point)`` returns ``(model, notes)``: ``notes`` (a dict, e.g. the model's term
    count) joins the point's row of the grid and its progress line;
    ``forecast(model, windows)`` forecasts windows open loop (``validation_score``).
    """
    scale = state_scale(problem.train)
    tried, best = [], None
    started = time.monotonic()
    for point in grid:
        (model, notes), seconds = timed(fit, point)
        score = validation_score(forecast(model, problem.val_windows),
                                 problem.val_windows['z_target'], scale)
        tried.append({**point, **notes, 'val_score': score, 'fit_seconds': round(seconds, 3)})
        described = ', '.join(f'{k} {v}' for k, v in {**point, **notes}.items())
        say(f'{described}: validation score {score:.4g} ({seconds:.1f} s)')
        if best is None or score < best[0]:
            best = (score, point, model, seconds)
    _, point, model, seconds = best
    return Tuned(point, model, seconds, tried, time.monotonic() - started)


class Progress:
    """Lines on stderr, prefixed with the adapter's name and the seconds since start."""

    def __init__(self, name: str, quiet: bool = False):
        self.name, self.quiet, self.t0 = name, quiet, time.monotonic()

    def __call__(self, message: str) -> None:
        """Print one progress line."""
        if not self.quiet:
            print(f'[{self.name} {time.monotonic() - self.t0:7.1f} s] {message}',
                  file=sys.stderr, flush=True)


def parser(name: str, doc: str) -> argparse.ArgumentParser:
    """Return the parser of the arguments every adapter takes."""
    p = argparse.ArgumentParser(prog=name, description=doc,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('--problem', type=Path, required=True, help='problem .npz (peer_io)')
    p.add_argument('--out', type=Path, required=True, help='answer .npz to write')
    p.add_argument('--quick', action='store_true',
                   help='the documented defaults only, no grid (for tests)')
    p.add_argument('--quiet', action='store_true', help='no progress on stderr')
    return p


def run(name: str, doc: str, solve, argv=None, args=None) -> int:
    """
    Parse the arguments, solve(problem, args, say) -> answer dict, write it; exit code.

    Failures end with one line ``NAME: error: ...`` on stderr and exit code 1 (2 for
    bad arguments, as argparse gives).
    """
    args = args if args is not None else parser(name, doc).parse_args(argv)
    say = Progress(name, args.quiet)
    try:
        problem = read_problem(args.problem)
        answer = solve(problem, args, say)
        write_answer(args.out, **answer)
    except PeerError as exc:
        print(f'{name}: error: {exc}', file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - a peer's own failure, reported in one line
        first = str(exc).splitlines()[0] if str(exc) else ''
        print(f'{name}: error: {type(exc).__name__}: {first}', file=sys.stderr)
        return 1
    say(f'wrote {args.out}')
    return 0
