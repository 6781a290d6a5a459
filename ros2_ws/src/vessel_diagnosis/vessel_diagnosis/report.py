"""
The report: REPORT_DIR/report.md with PNG figures, every number in findings.json.

``write_report(out, result)`` takes the findings.json mapping built by ``pipeline`` and
draws from it alone, so the figures and tables show exactly the numbers in the JSON.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from vessel_description.vocabulary import STATES as STATE_VOCABULARY  # noqa: E402
from vessel_diagnosis.locate import FORCE_UNITS  # noqa: E402

DPI = 110


def _fmt(x, digits: int = 3) -> str:
    if x is None:
        return '–'
    if isinstance(x, (int, np.integer)):
        return str(x)
    if x == 0:
        return '0'
    return f'{x:.{digits}g}'


def _pct(x) -> str:
    return '–' if x is None else f'{100 * x:+.0f} %'


def _vectors(result: dict) -> tuple[list[str], list[str], list[str], list[str]]:
    """Return the vessel's states and the family's forces, with units, from the findings."""
    states = result['vessel']['states']
    dofs = result['nominal_physics']['dofs']
    return (states, [STATE_VOCABULARY[s][0] for s in states], dofs,
            [FORCE_UNITS[d] for d in dofs])


def _map_figure(path: Path, maps: dict, names, units, title: str, regimes_label: dict) -> None:
    regimes = list(regimes_label)
    fig, axes = plt.subplots(len(names), len(regimes), figsize=(2.6 * len(regimes),
                                                                 1.9 * len(names)),
                             squeeze=False, sharex='col')
    for i, name in enumerate(names):
        for j, regime in enumerate(regimes):
            ax = axes[i, j]
            entry = maps.get(name, {}).get(regime)
            if entry and entry['centres']:
                x = np.array(entry['centres'])
                m = np.array(entry['mean'])
                h = np.array(entry['ci95_halfwidth'])
                ax.fill_between(x, m - h, m + h, color='tab:blue', alpha=0.25, lw=0)
                ax.plot(x, m, 'o-', color='tab:blue', ms=3, lw=1)
                eta = entry['eta2']
                extra = (f', within runs {entry["eta2_within_runs"]:.2f}'
                         if 'eta2_within_runs' in entry else '')
                ax.set_title(f'eta²={eta:.2f}{extra}', fontsize=7)
            ax.axhline(0.0, color='k', lw=0.5)
            ax.tick_params(labelsize=7)
            if i == len(names) - 1:
                ax.set_xlabel(regimes_label[regime], fontsize=7)
            if j == 0:
                ax.set_ylabel(f'{name} ({units[i]})', fontsize=8)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _windows_figure(path: Path, series: dict, windows: list[dict], dofs, units) -> None:
    runs = list(series)[:4]
    if not runs:
        return
    fig, axes = plt.subplots(len(dofs), len(runs), figsize=(4.0 * len(runs), 6.5),
                             squeeze=False, sharex='col')
    for j, run in enumerate(runs):
        t = np.array(series[run]['t'])
        for i, dof in enumerate(dofs):
            ax = axes[i, j]
            ax.plot(t / 60.0, np.array(series[run][dof]) / 1e3, lw=0.8)
            for w in windows:
                if w['run'] == run and w['dof'] == dof:
                    ax.axvspan(w['start_s'] / 60.0, w['end_s'] / 60.0, color='tab:red',
                               alpha=0.2, lw=0)
            ax.axhline(0.0, color='k', lw=0.5)
            ax.tick_params(labelsize=7)
            if j == 0:
                ax.set_ylabel(f'{dof} (k{units[i]})', fontsize=8)
            if i == 0:
                ax.set_title(run, fontsize=8)
            if i == len(dofs) - 1:
                ax.set_xlabel('time (min)', fontsize=8)
    fig.suptitle('Low-passed residual generalized force (shaded: departing windows)',
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _candidates_figure(path: Path, candidates: list[dict]) -> None:
    names = [c['name'] for c in candidates]
    probs = [c['max_inclusion_probability'] for c in candidates]
    colors = ['tab:red' if c['status'] == 'kept' else
              ('tab:orange' if c['status'].startswith('pruned') else
               ('lightgray' if c['status'].startswith('not identifiable') else 'tab:blue'))
              for c in candidates]
    fig, ax = plt.subplots(figsize=(7.0, 0.18 * len(names) + 1.2))
    y = np.arange(len(names))
    ax.barh(y, probs, color=colors)
    ax.set_yticks(y, names, fontsize=7)
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel('inclusion probability (largest over rounds)', fontsize=8)
    ax.set_title('Candidates: red kept, orange pruned by the held-out check, '
                 'gray not identifiable', fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _before_after_figure(path: Path, metrics: dict, states) -> None:
    one = metrics.get('one_step_rmse', {})
    fc = metrics.get('forecast', {})
    models = [m for m in ('nominal', 'augmented') if one.get(m)]
    if len(models) < 2:
        return
    fig, axes = plt.subplots(1, 3, figsize=(13.0, 3.4))
    width = 0.38
    x = np.arange(len(states))
    for k, model in enumerate(models):
        ref = np.array([one[models[0]][s] for s in states])
        vals = np.array([one[model][s] for s in states])
        axes[0].bar(x + (k - 0.5) * width, vals / ref, width, label=model)
        if fc.get(model):
            ref_f = np.array([fc[models[0]]['rmse'][s] for s in states])
            vals_f = np.array([fc[model]['rmse'][s] for s in states])
            axes[1].bar(x + (k - 0.5) * width, vals_f / ref_f, width, label=model)
            minutes = fc[model]['trajectory'].get('per_minute_mean') or []
            axes[2].plot(np.arange(1, len(minutes) + 1), minutes, 'o-', ms=3, label=model)
    steps = metrics.get('horizon')
    for ax, title in ((axes[0], 'one-step RMSE (relative to nominal)'),
                      (axes[1], f'{steps}-step forecast RMSE (relative to nominal)')):
        ax.set_xticks(x, states)
        ax.axhline(1.0, color='k', lw=0.5)
        ax.set_title(title, fontsize=9)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    axes[2].set_xlabel('forecast minute', fontsize=8)
    axes[2].set_ylabel('mean position error (m)', fontsize=8)
    axes[2].set_title('trajectory error along the forecast', fontsize=9)
    if axes[2].get_legend_handles_labels()[0]:
        axes[2].legend(fontsize=7)
    if not axes[1].get_legend_handles_labels()[0]:
        axes[1].set_title(f'no {steps}-step forecast fits in the held-out runs', fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def _findings_table(findings: list[dict]) -> list[str]:
    lines = ['| DOF | term | category | coefficient | unit | 95 % interval | of which noise '
             '| runs disagree (I²) | inclusion probability | affected states | '
             'cannot be told apart from |', '|---|---|---|---|---|---|---|---|---|---|---|']
    for f in findings:
        ci = f['ci95'] or [None, None]
        noise = f.get('ci95_noise') or [None, None]
        het = f.get('heterogeneity') or {}
        rel = (f' ({_pct(f["relative_change"])} of nominal)'
               if f.get('relative_change') is not None else '')
        aliases = ', '.join(f'{a["term"]} ({a["category"]}, {100 * a["share"]:.0f} %)'
                            for a in f['aliases']) or '–'
        lines.append(f'| {f["dof"]} | `{f["term"]}` | {f["category"]} | '
                     f'{_fmt(f["coefficient"], 4)}{rel} | {f["unit"]} | '
                     f'[{_fmt(ci[0], 4)}, {_fmt(ci[1], 4)}] | '
                     f'[{_fmt(noise[0], 4)}, {_fmt(noise[1], 4)}] | '
                     f'{_fmt(het.get("i2"), 2)} | '
                     f'{_fmt(f["inclusion_probability"], 2)} | '
                     f'{", ".join(f["affected_states"]) or "–"} | {aliases} |')
    return lines


def _kept_out_size(f: dict) -> str:
    """Return a kept-out term's size: its parameter's change, or its coefficient."""
    if f.get('parameter'):
        return (f'{f["parameter"]} {_fmt(f["nominal"], 4)} -> {_fmt(f["value"], 4)} '
                f'({_pct(f["relative_change"])})')
    return f'{_fmt(f["coefficient"], 4)} {f["unit"]}'


def _kept_out_table(kept_out: list[dict]) -> list[str]:
    lines = ['Found with certainty, but kept out of the augmented physics because it changes '
             'held-out forecasts too little (safety-relevant changes belong here too: read '
             'them):', '', '| term | category | size | 95 % interval | inclusion probability '
             '| why kept out |', '|---|---|---|---|---|---|']
    for f in kept_out:
        ci = f['ci95']
        lines.append(f'| `{f["term"]}` | {f["category"]} | {_kept_out_size(f)} | '
                     f'[{_fmt(ci[0], 4)}, {_fmt(ci[1], 4)}] | '
                     f'{_fmt(f["inclusion_probability"], 2)} | {f["why_kept_out"]} |')
    return lines + ['']


def _within_input_course(records: list[dict], states) -> list[str]:
    lines = ['Not reported as found: the selection took these with certainty, but their '
             "effect on every state's predictions stays below how much the predictions "
             "depend on the controls' unknown course between samples (held over each "
             'period or changing linearly): the recordings cannot tell them from it.', '']
    for f in records:
        worst = max(range(len(states)), key=lambda i: f['prediction_effect'][i]
                    / max(f['input_course_floor'][i], 1e-300))
        lines.append(f'- `{f["term"]}` ({f["category"]}, {_kept_out_size(f)}): effect on '
                     f'{states[worst]} {_fmt(f["prediction_effect"][worst], 3)} against '
                     f'{_fmt(f["input_course_floor"][worst], 3)}')
    return lines + ['']


def _metrics_tables(metrics: dict, states, state_units) -> list[str]:
    one = metrics.get('one_step_rmse', {})
    fc = metrics.get('forecast', {})
    imp = metrics.get('improvement', {})
    steps = metrics.get('horizon')
    lines = [f'Held-out runs: {", ".join(metrics.get("runs", []))}; errors after the first '
             f'{metrics.get("start_sample", 0)} samples of each (per-run terms are estimated '
             f'there); targets: {metrics.get("target")} states; '
             f'{metrics.get("n_forecasts", 0)} forecasts of {steps} steps.', '',
             '| error | model | ' + ' | '.join(f'{s} ({u})' for s, u in
                                               zip(states, state_units, strict=True))
             + ' | trajectory (m) |',
             '|---|---|' + '---|' * (len(states) + 1)]
    for model in ('nominal', 'augmented'):
        if one.get(model):
            lines.append(f'| one-step RMSE | {model} | '
                         + ' | '.join(_fmt(one[model][s]) for s in states) + ' | |')
    for model in ('nominal', 'augmented'):
        if fc.get(model):
            t = fc[model]['trajectory']
            lines.append(f'| {steps}-step RMSE | {model} | '
                         + ' | '.join(_fmt(fc[model]['rmse'][s]) for s in states)
                         + f' | {_fmt(t["mean"], 4)} ± {_fmt(t["ci95"], 2)} |')
    if imp.get('one_step_rmse'):
        lines.append('| one-step change | | ' + ' | '.join(
            _pct(-imp['one_step_rmse'][s]) for s in states) + ' | |')
    if imp.get('forecast_rmse'):
        lines.append(f'| {steps}-step change | | ' + ' | '.join(
            _pct(-imp['forecast_rmse'][s]) for s in states)
            + f' | {_pct(-imp["trajectory"]) if imp.get("trajectory") is not None else "–"} |')
    return lines


def write_report(out: Path, result: dict, series: dict | None = None) -> None:
    """Write findings.json, report.md and the figures into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / 'findings.json').write_text(json.dumps(result, indent=2, allow_nan=False))
    loc = result.get('locate') or {}
    regimes_label = dict(loc.get('regimes', {}))
    states, state_units, dofs, dof_units = _vectors(result)
    if loc.get('maps'):
        _map_figure(out / 'locate_force_maps.png', loc['maps']['force'], dofs, dof_units,
                    'Residual generalized force of the nominal physics (low-passed) '
                    'against regimes', regimes_label)
        _map_figure(out / 'locate_multistep_maps.png', loc['maps']['multistep'], states,
                    state_units, f'Free-run residual after {loc.get("multistep_horizon_s")} s '
                    'against regimes', regimes_label)
    if series:
        _windows_figure(out / 'locate_windows.png', series, loc.get('windows', []), dofs,
                        dof_units)
    if result.get('candidates'):
        _candidates_figure(out / 'candidates.png', result['candidates'])
    metrics = result.get('metrics') or {}
    if (metrics.get('one_step_rmse') or {}).get('augmented'):
        _before_after_figure(out / 'before_after.png', metrics, states)
    lines = _markdown(result, loc, metrics)
    (out / 'report.md').write_text('\n'.join(lines) + '\n')


