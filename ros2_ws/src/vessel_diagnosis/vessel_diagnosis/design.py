"""
The regression problem: free-run residuals and each candidate's effect on them.

Multiple shooting. Each run is cut into overlapping segments: a segment starts at a
measured state and runs the physics freely for ``horizon`` samples under the recorded
controls (``predict.Predictor.simulate``). Only its steps from ``skip`` on become
regression rows, and segments start every ``horizon - skip`` samples, so every sample
of a run is a row exactly once, seen ``skip`` to ``horizon - 1`` samples after the state
the prediction started from. A candidate's column is the change of those predictions per
unit of its coefficient, by a forward difference of the full model (``library.apply``):
its force pushed through the mass matrix, the couplings and the dynamics.

Why free runs and not one-step residuals: the measured start state carries sensor noise
(roll angle 0.002 rad against a wave-driven roll of a few thousandths), and a one-step
residual contains that noise propagated through restoring and damping. Regressed on
columns built from the same noisy states, the propagation passes for extra roll damping
or inertia (errors in variables), and a steady force mismatch passes for a larger mass
(both shrink the model's own accelerations). ``skip`` samples after the start the noise
has decayed (roll: 1/(zeta omega) = 11 s) and a mass error no longer matters while a
missing force has built up its full effect, so the rows carry slow physics, which is what
steers a 900-step forecast. Wave-driven motion stays in the residual as noise that the
columns, driven by the recorded controls, do not correlate with.

Rows are weighted per state by 1/sigma_s, sigma_s the RMS of that state's residual.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from vessel_diagnosis.library import Candidate, Library
from vessel_diagnosis.predict import Predictor, Variant
from vessel_diagnosis.recordings import Run
from vessel_physics.family import Physics

FD_STEP = 1.0e-2   # forward-difference step, as a share of each candidate's relevant scale


@dataclass(frozen=True)
class Column:
    """What a design column stands for: a global candidate, or one run's current."""

    name: str                 # e.g. 'Xauu' or 'current_north@run_003'
    candidate: str            # library candidate name
    run: str | None = None    # run id of a per-run column
    component: str = ''       # 'north' or 'east' for a current

    @property
    def per_run(self) -> bool:
        """Return whether the column belongs to one run only."""
        return self.run is not None


@dataclass
class Segments:
    """Free-run segments of all runs as one batch (m segments of ``horizon`` steps)."""

    z0: np.ndarray         # (m, n_state) measured start states
    psi0: np.ndarray       # (m,)
    c: np.ndarray          # (m, horizon + 1, n_control) controls from the start sample on
    target: np.ndarray     # (m, horizon, n_state) measured states after 1..horizon samples
    run_index: np.ndarray  # (m,) index into run_ids
    start: np.ndarray      # (m,) start sample within its run
    run_ids: tuple[str, ...]
    horizon: int
    skip: int
    dt: float
    states: tuple[str, ...] = ()   # the names of z

    def currents(self, per_run: Mapping[str, np.ndarray]) -> np.ndarray | None:
        """Return the per-segment current (m, 2) from run id -> (north, east); None if none."""
        if not per_run:
            return None
        table = np.array([per_run.get(r, np.zeros(2)) for r in self.run_ids])
        return table[self.run_index]

    @property
    def observed(self) -> np.ndarray:
        """Return the measured states of the rows (m, horizon - skip, n_state)."""
        return self.target[:, self.skip:]


def make_segments(runs: Sequence[Run], horizon: int, skip: int,
                  states: Sequence[str] = ()) -> Segments:
    """Cut every run into segments starting every ``horizon - skip`` samples."""
    if not 0 <= skip < horizon:
        raise ValueError(f'need 0 <= skip < horizon, got {skip}, {horizon}')
    stride = horizon - skip
    parts = []
    for i, run in enumerate(runs):
        starts = np.arange(0, run.length - horizon, stride)
        if not len(starts):
            continue
        idx = starts[:, None] + np.arange(horizon + 1)[None, :]
        parts.append((run.z[starts], run.psi[starts], run.c[idx], run.z[idx[:, 1:]],
                      np.full(len(starts), i), starts))
    if not parts:
        raise ValueError(f'no run is longer than the {horizon}-sample segments')
    cols = list(zip(*parts, strict=True))
    return Segments(*(np.concatenate(c) for c in cols), tuple(r.run_id for r in runs),
                    horizon, skip, runs[0].dt, tuple(states))


