"""
The whole diagnosis, for a vessel of any family: locate, name, model, show; one call.

``diagnose(recordings, physics, out)`` reads the recordings and the nominal physics of
any family (``vessel_physics``; default: the one the vessel file names), checks that the
recordings fit the vessel file's scale, keeps the candidates of the family's library the
vessel can have, holds some recordings out, locates the mismatch, identifies the missing
terms, evaluates nominal and augmented physics on the held-out recordings, writes the
augmented physics when it forecasts them better, and writes findings.json, report.md
and the figures into ``out``. It returns the findings mapping; its ``status`` says what
the CLI's exit code should be. A family's own settings (time scales, force floors) and
library are packaged data (config/families/ here, the family folder's
diagnosis_candidates.yaml); nothing else here
differs between families.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
import math
from pathlib import Path
import time

import numpy as np
import yaml

from vessel_description import Vessel, shipped_vessels
from vessel_diagnosis.admissible import admissible
from vessel_diagnosis.design import Segments, make_segments
from vessel_diagnosis.evaluate import evaluate
from vessel_diagnosis.findings import (
    SCHEMA,
    STATUS,
    augmented_physics,
    augmented_verdict,
    candidate_records,
    category_table,
    excitation_verdict,
    finding_records,
    kept_out_records,
    status_of,
    summary_line,
    within_input_course_records,
    write_augmented,
)
from vessel_diagnosis.identify import CURRENT, Identification, Identifier, Point
from vessel_diagnosis.library import Library, load_library
from vessel_diagnosis.locate import (
    compute_residuals,
    departures,
    regime_maps,
    regimes_for,
    state_summary,
    window_count,
)
from vessel_diagnosis.recordings import (
    RecordingsError,
    Run,
    load_recordings,
    recordings_vessel,
    signal_ranges,
    split_holdout,
)
from vessel_diagnosis.report import write_report
from vessel_diagnosis.scale import check_scale, scale_figures
from vessel_diagnosis.settings import Settings, SettingsError, load_settings
from vessel_physics.errors import ConfigError
from vessel_physics.family import Physics
from vessel_physics.files import display_name
from vessel_physics.physics_file import load_physics

SERIES_STEP_S = 5.0   # time step of the force series kept for the windows figure


class InsufficientDataError(ValueError):
    """The recordings are too short or too little excited; the message says why."""


@dataclass
class Named:
    """The naming step's result: what was kept, as findings, and the verdict."""

    identification: Identification
    records: list[dict]
    kept_out: list[dict]
    status: str
    enough: bool
    not_checkable: list[str]
    signals: dict
    identifier: Identifier
    segments: Segments


def name_missing_physics(runs: Sequence[Run], nominal: Physics, settings: Settings,
                         library: Library, vessel: Vessel,
                         say: Callable[[str], None] | None = None) -> Named:
    """Identify the missing physics on ``runs`` (no before/after evaluation, no report)."""
    dt = runs[0].dt
    reg = settings.regression
    try:
        segments = make_segments(runs, int(round(reg.horizon_s / dt)),
                                 int(round(reg.skip_s / dt)), vessel.state_names)
    except ValueError as exc:
        raise InsufficientDataError(f'every run is too short: {exc}') from None
    identifier = Identifier(nominal, library, settings, say)
    ident = identifier.run(segments)
    records = finding_records(ident, library, nominal, settings.validation.min_improvement,
                              vessel.state_names)
    kept_out = kept_out_records(ident, library, nominal)
    enough, missing = excitation_verdict(ident, library, settings.excitation.min_categories)
    return Named(ident, records, kept_out, status_of(records, enough, kept_out), enough,
                 missing, signal_ranges(runs, vessel), identifier, segments)


def _hours(runs: Sequence[Run]) -> float:
    return sum(r.length * r.dt for r in runs) / 3600.0


def _ranking(maps: dict) -> dict:
    out = {}
    for family, quantities in maps.items():
        out[family] = {}
        for name, regimes in quantities.items():
            scores = {r: max(e['eta2'], e.get('eta2_within_runs', 0.0))
                      for r, e in regimes.items()}
            out[family][name] = sorted(scores.items(), key=lambda kv: -kv[1])
    return out


def _series(residuals, dt: float) -> dict:
    step = max(1, int(round(SERIES_STEP_S / dt)))
    out = {}
    for i, run in enumerate(residuals.run_ids[:4]):
        rows = np.flatnonzero(residuals.run_index == i)[::step]
        out[run] = {'t': residuals.time[rows].tolist(),
                    **{d: residuals.force[rows, j].tolist()
                       for j, d in enumerate(residuals.dofs)}}
    return out


