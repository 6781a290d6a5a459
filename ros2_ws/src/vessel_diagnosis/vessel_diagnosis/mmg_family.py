"""
The diagnosis for vessels whose physics is the MMG standard model (``vessel_physics.mmg``).

Which coefficients or effects do the recordings ask for? Output error over short
segments: from each measured state the model predicts ``segment_s`` ahead under the
measured controls; the prediction errors of u, v, r (each scaled by its spread) are
regressed on the sensitivities of the prediction to the candidate parameters (finite
differences), in a few Gauss-Newton steps. Selection, inclusion probabilities and 95 %
intervals come from the block-bootstrap lasso of ``vessel_diagnosis.selection``: whole
blocks of ``block_s`` are resampled within each run.

What can exist follows the vessel description: the MMG family is 3-DOF, so no roll
candidates; no wind candidates without a declared wind sensor; no ocean current in a
basin. The augmented parameter file (nominal plus the corrections) is written only when
it improves forecasts over the vessel's horizon on held-out runs (whole runs: the
dataset's test split), and the report says which way it went.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
import json
import math
from pathlib import Path

import numpy as np
import yaml

from vessel_datasets.format import DatasetError, read_dataset, split_runs
from vessel_diagnosis.recordings import RecordingsError
from vessel_diagnosis.scale import check_scale, scale_figures
from vessel_diagnosis.selection import BootstrapLasso, effective_sample_ratio
from vessel_diagnosis.settings import SettingsError, config_dir, load_settings
from vessel_physics import mmg
from vessel_physics.errors import ConfigError
from vessel_physics.files import read_yaml

SETTINGS_FILE = 'mmg_diagnosis.yaml'
KINDS = ('parameter', 'effect')
# Step (in the parameter's unit) of the finite differences that give the sensitivities;
# exact for parameters entering the forces linearly, first order for delta_0 (rad).
SENSITIVITY_STEP = 1e-4
HOLDOUT_SEED, HOLDOUT_FRACTION = 0, 0.3
MAX_STEP_S = 0.1   # s, longest RK4 step of the predictions (the simulator's rule)


@dataclass(frozen=True)
class Candidate:
    """One parameter of ``MmgParams`` the recordings may ask to correct."""

    name: str
    category: str
    kind: str
    description: str


@dataclass(frozen=True)
class MmgSettings:
    """Settings of the MMG-family diagnosis (config/mmg_diagnosis.yaml documents them)."""

    segment_s: float
    gauss_newton_iterations: int
    block_s: float
    n_bootstrap: int
    inclusion_threshold: float
    max_terms: int
    forecast_stride_s: float
    min_improvement: float
    candidates: tuple[Candidate, ...]


def load_mmg_settings(path: str | Path | None = None) -> MmgSettings:
    """Load and check the settings; SettingsError (one line) names a bad key."""
    path = Path(path) if path else config_dir() / SETTINGS_FILE
    try:
        data = read_yaml(path, 'MMG diagnosis settings')
    except ConfigError as exc:
        raise SettingsError(str(exc)) from None
    names = [f.name for f in fields(MmgSettings)]
    if not isinstance(data, dict) or sorted(data) != sorted(names):
        raise SettingsError(f'{path}: expected exactly the keys {names}')
    known = {f.name for f in fields(mmg.MmgParams)}
    candidates = []
    for name, spec in (data['candidates'] or {}).items():
        if name not in known or not isinstance(spec, dict) or spec.get('kind') not in KINDS:
            raise SettingsError(f'{path}: candidates.{name}: must name an MMG parameter and '
                                f'give category, kind ({" or ".join(KINDS)}) and description')
        candidates.append(Candidate(name, str(spec.get('category')), spec['kind'],
                                    str(spec.get('description', ''))))
    values = {k: data[k] for k in names if k != 'candidates'}
    for key, value in values.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or value <= 0:
            raise SettingsError(f'{path}: {key}: must be a positive number, got {value!r}')
    integers = ('gauss_newton_iterations', 'n_bootstrap', 'max_terms')
    return MmgSettings(**{k: (int(v) if k in integers else float(v))
                          for k, v in values.items()}, candidates=tuple(candidates))


@dataclass
class MmgRun:
    """One recorded run in the MMG vectors: z = [u, v, r], c = [n (rad/s), delta (rad)]."""

    run_id: str
    split: str
    z: np.ndarray
    c: np.ndarray


def excluded_categories(vessel) -> dict[str, str]:
    """Return the effect categories the vessel cannot have, with the reason for each."""
    out = {'roll': f'vessel {vessel.name!r} has no roll states (the MMG family is 3-DOF)'}
    if 'wind' not in vessel.environment:
        out['wind'] = f'vessel {vessel.name!r} declares no wind sensor'
    else:
        out['wind'] = 'the MMG family has no wind-load candidates yet'
    if getattr(vessel, 'waters', 'open') == 'basin':
        out['current'] = f'vessel {vessel.name!r} is recorded in a basin (waters: basin)'
    else:
        out['current'] = 'the MMG family has no ocean-current candidates yet'
    return out


def load_mmg_runs(path: str | Path, params_file: str | Path | None = None):
    """Return (vessel, nominal MmgParams, parameter file, runs) of a dataset."""
    try:
        ds = read_dataset(path)
    except (DatasetError, OSError) as exc:
        raise RecordingsError(f'{path}: cannot read the dataset ({exc})') from None
    vessel = ds.vessel
    source = params_file or vessel.physics
    if source is None:
        raise RecordingsError(f'vessel {vessel.name!r} names no physics file; give --physics')
    try:
        file = mmg.find_params_file(source)
    except ConfigError as exc:
        raise RecordingsError(str(exc)) from None
    if not mmg.is_mmg_file(file):
        raise RecordingsError(f'{file} is not an MMG parameter file (format: {mmg.FORMAT})')
    if vessel.state_names != mmg.STATE_NAMES:
        raise RecordingsError(f'vessel {vessel.name!r} has states {vessel.state_names}; the '
                              f'MMG family takes {mmg.STATE_NAMES}')
    kinds = {a.kind: a.name for a in vessel.actuators}
    if sorted(a.kind for a in vessel.actuators) != ['propeller', 'rudder']:
        actuators = {a.name: a.kind for a in vessel.actuators}
        raise RecordingsError(f'vessel {vessel.name!r}: the MMG family needs one propeller '
                              f'and one rudder, got {actuators}')
    splits = {r['id']: r.get('split', 'unused') for r in ds.manifest['runs']}
    runs = []
    for run_id in ds.run_ids():
        table = ds.load(run_id)
        runs.append(MmgRun(run_id, splits[run_id], table[list(mmg.STATE_NAMES)].to_numpy(float),
                           table[[kinds['propeller'], kinds['rudder']]].to_numpy(float)))
    try:
        nominal = mmg.load_mmg(file, vessel.length_m, f'vessel {vessel.name!r}')
    except ConfigError as exc:
        raise RecordingsError(str(exc)) from None
    return vessel, nominal, mmg.display_name(file), runs


def uses_mmg(recordings: Sequence[str | Path], physics: str | Path | None) -> bool:
    """Tell whether to diagnose with the MMG family: --physics or the vessel's file is MMG."""
    if physics is not None:
        try:
            return mmg.is_mmg_file(mmg.find_params_file(physics))
        except ConfigError:
            return False
    for path in recordings:
        try:
            source = read_dataset(path).vessel.physics
            if source and mmg.is_mmg_file(mmg.find_params_file(source)):
                return True
        except (ValueError, OSError):   # not a dataset (e.g. a bag): not ours to route
            continue
    return False


