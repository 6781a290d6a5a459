"""
Locate the mismatch: which states and DOFs, in which regimes and time windows.

Residuals of the nominal physics on the diagnosis runs:

- one-step: z_k+1 measured minus predicted from the measured z_k (``Predictor.one_step``);
- multistep: measured minus free-run prediction ``horizon`` samples after a measured start;
- generalized force: the one-step velocity residual as the force that would explain it,
  M dnu / dt (N, N m about the family's reference point, FRD, per DOF of the family),
  low-passed (zero-phase) to remove the wave-frequency forcing that the recordings do
  not measure.

Regime variables per sample: speed u (m/s), turn rate r (deg/s), apparent wind angle
gamma_r (deg, where the apparent wind comes from, + starboard) and speed (m/s) where the
vessel measures the wind, sea state (significant wave height from the recordings'
metadata when every run has it, else, for a vessel with roll in a family that feels
waves, a roll-motion proxy: the rolling standard deviation of roll minus its 60-s mean,
deg) and heading (deg from north); a 6-DOF vehicle adds its heave speed w (m/s) and its
tilt from the vertical, arccos(cos phi cos theta) (deg): a multirotor's roll is its
manoeuvring, not a sea. Maps bin each residual against each regime variable (bin mean
with a 95 % interval from the effective sample size); the correlation ratio eta^2 (the
share of the residual's variance the bins explain) ranks how strongly a residual depends
on a regime. Heading also gets eta^2 within runs, because a current's signature (a
first harmonic in heading) changes phase from run to run and cancels when pooled.

Time windows of ``window_s`` are flagged where the mean force residual of a DOF is
``window_flag`` standard errors from zero and larger than the DOF's force floor.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.signal import butter, sosfiltfilt

from vessel_description import Vessel
from vessel_description.vocabulary import STATES as STATE_VOCABULARY
from vessel_diagnosis.predict import Predictor
from vessel_diagnosis.recordings import Run
from vessel_diagnosis.selection import effective_sample_ratio
from vessel_physics.family import Physics

FORCE_UNITS = {'X': 'N', 'Y': 'N', 'Z': 'N', 'K': 'N m', 'M': 'N m', 'N': 'N m'}
REGIMES = {
    'speed': 'speed u (m/s)',
    'turn_rate': 'turn rate r (deg/s)',
    'wind_angle': 'apparent wind angle (deg, + starboard)',
    'wind_speed': 'apparent wind speed (m/s)',
    'sea_state': 'sea state (metadata Hs, else a roll-motion proxy)',
    'heading': 'heading (deg from north)',
}
SPATIAL_REGIMES = {                  # a 6-DOF vehicle's (Vessel.is_spatial)
    'heave': 'heave speed w (m/s)',
    'tilt': 'tilt from the vertical (deg)',
}
ROLL_MEAN_S = 60.0   # roll is compared with its own running mean over this span (proxy)


def _roll_proxy(vessel: Vessel, family) -> bool:
    """Whether roll motion measures the sea: a vessel with roll in a family with waves."""
    return vessel.has_roll and (family is None or 'waves' in family.environment)


def regimes_for(vessel: Vessel, runs: Sequence[Run], family=None) -> dict[str, str]:
    """Return the regimes a vessel's recordings can be mapped against (module docstring)."""
    out = dict(REGIMES)
    if 'wind' not in vessel.environment:
        del out['wind_angle'], out['wind_speed']
    if not _roll_proxy(vessel, family) and not all('wave_hs_m' in r.info for r in runs):
        del out['sea_state']
    if vessel.is_spatial:
        out.update(SPATIAL_REGIMES)
    return out


def lowpass_runs(x: np.ndarray, run_index: np.ndarray, period_s: float, dt: float,
                 order: int) -> np.ndarray:
    """Zero-phase Butterworth low-pass (cut-off 1/period_s) along axis 0, run by run."""
    sos = butter(order, 2.0 * dt / period_s, output='sos')   # normalized to Nyquist
    out = np.empty_like(x)
    for i in np.unique(run_index):
        rows = run_index == i
        pad = min(3 * (2 * len(sos) + 1), int(rows.sum()) - 1)
        out[rows] = sosfiltfilt(sos, x[rows], axis=0, padlen=pad)
    return out


