"""
The MMG standard model with the published KVLCC2 coefficients against the 13 HSVA zig-zags.

Usage:  tools/with_env.sh python docs/results/real/analysis/kvlcc2_mmg.py DATASET OUT
DATASET is the KVLCC2 dataset made by docs/results/real/kvlcc2/run.sh (offline/
table_to_dataset.py); OUT receives mmg_alone.json, mmg_alone.md and mmg_zigzags.png.

For each parameter set (the published one as printed, and the same hull with HSVA's
water, particulars and propeller) it reports, per state:
- one-step error (0.1 s ahead from the measured state) against persistence;
- the free run over the whole manoeuvre from its first sample under the measured
  controls, and 60 s forecasts started every 10 s (the vessel file's horizon);
- where the free run departs: the zig-zag figures (first and second overshoot, peak yaw
  rate, speed loss) measured against predicted, the error in the 5 s after each rudder
  reversal against the rest, and the first time each state's error exceeds 10 % of its
  measured range.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import sys

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vessel_datasets.format import read_dataset  # noqa: E402
from vessel_physics import integrator  # noqa: E402
from vessel_physics.mmg.zigzag import overshoots  # noqa: E402
from vessel_physics.physics_file import load_physics  # noqa: E402

STATES = ('u', 'v', 'r')
SUBSTEPS = 4
HORIZON_S, STRIDE_S = 60.0, 10.0
AFTER_REVERSAL_S = 5.0
DEPARTURE_FRACTION = 0.10
PARAMETER_SETS = {
    'published': 'kvlcc2_mmg_yasukawa2015.yaml',
    'published hull, HSVA water/particulars/propeller': 'kvlcc2_hsva_mmg.yaml',
}


def rms(a, axis=None):
    """Return the root mean square."""
    return np.sqrt(np.mean(np.square(a), axis=axis))


def free_run(physics, z0, controls, dt):
    """Return the states (T, 3) from z0 under the controls (T-1, 2), held per sample."""
    return integrator.free_run(physics.derivative, z0, controls, dt, SUBSTEPS)


def heading(r, psi0, dt):
    """Integrate the yaw rate (trapezoid) into a heading from psi0 (rad)."""
    return psi0 + np.concatenate([[0.0], np.cumsum(0.5 * dt * (r[1:] + r[:-1]))])


def check_angle(run_id: str) -> float:
    """Return the check angle (rad) of an HSVA run named ..._Z_<rudder>_<check>[_P|_S]."""
    return math.radians(float(run_id.split('_Z_')[1].split('_')[1]))


def reversals(delta, dt):
    """Return the samples where the rudder starts moving the other way (order changes)."""
    rate = np.sign(np.round(np.diff(delta) / dt, 3))
    moving = np.flatnonzero(rate != 0)
    return [int(moving[i]) for i in range(1, len(moving))
            if rate[moving[i]] != rate[moving[i - 1]]]


def analyse(physics, runs, dt):
    """Return every figure for one parameter set."""
    one_step, persistence, free_err, windows_err = [], [], [], []
    per_run, departures, after, elsewhere = {}, {s: [] for s in STATES}, [], []
    h, stride = int(round(HORIZON_S / dt)), int(round(STRIDE_S / dt))
    for run_id, table in runs.items():
        z = table[list(STATES)].to_numpy()
        c = table[['n', 'delta']].to_numpy()
        pred = free_run(physics, z[:-1], c[:-1, None, :], dt)[:, -1]
        one_step.append(pred - z[1:])
        persistence.append(z[:-1] - z[1:])
        free = free_run(physics, z[0], c[:-1], dt)
        err = free - z
        free_err.append(err)
        starts = np.arange(0, len(z) - h, stride)
        forecasts = free_run(physics, z[starts], np.stack([c[k:k + h] for k in starts]), dt)
        windows_err.extend(forecasts - np.stack([z[k:k + h + 1] for k in starts]))
        psi_meas = table['psi'].to_numpy()
        psi_pred = heading(free[:, 2], psi_meas[0], dt)
        spans = z.max(axis=0) - z.min(axis=0)
        first = {}
        for i, s in enumerate(STATES):
            over = np.flatnonzero(np.abs(err[:, i]) > DEPARTURE_FRACTION * spans[i])
            first[s] = float(over[0] * dt) if over.size else None
            if over.size:
                departures[s].append(float(over[0] * dt))
        mask = np.zeros(len(z), dtype=bool)
        for k in reversals(c[:, 1], dt):
            mask[k:k + int(round(AFTER_REVERSAL_S / dt))] = True
        one = np.abs(one_step[-1])
        after.append(one[mask[1:]])
        elsewhere.append(one[~mask[1:]])
        per_run[run_id] = {
            'overshoot_deg': {'measured': list(overshoots(psi_meas - psi_meas[0],
                                                          check_angle(run_id))),
                              'mmg': list(overshoots(psi_pred - psi_pred[0],
                                                     check_angle(run_id)))},
            'peak_yaw_rate_deg_s': {'measured': float(np.degrees(np.abs(z[:, 2]).max())),
                                    'mmg': float(np.degrees(np.abs(free[:, 2]).max()))},
            'speed_loss_pct': {'measured': float(100 * (1 - z[:, 0].min() / z[0, 0])),
                               'mmg': float(100 * (1 - free[:, 0].min() / z[0, 0]))},
            'free_run_rmse': dict(zip(STATES, rms(err, axis=0).tolist(), strict=True)),
            'heading_rmse_deg': float(np.degrees(rms(psi_pred - psi_meas))),
            'first_departure_s': first,
        }
    cat = np.concatenate
    windows = np.stack(windows_err)
    return {
        'one_step_rmse': dict(zip(STATES, rms(cat(one_step), axis=0).tolist(), strict=True)),
        'persistence_rmse': dict(zip(STATES, rms(cat(persistence), axis=0).tolist(),
                                     strict=True)),
        'free_run_rmse': dict(zip(STATES, rms(cat(free_err), axis=0).tolist(), strict=True)),
        'forecast_60s_rmse': dict(zip(STATES, rms(windows, axis=(0, 1)).tolist(), strict=True)),
        'forecast_60s_rmse_at_end': dict(zip(STATES, rms(windows[:, -1], axis=0).tolist(),
                                             strict=True)),
        'one_step_abs_after_reversal': dict(zip(STATES, cat(after).mean(axis=0).tolist(),
                                                strict=True)),
        'one_step_abs_elsewhere': dict(zip(STATES, cat(elsewhere).mean(axis=0).tolist(),
                                           strict=True)),
        'median_first_departure_s': {s: (float(np.median(v)) if v else None)
                                     for s, v in departures.items()},
        'runs': per_run,
    }


def table_md(results) -> str:
    """Return the Markdown summary of every parameter set."""
    lines = ['| parameters | state | one-step RMSE (persistence) | free run RMSE | '
             '60 s forecast RMSE | after reversal / elsewhere (one-step abs) | '
             'median first departure [s] |', '|---|---|---|---|---|---|---|']
    for name, res in results.items():
        for s in STATES:
            lines.append(
                f'| {name} | {s} | {res["one_step_rmse"][s]:.2e} '
                f'({res["persistence_rmse"][s]:.2e}) | {res["free_run_rmse"][s]:.3g} | '
                f'{res["forecast_60s_rmse"][s]:.3g} | '
                f'{res["one_step_abs_after_reversal"][s]:.2e} / '
                f'{res["one_step_abs_elsewhere"][s]:.2e} | '
                f'{res["median_first_departure_s"][s]} |')
    lines += ['', '| run | parameters | 1st / 2nd overshoot [deg] measured -> MMG | '
              'peak yaw rate [deg/s] | speed loss [%] | heading RMSE [deg] |',
              '|---|---|---|---|---|---|']
    for name, res in results.items():
        for run_id, r in res['runs'].items():
            ov = r['overshoot_deg']
            lines.append(
                f'| {run_id.replace("HSVA_CPMC_KVLCC2_", "")} | {name} | '
                f'{"/".join(f"{v:.1f}" for v in ov["measured"])} -> '
                f'{"/".join(f"{v:.1f}" for v in ov["mmg"])} | '
                f'{r["peak_yaw_rate_deg_s"]["measured"]:.2f} -> '
                f'{r["peak_yaw_rate_deg_s"]["mmg"]:.2f} | '
                f'{r["speed_loss_pct"]["measured"]:.1f} -> {r["speed_loss_pct"]["mmg"]:.1f} | '
                f'{r["heading_rmse_deg"]:.1f} |')
    return '\n'.join(lines) + '\n'


def figure(physics, runs, dt, path):
    """Plot measured against MMG free runs for three zig-zags."""
    chosen = [k for k in runs if k.endswith(('10_10_S', '20_05', '35_05'))]
    fig, axes = plt.subplots(len(chosen), 3, figsize=(13, 3 * len(chosen)), squeeze=False)
    for row, run_id in zip(axes, chosen, strict=True):
        table = runs[run_id]
        z = table[list(STATES)].to_numpy()
        c = table[['n', 'delta']].to_numpy()
        free = free_run(physics, z[0], c[:-1], dt)
        t = table['t'].to_numpy()
        for ax, i, unit, scale in ((row[0], 0, 'm/s', 1.0), (row[1], 1, 'm/s', 1.0),
                                   (row[2], 2, 'deg/s', 180 / math.pi)):
            ax.plot(t, z[:, i] * scale, 'k', lw=1, label='measured')
            ax.plot(t, free[:, i] * scale, 'C1', lw=1, label='MMG free run')
            ax.set_title(f'{run_id.replace("HSVA_CPMC_KVLCC2_", "")}: {STATES[i]} [{unit}]')
        row[2].plot(t, np.degrees(c[:, 1]) / 10, 'C2', lw=0.7, label='rudder / 10 [deg]')
    axes[0, 2].legend(fontsize=8)
    for ax in axes[-1]:
        ax.set_xlabel('t [s]')
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main(argv):
    """Run the analysis; write JSON, Markdown and a figure."""
    if len(argv) != 2:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    dataset, out = read_dataset(argv[0]), Path(argv[1])
    out.mkdir(parents=True, exist_ok=True)
    dt = 1.0 / dataset.rate_hz
    runs = {run_id: dataset.load(run_id) for run_id in dataset.run_ids()}
    results = {}
    for name, file in PARAMETER_SETS.items():
        print(f'MMG ({name}) on {len(runs)} runs', file=sys.stderr)
        results[name] = analyse(load_physics(file), runs, dt)
    (out / 'mmg_alone.json').write_text(json.dumps(results, indent=1))
    (out / 'mmg_alone.md').write_text(table_md(results))
    figure(load_physics(PARAMETER_SETS[list(PARAMETER_SETS)[-1]]), runs, dt,
           out / 'mmg_zigzags.png')
    print(table_md(results))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv[1:]))