def nominal_physics(physics: str | Path | Physics | None, vessel: Vessel) -> Physics:
    """
    Return the nominal physics bound to the vessel.

    Given (a file or an object), or the one the vessel file names; RecordingsError (one
    line) where it does not fit the vessel.
    """
    try:
        if isinstance(physics, Physics):
            return physics.for_vessel(vessel)
        if physics is None:
            if vessel.physics is None:
                raise RecordingsError(f'vessel {vessel.name!r} names no physics file (key '
                                      f'physics: in its vessel file); give --physics')
            return load_physics(vessel.physics, vessel)
        return load_physics(physics, vessel)
    except ConfigError as exc:
        raise RecordingsError(f'{exc}; the diagnosis needs a physics of the vessel '
                              f"{vessel.name!r} (its vessel file's physics: or --physics)"
                              ) from None


def vessel_reference(vessel: Vessel, out: Path) -> str:
    """How an augmented scenario names the vessel: a shipped name, else a copy beside it."""
    if vessel.name in shipped_vessels():
        return vessel.name
    out.mkdir(parents=True, exist_ok=True)
    (out / 'vessel.yaml').write_text(yaml.safe_dump(vessel.to_dict(), sort_keys=False))
    return 'vessel.yaml'


def _check_settings(settings: Settings, physics: Physics) -> None:
    floors = settings.locate.force_floor
    if len(floors) != len(physics.family.dofs):
        raise SettingsError(f'locate.force_floor: expected one floor per force of the '
                            f'{physics.family.title} ({", ".join(physics.family.dofs)}), got '
                            f'{list(floors)}')