def segments(runs: Sequence[MmgRun], length: int) -> tuple[np.ndarray, ...]:
    """Return start states (S, 3), controls (S, L, 2), measured (S, L, 3) and run indices."""
    z0, controls, measured, owner = [], [], [], []
    for i, run in enumerate(runs):
        for k in range(0, len(run.z) - length, length):
            z0.append(run.z[k])
            controls.append(run.c[k:k + length])
            measured.append(run.z[k + 1:k + length + 1])
            owner.append(i)
    if not z0:
        raise RecordingsError(f'every run is shorter than one segment ({length} samples)')
    return np.array(z0), np.array(controls), np.array(measured), np.array(owner)


def substeps(dt: float) -> int:
    """Return the RK4 steps per sample period that keep each step within MAX_STEP_S."""
    return max(1, math.ceil(dt / MAX_STEP_S - 1e-9))


def predicted(params: mmg.MmgParams, z0, controls, dt: float) -> np.ndarray:
    """Return the model's states over each segment (S, L, 3), from the measured start."""
    return mmg.simulate(params, z0, controls, dt, substeps(dt))[:, 1:]


def sensitivities(params: mmg.MmgParams, z0, controls, dt: float, base: np.ndarray,
                  names: Sequence[str]) -> np.ndarray:
    """Return d predicted / d theta_j (S, L, 3, K) by one-sided differences."""
    return np.stack([(predicted(params.replace(**{n: getattr(params, n) + SENSITIVITY_STEP}),
                                z0, controls, dt) - base) / SENSITIVITY_STEP for n in names],
                    axis=-1)