def _header(result: dict) -> list[str]:
    rec, nominal = result['recordings'], result['nominal_physics']
    lines = ['# Simulation-to-reality diagnosis', '', f'**{result["summary"]}**', '',
             f'Status: `{result["status"]}`. Nominal physics: `{nominal["source"]}`, the '
             f'{nominal["title"]} (terms: {", ".join(nominal["terms"])}).', '',
             f'Recordings: {rec["n_runs"]} runs, {rec["hours"]:.2f} h; diagnosed on '
             f'{len(rec["diagnosis_runs"])} runs ({rec["diagnosis_hours"]:.2f} h), held out '
             f'{len(rec["held_out_runs"])} ({rec["held_out_how"]}). Run time '
             f'{result["timing_s"]["total"]:.0f} s.', '']
    lines += _vessel_lines(result)
    missing = result.get('excitation', {}).get('not_checkable')
    if missing:
        lines += [f'Not checkable with these recordings (no candidate of the category can be '
                  f'told from the other categories): {", ".join(missing)}.', '']
    return lines


def _vessel_lines(result: dict) -> list[str]:
    """Return what the vessel file admits: its scale check and the candidates left out."""
    vessel, scale = result.get('vessel'), result.get('scale_check')
    if not vessel:
        return []
    lines = [f'Vessel: `{vessel["name"]}` ({vessel["source"]}): states '
             f'{", ".join(vessel["states"])}; environment '
             f'{", ".join(vessel["environment"]) or "none"}; waters {vessel["waters"]}; '
             f'length {vessel["length_m"]:g} m.']
    if scale and scale.get('froude') is None:      # a 6-DOF vehicle: its limits only
        lines[0] += (f' Scale check{"" if scale["checked"] else " (skipped)"}: the states '
                     f'within the limits of the vehicle file (a 6-DOF vehicle has no hull '
                     f'speed or turning radius to judge).')
    elif scale:
        lines[0] += (f' Scale check{"" if scale["checked"] else " (skipped)"}: Froude number '
                     f'{scale["froude"]:.2f}, turning rate r L / U {scale["turning_rate"]:.2f} '
                     f'({100 * scale["quantile"]:g} % quantiles).')
    excluded = result.get('excluded_lines') or []
    if excluded:
        lines += ['', 'Not tried, because this vessel cannot have them:', '']
        lines += [f'- {line}' for line in excluded]
    return lines + ['']