def candidate_columns(run_ids: Sequence[str], library: Library,
                      names: Sequence[str] | None = None) -> tuple[Column, ...]:
    """Columns for the named candidates (default all): per-run ones once per run."""
    chosen = [library.by_name[n] for n in names] if names is not None else library.candidates
    out = []
    for cand in chosen:
        if cand.kind == 'current':
            for run in run_ids:
                out += [Column(f'current_north@{run}', cand.name, run, 'north'),
                        Column(f'current_east@{run}', cand.name, run, 'east')]
        else:
            out.append(Column(cand.name, cand.name))
    return tuple(out)


@dataclass
class Design:
    """Residual rows, candidate columns, weights and bootstrap blocks."""

    y: np.ndarray            # (m, rows, n_state) residual: measured minus predicted
    X: np.ndarray            # (m, rows, n_state, K) effect of one unit of each coefficient
    columns: tuple[Column, ...]
    sigma: np.ndarray        # (n_state,) RMS of the residual per state
    blocks: np.ndarray       # (m,) bootstrap block of every segment
    scales: np.ndarray       # (K,) relevant size of every coefficient

    @property
    def names(self) -> list[str]:
        """Return the column names."""
        return [c.name for c in self.columns]

    def stacked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return the weighted design (n, K), target (n,) and block of every stacked row."""
        w = 1.0 / self.sigma
        k = self.X.shape[-1]
        X = (self.X * w[None, None, :, None]).reshape(-1, k)
        y = (self.y * w[None, None, :]).reshape(-1)
        per_segment = self.y.shape[1] * self.y.shape[2]
        return X, y, np.repeat(self.blocks, per_segment)


MIN_BLOCKS_PER_RUN = 2   # resampling within a run and two-fold checks need two blocks


def make_blocks(segments: Segments, block_samples: int) -> np.ndarray:
    """
    Block id per segment: about ``block_samples`` consecutive samples of one run.

    A run gets at least two blocks (shorter ones if it is short) when it has two segments.
    """
    blocks = np.empty(len(segments.start), dtype=np.int64)
    next_id = 0
    for i in range(len(segments.run_ids)):
        rows = np.flatnonzero(segments.run_index == i)
        if not len(rows):
            continue
        span = segments.start[rows].max() + segments.horizon
        n_blocks = min(len(rows), max(MIN_BLOCKS_PER_RUN, int(round(span / block_samples))))
        local = np.minimum(segments.start[rows] * n_blocks // span, n_blocks - 1)
        blocks[rows] = next_id + local
        next_id += n_blocks
    return blocks


def build_design(segments: Segments, physics: Physics, library: Library,
                 currents: Mapping[str, np.ndarray], columns: Sequence[Column], settings
                 ) -> Design:
    """Residuals and candidate effects at ``physics`` with the per-run ``currents``."""
    cur = segments.currents(currents)
    scales = np.array([library.absolute_scale(library.by_name[col.candidate], physics)
                       for col in columns])
    steps = FD_STEP * scales
    variants, slot = [], []     # slot[k]: which variant gives column k
    current_slot: dict[str, int] = {}
    for k, col in enumerate(columns):
        cand: Candidate = library.by_name[col.candidate]
        if cand.kind == 'current':
            if col.component not in current_slot:
                shift = (steps[k], 0.0) if col.component == 'north' else (0.0, steps[k])
                variants.append(Variant(current_shift=shift))
                current_slot[col.component] = len(variants)
            slot.append(current_slot[col.component])
        else:
            variants.append(library.variant(cand, physics, steps[k]))
            slot.append(len(variants))
    predictor = Predictor(physics, segments.dt, settings.regression.substeps)
    pred = predictor.simulate_variants(segments.z0, segments.psi0, segments.c, cur, variants)
    pred = pred[:, :, segments.skip:]
    base = pred[0]
    X = np.zeros(base.shape + (len(columns),))
    for k, col in enumerate(columns):
        effect = (pred[slot[k]] - base) / steps[k]
        if col.per_run:
            rows = segments.run_index == segments.run_ids.index(col.run)
            X[rows, :, :, k] = effect[rows]
        else:
            X[..., k] = effect
    y = segments.observed - base
    sigma = np.sqrt(np.mean(y ** 2, axis=(0, 1)))
    sigma = np.where(sigma > 0, sigma, 1.0)
    block_samples = max(1, int(round(settings.selection.block_s / segments.dt)))
    return Design(y, X, tuple(columns), sigma, make_blocks(segments, block_samples), scales)