def identify(params: mmg.MmgParams, runs: Sequence[MmgRun], dt: float,
             settings: MmgSettings, names: Sequence[str]) -> dict:
    """
    Select and estimate parameter corrections on ``runs``; every figure in a mapping.

    Output error over short segments: from each measured start, the model predicts
    ``segment_s`` ahead under the measured controls, and the prediction error is regressed
    on the sensitivities of the prediction to each candidate (Gauss-Newton). Measured
    states are never differentiated, so sensor noise does not leak into the regressors
    (an equation error on differentiated states biases the added-mass candidates), and
    segments long against the sensor noise's effect keep the start states' noise from
    biasing the rest (5 s at 10 Hz: unbiased within the intervals in the tests).
    The support is chosen on the first linearization; later iterations refine the kept
    coefficients and their intervals around the updated parameters.
    """
    length = max(int(round(settings.segment_s / dt)), 1)
    z0, controls, measured, owner = segments(runs, length)
    per_block = max(int(round(settings.block_s / settings.segment_s)), 1)
    order = np.arange(len(z0))
    blocks = owner * 100000 + (order - np.searchsorted(owner, owner)) // per_block
    rows = measured.shape[1] * 3
    scale = None
    current, support = params, None
    probability, ci95 = np.zeros(len(names)), np.zeros((len(names), 2))
    for _ in range(settings.gauss_newton_iterations):
        base = predicted(current, z0, controls, dt)
        error = measured - base
        if scale is None:
            scale = error.reshape(-1, 3).std(axis=0)
            scale = np.where(scale > 0, scale, 1.0)
            nominal_rms = np.sqrt(np.mean(error.reshape(-1, 3) ** 2, axis=0))
            # The rows of one segment are one smooth error curve, not independent
            # samples: their autocorrelation sets how much evidence the rows carry.
            neff = effective_sample_ratio(error.reshape(-1, 3))
        x = sensitivities(current, z0, controls, dt, base, names) / scale[:, None]
        y = (error / scale).reshape(-1)
        x = x.reshape(-1, len(names))
        columns = np.arange(len(names)) if support is None else np.flatnonzero(support)
        if not len(columns):
            break
        model = BootstrapLasso(settings.n_bootstrap, settings.inclusion_threshold, neff,
                               settings.max_terms, random_state=0)
        model.fit(x[:, columns], y, np.repeat(blocks, rows), [names[j] for j in columns],
                  np.repeat(owner, rows))
        if support is None:
            support, probability = model.support_, model.inclusion_probability_
        else:       # refine the kept coefficients: all of them, with their intervals
            model.set_support(np.ones(len(columns), dtype=bool))
        coef = np.zeros(len(names))
        ci95 = np.zeros((len(names), 2))
        coef[columns], ci95[columns] = model.coef_, model.ci95_
        ci95 = ci95 + np.array([[getattr(current, n) - getattr(params, n)] for n in names])
        current = current.replace(**{n: getattr(current, n) + coef[j]
                                     for j, n in enumerate(names) if support[j]})
    final = current
    error = measured - predicted(final, z0, controls, dt)
    return {
        'segment_s': length * dt,
        'prediction_rms': {'nominal': dict(zip(mmg.STATE_NAMES, nominal_rms.tolist(),
                                               strict=True)),
                           'corrected': dict(zip(mmg.STATE_NAMES, np.sqrt(np.mean(
                               error.reshape(-1, 3) ** 2, axis=0)).tolist(), strict=True))},
        'effective_sample_ratio': neff,
        'candidates': {n: {'nominal': float(getattr(params, n)),
                           'correction': float(getattr(final, n) - getattr(params, n)),
                           'ci95': [float(v) for v in ci95[j]] if support[j] else [0.0, 0.0],
                           'inclusion_probability': float(probability[j]),
                           'selected': bool(support[j])}
                       for j, n in enumerate(names)},
    }