def _locate_section(loc: dict, result: dict) -> list[str]:
    lines = ['## 1. Where the nominal physics departs', '']
    if not loc:
        return lines + ['Not located (the recordings could not be diagnosed).', '']
    states, _, dofs, dof_units = _vectors(result)
    summ = loc['summary']
    lines += ['| residual | ' + ' | '.join(states) + ' |', '|---|' + '---|' * len(states)]
    horizon = f'{loc["multistep_horizon_s"]:g}-s RMS'
    for kind, label in (('one_step', 'one-step RMS'), ('multistep', horizon)):
        if summ.get(kind):
            lines.append(f'| {label} | '
                         + ' | '.join(_fmt(summ[kind][s]['rms']) for s in states) + ' |')
    lines += ['', '| DOF | mean force | RMS (low-passed) | strongest regime (eta²) | '
              'departing windows |', '|---|---|---|---|---|']
    for j, dof in enumerate(dofs):
        f = summ['force'][dof]
        top = ', '.join(f'{r} ({v:.2f})' for r, v in loc['ranking']['force'][dof][:2])
        n_win = sum(1 for w in loc['windows'] if w['dof'] == dof)
        lines.append(f'| {dof} | {_fmt(f["mean"])} {dof_units[j]} | {_fmt(f["rms"])} '
                     f'{dof_units[j]} | {top} | {n_win} of {loc["windows_checked"]} |')
    lines += ['', f'Sea state: {loc["sea_state"]}. Departing windows are '
              f'{loc["window_s"]:.0f}-s spans whose mean force residual is at least '
              f'{loc["window_flag"]:g} standard errors from zero and above the force floor.', '']
    shown = sorted(loc['windows'], key=lambda w: -w['z_score'])[:10]
    if shown:
        lines += ['| run | from (s) | to (s) | DOF | mean force | z |',
                  '|---|---|---|---|---|---|']
        lines += [f'| {w["run"]} | {w["start_s"]:.0f} | {w["end_s"]:.0f} | {w["dof"]} | '
                  f'{_fmt(w["mean_force"])} {w["unit"]} | {w["z_score"]:.1f} |' for w in shown]
        lines.append('')
    return lines + ['![force maps](locate_force_maps.png)', '',
                    '![multistep maps](locate_multistep_maps.png)', '',
                    '![windows](locate_windows.png)', '']


