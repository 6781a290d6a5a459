"""
Name the missing physics: select candidates, refit them, keep those that predict better.

Rounds. Each round builds the design (``design.build_design``) at the physics found so
far, selects candidates by lasso-BIC with block-bootstrap inclusion probabilities
(``selection.BootstrapLasso``; bootstrap blocks stay within their run) and adds those
included at least ``inclusion_threshold`` of the time. The coefficients of all terms
found are then refitted by Gauss-Newton on the free-run residuals (the effects are
nonlinear in a current of 1 m/s or a missing wind load), and the next round looks again
at what is left. It stops when a round adds nothing.

Pruning. A term stays only if leaving it out makes held-out predictions worse by at least
``min_improvement`` for some state: bootstrap blocks alternate between folds, the
coefficients are refitted on one fold and predict the other; the weakest term goes first,
the rest are refitted, and again until every term earns its place. Then plausibility:
a parameter correction that flips its sign, exceeds ``max_parameter_change`` times its
nominal size or needs a value outside its valid range goes, one at a time when several
do (the furthest out first; the rest are refitted). Of two candidates
that explain the same thing only one survives this, and the other is reported as an
alias: a candidate outside the model that explains at least ``alias_share`` of what a
kept term explains cannot be told apart from it by these recordings. A term the
selection took in but pruning left out is still reported, with its size and interval
(``Identification.kept_out``): identified with certainty, it is found, only too small to
change forecasts.

Intervals. The block bootstrap of the linearized refit measures how far the estimate
moves with the data's noise. Where the model is misspecified that is not all: the
correction each run asks for differs between runs (a coefficient standing in for
something else takes the value the run's manoeuvres need), beyond what their noise
explains. That between-run spread is estimated as the heterogeneity tau^2 of a
random-effects model (DerSimonian & Laird 1986) from per-run estimates of each
coefficient (the others held at the fitted values; per bootstrap block when there are
fewer than ``MIN_GROUPS`` runs), and the reported 95 % interval is the wider of the
bootstrap's and estimate +- 1.96 sqrt(se^2 + tau^2): the value another run of the same
vessel would ask for. ``ci95_noise`` keeps the bootstrap interval alone, and ``i2`` the
share of the per-run spread that noise does not explain (0: consistent; near 1: the runs
disagree, a sign of misspecification).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from vessel_diagnosis.design import (
    Column,
    Design,
    Segments,
    build_design,
    candidate_columns,
)
from vessel_diagnosis.library import Library
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.selection import (
    BlockStats,
    BootstrapLasso,
    effective_sample_ratio,
    least_squares,
    rss,
)
from vessel_physics.errors import ConfigError
from vessel_physics.family import Physics

CURRENT = 'current'
MAX_HALVINGS = 3   # step halvings of a Gauss-Newton update that made the fit worse
MIN_GROUPS = 3     # runs needed to estimate the between-run spread (else: blocks)
Z95 = 1.959964     # two-sided 95 % quantile of the normal distribution


@dataclass
class Point:
    """Coefficients found so far: global candidate -> value, run id -> current (N, E)."""

    theta: dict[str, float] = field(default_factory=dict)
    currents: dict[str, np.ndarray] = field(default_factory=dict)

    def physics(self, nominal: Physics, library: Library) -> Physics:
        """Return the nominal physics with the global coefficients applied."""
        return library.apply(nominal, self.theta) if self.theta else nominal

    def moved(self, columns: Sequence[Column], delta: np.ndarray, fraction: float = 1.0
              ) -> Point:
        """Return a point moved by ``fraction * delta`` along ``columns``."""
        theta = dict(self.theta)
        currents = {k: v.copy() for k, v in self.currents.items()}
        for col, d in zip(columns, delta, strict=True):
            if col.per_run:
                vec = currents.setdefault(col.run, np.zeros(2))
                vec[0 if col.component == 'north' else 1] += fraction * d
            else:
                theta[col.candidate] = theta.get(col.candidate, 0.0) + fraction * d
        return Point(theta, currents)

    def without(self, candidate: str) -> Point:
        """Return the point with one candidate (or the current) removed."""
        if candidate == CURRENT:
            return Point(dict(self.theta), {})
        return Point({k: v for k, v in self.theta.items() if k != candidate},
                     {k: v.copy() for k, v in self.currents.items()})

    def values(self, columns: Sequence[Column]) -> np.ndarray:
        """Return the current coefficient of every column."""
        out = []
        for col in columns:
            if col.per_run:
                vec = self.currents.get(col.run, np.zeros(2))
                out.append(vec[0 if col.component == 'north' else 1])
            else:
                out.append(self.theta.get(col.candidate, 0.0))
        return np.array(out)


@dataclass
class Selected:
    """A candidate the selection took in, with how often and in which round."""

    candidate: str
    inclusion_probability: float
    round: int
    per_run_probability: dict[str, float] = field(default_factory=dict)


@dataclass
class Alias:
    """A candidate outside the model that explains much of what a kept term explains."""

    candidate: str
    category: str
    share: float          # its explained sum of squares / the kept term's
    correlation: float    # of the two weighted columns


@dataclass
class Identification:
    """What the identification found (before turning it into findings)."""

    point: Point
    physics: Physics
    selected: dict[str, Selected]
    kept: list[str]
    improvement: dict[str, dict[str, float]]   # candidate -> state -> held-out RMSE gain
    ci95: dict[str, tuple[float, float]]
    current_ci95: dict[str, np.ndarray]         # run -> (2, 2) [[n_lo, n_hi], [e_lo, e_hi]]
    current_speed_ci95: tuple[float, float] | None
    aliases: dict[str, list[Alias]]
    pruned: dict[str, str]                      # candidate -> why it was dropped
    identifiability: dict[str, dict]            # candidate -> marginal/joint SE vs scale
    rounds: list[dict]
    ci95_noise: dict[str, tuple[float, float]] = field(default_factory=dict)
    heterogeneity: dict[str, dict] = field(default_factory=dict)   # candidate -> tau, i2
    kept_out: dict[str, dict] = field(default_factory=dict)  # selected, then pruned


def random_effects(estimates: np.ndarray, variances: np.ndarray) -> tuple[float, float]:
    """
    Return (tau^2, I^2) of per-group estimates with their variances (DerSimonian-Laird).

    tau^2 is the variance of the groups' true values around their mean beyond what the
    variances explain; I^2 = (Q - (G - 1)) / Q the share of the spread it makes.
    """
    ok = np.isfinite(estimates) & np.isfinite(variances) & (variances > 0)
    d, v = estimates[ok], variances[ok]
    if len(d) < 2:
        return 0.0, 0.0
    w = 1.0 / v
    mean = np.sum(w * d) / np.sum(w)
    q = float(np.sum(w * (d - mean) ** 2))
    c = float(np.sum(w) - np.sum(w * w) / np.sum(w))
    tau2 = max(0.0, (q - (len(d) - 1)) / c) if c > 0 else 0.0
    i2 = max(0.0, (q - (len(d) - 1)) / q) if q > 0 else 0.0
    return tau2, i2


def _strata(design: Design, segments: Segments) -> np.ndarray:
    return np.repeat(segments.run_index, design.y.shape[1] * design.y.shape[2])


def _candidate_probability(columns: Sequence[Column], pi: np.ndarray, selected: np.ndarray
                           ) -> tuple[dict[str, float], dict[str, float]]:
    """Inclusion probability per candidate; a current's is the mean over runs of P(N or E)."""
    out: dict[str, float] = {}
    per_run: dict[str, float] = {}
    runs: dict[str, list[int]] = {}
    for k, col in enumerate(columns):
        if col.per_run:
            runs.setdefault(col.run, []).append(k)
        else:
            out[col.candidate] = float(pi[k])
    for run, idx in runs.items():
        per_run[run] = float(selected[:, idx].any(axis=1).mean()) if len(selected) else 0.0
    if runs:
        out[CURRENT] = float(np.mean(list(per_run.values())))
    return out, per_run