def corrected(params: mmg.MmgParams, found: Mapping[str, dict]) -> mmg.MmgParams:
    """Return the nominal parameters with the selected corrections applied."""
    changes = {n: v['nominal'] + v['correction'] for n, v in found.items() if v['selected']}
    return params.replace(**changes) if changes else params


def forecast_rmse(params: mmg.MmgParams, runs: Sequence[MmgRun], dt: float, horizon: int,
                  stride: int) -> dict[str, float]:
    """RMSE per state of forecasts over ``horizon`` samples started every ``stride``."""
    starts = [(run, k) for run in runs for k in range(0, len(run.z) - horizon, stride)]
    if not starts:
        raise RecordingsError(f'no held-out run is longer than the horizon ({horizon * dt} s)')
    z0 = np.stack([run.z[k] for run, k in starts])
    controls = np.stack([run.c[k:k + horizon] for run, k in starts])
    truth = np.stack([run.z[k:k + horizon + 1] for run, k in starts])
    err = mmg.simulate(params, z0, controls, dt, substeps(dt)) - truth
    return dict(zip(mmg.STATE_NAMES, np.sqrt(np.mean(err ** 2, axis=(0, 1))).tolist(),
                    strict=True))


def held_out(runs: Sequence[MmgRun]) -> tuple[list[MmgRun], list[MmgRun], str]:
    """Return (diagnosis runs, held-out runs, how): the test split, else a seeded share."""
    test = [r for r in runs if r.split == 'test']
    if test and len(test) < len(runs):
        return [r for r in runs if r.split != 'test'], test, 'the dataset test split'
    if len(runs) < 2:
        raise RecordingsError('the MMG diagnosis holds out whole runs and needs at least two')
    split = split_runs([r.run_id for r in runs], HOLDOUT_SEED,
                       (1.0 - HOLDOUT_FRACTION, 0.0, HOLDOUT_FRACTION))
    chosen = set(split['test'])
    return ([r for r in runs if r.run_id not in chosen], [r for r in runs if r.run_id in chosen],
            f'a seeded {HOLDOUT_FRACTION:.0%} of the runs (seed {HOLDOUT_SEED})')


def verdict(found: Mapping[str, dict], settings: MmgSettings) -> str:
    """Say in one sentence whether a parameter correction, an effect, or nothing was found."""
    kinds = {c.name: c.kind for c in settings.candidates}
    chosen = [n for n, v in found.items() if v['selected']]
    if not chosen:
        return 'nothing: no candidate is selected often enough'
    parts = []
    for kind, label in (('parameter', 'parameter corrections of the standard method'),
                        ('effect', 'effects outside the standard method')):
        names = [n for n in chosen if kinds[n] == kind]
        if names:
            parts.append(f'{label} ({", ".join(names)})')
    return ' and '.join(parts)


def diagnose_mmg(dataset: str | Path, out: str | Path, settings: MmgSettings | None = None,
                 params_file: str | Path | None = None,
                 say: Callable[[str], None] | None = None, scale_check: bool = True) -> dict:
    """
    Run the MMG-family diagnosis on a dataset; write findings.json and report.md.

    The recordings' scale is checked against the vessel file first (the thresholds of
    ``scale_check`` in diagnosis.yaml); ``scale_check=False`` only records the figures.
    """
    say = say or (lambda message: None)
    settings = settings or load_mmg_settings()
    out = Path(out)
    vessel, nominal, source, runs = load_mmg_runs(dataset, params_file)
    cfg = load_settings().scale_check
    scale = (check_scale if scale_check else scale_figures)(runs, vessel, cfg,
                                                            mmg.STATE_NAMES)
    dt = 1.0 / vessel.rate_hz
    diag, held, how = held_out(runs)
    excluded = excluded_categories(vessel)
    names = [c.name for c in settings.candidates if c.category not in excluded]
    say(f'identifying on {len(diag)} runs ({len(names)} candidates), '
        f'holding out {len(held)} ({how})')
    ident = identify(nominal, diag, dt, settings, names)
    augmented = corrected(nominal, ident['candidates'])
    say('forecasting the held-out runs with the nominal and the augmented physics')
    horizon, stride = vessel.horizon, int(round(settings.forecast_stride_s / dt))
    before = forecast_rmse(nominal, held, dt, horizon, stride)
    after = forecast_rmse(augmented, held, dt, horizon, stride)
    change = {s: after[s] / before[s] - 1.0 for s in before}
    improved = bool(np.mean(list(change.values())) <= -settings.min_improvement)
    result = {
        'family': 'mmg', 'vessel': vessel.name, 'nominal_physics': source,
        'recordings': {'dataset': str(dataset), 'diagnosis_runs': [r.run_id for r in diag],
                       'held_out_runs': [r.run_id for r in held], 'held_out_how': how},
        'scale_check': {**scale, 'checked': scale_check},
        'excluded': excluded, 'candidates_tried': names,
        'identification': ident, 'verdict': verdict(ident['candidates'], settings),
        'held_out_forecast_rmse': {'horizon_s': horizon * dt, 'nominal': before,
                                   'augmented': after, 'relative_change': change},
        'augmented_written': improved,
    }
    out.mkdir(parents=True, exist_ok=True)
    if improved:
        write_params(augmented, out / 'augmented_mmg.yaml', source, result['verdict'])
    (out / 'findings.json').write_text(json.dumps(result, indent=2))
    (out / 'report.md').write_text(report(result, settings))
    return result