def _current_table(finding: dict) -> list[str]:
    lines = [f'Current per run (`{finding["term"]}`): direction it flows to, from north.', '',
             '| run | north (m/s) | east (m/s) | speed (m/s) | direction (deg) | '
             'inclusion probability |', '|---|---|---|---|---|---|']
    lines += [f'| {run} | {_fmt(v["north"])} | {_fmt(v["east"])} | {_fmt(v["speed"])} | '
              f'{v["direction_deg"]:.0f} | {_fmt(v["inclusion_probability"], 2)} |'
              for run, v in finding['per_run'].items()]
    return lines + ['']


def _name_section(result: dict) -> list[str]:
    lines = ['## 2. What is missing', '']
    findings = result['findings']
    if findings:
        lines += _findings_table(findings) + ['']
        for f in findings:
            if f.get('per_run'):
                lines += _current_table(f)
        settings = result['settings']
        lines += ['Held-out gain: how much worse the free-run predictions of each state get '
                  'without the term (cross-fitted); a term is kept only if some state gains '
                  f'{100 * settings["validation"]["min_improvement"]:.0f} % or more. '
                  '"Cannot be told apart": another candidate explains at least '
                  f'{100 * settings["collinearity"]["alias_share"]:.0f} % of what the term '
                  'explains (share in brackets); these recordings do not decide between '
                  'them. The 95 % interval holds the value another run would ask for: the '
                  'bootstrap interval ("of which noise") widened by how much the runs '
                  'disagree beyond their noise (I² near 1: the model is misspecified and '
                  'the coefficient stands in for something else).', '']
    else:
        lines += [result['summary'], '']
    if result.get('kept_out'):
        lines += _kept_out_table(result['kept_out'])
    if result.get('within_input_course'):
        lines += _within_input_course(result['within_input_course'],
                                      result['vessel']['states'])
    pruned = [c for c in result['candidates'] if c['status'].startswith('pruned')]
    if pruned:
        lines += ['Selected but dropped:', '']
        lines += [f'- `{c["name"]}` ({c["category"]}): {c["status"][len("pruned: "):]}'
                  for c in pruned]
        lines.append('')
    return lines + ['![candidates](candidates.png)', '']


