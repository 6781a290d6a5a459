#!/usr/bin/env python3
"""
SysIdentPy as a peer: a polynomial NARX per state, structure by FROLS, simulated jointly.

    .venv-bench/bin/python offline/peers/narx.py --problem P.npz --out A.npz [--quick]

Reads a problem of ``peer_io``. SysIdentPy identifies one output at a time (MISO): for
each state i, ``FROLS`` selects the polynomial regressors of y = z_i from its own lags and
the lags of the other states and of the controls (inputs x), on every training run.
SysIdentPy takes one series; laid end to end, the rows after each run boundary would
regress one run's start on another's end, so its regressor matrix is built run by run
with its own functions (``build_lagged_matrix``, ``Polynomial.fit``) and stacked, and
FROLS runs on that (a Polynomial whose ``fit`` returns the stacked matrix; everything
else is SysIdentPy's). The identified models are simulated together, open loop:
every step each state's model reads the lagged joint history (states forecast so far, the
window's measured ones before), the controls as the problem gives them. Their terms and
coefficients are SysIdentPy's own (``final_model``, ``theta``); evaluating them here, all
windows at once, is checked against SysIdentPy's ``predict`` one step ahead.

Tuning: the documented defaults (ylag = xlag = 2, Polynomial(degree=2), the
RecursiveLeastSquares estimator, order selection by AIC over n_info_values = 15 terms) and
a small grid: the LeastSquares estimator at degree {1, 2} x lags {1, 2}; the point with
the lowest validation score (sum over states of RMSE / training std over the validation
windows, open loop) forecasts the test windows.
Deterministic: one seed. A forecast that leaves |x| > 1e6 or stops being finite is
reported as diverged (NaN from there on).
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
import peer_io

NAME = 'narx'
DEFAULT = {'degree': 2, 'lag': 2, 'estimator': 'RecursiveLeastSquares', 'n_info_values': 15}
# The defaults, then least squares at degree {1, 2} x lags {1, 2} (RecursiveLeastSquares,
# a Python loop over the rows, takes minutes per fit on the larger sets: defaults only).
GRID = [DEFAULT] + [{'degree': d, 'lag': lag, 'estimator': 'LeastSquares', 'n_info_values': 15}
                    for d in (1, 2) for lag in (1, 2)]


def _estimator(name: str):
    from sysidentpy import parameter_estimation as pe
    return getattr(pe, name)()


def _runwise_polynomial(degree: int):
    """Return a SysIdentPy Polynomial whose fit gives a regressor matrix stacked run by run."""
    from sysidentpy.basis_function import Polynomial

    class RunwisePolynomial(Polynomial):
        stacked = None

        def fit(self, data, max_lag=1, ylag=1, xlag=1, model_type='NARMAX',
                predefined_regressors=None):
            if self.stacked is not None and predefined_regressors is None:
                return self.stacked
            return super().fit(data, max_lag, ylag, xlag, model_type, predefined_regressors)

    return RunwisePolynomial(degree=degree)


def _fit_runwise(model, basis, runs_x: list, runs_y: list) -> None:
    """FROLS.fit on the runs without rows that span two of them."""
    from sysidentpy.utils.information_matrix import build_lagged_matrix
    lag = model._get_max_lag()
    blocks, targets = [], []
    for x, y in zip(runs_x, runs_y, strict=True):
        if len(y) <= lag:
            continue
        lagged = build_lagged_matrix(x, y, model.xlag, model.ylag, 'NARMAX')
        blocks.append(basis.fit(lagged, lag, model.ylag, model.xlag, 'NARMAX'))
        targets.append(y[lag:])
    basis.stacked = np.concatenate(blocks)
    # FROLS regresses y[max_lag:] on the matrix: the first run's first rows lead.
    y_all = np.concatenate([runs_y[0][:lag]] + targets)
    x_all = np.concatenate([runs_x[0][:lag]] + [x[lag:] for x, y in zip(runs_x, runs_y,
                                                                         strict=True)
                                                  if len(y) > lag])
    try:
        model.fit(X=x_all, y=y_all)
    finally:
        basis.stacked = None


class JointNarx:
    """One FROLS model per state; the joint open-loop simulation of all of them."""

    def __init__(self, point: dict, runs: list):
        from sysidentpy.model_structure_selection import FROLS
        self.n, self.m, self.lag = runs[0][0].shape[1], runs[0][1].shape[1], point['lag']
        self.terms = []   # per state: [(coefficient, [(column of [z | c], lag), ...])]
        self.fitted = []
        lags = list(range(1, self.lag + 1))
        for i in range(self.n):
            cols = [j for j in range(self.n) if j != i] + [self.n + j for j in range(self.m)]
            basis = _runwise_polynomial(point['degree'])
            model = FROLS(ylag=self.lag, xlag=[lags] * len(cols), basis_function=basis,
                          estimator=_estimator(point['estimator']),
                          n_info_values=min(point['n_info_values'], 1 + len(cols) * 4),
                          info_criteria='aic', order_selection=True)
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                _fit_runwise(model, basis,
                             [np.concatenate([z, c], axis=1)[:, cols] for z, c in runs],
                             [z[:, i:i + 1] for z, _ in runs])
            self.fitted.append((model, cols))
            self.terms.append(self._decode(model, i, cols))

    @staticmethod
    def _decode(model, i: int, cols: list) -> list:
        """SysIdentPy's regressor codes as (coefficient, [(joint column, lag)])."""
        out = []
        for code_row, theta in zip(model.final_model, np.ravel(model.theta), strict=True):
            factors = []
            for code in code_row:
                code = int(code)
                if code == 0:
                    continue
                var, lag = divmod(code, 1000)
                factors.append((i if var == 1 else cols[var - 2], lag))
            out.append((float(theta), factors))
        return out

    def n_terms(self) -> int:
        """Return the number of regressors over all states."""
        return sum(len(t) for t in self.terms)

    def _step(self, joint: np.ndarray, k: int) -> np.ndarray:
        """States at index k of ``joint`` (B, T, n + m) from the rows before it: (B, n)."""
        out = np.zeros((joint.shape[0], self.n))
        for i, terms in enumerate(self.terms):
            for theta, factors in terms:
                value = np.full(joint.shape[0], theta)
                for col, lag in factors:
                    value = value * joint[:, k - lag, col]
                out[:, i] += value
        return out

    def forecast(self, windows: dict) -> np.ndarray:
        """Open-loop forecasts (B, H, n) of every window."""
        z, c = peer_io.history(windows)
        b, w, _ = z.shape
        h = windows['c_future'].shape[1]
        if w < self.lag:
            raise peer_io.PeerError(f'a window of {w} samples is shorter than lag {self.lag}')
        joint = np.full((b, w + h, self.n + self.m), np.nan)
        joint[:, :w, :self.n] = z
        joint[:, :w + h - 1, self.n:] = c
        with np.errstate(all='ignore'):
            for k in range(w, w + h):
                joint[:, k, :self.n] = self._step(joint, k)
                blown = ~np.isfinite(joint[:, k, :self.n]) | (np.abs(joint[:, k, :self.n]) > 1e6)
                joint[blown.any(axis=1), k, :self.n] = np.nan
        return peer_io.limited(joint[:, w:, :self.n])

    def check_one_step(self, runs: list) -> float:
        """Largest difference of the decoded one-step prediction from SysIdentPy's own."""
        z, c = runs[0]
        worst = 0.0
        joint = np.concatenate([z, c], axis=1)[None]
        mine = np.stack([self._step(joint, k) for k in range(self.lag, len(z))], axis=1)[0]
        for i, (model, cols) in enumerate(self.fitted):
            x = np.concatenate([z, c], axis=1)[:, cols]
            with warnings.catch_warnings():
                warnings.simplefilter('ignore')
                theirs = model.predict(X=x, y=z[:, i:i + 1], steps_ahead=1).ravel()
            worst = max(worst, float(np.max(np.abs(theirs[self.lag:] - mine[:, i]))))
        return worst