def _clean(value):
    """Return ``value`` with numpy scalars as floats and non-finite numbers as None."""
    if isinstance(value, dict):
        return {str(k): _clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_clean(v) for v in value]
    if isinstance(value, (np.floating, float)):
        return float(value) if math.isfinite(float(value)) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def diagnose(recordings: Sequence[str | Path], physics: str | Path | Physics | None,
             out: str | Path, settings: Settings | None = None, library: Library | None = None,
             topic_map=None, say: Callable[[str], None] | None = None,
             vessel: Vessel | None = None, scale_check: bool = True) -> dict:
    """
    Run the diagnosis and write REPORT_DIR; return the findings mapping.

    ``physics``: the nominal physics (default: the vessel file's); ``vessel``: the
    description the recordings come from (default: the one the datasets carry);
    ``settings`` and ``library`` default to the physics family's;
    ``scale_check=False`` skips the refusal of recordings that do not fit its scale.
    """
    say = say or (lambda message: None)
    out = Path(out)
    timing: dict[str, float] = {}
    start = time.perf_counter()
    say('reading the recordings')
    vessel = recordings_vessel(recordings, vessel)
    nominal = nominal_physics(physics, vessel)
    settings = settings or load_settings(family=nominal.family.name)
    _check_settings(settings, nominal)
    library = library or load_library(None, nominal.family)
    if library.family != nominal.family.name:
        raise RecordingsError(f'the library is for the {library.family} family, the physics '
                              f'of the {nominal.family.title}')
    runs = load_recordings(recordings, vessel, topic_map)
    # Before anything is fitted: a vessel file of another scale makes every fit absurd.
    scale = (check_scale(runs, vessel, settings.scale_check) if scale_check
             else scale_figures(runs, vessel, settings.scale_check))
    library, excluded = admissible(library.scaled_to(vessel.length_m), vessel, nominal.family)
    ev = settings.evaluation
    diag, held, how = split_holdout(runs, ev.holdout_fraction, ev.holdout_seed)
    result = {
        'schema': SCHEMA,
        'recordings': {'paths': [str(p) for p in recordings], 'n_runs': len(runs),
                       'hours': _hours(runs), 'diagnosis_runs': [r.run_id for r in diag],
                       'diagnosis_hours': _hours(diag), 'held_out_runs': [r.run_id for r in held],
                       'held_out_how': how, 'rate_hz': 1.0 / runs[0].dt},
        'vessel': {'name': vessel.name, 'source': vessel.source,
                   'environment': list(vessel.environment), 'waters': vessel.waters,
                   'states': list(vessel.states), 'length_m': vessel.length_m},
        'scale_check': {**scale, 'checked': scale_check},
        'excluded': [e.to_dict() for e in excluded],
        'excluded_lines': [e.line() for e in excluded],
        'nominal_physics': {'source': display_name(nominal.source),
                            'family': nominal.family.name, 'title': nominal.family.title,
                            'parameters': nominal.params.name, 'terms': list(nominal.terms),
                            'dofs': list(nominal.family.dofs),
                            'extra_terms': [t.to_dict() for t in nominal.extra_terms]},
        'categories': category_table(),
        'settings': settings.to_dict(),
    }
    seconds = _hours(diag) * 3600.0
    if seconds < settings.excitation.min_duration_s:
        raise InsufficientDataError(
            f'the recordings give {seconds:.0f} s to diagnose on (after holding out '
            f'{len(held)} run(s) for the before/after check); the diagnosis needs at least '
            f'{settings.excitation.min_duration_s:.0f} s of recording with the vessel under '
            f'way')
    timing['read'] = time.perf_counter() - start

    say(f'locating: residuals of the nominal physics on {len(diag)} runs '
        f'({seconds / 3600:.2f} h)')
    t0 = time.perf_counter()
    residuals = compute_residuals(diag, nominal, settings, vessel)
    maps = regime_maps(residuals, settings)
    dt = diag[0].dt
    locate = {'summary': state_summary(residuals), 'maps': maps, 'ranking': _ranking(maps),
              'windows': departures(residuals, dt, settings),
              'windows_checked': window_count(residuals, dt, settings),
              'window_s': settings.locate.window_s, 'window_flag': settings.locate.window_flag,
              'multistep_horizon_s': settings.residuals.multistep_horizon_s,
              'sea_state': residuals.sea_state_label,
              'regimes': {**regimes_for(vessel, diag, nominal.family),
                          **({'sea_state': residuals.sea_state_axis}
                             if 'sea_state' in residuals.regimes else {})}}
    timing['locate'] = time.perf_counter() - t0

    say('naming: sparse regression over the candidate library')
    t0 = time.perf_counter()
    named = name_missing_physics(diag, nominal, settings, library, vessel,
                                 lambda m: say('  ' + m))
    ident, records, status = named.identification, named.records, named.status
    enough, missing, signals = named.enough, named.not_checkable, named.signals
    identifier, segments = named.identifier, named.segments
    timing['name'] = time.perf_counter() - t0
    result.update({
        'status': status, 'status_meaning': STATUS[status],
        'summary': summary_line(status, records, missing, signals, named.kept_out),
        'findings': records,
        'kept_out': named.kept_out,
        'within_input_course': within_input_course_records(ident, library, nominal),
        'candidates': candidate_records(ident, library),
        'rounds': ident.rounds,
        'excitation': {'enough': enough, 'not_checkable': missing,
                       'min_categories': settings.excitation.min_categories,
                       'signals': signals},
        'locate': locate,
    })

    aug = augmented_physics(ident, records, nominal) if records else None
    t0 = time.perf_counter()
    if held and aug is not None:
        say(f'showing: nominal and augmented physics on {len(held)} held-out runs')
        currents = {}
        if CURRENT in ident.kept:
            calib = int(round(ev.calibration_s / dt))
            pieces = [r.piece(0, min(calib + 1, r.length), '', 'test') for r in held
                      if min(calib + 1, r.length) > segments.horizon]
            if pieces:
                calib_segments = make_segments(pieces, segments.horizon, segments.skip,
                                               vessel.state_names)
                point, _ = identifier.refit(calib_segments, Point(dict(ident.point.theta)),
                                            [CURRENT])
                currents = point.currents
        metrics = evaluate(held, {'nominal': (nominal, {}), 'augmented': (aug, currents)},
                           settings, vessel)
        metrics['held_out_currents'] = {k: v.tolist() for k, v in currents.items()}
        result['metrics'] = metrics
    elif held:
        say(f'showing: nominal physics on {len(held)} held-out runs')
        result['metrics'] = evaluate(held, {'nominal': (nominal, {})}, settings, vessel)
    else:
        result['metrics'] = None
    verdict = augmented_verdict(result['metrics'], ev) if aug is not None else None
    result['augmented_verdict'] = verdict
    result['augmented_physics'] = None
    if verdict is not None:
        result['summary'] += ' ' + verdict['sentence']
        if verdict['written']:
            say('modelling: writing the augmented physics')
            out.mkdir(parents=True, exist_ok=True)
            result['augmented_physics'] = write_augmented(
                out, aug, records, display_name(nominal.source), vessel_reference(vessel, out))
    timing['show'] = time.perf_counter() - t0
    timing['total'] = time.perf_counter() - start
    result['timing_s'] = timing
    result = _clean(result)
    say('writing the report')
    write_report(out, result, _series(residuals, dt))
    return result