def _model_section(result: dict) -> list[str]:
    lines = ['## 3. Augmented physics', '']
    aug, verdict = result.get('augmented_physics'), result.get('augmented_verdict')
    if verdict:
        lines += [verdict['sentence'], '']
    if not aug:
        return lines + ([] if verdict else ['No augmented physics: nothing was found to add.',
                                            ''])
    return lines + [
        f'- `{aug["physics"]}`: nominal terms plus the extra terms (load with '
        '`vessel_physics.physics_file.load_physics`; a hybrid takes it as '
        '`model.physical.physics`);',
        f'- `{aug["parameters"]}`: the parameters with the corrections folded in;',
        f'- `{aug["simulation"]}`: a simulator scenario with it '
        '(`offline/simulate.py --config`).', '']


def _show_section(metrics: dict, result: dict) -> list[str]:
    lines = ['## 4. Before and after, on held-out recordings', '']
    states, units, _, _ = _vectors(result)
    if (metrics.get('one_step_rmse') or {}).get('augmented'):
        return lines + _metrics_tables(metrics, states, units) + [
            '', '![before/after](before_after.png)', '']
    if metrics.get('one_step_rmse'):
        return lines + ['Nothing was added, so there is no "after"; the nominal physics on '
                        'the held-out runs:', ''] + _metrics_tables(metrics, states, units) + [
            '']
    return lines + ['Not evaluated (no held-out recordings).', '']


def _markdown(result: dict, loc: dict, metrics: dict) -> list[str]:
    return (_header(result) + _locate_section(loc, result) + _name_section(result)
            + _model_section(result) + _show_section(metrics, result)
            + ['Every number above is in `findings.json` (schema in docs/diagnosis.md).'])