@dataclass
class Residuals:
    """Nominal residuals and regimes of all diagnosis runs (rows = sample pairs)."""

    one_step: np.ndarray      # (n, n_state) measured minus one-step prediction
    force: np.ndarray         # (n, n_dof) low-passed generalized force residual
    regimes: dict[str, np.ndarray]   # name -> (n,)
    run_index: np.ndarray     # (n,)
    time: np.ndarray          # (n,) s since the run's start
    multistep: np.ndarray     # (m, n_state) free-run residual at the horizon
    multistep_regimes: dict[str, np.ndarray]
    multistep_run: np.ndarray  # (m,)
    sea_state_label: str
    run_ids: tuple[str, ...]
    states: tuple[str, ...]
    dofs: tuple[str, ...]

    @property
    def sea_state_axis(self) -> str:
        """Return a short axis label for the sea-state regime."""
        return ('sea state Hs (m)' if self.sea_state_label.startswith('significant')
                else 'sea state, roll proxy (deg)')


def sea_state(runs: Sequence[Run], window_s: float, vessel: Vessel, family=None
              ) -> tuple[list[np.ndarray], str]:
    """Per-sample sea state of each run: metadata Hs (m) when all runs have it, else proxy."""
    if all('wave_hs_m' in r.info for r in runs):
        return ([np.full(r.length, float(r.info['wave_hs_m'])) for r in runs],
                "significant wave height Hs (m, from the recordings' metadata)")
    if not vessel.has_roll:
        return [np.zeros(r.length) for r in runs], 'none (no roll states, no metadata)'
    if not _roll_proxy(vessel, family):
        return ([np.zeros(r.length) for r in runs],
                f'none (the {family.title} feels no waves, and no metadata)')
    out = []
    for run in runs:
        n_mean = max(3, int(round(ROLL_MEAN_S / run.dt)) | 1)
        n_std = max(3, int(round(window_s / run.dt)) | 1)
        phi = run.z[:, vessel.state_index('phi')]
        kernel = np.ones(n_mean) / n_mean
        wave = phi - np.convolve(np.pad(phi, n_mean // 2, mode='edge'), kernel, 'valid')
        sq = np.convolve(np.pad(wave ** 2, n_std // 2, mode='edge'), np.ones(n_std) / n_std,
                         'valid')
        out.append(np.degrees(np.sqrt(sq)))
    return out, 'roll-motion sea-state proxy (deg, rolling std of roll about its 60-s mean)'


def regimes_of(run: Run, rows: np.ndarray, sea: np.ndarray, vessel: Vessel,
               regimes: dict[str, str]) -> dict[str, np.ndarray]:
    """Regime variables at the sample indices ``rows`` of a run."""
    z, c = run.z[rows], run.c[rows]
    u, v = z[:, vessel.state_index('u')], z[:, vessel.state_index('v')]
    out = {'speed': u, 'turn_rate': np.degrees(z[:, vessel.state_index('r')]),
           'sea_state': sea[rows], 'heading': np.degrees(np.mod(run.psi[rows], 2 * np.pi))}
    if vessel.is_spatial:
        out['heave'] = z[:, vessel.state_index('w')]
        out['tilt'] = np.degrees(np.arccos(np.clip(
            np.cos(z[:, vessel.state_index('phi')]) * np.cos(z[:, vessel.state_index('theta')]),
            -1.0, 1.0)))
    if 'wind_angle' in regimes:
        speed = c[:, vessel.control_index('wind_speed')]
        from_x = speed * c[:, vessel.control_index('wind_dir_cos')] + u
        from_y = speed * c[:, vessel.control_index('wind_dir_sin')] + v
        out['wind_angle'] = np.degrees(np.arctan2(from_y, from_x))
        out['wind_speed'] = np.hypot(from_x, from_y)
    return {k: out[k] for k in regimes}


def compute_residuals(runs: Sequence[Run], physics: Physics, settings,
                      vessel: Vessel) -> Residuals:
    """Nominal one-step, force and multistep residuals with their regimes."""
    dt = runs[0].dt
    predictor = Predictor(physics, dt, settings.prediction.substeps)
    seas, label = sea_state(runs, settings.locate.sea_state_window_s, vessel, physics.family)
    regimes = regimes_for(vessel, runs, physics.family)
    one, reg, run_idx, time = [], [], [], []
    for i, run in enumerate(runs):
        pred = predictor.one_step(run.z[:-1], run.psi[:-1], run.c[:-1], run.c[1:])
        one.append(run.z[1:] - pred)
        rows = np.arange(run.length - 1)
        reg.append(regimes_of(run, rows, seas[i], vessel, regimes))
        run_idx.append(np.full(len(rows), i))
        time.append(run.t[:-1])
    one_step = np.concatenate(one)
    run_index = np.concatenate(run_idx)
    n_dof = len(physics.family.dofs)
    force = (one_step[:, :n_dof] / dt) @ physics.mass_matrix().T
    res = settings.residuals
    force = lowpass_runs(force, run_index, res.lowpass_period_s, dt, res.lowpass_order)
    horizon = max(1, int(round(res.multistep_horizon_s / dt)))
    multi, multi_reg, multi_run = [], [], []
    for i, run in enumerate(runs):
        starts = np.arange(0, run.length - horizon, horizon)
        if not len(starts):
            continue
        idx = starts[:, None] + np.arange(horizon + 1)[None, :]
        pred = predictor.simulate(run.z[starts], run.psi[starts], run.c[idx])
        multi.append(run.z[starts + horizon] - pred[:, -1])
        multi_reg.append(regimes_of(run, starts + horizon // 2, seas[i], vessel, regimes))
        multi_run.append(np.full(len(starts), i))
    merged = {k: np.concatenate([r[k] for r in reg]) for k in regimes}
    if multi:
        multistep = np.concatenate(multi)
        multi_merged = {k: np.concatenate([r[k] for r in multi_reg]) for k in regimes}
        multi_runs = np.concatenate(multi_run)
    else:
        multistep = np.zeros((0, len(vessel.state_names)))
        multi_merged = {k: np.zeros(0) for k in regimes}
        multi_runs = np.zeros(0, dtype=int)
    return Residuals(one_step, force, merged, run_index, np.concatenate(time), multistep,
                     multi_merged, multi_runs, label, tuple(r.run_id for r in runs),
                     tuple(vessel.state_names), tuple(physics.family.dofs))


def _edges(values: np.ndarray, bins: int, regime: str) -> np.ndarray:
    if regime == 'heading':
        return np.linspace(0.0, 360.0, bins + 1)
    if regime == 'wind_angle':
        return np.linspace(-180.0, 180.0, bins + 1)
    lo, hi = np.percentile(values, [1, 99]) if len(values) else (0.0, 1.0)
    if not hi > lo:
        hi = lo + 1e-9
    return np.linspace(lo, hi, bins + 1)


def binned(values: np.ndarray, residual: np.ndarray, regime: str, bins: int, min_count: int,
           neff_ratio: float) -> dict:
    """Bin means of ``residual`` against ``values`` with 95 % intervals and eta^2."""
    edges = _edges(values, bins, regime)
    which = np.clip(np.digitize(values, edges) - 1, 0, bins - 1)
    inside = (values >= edges[0]) & (values <= edges[-1])
    centres, means, halfwidths, counts = [], [], [], []
    total_var = float(np.var(residual[inside])) if inside.any() else 0.0
    between = 0.0
    grand = float(np.mean(residual[inside])) if inside.any() else 0.0
    for b in range(bins):
        sel = inside & (which == b)
        n = int(sel.sum())
        if n < min_count:
            continue
        mean = float(np.mean(residual[sel]))
        sd = float(np.std(residual[sel]))
        centres.append(0.5 * (edges[b] + edges[b + 1]))
        means.append(mean)
        halfwidths.append(1.96 * sd / np.sqrt(max(n * neff_ratio, 1.0)))
        counts.append(n)
        between += n * (mean - grand) ** 2
    n_in = int(inside.sum())
    eta2 = between / (n_in * total_var) if (n_in and total_var > 0) else 0.0
    return {'centres': centres, 'mean': means, 'ci95_halfwidth': halfwidths, 'count': counts,
            'eta2': float(eta2)}


def within_run_eta2(values: np.ndarray, residual: np.ndarray, run_index: np.ndarray,
                    regime: str, bins: int, min_count: int) -> float:
    """Mean over runs of eta^2 of the residual against the regime, bins per run."""
    scores, weights = [], []
    for i in np.unique(run_index):
        sel = run_index == i
        if sel.sum() < 2 * min_count:
            continue
        scores.append(binned(values[sel], residual[sel], regime, bins, min_count, 1.0)['eta2'])
        weights.append(int(sel.sum()))
    return float(np.average(scores, weights=weights)) if scores else 0.0


def regime_maps(res: Residuals, settings) -> dict:
    """Every map: family -> quantity -> regime -> binned numbers (see ``binned``)."""
    cfg = settings.locate
    families = {
        'force': (res.force, res.dofs, res.regimes, res.run_index),
        'one_step': (res.one_step, res.states, res.regimes, res.run_index),
        'multistep': (res.multistep, res.states, res.multistep_regimes, res.multistep_run),
    }
    out: dict = {}
    for family, (values, names, regimes, runs) in families.items():
        out[family] = {}
        if not len(values):
            continue
        for j, name in enumerate(names):
            ratio = effective_sample_ratio(values[:, j]) if len(values) > 3 else 1.0
            out[family][name] = {}
            min_count = cfg.min_bin_samples if family != 'multistep' else 3
            for regime in regimes:
                entry = binned(regimes[regime], values[:, j], regime, cfg.bins, min_count,
                               ratio)
                if regime == 'heading':
                    entry['eta2_within_runs'] = within_run_eta2(
                        regimes[regime], values[:, j], runs, regime, cfg.bins, min_count)
                out[family][name][regime] = entry
    return out


def state_summary(res: Residuals) -> dict:
    """RMS and mean of every residual (one-step, multistep per state; force per DOF)."""
    out = {'one_step': {}, 'multistep': {}, 'force': {}}
    for j, s in enumerate(res.states):
        out['one_step'][s] = {'rms': float(np.sqrt(np.mean(res.one_step[:, j] ** 2))),
                              'mean': float(np.mean(res.one_step[:, j])),
                              'unit': STATE_VOCABULARY[s][0]}
        if len(res.multistep):
            out['multistep'][s] = {'rms': float(np.sqrt(np.mean(res.multistep[:, j] ** 2))),
                                   'mean': float(np.mean(res.multistep[:, j])),
                                   'unit': STATE_VOCABULARY[s][0]}
    for j, d in enumerate(res.dofs):
        out['force'][d] = {'rms': float(np.sqrt(np.mean(res.force[:, j] ** 2))),
                           'mean': float(np.mean(res.force[:, j])), 'unit': FORCE_UNITS[d]}
    return out


def departures(res: Residuals, dt: float, settings) -> list[dict]:
    """Time windows where the low-passed force residual of a DOF departs from zero."""
    cfg = settings.locate
    width = max(2, int(round(cfg.window_s / dt)))
    ratios = [effective_sample_ratio(res.force[:, j]) for j in range(len(res.dofs))]
    out = []
    for i, run_id in enumerate(res.run_ids):
        rows = np.flatnonzero(res.run_index == i)
        for start in range(0, len(rows) - width // 2, width):
            sel = rows[start:start + width]
            for j, dof in enumerate(res.dofs):
                values = res.force[sel, j]
                mean = float(np.mean(values))
                se = float(np.std(values) / np.sqrt(max(len(values) * ratios[j], 1.0)))
                z = abs(mean) / se if se > 0 else 0.0
                if z >= cfg.window_flag and abs(mean) >= cfg.force_floor[j]:
                    out.append({'run': run_id, 'start_s': float(res.time[sel[0]]),
                                'end_s': float(res.time[sel[-1]] + dt), 'dof': dof,
                                'mean_force': mean, 'unit': FORCE_UNITS[dof], 'z_score': z})
    return out


def window_count(res: Residuals, dt: float, settings) -> int:
    """Return the number of time windows checked per DOF."""
    width = max(2, int(round(settings.locate.window_s / dt)))
    return sum(len(range(0, int((res.run_index == i).sum()) - width // 2, width))
               for i in range(len(res.run_ids)))
