"""
Sparse regression with block-bootstrap inclusion probabilities (an estimator, fit/predict).

``BootstrapLasso`` selects columns of a linear model y = X b by the lasso path of
scikit-learn (``lars_path_gram``, LARS on the Gram matrix) with the support chosen by BIC,
on the full data and on ``n_bootstrap`` block-bootstrap replicates: whole blocks of
consecutive rows are resampled, because residuals of a moving ship are correlated in time
and row-wise resampling would overstate the evidence. A column's inclusion probability is
the share of replicates that select it (stability selection, Meinshausen & Buehlmann
2010, with the bootstrap of Bach 2008). The kept support is the columns selected at least
``threshold`` of the time; its coefficients are refitted by least squares (relaxed lasso),
and their 95 % intervals are the 2.5 and 97.5 percentiles of the same refit on the
replicates.

Everything works on per-block sufficient statistics (X'X, X'y, y'y per block), so a
replicate costs a weighted sum of small matrices, not a pass over the rows.

BIC uses an effective sample size ``n * neff_ratio``: after a low-pass of cut-off f_c the
rows carry about 2 f_c / f_s independent values each (f_s the sample rate).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from sklearn.linear_model import lars_path_gram

RIDGE = 1e-10   # relative ridge of the least-squares refits (numerical safety only)


class BlockStats:
    """Per-block Gram matrices, cross products and sums of squares of standardized data."""

    def __init__(self, X: np.ndarray, y: np.ndarray, blocks: np.ndarray,
                 strata: np.ndarray | None = None):
        self.ids, first, inverse = np.unique(blocks, return_index=True, return_inverse=True)
        self.strata = (np.zeros(len(self.ids), dtype=np.int64) if strata is None
                       else np.asarray(strata)[first])
        k = X.shape[1]
        nb = len(self.ids)
        self.G = np.zeros((nb, k, k))
        self.Xy = np.zeros((nb, k))
        self.yy = np.zeros(nb)
        self.n = np.bincount(inverse, minlength=nb).astype(float)
        order = np.argsort(inverse, kind='stable')
        bounds = np.concatenate([[0], np.cumsum(self.n).astype(int)])
        for b in range(nb):
            rows = order[bounds[b]:bounds[b + 1]]
            xb, yb = X[rows], y[rows]
            self.G[b] = xb.T @ xb
            self.Xy[b] = xb.T @ yb
            self.yy[b] = yb @ yb

    def resample(self, rng: np.random.Generator) -> np.ndarray:
        """Return block multiplicities of one replicate, resampling within each stratum."""
        w = np.zeros(len(self.n))
        for stratum in np.unique(self.strata):
            members = np.flatnonzero(self.strata == stratum)
            np.add.at(w, rng.choice(members, len(members)), 1.0)
        return w

    def total(self, weights: np.ndarray | None = None):
        """Return (G, Xy, yy, n) summed over blocks with multiplicities ``weights``."""
        w = np.ones(len(self.n)) if weights is None else weights
        return (np.tensordot(w, self.G, 1), w @ self.Xy, float(w @ self.yy), float(w @ self.n))


def effective_sample_ratio(series: np.ndarray, max_lag: int = 300) -> float:
    """
    Return n_eff / n of a time series (n,) or of each column of (n, s), averaged.

    n_eff = n / (1 + 2 sum rho_k) with the autocorrelations rho_k summed up to the first
    that is not positive (Geyer's initial positive sequence, simplified).
    """
    x = np.asarray(series, float)
    x = x[:, None] if x.ndim == 1 else x
    ratios = []
    for col in x.T:
        col = col - col.mean()
        var = col @ col
        if var <= 0 or len(col) < 3:
            ratios.append(1.0)
            continue
        spectrum = np.fft.rfft(col, 2 * len(col))
        acov = np.fft.irfft(spectrum * np.conj(spectrum))[:min(max_lag, len(col) - 1) + 1]
        rho = acov[1:] / acov[0]
        stop = np.flatnonzero(rho <= 0)
        total = rho[:stop[0]].sum() if len(stop) else rho.sum()
        ratios.append(1.0 / (1.0 + 2.0 * total))
    return float(np.mean(ratios))


def least_squares(G: np.ndarray, Xy: np.ndarray, support: np.ndarray) -> np.ndarray:
    """Return the least-squares coefficients on ``support`` (zeros elsewhere)."""
    coef = np.zeros(len(Xy))
    idx = np.flatnonzero(support)
    if len(idx):
        g = G[np.ix_(idx, idx)]
        ridge = RIDGE * (np.trace(g) / len(idx) + 1e-300)
        coef[idx] = np.linalg.solve(g + ridge * np.eye(len(idx)), Xy[idx])
    return coef


def rss(G: np.ndarray, Xy: np.ndarray, yy: float, coef: np.ndarray) -> float:
    """Return the residual sum of squares of ``coef`` from sufficient statistics."""
    return max(yy - 2.0 * coef @ Xy + coef @ G @ coef, 0.0)


def bic_support(G: np.ndarray, Xy: np.ndarray, yy: float, n: float, neff_ratio: float,
                max_terms: int) -> np.ndarray:
    """Support (bool, K) minimizing BIC along the lasso path, at most ``max_terms`` columns."""
    k = len(Xy)
    best = np.zeros(k, dtype=bool)
    if k == 0 or yy <= 0:
        return best
    _, _, coefs = lars_path_gram(Xy, G, n_samples=int(n), method='lasso',
                                 max_iter=8 * max_terms)
    n_eff = max(n * neff_ratio, 2.0)
    best_bic = n_eff * np.log(yy / n)
    seen = set()
    for j in range(coefs.shape[1]):
        support = coefs[:, j] != 0
        df = int(support.sum())
        key = support.tobytes()
        if df == 0 or df > max_terms or key in seen:
            continue
        seen.add(key)
        value = rss(G, Xy, yy, least_squares(G, Xy, support))
        bic = n_eff * np.log(max(value, 1e-300) / n) + np.log(n_eff) * df
        if bic < best_bic:
            best_bic, best = bic, support
    return best


class BootstrapLasso:
    """
    Lasso-BIC selection with block-bootstrap inclusion probabilities; see module doc.

    After ``fit``: ``inclusion_probability_`` (K,), ``support_`` (bool, K), ``coef_`` (K,)
    in the units of the unstandardized columns, ``ci95_`` (K, 2), ``bootstrap_coef_``
    (B, K), ``feature_names_in_``.
    """

    def __init__(self, n_bootstrap: int = 200, threshold: float = 0.8, neff_ratio: float = 1.0,
                 max_terms: int = 12, random_state: int = 0):
        self.n_bootstrap = int(n_bootstrap)
        self.threshold = float(threshold)
        self.neff_ratio = float(neff_ratio)
        self.max_terms = int(max_terms)
        self.random_state = random_state

    def fit(self, X: np.ndarray, y: np.ndarray, blocks: np.ndarray,
            feature_names: Sequence[str] | None = None,
            strata: np.ndarray | None = None) -> BootstrapLasso:
        """
        Select and fit; ``blocks`` (n,) groups rows that are resampled together.

        ``strata`` (n,), optional: blocks are resampled within each stratum (e.g. a run),
        so that columns that live in one stratum (a run's current) always have data.
        """
        X = np.asarray(X, float)
        y = np.asarray(y, float)
        k = X.shape[1]
        self.feature_names_in_ = np.array(feature_names if feature_names is not None
                                          else [f'x{i}' for i in range(k)], dtype=object)
        norm = np.sqrt(np.mean(X ** 2, axis=0))
        self.scale_ = np.where(norm > 0, norm, 1.0)
        usable = norm > 0
        stats = BlockStats(X / self.scale_, y, blocks, strata)
        self.stats_ = stats
        rng = np.random.default_rng(self.random_state)
        nb = len(stats.n)
        selected = np.zeros((self.n_bootstrap, k), dtype=bool)
        self.weights_ = np.empty((self.n_bootstrap, nb))
        for b in range(self.n_bootstrap):
            w = stats.resample(rng)
            self.weights_[b] = w
            G, Xy, yy, n = stats.total(w)
            selected[b] = bic_support(G, Xy, yy, n, self.neff_ratio, self.max_terms) & usable
        self.selected_ = selected
        self.inclusion_probability_ = selected.mean(axis=0) if self.n_bootstrap else np.zeros(k)
        G, Xy, yy, n = stats.total()
        self.full_support_ = bic_support(G, Xy, yy, n, self.neff_ratio, self.max_terms) & usable
        self.set_support(self.inclusion_probability_ >= self.threshold)
        return self

    def set_support(self, support: np.ndarray) -> BootstrapLasso:
        """Refit coefficients and bootstrap intervals on a given support (bool, K)."""
        self.support_ = np.asarray(support, bool)
        G, Xy, _, _ = self.stats_.total()
        self.coef_ = least_squares(G, Xy, self.support_) / self.scale_
        boot = np.array([least_squares(*self.stats_.total(w)[:2], self.support_)
                         for w in self.weights_]) / self.scale_ if len(self.weights_) else (
            np.zeros((0, len(Xy))))
        self.bootstrap_coef_ = boot
        if len(boot):
            self.ci95_ = np.stack([np.percentile(boot, 2.5, axis=0),
                                   np.percentile(boot, 97.5, axis=0)], axis=1)
        else:
            self.ci95_ = np.stack([self.coef_, self.coef_], axis=1)
        return self

    def predict(self, X: np.ndarray) -> np.ndarray:
        """Return X @ coef_."""
        return np.asarray(X, float) @ self.coef_

