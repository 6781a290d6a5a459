"""Human-readable results: the Table-2 style Markdown table and PNG figures."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use('Agg')
from matplotlib import ticker  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hybrid_models.metrics import positions, trajectory_errors  # noqa: E402
from vessel_description import Vessel  # noqa: E402

# Decimals per unit, as in the paper's table.
DECIMALS = {'m/s': 3, 'rad/s': 4, 'rad': 4}


def _fmt(x, decimals: int) -> str:
    return '–' if x is None else f'{x:.{decimals}f}'


def trajectory_cell(traj: dict) -> str:
    """'mean ± ci' in m, rounded like the paper (whole metres above 100 m)."""
    mean, ci = traj.get('mean'), traj.get('ci95')
    if mean is None:
        return 'diverged'
    d = 0 if mean >= 100 else 1 if mean >= 10 else 2
    return f'{mean:.{d}f} ± {_fmt(ci, d)}'


def markdown_table(rows: list[dict], spec: Vessel) -> str:
    """
    Rows of {'label', 'metrics'}: per-state RMSE and the trajectory error.

    Rows of several seeds (``evaluation.seed_row``) show mean ± standard deviation over
    the seeds; then the trajectory columns do too, and a single model's ± is omitted
    (its CI95 over forecasts is another kind of spread).
    """
    seeded = any(row.get('seeds', 1) > 1 for row in rows)
    units = list(zip(spec.state_names, spec.state_units, strict=True))
    head = ['model'] + [f'{s} [{u}]' for s, u in units]
    if seeded:
        head += ['seeds', 'trajectory, mean ± sd over seeds [m]', 'at the horizon [m]']
    else:
        head += ['trajectory, mean ± CI95 [m]']
    lines = ['| ' + ' | '.join(head) + ' |', '|' + '---|' * len(head)]
    for row in rows:
        m, sd = row['metrics'], row.get('spread')
        if m['diverged'] and m['trajectory']['mean'] is None:
            cells = ['diverged'] * (len(head) - 1)
        else:
            cells = [_with_spread(m['rmse'][s], sd and sd['rmse'][s], DECIMALS.get(u, 4))
                     for s, u in units]
            traj = m['trajectory']
            if seeded:
                d = 0 if (traj['mean'] or 0) >= 100 else 1 if (traj['mean'] or 0) >= 10 else 2
                cells += [str(row.get('seeds', 1)),
                          _with_spread(traj['mean'], sd and sd['trajectory']['mean'], d),
                          _with_spread(traj['final_mean'],
                                       sd and sd['trajectory']['final_mean'], d)]
            else:
                cells.append(trajectory_cell(traj))
        lines.append('| ' + ' | '.join([row['label']] + cells) + ' |')
    return '\n'.join(lines) + '\n'


def _with_spread(value, spread, decimals: int) -> str:
    cell = _fmt(value, decimals)
    return cell if spread is None or value is None else f'{cell} ± {spread:.{decimals}f}'


def plot_states(path: Path, spec: Vessel, true: np.ndarray, preds: dict[str, np.ndarray],
                title: str) -> None:
    """One forecast: each state over time, truth and every model."""
    t = np.arange(1, len(true) + 1) * spec.dt
    fig, axes = plt.subplots(spec.n_state, 1, figsize=(9, 2.0 * spec.n_state), sharex=True)
    for i, ax in enumerate(axes):
        ax.plot(t, true[:, i], 'k', lw=1.5, label='true')
        for label, pred in preds.items():
            ax.plot(t, pred[:, i], lw=1, label=label)
        ax.set_ylabel(f'{spec.state_names[i]} [{spec.state_units[i]}]')
        ax.grid(alpha=0.3)
    axes[0].set_title(title)
    axes[0].legend(fontsize=7, ncol=4, loc='upper right')
    axes[-1].set_xlabel('time since forecast start [s]')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_trajectories(path: Path, spec: Vessel, true: np.ndarray,
                      preds: dict[str, np.ndarray], title: str) -> None:
    """One forecast's integrated paths from the origin (x north/forward, y east)."""
    fig, ax = plt.subplots(figsize=(6, 6))
    p = positions(true, spec)
    ax.plot(p[:, 1], p[:, 0], 'k', lw=2, label='true')
    for label, pred in preds.items():
        with np.errstate(all='ignore'):
            q = positions(pred, spec)
        if np.isfinite(q).all():
            ax.plot(q[:, 1], q[:, 0], lw=1, label=label)
    ax.set_xlabel('y [m]')
    ax.set_ylabel('x [m]')
    ax.set_aspect('equal', adjustable='datalim')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_error_per_minute(path: Path, spec: Vessel, true: np.ndarray,
                          preds: dict[str, np.ndarray], minute: int = 60) -> None:
    """Boxplots of each forecast's mean trajectory error within each minute."""
    fig, ax = plt.subplots(figsize=(10, 4))
    n_models = len(preds)
    width = 0.8 / max(n_models, 1)
    for j, (label, pred) in enumerate(preds.items()):
        err = trajectory_errors(pred, true, spec)
        steps = err.shape[1] // minute * minute
        per_min = err[:, :steps].reshape(len(err), -1, minute).mean(axis=2)
        per_min = np.where(np.isfinite(per_min), per_min, np.nan)
        pos = np.arange(per_min.shape[1]) + 1 + (j - (n_models - 1) / 2) * width
        bp = ax.boxplot([c[np.isfinite(c)] for c in per_min.T], positions=pos,
                        widths=width * 0.9, showfliers=False, patch_artist=True,
                        medianprops={'color': 'k'})
        for box in bp['boxes']:
            box.set_facecolor(f'C{j}')
            box.set_alpha(0.6)
        ax.plot([], [], color=f'C{j}', lw=6, alpha=0.6, label=label)
    ax.set_xlabel('minute of the forecast')
    ax.set_ylabel('trajectory error [m]')
    minutes = np.arange(1, true.shape[1] // minute + 1)
    ax.set_xticks(minutes, labels=[str(m) for m in minutes])
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_position_curves(path: Path, spec: Vessel,
                         curves: dict[str, list[list[float]]]) -> None:
    """Mean position error over the horizon per model: the seeds' mean, their range shaded."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for k, (label, per_seed) in enumerate(curves.items()):
        c = np.asarray(per_seed, np.float64)
        t = np.arange(1, c.shape[1] + 1) * spec.dt
        ax.plot(t, c.mean(axis=0), color=f'C{k}', lw=1.5,
                label=label + (f' ({len(c)} seeds)' if len(c) > 1 else ''))
        if len(c) > 1:
            ax.fill_between(t, c.min(axis=0), c.max(axis=0), color=f'C{k}', alpha=0.2)
    ax.set_xlabel('time since forecast start [s]')
    ax.set_ylabel('mean position error [m]')
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_threshold(path: Path, spec: Vessel, sweeps: dict[str, list[dict]],
                   title: str) -> None:
    """
    Per-state RMSE and trajectory error against the relative threshold, one line per sweep.

    ``sweeps`` maps a label to ``threshold_sweep`` rows; a row at threshold 0 (physics
    only) is drawn at the left edge, the unconstrained row as a dashed line.
    """
    names = list(spec.state_names) + ['trajectory']
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.2))
    for k, (label, sweep) in enumerate(sweeps.items()):
        color = f'C{k}'
        free = next((r for r in sweep if r['relative_threshold'] is None), None)
        rows = sorted((r for r in sweep if r['relative_threshold'] is not None),
                      key=lambda r: r['relative_threshold'])
        positive = [r['relative_threshold'] for r in rows if r['relative_threshold'] > 0]
        floor = min(positive) / 2 if positive else 1e-3
        ts = [100 * (r['relative_threshold'] or floor) for r in rows]
        for ax, name in zip(axes, names, strict=True):
            def value(row, name=name):
                if name == 'trajectory':
                    return row['trajectory'].get('mean') or np.nan
                return np.nan if row['rmse'][name] is None else row['rmse'][name]
            ax.plot(ts, [value(r) for r in rows], 'o-', color=color, ms=3,
                    label=f'{label}, constrained')
            if free is not None:
                ax.axhline(value(free), color=color, ls='--', lw=1,
                           label=f'{label}, unconstrained')
    units = dict(zip(spec.state_names, spec.state_units, strict=True), trajectory='m')
    for ax, name in zip(axes, names, strict=True):
        ax.set_xscale('log')
        ax.xaxis.set_major_locator(ticker.LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(ticker.FormatStrFormatter('%g'))
        ax.xaxis.set_minor_formatter(ticker.NullFormatter())
        ax.set_xlabel('relative threshold [%]')
        ax.set_title(f'{name} {"error" if name == "trajectory" else "RMSE"} [{units[name]}]')
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=6)
    fig.suptitle(f'{title} (leftmost point: the physics alone, threshold 0)'
                 if any(r['relative_threshold'] == 0 for sweep in sweeps.values()
                        for r in sweep) else title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