def rms_speed_interval(boot: np.ndarray, estimate: np.ndarray) -> tuple[float, float]:
    """
    Return the 95 % interval of the RMS current speed over the runs (m/s).

    ``boot`` (B, 2 R) holds bootstrap (north, east) components of the R runs, ``estimate``
    (2 R,) the estimated ones. The bootstrap noise adds to every squared speed, so the
    replicates' squared RMS speeds lie above the estimate's by the noise variance; that
    bias (their mean minus the estimate's) is removed before taking percentiles, or a
    current small against its uncertainty would get an interval above its estimate.
    """
    squares = np.mean(boot ** 2, axis=1) * 2.0
    estimate_square = float(np.mean(np.square(estimate)) * 2.0)
    centred = squares - (squares.mean() - estimate_square)
    low, high = np.percentile(centred, [2.5, 97.5])
    return float(np.sqrt(max(low, 0.0))), float(np.sqrt(max(high, 0.0)))


class Identifier:
    """Runs the rounds, refits and pruning of the module docstring on one set of runs."""

    def __init__(self, nominal: Physics, library: Library, settings,
                 progress: Callable[[str], None] | None = None):
        self.nominal = nominal
        self.library = library
        self.settings = settings
        self.say = progress or (lambda message: None)
        self.pruned_gain: dict[str, float] = {}
        # Coefficients the last refit held because the fit would take their parameter out
        # of its valid range (a drag coefficient below zero): name -> why.
        self.out_of_range: dict[str, str] = {}

    # ------------------------------------------------------------------ helpers
    def _columns(self, runs: Sequence[str], names: Sequence[str] | None = None):
        return candidate_columns(runs, self.library, names)

    def _design(self, segments: Segments, point: Point, columns) -> Design:
        return build_design(segments, point.physics(self.nominal, self.library), self.library,
                            point.currents, columns, self.settings)

    def _neff_ratio(self, design: Design) -> float:
        X, y, _ = design.stacked()
        norm = np.sqrt(np.mean(X ** 2, axis=0))
        keep = norm > 0
        if keep.any():
            coef = np.linalg.lstsq(X[:, keep] / norm[keep], y, rcond=None)[0]
            y = y - (X[:, keep] / norm[keep]) @ coef
        series = y.reshape(design.y.shape).reshape(-1, design.y.shape[-1])
        return effective_sample_ratio(series)

    # ------------------------------------------------------------------ steps
    def select(self, segments: Segments, point: Point, round_index: int):
        """Run one selection round over the whole library at ``point``."""
        cfg = self.settings.selection
        columns = self._columns(segments.run_ids)
        design = self._design(segments, point, columns)
        X, y, blocks = design.stacked()
        n_per_run = 2 * len(segments.run_ids) if self.library.has_current else 0
        model = BootstrapLasso(cfg.bootstrap, cfg.inclusion_threshold, self._neff_ratio(design),
                               cfg.max_terms + n_per_run, cfg.seed + round_index)
        model.fit(X, y, blocks, design.names, _strata(design, segments))
        probability, per_run = _candidate_probability(columns, model.inclusion_probability_,
                                                      model.selected_)
        return design, model, probability, per_run

    def refit(self, segments: Segments, point: Point, names: Sequence[str],
              iterations: int | None = None) -> tuple[Point, Design]:
        """
        Refit the coefficients of ``names`` (and per-run currents) by Gauss-Newton.

        At most ``iterations`` steps (default: the settings' per-round number). Returns
        the new point and the design of ``names`` at it.
        """
        columns = self._columns(segments.run_ids, names)
        design = self._design(segments, point, columns)
        if iterations is None:
            iterations = self.settings.selection.gauss_newton_iterations
        self.out_of_range = {}
        for _ in range(iterations):
            X, y, _ = design.stacked()
            before = float(y @ y)
            norm = np.sqrt(np.mean(X ** 2, axis=0))
            norm = np.where(norm > 0, norm, 1.0)
            G = (X / norm).T @ (X / norm)
            free = np.ones(len(columns), bool)
            delta = least_squares(G, (X / norm).T @ y, free) / norm
            accepted = self._step(segments, point, columns, delta, design.sigma, before)
            if accepted is None:
                # No halving was accepted. Coefficients whose own move leaves their
                # parameter's valid range even at the smallest halving (a drag coefficient
                # at zero the data would take below it) block every trial: hold them and
                # solve for the others.
                blocked = self._leaving_range(point, columns, delta * 0.5 ** MAX_HALVINGS)
                if blocked:
                    self.out_of_range.update(blocked)
                    free &= np.array([c.candidate not in blocked for c in columns])
                    delta = least_squares(G, (X / norm).T @ y, free) / norm
                    accepted = self._step(segments, point, columns, delta, design.sigma,
                                          before)
            if accepted is None:     # no step along delta improves the fit: converged
                break
            point, design = accepted
            if np.max(np.abs(delta) / np.maximum(design.scales, 1e-300)) < 1e-3:
                break
        return point, design

    def _step(self, segments: Segments, point: Point, columns, delta: np.ndarray,
              sigma: np.ndarray, before: float) -> tuple[Point, Design] | None:
        """Return the first of ``delta``'s halvings that fits no worse, with its design."""
        for halving in range(MAX_HALVINGS + 1):
            trial = point.moved(columns, delta, 0.5 ** halving)
            try:
                with np.errstate(over='ignore', invalid='ignore', divide='ignore'):
                    trial_design = self._design(segments, trial, columns)
            except ConfigError:      # a step out of a parameter's valid range
                continue
            # The weights (1/sigma) change with the point; compare at the old weights.
            scaled = (trial_design.y / sigma).reshape(-1)
            score = float(scaled @ scaled)
            if np.isfinite(score) and np.isfinite(trial_design.X).all() and score <= before:
                return trial, trial_design
        return None

    def _leaving_range(self, point: Point, columns, delta: np.ndarray) -> dict[str, str]:
        """Return the coefficients whose move by ``delta`` alone is out of range, and why."""
        out = {}
        for col, d in zip(columns, delta, strict=True):
            if col.per_run or self.library.by_name[col.candidate].kind != 'parameter':
                continue
            moved = {**point.theta, col.candidate: point.theta.get(col.candidate, 0.0) + d}
            try:
                self.library.apply(self.nominal, moved)
            except ConfigError as exc:
                out[col.candidate] = ' '.join(str(exc).split())
        return out

    @staticmethod
    def _folds(design: Design, segments: Segments, folds: int) -> np.ndarray:
        """Fold of every segment: the blocks of each run alternate between folds."""
        first: dict[int, int] = {}
        for b, r in zip(design.blocks, segments.run_index, strict=True):
            first.setdefault(int(r), int(b))
        return np.array([(b - first[int(r)]) % folds for b, r in
                         zip(design.blocks, segments.run_index, strict=True)])

    def held_out_gain(self, design: Design, segments: Segments, point: Point,
                      names: Sequence[str], dropped: Sequence[str] = ()
                      ) -> dict[str, dict[str, float]]:
        """
        Return each term's held-out RMSE gain per state: how much worse predictions get without it.

        ``design`` has the columns of ``names`` and ``dropped`` at ``point``; terms in
        ``dropped`` are taken out (their effect removed, linearized) before anything else.
        Cross-fitting over alternating blocks of each run.
        """
        columns = design.columns
        folds = self.settings.validation.folds
        fold = self._folds(design, segments, folds)
        w = 1.0 / design.sigma
        theta = point.values(columns)
        groups = {n: [k for k, c in enumerate(columns) if c.candidate == n]
                  for n in list(names) + list(dropped)}
        base_y = design.y.copy()
        base_keep = np.ones(len(columns), bool)
        for name in dropped:
            idx = groups[name]
            base_y += np.tensordot(design.X[..., idx], theta[idx], axes=([-1], [0]))
            base_keep[idx] = False

        def fitted_residual(drop: str | None) -> np.ndarray:
            y = base_y.copy()
            keep = base_keep.copy()
            if drop is not None:
                idx = groups[drop]
                y += np.tensordot(design.X[..., idx], theta[idx], axes=([-1], [0]))
                keep[idx] = False
            out = np.empty_like(y)
            for f in range(folds):
                train, test = fold != f, fold == f
                Xw = (design.X[train] * w[None, None, :, None]).reshape(-1, len(columns))
                yw = (y[train] * w[None, None, :]).reshape(-1)
                norm = np.sqrt(np.mean(Xw ** 2, axis=0))
                norm = np.where(norm > 0, norm, 1.0)
                coef = least_squares((Xw / norm).T @ (Xw / norm), (Xw / norm).T @ yw, keep)
                out[test] = y[test] - np.tensordot(design.X[test], coef / norm,
                                                   axes=([-1], [0]))
            return out

        full = np.sqrt(np.mean(fitted_residual(None) ** 2, axis=(0, 1)))
        gains = {}
        for name in names:
            without = np.sqrt(np.mean(fitted_residual(name) ** 2, axis=(0, 1)))
            gains[name] = {s: float((without[i] - full[i]) / without[i]) if without[i] > 0
                           else 0.0 for i, s in enumerate(segments.states)}
        return gains

    def prune(self, design: Design, segments: Segments, point: Point, names: Sequence[str]):
        """Backward elimination on the linearized model; returns kept, gains, pruned."""
        kept, dropped = list(names), []
        pruned: dict[str, str] = {}
        min_gain = self.settings.validation.min_improvement
        gains: dict[str, dict[str, float]] = {}
        while kept:
            gains = self.held_out_gain(design, segments, point, kept, dropped)
            best = {n: max(g.values()) for n, g in gains.items()}
            weakest = min(best, key=best.get)
            if best[weakest] >= min_gain:
                break
            pruned[weakest] = (f'leaving it out changes held-out predictions by '
                               f'{100 * best[weakest]:.1f} % at most (< '
                               f'{100 * min_gain:.0f} %)')
            self.pruned_gain[weakest] = best[weakest]
            self.say(f'  pruned {weakest}: {pruned[weakest]}')
            kept.remove(weakest)
            dropped.append(weakest)
        return kept, (gains if kept else {}), pruned

    def implausible(self, point: Point, names: Sequence[str]) -> dict[str, str]:
        """
        Parameter corrections that flip a parameter's sign or exceed the allowed change.

        Also those the last refit had to hold at the edge of their valid range: the data
        ask for a value the parameter cannot take (a negative drag coefficient).
        """
        limit = self.settings.validation.max_parameter_change
        out = {}
        for name in names:
            cand = self.library.by_name[name]
            if cand.kind != 'parameter':
                continue
            if name in self.out_of_range:
                out[name] = (f'implausible: the fit would take {cand.target} out of its '
                             f'valid range ({self.out_of_range[name]})')
                continue
            nominal = self.nominal.parameter(cand.target)
            change = point.theta.get(name, 0.0)
            if nominal != 0 and self._excess(point, name) > limit:
                out[name] = (f'implausible: {cand.target} would go from {nominal:.4g} to '
                             f'{nominal + change:.4g} (a sign change or more than '
                             f'{limit:g} times its nominal size away)')
        return out

    def _excess(self, point: Point, name: str) -> float:
        """Return how far a parameter's correction lies out (inf: its range or sign left)."""
        nominal = self.nominal.parameter(self.library.by_name[name].target)
        change = point.theta.get(name, 0.0)
        if name in self.out_of_range or nominal == 0 or np.sign(nominal + change) != np.sign(
                nominal):
            return float('inf')
        return abs(change / nominal)

    def intervals(self, design: Design, segments: Segments, point: Point):
        """
        Block-bootstrap coefficients (B, K) of the design's columns around ``point``.

        A replicate refits the model linearized at ``point`` on resampled blocks; how far
        that refit lands from the same refit on all the data is how far the estimate moves
        with the data. Adding the replicate's refit itself to ``point`` would centre the
        interval one Gauss-Newton step beyond ``point`` wherever the nonlinear refit
        stopped short of its optimum, and the interval could miss its own estimate.
        """
        cfg = self.settings.selection
        X, y, blocks = design.stacked()
        norm = np.sqrt(np.mean(X ** 2, axis=0))
        norm = np.where(norm > 0, norm, 1.0)
        stats = BlockStats(X / norm, y, blocks, _strata(design, segments))
        rng = np.random.default_rng(cfg.seed)
        support = np.ones(X.shape[1], bool)
        full = least_squares(*stats.total()[:2], support)
        boot = np.array([least_squares(*stats.total(stats.resample(rng))[:2], support)
                         for _ in range(cfg.bootstrap)])
        return point.values(design.columns)[None, :] + (boot - full[None, :]) / norm

    def heterogeneity(self, design: Design, segments: Segments, names: Sequence[str]
                      ) -> dict[str, dict]:
        """
        Return the between-run spread of each global coefficient (module doc, Intervals).

        Per run (per block with fewer than ``MIN_GROUPS`` runs), the correction of one
        coefficient that the run's residual at the fitted point asks for, with the others
        held, and its variance from the run's residual and the rows' effective share.
        """
        X, y, blocks = design.stacked()
        per_segment = design.y.shape[1] * design.y.shape[2]
        groups = (np.repeat(segments.run_index, per_segment)
                  if len(segments.run_ids) >= MIN_GROUPS else blocks)
        ratio = max(self._neff_ratio(design), 1e-6)
        out = {}
        for name in names:
            idx = [k for k, c in enumerate(design.columns) if c.candidate == name]
            if name == CURRENT or len(idx) != 1:
                continue
            x = X[:, idx[0]]
            estimates, variances = [], []
            for g in np.unique(groups):
                rows = groups == g
                sxx = float(x[rows] @ x[rows])
                if sxx <= 0 or rows.sum() < 3:
                    continue
                d = float(x[rows] @ y[rows]) / sxx
                residual = y[rows] - x[rows] * d
                variances.append(float(residual @ residual) / (rows.sum() - 1) / sxx / ratio)
                estimates.append(d)
            tau2, i2 = random_effects(np.array(estimates), np.array(variances))
            out[name] = {'tau': float(np.sqrt(tau2)), 'i2': i2, 'groups': len(estimates),
                         'grouped_by': 'run' if len(segments.run_ids) >= MIN_GROUPS
                         else 'block',
                         'spread': float(np.std(estimates)) if estimates else 0.0}
        return out

    def widened(self, estimate: float, boot: np.ndarray, tau: float) -> tuple[float, float]:
        """Return the 95 % interval: the bootstrap's, widened by the between-run spread tau."""
        low, high = (float(v) for v in np.percentile(boot, [2.5, 97.5]))
        half = Z95 * float(np.sqrt(np.var(boot) + tau * tau))
        return min(low, float(estimate) - half), max(high, float(estimate) + half)

    def aliases(self, segments: Segments, point: Point, names: Sequence[str]
                ) -> dict[str, list[Alias]]:
        """Candidates outside the model that explain most of what a kept term explains."""
        cfg = self.settings.collinearity
        globals_in = [n for n in names if n != CURRENT]
        others = [c.name for c in self.library.global_candidates if c.name not in names]
        if not globals_in or not others:
            return {n: [] for n in names}
        columns = self._columns(segments.run_ids, list(names) + others)
        design = self._design(segments, point, columns)
        X, y, _ = design.stacked()
        norm = np.sqrt(np.mean(X ** 2, axis=0))
        norm = np.where(norm > 0, norm, 1.0)
        Xn = X / norm
        G, Xy, yy = Xn.T @ Xn, Xn.T @ y, float(y @ y)
        index = {c.name: k for k, c in enumerate(columns)}
        model_idx = [k for k, c in enumerate(columns) if c.candidate in names]
        theta = point.values(columns) * norm
        out: dict[str, list[Alias]] = {n: [] for n in names}
        for name in globals_in:
            k = index[name]
            # Residual with the term taken out again: what it explains is measured on it.
            Xy_k = Xy + G[:, k] * theta[k]
            yy_k = yy + 2 * theta[k] * Xy[k] + theta[k] ** 2 * G[k, k]
            rest = np.zeros(len(columns), bool)
            rest[model_idx] = True
            rest[k] = False
            base_rss = rss(G, Xy_k, yy_k, least_squares(G, Xy_k, rest))
            with_k = rest.copy()
            with_k[k] = True
            explained = base_rss - rss(G, Xy_k, yy_k, least_squares(G, Xy_k, with_k))
            if explained <= 0:
                continue
            for other in others:
                j = index[other]
                corr = G[k, j] / np.sqrt(G[k, k] * G[j, j]) if G[j, j] > 0 else 0.0
                if abs(corr) < cfg.alias_min_correlation:
                    continue
                swap = rest.copy()
                swap[j] = True
                share = (base_rss - rss(G, Xy_k, yy_k, least_squares(G, Xy_k, swap))) / explained
                if share >= cfg.alias_share:
                    cand = self.library.by_name[other]
                    out[name].append(Alias(other, cand.category, float(share), float(corr)))
            out[name].sort(key=lambda a: -a.share)
        return out

    def identifiability(self, design: Design, ratio: float) -> dict[str, dict]:
        """
        Return the standard error of each coefficient against its relevant scale.

        Alone (``excited``) and fitted together with every candidate of the OTHER
        categories (``separable``). Candidates of one category are meant to overlap
        (Isherwood's wind and the generic wind shapes); what the recordings must do is keep
        categories apart.
        """
        X, y, _ = design.stacked()
        n_eff = max(len(y) * ratio, 1.0)
        sigma = float(np.sqrt(np.mean(y ** 2)))
        norm2 = np.sum(X ** 2, axis=0)
        norm = np.sqrt(np.where(norm2 > 0, norm2, 1.0))
        G = (X / norm).T @ (X / norm)
        inflate = sigma * np.sqrt(len(y) / n_eff)
        categories = [self.library.by_name[c.candidate].category for c in design.columns]
        out: dict[str, dict] = {}
        limit = self.settings.excitation.identifiable_se
        for k, col in enumerate(design.columns):
            if norm2[k] > 0:
                marginal = inflate / np.sqrt(norm2[k])
                idx = [k] + [j for j in range(len(categories)) if categories[j] != categories[k]
                             and norm2[j] > 0]
                inv = np.linalg.pinv(G[np.ix_(idx, idx)], rcond=1e-12, hermitian=True)
                joint = inflate * np.sqrt(max(inv[0, 0], 0.0)) / norm[k]
            else:
                marginal = joint = np.inf
            entry = out.setdefault(col.candidate, {'scale': float(design.scales[k]),
                                                   'marginal_se': 0.0, 'joint_se': 0.0})
            entry['marginal_se'] = max(entry['marginal_se'], float(marginal))
            entry['joint_se'] = max(entry['joint_se'], float(joint))
        for entry in out.values():
            entry['excited'] = bool(entry['marginal_se'] <= limit * entry['scale'])
            entry['separable'] = bool(entry['joint_se'] <= limit * entry['scale'])
        return out

    # ------------------------------------------------------------------ the whole
    def run(self, segments: Segments) -> Identification:
        """Identify on the segments of the diagnosis runs."""
        cfg = self.settings.selection
        point = Point()
        kept: list[str] = []
        selected: dict[str, Selected] = {}
        rounds: list[dict] = []
        identifiability: dict[str, dict] = {}
        for r in range(cfg.rounds):
            self.say(f'selection round {r + 1}: {len(self.library.candidates)} candidates, '
                     f'{cfg.bootstrap} bootstrap replicates')
            design, model, probability, per_run = self.select(segments, point, r)
            # Judged on the latest round: its residual no longer holds the effects found,
            # which would otherwise make every candidate look unidentifiable.
            identifiability = self.identifiability(design, model.neff_ratio)
            new = [n for n, p in probability.items() if p >= cfg.inclusion_threshold
                   and n not in kept]
            rounds.append({'round': r + 1, 'added': new,
                           'inclusion_probability': {n: p for n, p in probability.items()
                                                     if p >= 0.05},
                           'effective_sample_ratio': model.neff_ratio})
            for n in new:
                selected[n] = Selected(n, probability[n], r + 1,
                                       per_run if n == CURRENT else {})
            if not new:
                break
            kept += new
            self.say(f'  added {", ".join(new)}; refitting {len(kept)} terms')
            point, design = self.refit(segments, point, kept)
        pruned: dict[str, str] = {}
        pruned_values: dict[str, float] = {}
        gains: dict[str, dict[str, float]] = {}
        while kept:
            design = self._design(segments, point, self._columns(segments.run_ids, kept))
            survivors, gains, dropped = self.prune(design, segments, point, kept)
            pruned.update(dropped)
            if survivors != kept:
                for name in dropped:
                    if name in point.theta:
                        pruned_values[name] = point.theta[name]
                    point = point.without(name)
                kept = survivors
                if kept:
                    point, design = self.refit(segments, point, kept)
            implausible = self.implausible(point, kept)
            if not implausible:
                break
            if len(implausible) > 1:
                # Two look-alikes in the model drift together along what the recordings
                # cannot tell apart (a payload's mass and the rotors' thrust coefficient,
                # whose ratio alone the motion fixes): the one furthest out goes, the
                # other is refitted alone and checked again.
                worst = max(implausible, key=lambda n: self._excess(point, n))
                implausible = {worst: implausible[worst]}
            for name, why in implausible.items():
                self.say(f'  pruned {name}: {why}')
                pruned[name] = why
                kept.remove(name)
                point = point.without(name)
            if kept:
                point, design = self.refit(segments, point, kept)
        ci95: dict[str, tuple[float, float]] = {}
        ci95_noise: dict[str, tuple[float, float]] = {}
        hetero: dict[str, dict] = {}
        current_ci: dict[str, np.ndarray] = {}
        speed_ci = None
        aliases: dict[str, list[Alias]] = {}
        if kept:
            # The reported coefficients are the converged refit, which the intervals
            # describe; the rounds' few iterations are only a start.
            point, design = self.refit(segments, point, kept,
                                       cfg.final_gauss_newton_iterations)
            columns = design.columns
            boot = self.intervals(design, segments, point)
            for name in kept:
                idx = [k for k, c in enumerate(columns) if c.candidate == name]
                if name == CURRENT:
                    for k in idx:
                        col = columns[k]
                        ci = current_ci.setdefault(col.run, np.zeros((2, 2)))
                        ci[0 if col.component == 'north' else 1] = np.percentile(
                            boot[:, k], [2.5, 97.5])
                    speed_ci = rms_speed_interval(boot[:, idx], point.values(columns)[idx])
                else:
                    ci95_noise[name] = tuple(float(v) for v in np.percentile(
                        boot[:, idx[0]], [2.5, 97.5]))
            hetero = self.heterogeneity(design, segments, kept)
            for name, h in hetero.items():
                k = [j for j, c in enumerate(columns) if c.candidate == name][0]
                ci95[name] = self.widened(point.theta.get(name, 0.0), boot[:, k], h['tau'])
            aliases = self.aliases(segments, point, kept)
        kept_out = self.kept_out(segments, point, kept, selected, pruned, pruned_values)
        return Identification(point, point.physics(self.nominal, self.library), selected, kept,
                              gains, ci95, current_ci, speed_ci, aliases, pruned,
                              identifiability, rounds, ci95_noise, hetero, kept_out)

    def kept_out(self, segments: Segments, point: Point, kept: Sequence[str],
                 selected: dict[str, Selected], pruned: dict[str, str],
                 values: dict[str, float]) -> dict[str, dict]:
        """
        Return the terms the selection took in but pruning left out for their small effect.

        Their size and interval at the fitted point with them, why they were left out,
        and whether they are certain: selected again, at least ``inclusion_threshold`` of
        the time, when offered alone at the final point (every kept term fitted), an
        interval that excludes zero, a size of at least ``kept_out_share`` of the
        library's physically relevant scale (a GM 20 % low is; a damping 5 % off is not),
        and an effect on some state's predictions larger than the recordings' own
        ambiguity about the controls between samples (``input_course_floor``).
        """
        names = [n for n in pruned if n in selected and n in values and n != CURRENT
                 and n in self.pruned_gain]
        if not names:
            return {}
        cfg = self.settings.selection
        residual = self._design(segments, point, self._columns(segments.run_ids, names))
        X, y, blocks = residual.stacked()
        again = BootstrapLasso(cfg.bootstrap, cfg.inclusion_threshold,
                               self._neff_ratio(residual), cfg.max_terms,
                               cfg.seed + len(names)).fit(X, y, blocks, residual.names,
                                                          _strata(residual, segments))
        probability = dict(zip(residual.names, again.inclusion_probability_, strict=True))
        full = Point({**point.theta, **{n: values[n] for n in names}},
                     {k: v.copy() for k, v in point.currents.items()})
        design = self._design(segments, full, self._columns(segments.run_ids,
                                                            list(kept) + names))
        boot = self.intervals(design, segments, full)
        hetero = self.heterogeneity(design, segments, names)
        # The design's own free runs (linear course) are its residuals' other side.
        floor = self.input_course_floor(segments, full, segments.observed - design.y)
        out = {}
        for name in names:
            k = [j for j, c in enumerate(design.columns) if c.candidate == name][0]
            effect = np.sqrt(np.mean((values[name] * design.X[..., k]) ** 2, axis=(0, 1)))
            ci = self.widened(values[name], boot[:, k], hetero.get(name, {}).get('tau', 0.0))
            p_final = float(probability[name])
            relevant = self.settings.validation.kept_out_share * self.library.absolute_scale(
                self.library.by_name[name], self.nominal)
            noise = tuple(float(v) for v in np.percentile(boot[:, k], [2.5, 97.5]))
            out[name] = {'coefficient': float(values[name]), 'ci95': ci, 'ci95_noise': noise,
                         'heterogeneity': hetero.get(name),
                         'relevant_size': float(relevant),
                         'inclusion_probability': p_final,
                         'selected_probability': selected[name].inclusion_probability,
                         'held_out_gain': float(self.pruned_gain[name]),
                         'why': pruned[name],
                         'prediction_effect': effect.tolist(),
                         'input_course_floor': floor.tolist(),
                         'above_input_course_floor': bool((effect > floor).any()),
                         'statistically_certain': bool(p_final >= cfg.inclusion_threshold
                                                       and not ci[0] <= 0.0 <= ci[1]
                                                       and abs(values[name]) >= relevant)}
            out[name]['certain'] = (out[name]['statistically_certain']
                                    and out[name]['above_input_course_floor'])
        return out

    def input_course_floor(self, segments: Segments, point: Point,
                           linear: np.ndarray) -> np.ndarray:
        """
        Return, per state, how much the predictions depend on the controls between samples.

        The RMS difference (over the regression's segments) between free runs with each
        sample's controls held over its period and ``linear``, the free runs at ``point``
        with their linear course (m, horizon - skip, n_state; a design's): the
        recordings cannot say which is right, so a term whose effect on every state's
        predictions stays below it cannot be told from that ambiguity. At the patrol
        boat's 1 Hz it reached 10 % of the roll rate's RMS and let an added mass in roll
        pass as "found with certainty" in a case with nothing concealed (issue 46).
        """
        predictor = Predictor(point.physics(self.nominal, self.library), segments.dt,
                              self.settings.regression.substeps)
        cur = segments.currents(point.currents)
        held = predictor.simulate(segments.z0, segments.psi0, segments.c, cur,
                                  hold=True)[:, segments.skip:]
        return np.sqrt(np.mean((held - linear) ** 2, axis=(0, 1)))
