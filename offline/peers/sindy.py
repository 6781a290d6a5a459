#!/usr/bin/env python3
"""
PySINDy as a peer: discrete-time sparse identification with control inputs (SINDYc).

    .venv-bench/bin/python offline/peers/sindy.py --problem P.npz --out A.npz [--quick]

Reads a problem of ``peer_io`` (our training runs, validation and test windows), fits
``pysindy.DiscreteSINDy`` z[t+1] = Theta(z[t], c[t]) Xi on every training run (each run
a trajectory of its own, no pair across two runs) with states and controls scaled to
zero mean and unit variance on the training runs (STLSQ thresholds coefficients, which
are otherwise in each state's own units), and forecasts every window open loop from its
last state with the controls of the horizon. Tuning: the documented defaults
(PolynomialLibrary(degree=2), STLSQ(threshold=0.1, alpha=0.05)) and a small grid,
degree {1, 2} x threshold {0.1, 0.01, 0.001}; the point with the lowest validation score
(sum over states of RMSE / training std over the validation windows' horizons, open
loop) forecasts the test windows (the fit is deterministic: one seed). A forecast
that leaves |x| > 1e6 or stops being finite is reported as diverged (NaN from there on).
"""

from __future__ import annotations

import sys

import numpy as np
import peer_io

NAME = 'sindy'
DEFAULT = {'degree': 2, 'threshold': 0.1, 'alpha': 0.05}
GRID = [{'degree': d, 'threshold': t, 'alpha': 0.05} for d in (1, 2)
        for t in (0.1, 0.01, 0.001)]


class Scaled:
    """A fitted DiscreteSINDy in scaled units, forecasting in the problem's units."""

    def __init__(self, point: dict, runs: list):
        import pysindy as ps
        z_all = np.concatenate([z for z, _ in runs])
        c_all = np.concatenate([c for _, c in runs])
        self.zm, self.zs = z_all.mean(axis=0), _sd(z_all)
        self.cm, self.cs = c_all.mean(axis=0), _sd(c_all)
        self.model = ps.DiscreteSINDy(
            optimizer=ps.STLSQ(threshold=point['threshold'], alpha=point['alpha']),
            feature_library=ps.PolynomialLibrary(degree=point['degree']))
        self.model.fit([(z - self.zm) / self.zs for z, _ in runs], t=1.0,
                       u=[(c - self.cm) / self.cs for _, c in runs])

    def terms(self) -> int:
        """Return the number of nonzero coefficients."""
        return int(np.count_nonzero(self.model.coefficients()))

    def forecast(self, windows: dict) -> np.ndarray:
        """Open-loop forecasts (B, H, n) of every window, all windows a step at a time."""
        x = (np.asarray(windows['z_window'])[:, -1] - self.zm) / self.zs
        u = (np.asarray(windows['c_future']) - self.cm) / self.cs
        out = np.empty(u.shape[:2] + (x.shape[1],))
        with np.errstate(all='ignore'):
            for k in range(u.shape[1]):
                ok = np.isfinite(x).all(axis=1) & (np.abs(x) < 1e6).all(axis=1)
                nxt = np.full_like(x, np.nan)
                if ok.any():
                    nxt[ok] = self.model.predict(x[ok], u=u[ok, k])
                x = nxt
                out[:, k] = x
        return peer_io.limited(out * self.zs + self.zm)


def _sd(x: np.ndarray) -> np.ndarray:
    sd = x.std(axis=0)
    return np.where(sd > 0, sd, 1.0)


def solve(problem: peer_io.Problem, args, say) -> dict:
    """Fit, tune on validation, forecast the test windows."""
    import pysindy
    grid = [DEFAULT] if args.quick else GRID

    def fit(point):
        model = Scaled(point, problem.train)
        return model, {'terms': model.terms()}

    tuned = peer_io.tune(grid, fit, lambda model, w: model.forecast(w), problem, say)
    point, model = tuned.point, tuned.model
    pred, seconds = peer_io.timed(model.forecast, problem.test_windows)
    say(f'chosen {point}; forecast {len(pred)} test windows in {seconds:.1f} s')
    return {'pred': pred[None], 'seeds': [0], 'fit_seconds': [tuned.fit_seconds],
            'forecast_seconds': [seconds],
            'meta': {'peer': 'PySINDy DiscreteSINDy (SINDYc)', 'package': 'pysindy',
                     'version': pysindy.__version__, 'defaults': DEFAULT, 'grid': tuned.grid,
                     'chosen': point, 'terms': model.terms(), 'tuning_seconds': tuned.seconds,
                     'stochastic': False,
                     'notes': 'states and controls scaled on the training runs; '
                              'z[t+1] = Theta(z[t], c[t]) Xi, open loop'}}


if __name__ == '__main__':
    sys.exit(peer_io.run(NAME, __doc__, solve))