def solve(problem: peer_io.Problem, args, say) -> dict:
    """Fit, tune on validation, forecast the test windows."""
    import sysidentpy
    grid = [DEFAULT] if args.quick else GRID

    def fit(point):
        model = JointNarx(point, problem.train)
        return model, {'terms': model.n_terms()}

    tuned = peer_io.tune(grid, fit, lambda model, w: model.forecast(w), problem, say)
    point, model = tuned.point, tuned.model
    check = model.check_one_step(problem.train)
    say(f'decoded terms against SysIdentPy one step ahead: largest difference {check:.2e}')
    if not check < 1e-6 * (1.0 + float(np.abs(problem.train[0][0]).max())):
        raise peer_io.PeerError(f'decoded NARX differs from SysIdentPy by {check:.3g}')
    pred, seconds = peer_io.timed(model.forecast, problem.test_windows)
    say(f'chosen {point}; forecast {len(pred)} test windows in {seconds:.1f} s')
    return {'pred': pred[None], 'seeds': [0], 'fit_seconds': [tuned.fit_seconds],
            'forecast_seconds': [seconds],
            'meta': {'peer': 'SysIdentPy FROLS polynomial NARX, one MISO model per state',
                     'package': 'sysidentpy', 'version': sysidentpy.__version__,
                     'defaults': DEFAULT, 'grid': tuned.grid, 'chosen': point,
                     'terms': model.n_terms(), 'tuning_seconds': tuned.seconds,
                     'one_step_check': check, 'stochastic': False,
                     'model': [[(theta, factors) for theta, factors in t]
                               for t in model.terms]}}


if __name__ == '__main__':
    sys.exit(peer_io.run(NAME, __doc__, solve))
