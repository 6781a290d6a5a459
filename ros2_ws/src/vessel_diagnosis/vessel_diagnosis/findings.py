"""
Findings: what the identification kept, as records of the findings.json schema.

Also the verdict and the augmented physics written from the findings; docs/diagnosis.md
documents both.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
import math
from pathlib import Path

import numpy as np

from vessel_diagnosis.identify import CURRENT, Identification
from vessel_diagnosis.library import CATEGORIES, Library
from vessel_physics.family import ExtraTerm, Physics
from vessel_physics.physics_file import write_parameters, write_physics

SCHEMA = 'vessel-diagnosis/1'
STATUS = {
    'findings': 'the nominal physics lacks something: see the findings (and the terms '
                'found but kept out of the augmented physics)',
    'nothing_significant': 'nothing significant is missing from the nominal physics',
    'insufficient_excitation': 'the recordings cannot tell whether physics is missing',
}


def _finite(x) -> float | None:
    return float(x) if x is not None and math.isfinite(float(x)) else None


def finding_records(ident: Identification, library: Library, nominal: Physics,
                    min_gain: float, states: tuple[str, ...]) -> list[dict]:
    """
    One record per kept term (findings.json ``findings``), strongest effect first.

    ``affected_states`` are those whose held-out RMSE the term lowers by ``min_gain`` or more.
    """
    records = []
    for name in ident.kept:
        cand = library.by_name[name]
        gain = ident.improvement.get(name, {})
        sel = ident.selected.get(name)
        record = {
            'dof': cand.dofs,
            'term': name,
            'category': cand.category,
            'kind': cand.kind,
            'description': cand.description,
            'unit': cand.unit,
            'inclusion_probability': float(sel.inclusion_probability) if sel else None,
            'round': sel.round if sel else None,
            'held_out_gain': {s: _finite(gain.get(s)) for s in states},
            'aliases': [{'term': a.candidate, 'category': a.category, 'share': a.share,
                         'correlation': a.correlation} for a in ident.aliases.get(name, [])],
        }
        record['cannot_be_told_apart'] = bool(record['aliases'])
        if name == CURRENT:
            per_run = {}
            speeds = []
            for run, vec in sorted(ident.point.currents.items()):
                ci = ident.current_ci95.get(run, np.full((2, 2), np.nan))
                speed = float(np.hypot(*vec))
                speeds.append(speed)
                per_run[run] = {
                    'north': float(vec[0]), 'east': float(vec[1]), 'speed': speed,
                    'direction_deg': float(np.degrees(np.arctan2(vec[1], vec[0])) % 360.0),
                    'ci95_north': [_finite(v) for v in ci[0]],
                    'ci95_east': [_finite(v) for v in ci[1]],
                    'inclusion_probability': (sel.per_run_probability.get(run) if sel else None),
                }
            record.update({
                'coefficient': float(np.sqrt(np.mean(np.square(speeds)))) if speeds else 0.0,
                'ci95': list(ident.current_speed_ci95) if ident.current_speed_ci95 else None,
                'coefficient_meaning': 'RMS current speed over the runs (m/s); per run in '
                                       'per_run (direction the current flows to, deg from '
                                       'north)',
                'per_run': per_run,
            })
        else:
            value = float(ident.point.theta.get(name, 0.0))
            record['coefficient'] = value
            record['ci95'] = list(ident.ci95.get(name, (value, value)))
            record['ci95_noise'] = list(ident.ci95_noise.get(name, (value, value)))
            record['heterogeneity'] = ident.heterogeneity.get(name)
            if cand.kind == 'parameter':
                nominal_value = nominal.parameter(cand.target)
                record.update({
                    'parameter': cand.target,
                    'nominal': nominal_value,
                    'value': nominal_value + value,
                    'relative_change': value / nominal_value if nominal_value else None,
                    'coefficient_meaning': f'change of {cand.target} ({cand.unit})',
                })
            else:
                record['coefficient_meaning'] = (
                    f'{cand.target} times this coefficient on {cand.dofs}')
        record['affected_states'] = [s for s in states if (gain.get(s) or 0.0) >= min_gain]
        records.append(record)
    records.sort(key=lambda r: -max(v or 0.0 for v in r['held_out_gain'].values()))
    return records


def kept_out_records(ident: Identification, library: Library, nominal: Physics) -> list[dict]:
    """
    Return the terms found with certainty but kept out of the augmented physics.

    Selected, selected again at the final point, an interval excluding zero, but too
    small an effect on forecasts: their size and why.
    """
    return [_kept_out_record(name, info, library, nominal)
            for name, info in ident.kept_out.items() if info['certain']]


def within_input_course_records(ident: Identification, library: Library,
                                nominal: Physics) -> list[dict]:
    """
    Return the kept-out terms that would be certain but for the input-course floor.

    Their effect on every state's predictions stays below how much those predictions
    depend on the controls' unknown course between samples: reported as such, not as
    found (``Identifier.input_course_floor``).
    """
    out = []
    for name, info in ident.kept_out.items():
        if info.get('statistically_certain') and not info['above_input_course_floor']:
            record = _kept_out_record(name, info, library, nominal)
            record.update(prediction_effect=info['prediction_effect'],
                          input_course_floor=info['input_course_floor'])
            out.append(record)
    return out


def _kept_out_record(name: str, info: Mapping, library: Library, nominal: Physics) -> dict:
    """Return the record of one kept-out term: its size, interval and why."""
    cand = library.by_name[name]
    record = {'term': name, 'category': cand.category, 'kind': cand.kind,
              'dof': cand.dofs, 'unit': cand.unit, 'description': cand.description,
              'coefficient': info['coefficient'], 'ci95': list(info['ci95']),
              'ci95_noise': list(info['ci95_noise']),
              'heterogeneity': info['heterogeneity'],
              'inclusion_probability': info['inclusion_probability'],
              'held_out_gain': info['held_out_gain'], 'why_kept_out': info['why']}
    if cand.kind == 'parameter':
        nominal_value = nominal.parameter(cand.target)
        record.update({'parameter': cand.target, 'nominal': nominal_value,
                       'value': nominal_value + info['coefficient'],
                       'relative_change': (info['coefficient'] / nominal_value
                                           if nominal_value else None)})
    return record


def _size(record: Mapping) -> str:
    if record.get('relative_change') is not None:
        return f'{record["parameter"]} {100 * record["relative_change"]:+.0f} %'
    return f'{record["term"]} {record["coefficient"]:.3g} {record["unit"]}'


def candidate_records(ident: Identification, library: Library) -> list[dict]:
    """Return what happened to every candidate: kept, pruned, not selected, not identifiable."""
    best = {}
    for round_info in ident.rounds:
        for name, p in round_info['inclusion_probability'].items():
            best[name] = max(best.get(name, 0.0), p)
    out = []
    for cand in library.candidates:
        ident_info = ident.identifiability.get(cand.name, {})
        if cand.name in ident.kept:
            status = 'kept'
        elif cand.name in ident.pruned:
            status = 'pruned: ' + ident.pruned[cand.name]
        elif ident_info and not ident_info.get('excited', True):
            status = 'not identifiable: the recordings hardly excite it'
        elif ident_info and not ident_info.get('separable', True):
            status = 'not identifiable: the recordings cannot tell it from other categories'
        else:
            status = 'not selected'
        out.append({'name': cand.name, 'category': cand.category, 'kind': cand.kind,
                    'dofs': cand.dofs, 'unit': cand.unit, 'scale': ident_info.get('scale'),
                    'marginal_se': _finite(ident_info.get('marginal_se')),
                    'joint_se': _finite(ident_info.get('joint_se')),
                    'excited': ident_info.get('excited'),
                    'separable': ident_info.get('separable'),
                    'max_inclusion_probability': best.get(cand.name, 0.0), 'status': status})
    return out


def excitation_verdict(ident: Identification, library: Library, min_categories: int
                       ) -> tuple[bool, list[str]]:
    """
    Return (enough, categories that cannot be checked) from the identifiability table.

    A category can be checked when one of its candidates is separable from the other
    categories; fewer than ``min_categories`` such categories is too little excitation.
    """
    checked = {library.by_name[n].category for n, e in ident.identifiability.items()
               if e.get('separable')}
    missing = [c for c in CATEGORIES if c not in checked
               and any(x.category == c for x in library.candidates)]
    return len(checked) >= min_categories, missing


def status_of(records: Sequence[dict], enough: bool, kept_out: Sequence[dict] = ()) -> str:
    """Return the overall status (a key of STATUS): a term found with certainty counts."""
    if records or kept_out:
        return 'findings'
    return 'nothing_significant' if enough else 'insufficient_excitation'


def summary_line(status: str, records: Sequence[dict], missing: Sequence[str],
                 signals: Mapping[str, Mapping[str, float]] | None = None,
                 kept_out: Sequence[dict] = ()) -> str:
    """One plain sentence for the top of the report."""
    if status == 'findings':
        parts = []
        for r in records:
            alias = (f' (cannot be told apart from {", ".join(a["term"] for a in r["aliases"])})'
                     if r['aliases'] else '')
            parts.append(f'{r["category"]} ({r["term"]} on {r["dof"]}){alias}')
        out = ('Missing physics found: ' + '; '.join(parts) + '.') if parts else \
            'No term improves held-out forecasts enough to enter the augmented physics.'
        if kept_out:
            out += (' Found with certainty but kept out of the augmented physics for its '
                    'small effect on forecasts: ' + '; '.join(
                        f'{r["category"]} ({_size(r)}, P = {r["inclusion_probability"]:.2f}, '
                        f'{100 * r["held_out_gain"]:.1f} % on held-out predictions)'
                        for r in kept_out) + '.')
        return out
    if status == 'nothing_significant':
        note = (f' Not checkable with these recordings: {", ".join(missing)}.' if missing
                else '')
        return ('Nothing significant is missing: no candidate term improves held-out '
                'predictions.' + note)
    spread = ''
    if signals:
        inputs = [f'{name} by {v["std_within_runs"]:.3g}' for name, v in signals.items()
                  if name not in ('speed_mps', 'yaw_rate_deg_s', 'wind_speed_mps')]
        spread = (f'; within runs {", ".join(inputs)} (std), speeds span '
                  f'{signals["speed_mps"]["min"]:.1f}-{signals["speed_mps"]["max"]:.1f} m/s'
                  + (f', wind reaches {signals["wind_speed_mps"]["max"]:.1f} m/s'
                     if 'wind_speed_mps' in signals else ''))
    return ('The recordings cannot tell whether physics is missing: too little excitation'
            + (f' (not checkable: {", ".join(missing)})' if missing else '') + spread
            + '. Record manoeuvres: speed changes, turns both ways, different headings.')


def augmented_verdict(metrics: Mapping | None, ev) -> dict:
    """
    Return whether the augmented physics earns its file on the held-out forecasts.

    Written when the mean 900-step trajectory error drops by at least
    ``ev.min_trajectory_gain`` and no state's forecast RMSE grows by more than
    ``ev.max_state_loss`` (relative); the record carries the figures and one sentence.
    """
    imp = (metrics or {}).get('improvement') or {}
    trajectory, per_state = imp.get('trajectory'), imp.get('forecast_rmse') or {}
    out = {'written': False, 'trajectory_gain': trajectory, 'forecast_rmse_gain': per_state,
           'min_trajectory_gain': ev.min_trajectory_gain, 'max_state_loss': ev.max_state_loss}
    if trajectory is None:
        out['sentence'] = ('The augmented physics was not written: there are no held-out '
                           'forecasts to show that it predicts better.')
        return out
    gains = {s: g for s, g in per_state.items() if g is not None}
    worst = min(gains, key=gains.get) if gains else None
    traj = metrics['forecast']
    figures = (f'held-out trajectory error {traj["nominal"]["trajectory"]["mean"]:.3g} -> '
               f'{traj["augmented"]["trajectory"]["mean"]:.3g} m ({-100 * trajectory:+.0f} %)'
               + (f', worst state {worst} RMSE {-100 * gains[worst]:+.0f} %' if worst else ''))
    out['written'] = bool(trajectory >= ev.min_trajectory_gain and (
        worst is None or gains[worst] >= -ev.max_state_loss))
    out['sentence'] = (f'The augmented physics forecasts the held-out runs better and was '
                       f'written: {figures}.' if out['written'] else
                       f'The augmented physics was not written: it does not forecast the '
                       f'held-out runs better ({figures}; it needs the trajectory error '
                       f'{-100 * ev.min_trajectory_gain:+.0f} % or less and no state above '
                       f'{100 * ev.max_state_loss:+.0f} %).')
    return out


def augmented_physics(ident: Identification, records: Sequence[dict], nominal: Physics
                      ) -> Physics:
    """Return the nominal physics plus the kept terms, with their statistics as information."""
    by_term = {r['term']: r for r in records}
    extras = []
    for term in ident.physics.extra_terms:
        name = term.info.get('candidate')
        rec = by_term.get(name, {})
        info = {**dict(term.info), 'ci95': rec.get('ci95'),
                'inclusion_probability': rec.get('inclusion_probability')}
        extras.append(ExtraTerm(term.term, term.dofs, term.coefficient, info))
    environment = {}
    if CURRENT in by_term:
        environment['current'] = {
            'model': 'per_run',
            'note': 'a steady current differs between runs: estimate it on each new run '
                    '(vessel_diagnosis.evaluate does so from its first minutes)',
            'runs': {run: {'north_mps': v['north'], 'east_mps': v['east']}
                     for run, v in by_term[CURRENT]['per_run'].items()},
        }
    params = nominal.family.replace(ident.physics.params,
                                    name=f'{nominal.params.name}_augmented')
    return nominal.replace(params=params, extra_terms=tuple(extras), environment=environment,
                           parameters_file='augmented_parameters.yaml')


def write_augmented(out: Path, physics: Physics, records: Sequence[dict], nominal_source: str,
                    vessel_file: str) -> dict[str, str]:
    """Write the augmented parameters, physics and simulator scenario; return their names."""
    changed = [f'{r["parameter"]}: {r["nominal"]:.6g} -> {r["value"]:.6g}' for r in records
               if r['kind'] == 'parameter']
    header = ('Augmented parameters written by offline/diagnose.py: the nominal parameters of\n'
              f'{nominal_source} with those the recordings corrected:\n'
              + ('\n'.join(changed) if changed else '(none)'))
    write_parameters(physics, out / 'augmented_parameters.yaml', header)
    write_physics(physics, out / 'augmented_physics.yaml', 'augmented_parameters.yaml',
                  'Augmented physics written by offline/diagnose.py (format: '
                  'vessel_physics.physics_file).\nLoad with '
                  'vessel_physics.physics_file.load_physics; findings.json has every number.')
    scenario = ['# Simulator scenario with the augmented physics (docs/diagnosis.md):',
                '# offline/simulate.py --config augmented_simulation.yaml',
                f'vessel: {vessel_file}', 'physics: augmented_physics.yaml']
    if 'current' in physics.environment:
        speeds = [math.hypot(v['north_mps'], v['east_mps'])
                  for v in physics.environment['current']['runs'].values()]
        scenario += ["current:   # the recordings' currents (the simulator draws directions)",
                     '  enabled: true',
                     f'  speed_mps: [{min(speeds):.3f}, {max(speeds):.3f}]',
                     '  variation: 0.0']
    (out / 'augmented_simulation.yaml').write_text('\n'.join(scenario) + '\n')
    return {'physics': 'augmented_physics.yaml', 'parameters': 'augmented_parameters.yaml',
            'simulation': 'augmented_simulation.yaml'}


def category_table() -> Mapping[str, str]:
    """Return the documented categories (name -> what they stand for)."""
    return dict(CATEGORIES)