def write_params(params: mmg.MmgParams, path: Path, source: str, why: str) -> Path:
    """Write an MMG parameter file that ``load_mmg`` reads back exactly."""
    values = {'format': mmg.FORMAT, 'description': f'{source} corrected by the diagnosis: '
              f'{why}'}
    for f in fields(mmg.MmgParams):
        value = getattr(params, f.name)
        values[f.name] = value if isinstance(value, str) else float(value)
    values['name'] = f'{params.name}_augmented'
    path.write_text(yaml.safe_dump(values, sort_keys=False))
    return path


def report(result: Mapping, settings: MmgSettings) -> str:
    """Return the Markdown report of an MMG-family diagnosis."""
    kinds = {c.name: c for c in settings.candidates}
    ident, rmse = result['identification'], result['held_out_forecast_rmse']
    lines = [f'# Diagnosis of {result["vessel"]} (MMG standard model)', '',
             f'Nominal physics: `{result["nominal_physics"]}`. Held out: '
             f'{", ".join(result["recordings"]["held_out_runs"])} '
             f'({result["recordings"]["held_out_how"]}).', '',
             f'**Found: {result["verdict"]}.**', '',
             f'Scale: Froude number {result["scale_check"]["froude"]:.2f} and turning rate '
             f'r L / U {result["scale_check"]["turning_rate"]:.2f} for length_m '
             f'{result["scale_check"]["length_m"]:g}'
             f'{"" if result["scale_check"]["checked"] else " (check skipped)"}.', '',
             '## What cannot exist here', '']
    lines += [f'- {category}: {why}' for category, why in result['excluded'].items()]
    lines += ['', '## Candidates', '',
              f'Prediction error over {ident["segment_s"]:g} s from measured states, RMS '
              f'nominal -> corrected: ' + ', '.join(
                  f'{s} {v:.3g} -> {ident["prediction_rms"]["corrected"][s]:.3g}'
                  for s, v in ident['prediction_rms']['nominal'].items()) + '.', '',
              '| candidate | kind | category | nominal | correction | 95 % interval | '
              'P(included) | kept |', '|---|---|---|---|---|---|---|---|']
    for name, v in ident['candidates'].items():
        c = kinds[name]
        lines.append(f'| {name} | {c.kind} | {c.category} | {v["nominal"]:.4g} | '
                     f'{v["correction"]:+.4g} | [{v["ci95"][0]:+.4g}, {v["ci95"][1]:+.4g}] | '
                     f'{v["inclusion_probability"]:.2f} | {"yes" if v["selected"] else ""} |')
    lines += ['', f'## Held-out forecasts over {rmse["horizon_s"]:g} s', '',
              '| state | nominal RMSE | augmented RMSE | change |', '|---|---|---|---|']
    for s, before in rmse['nominal'].items():
        lines.append(f'| {s} | {before:.4g} | {rmse["augmented"][s]:.4g} | '
                     f'{100 * rmse["relative_change"][s]:+.1f} % |')
    lines += ['', ('The augmented parameters improve the held-out forecasts: written to '
                   '`augmented_mmg.yaml`.') if result['augmented_written'] else
              (f'The augmented parameters do not improve the held-out forecasts by '
               f'{settings.min_improvement:.0%} on average: no augmented file is written.'), '']
    return '\n'.join(lines)
