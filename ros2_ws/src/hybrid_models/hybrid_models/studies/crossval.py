"""
Cross-validated, seeded comparisons of models on whole recordings.

A plan is folds x models x seeds. With ``folds=K`` every recording is in the test set of
exactly one fold (K groups of a seeded shuffle of the recordings; runs cut from one
recording stay together), a share of the others validates and the rest trains; with
``folds=None`` the dataset's own split is the one fold. A fold is a view of the dataset
(``vessel_datasets.format.resplit``): nothing is copied.

``train_plan`` trains every (model, fold, seed) as a resumable process of its own
(``training.jobs``), a few at a time. ``ensemble_plan`` packs each hybrid's seeds of a
fold into the ensemble a user would serve (``training.ensemble``: its threshold and
bands chosen on the fold's validation runs). ``evaluate_plan`` forecasts each fold's
test runs with that fold's models and pools the folds, so every figure is over all
held-out runs; a model's row is the mean ± sd over its seeds (``evaluation.seed_row``),
an ensemble's row follows its model's, every distinct physics of the hybrids gets a row
of its own, and each hybrid seed and ensemble is checked against its own physics at
every reported horizon step (``selection.harms``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field
import json
from pathlib import Path
import re
import sys

import numpy as np

from hybrid_models import report
from hybrid_models.checkpoint import CheckpointError, load_model, read_header
from hybrid_models.cross_bands import HeldOut
from hybrid_models.data import evaluation_protocol, forecast_windows, load_runs
from hybrid_models.ensemble import is_hybrid
from hybrid_models.evaluation import PhysicsOnly, seed_row
from hybrid_models.metrics import StepErrors, forecast_metrics
from hybrid_models.models import predict
from hybrid_models.physical.identity import physics_identity, physics_label
from hybrid_models.selection import harms
from hybrid_models.training.ensemble import serve_ensemble
from hybrid_models.training.jobs import train_job
from hybrid_models.training.train import MODEL_FILE
from vessel_datasets.format import Dataset, read_dataset, resplit

RESULTS_FILE = 'results.json'
ENSEMBLE = 'ensemble'   # the key of a model's ensemble beside its seeds' numbers


@dataclass(frozen=True)
class Fold:
    """One fold: its dataset view and the runs of each split."""

    index: int
    path: Path
    train: tuple[str, ...]
    val: tuple[str, ...]
    test: tuple[str, ...]

    def describe(self) -> dict:
        """Return the fold as JSON-ready data."""
        return {'index': self.index, 'path': str(self.path), 'train': list(self.train),
                'val': list(self.val), 'test': list(self.test)}


@dataclass(frozen=True)
class ModelPlan:
    """
    A model to train on every fold: a config and its overrides (fixed, or per fold).

    ``start_from`` names another model of the plan whose training of the same fold and
    seed starts this one's recurrent layers (``training.init_from``); it trains first.
    """

    label: str
    config: Path
    overrides: Sequence[str] | Callable[[Fold], Sequence[str]] = field(default=())
    start_from: str | None = None

    def overrides_for(self, fold: Fold) -> list[str]:
        """Return the config overrides of this model on ``fold``."""
        return list(self.overrides(fold) if callable(self.overrides) else self.overrides)


def make_folds(dataset: Dataset, out: Path, folds: int | None, seed: int = 0,
               val_fraction: float = 0.1, fold_by: str | None = None,
               min_val_samples: int = 0, balance: str = 'samples') -> list[Fold]:
    """
    Write the fold views under ``out/folds`` and return them.

    ``folds`` None keeps the dataset's split (one fold). Otherwise recordings are
    shuffled with ``seed`` and dealt into ``folds`` test groups of about as many samples
    as whole recordings allow (``balance`` 'samples': the longest recording first, each
    into the group with the fewest samples so far, as scikit-learn's GroupKFold deals
    groups), or of as many recordings ('recordings': a few long recordings can then
    make one fold hold a third of the data). ``fold_by`` (a regular
    expression) instead makes one fold per distinct match in the recordings' names, e.g.
    one per kind of manoeuvre; recordings it does not match always train. Of each fold's
    other recordings, ``val_fraction`` (at least one) validate and the rest train; a
    validating recording needs a run of ``min_val_samples`` (a window and its horizon:
    training selects on validation forecasts), so shorter ones train.
    """
    if folds is None and fold_by is None:
        splits = [{name: dataset.run_ids(name) for name in ('train', 'val', 'test')}]
        notes = ["the dataset's own split"]
    else:
        recordings = dataset.recordings()
        if not 0 < val_fraction < 1:
            raise ValueError(f'val_fraction must be in (0, 1), got {val_fraction}')
        names = sorted(recordings)
        order = [names[i] for i in np.random.default_rng(seed).permutation(len(names))]
        groups, notes = _test_groups(order, folds, fold_by, dataset, balance)
        splits = []
        for k, test in enumerate(groups):
            rest = [r for r in order if r not in test]
            rest = [rest[i] for i in np.random.default_rng([seed, k]).permutation(len(rest))]
            rest = _long_enough_first(rest, recordings, dataset, min_val_samples, k)
            n_val = max(1, round(val_fraction * len(rest)))
            runs = {name: sorted(run for rec in recs for run in recordings[rec])
                    for name, recs in (('test', test), ('val', rest[:n_val]),
                                       ('train', rest[n_val:]))}
            splits.append(runs)
    out_folds = []
    for k, (split, note) in enumerate(zip(splits, notes, strict=True)):
        path = fold_dir(out, k)
        resplit(dataset, path, split, note)
        out_folds.append(Fold(k, path, *(tuple(split[s]) for s in ('train', 'val', 'test'))))
    return out_folds


def fold_dir(out: Path, index: int) -> Path:
    """Return where ``make_folds`` writes the view of fold ``index`` of a study in ``out``."""
    return Path(out) / 'folds' / f'fold{index}'


def _long_enough_first(names: list[str], recordings: dict[str, list[str]], dataset: Dataset,
                       min_samples: int, fold: int) -> list[str]:
    """Reorder ``names`` so recordings with a run of ``min_samples`` come first."""
    samples = run_samples(dataset)
    longest = {name: max(samples[run] for run in recordings[name]) for name in names}
    long = [name for name in names if longest[name] >= min_samples]
    if not long:
        raise ValueError(f'fold {fold}: no recording outside its test runs has a run of '
                         f'{min_samples} samples (a forecast window) to validate on; use '
                         f'fewer folds or a shorter window or horizon')
    return long + [name for name in names if longest[name] < min_samples]


def _test_groups(order: list[str], folds: int | None, fold_by: str | None,
                 dataset: Dataset, balance: str) -> tuple[list[list[str]], list[str]]:
    """Return the recordings each fold tests, and what each fold is."""
    if fold_by is not None:
        pattern = re.compile(fold_by)
        keys = {rec: m.group(0) for rec in order if (m := pattern.search(Path(rec).name))}
        kinds = sorted(set(keys.values()))
        if len(kinds) < 2:
            raise ValueError(f'--fold-by {fold_by!r} matches {len(kinds)} distinct kinds of '
                             f'recording in {dataset.root}; it needs at least 2')
        return ([[rec for rec in order if keys.get(rec) == kind] for kind in kinds],
                [f'fold of the recordings matching {kind!r} ({fold_by!r})' for kind in kinds])
    if not 2 <= folds <= len(order):
        raise ValueError(f'folds must be between 2 and the {len(order)} recordings of '
                         f'{dataset.root}, got {folds}')
    if balance == 'recordings':
        groups = [list(g) for g in np.array_split(np.asarray(order, dtype=object), folds)]
        return groups, [f'fold {k} of {folds} (recordings shuffled)' for k in range(folds)]
    if balance != 'samples':
        raise ValueError(f"balance must be 'recordings' or 'samples', got {balance!r}")
    size = recording_samples(dataset)
    groups, totals = [[] for _ in range(folds)], np.zeros(folds)
    # Longest first, ties in the shuffled order (a stable sort): each recording joins
    # the group with the fewest samples so far.
    for rec in sorted(order, key=lambda name: -size[name]):
        k = int(np.argmin(totals))
        groups[k].append(rec)
        totals[k] += size[rec]
    groups = [[rec for rec in order if rec in group] for group in groups]
    return groups, [f'fold {k} of {folds} (recordings shuffled, {int(totals[k])} samples)'
                    for k in range(folds)]


def run_samples(dataset: Dataset) -> dict[str, int]:
    """Return each run's samples, by run id."""
    return {r['id']: int(r['n_samples']) for r in dataset.manifest['runs']}


def recording_samples(dataset: Dataset) -> dict[str, int]:
    """Return each recording's samples, summed over its runs."""
    samples = run_samples(dataset)
    return {name: sum(samples[run] for run in runs)
            for name, runs in dataset.recordings().items()}


def run_dir(out: Path, label: str, fold: Fold, seed: int) -> Path:
    """Return where a (model, fold, seed) training writes (the label made a folder name)."""
    folder = re.sub(r'[^A-Za-z0-9_.+-]+', '_', label).strip('_') or 'model'
    return Path(out) / 'runs' / folder / f'fold{fold.index}' / f'seed{seed}'


def ensemble_path(out: Path, label: str, fold: Fold) -> Path:
    """Return where the ensemble of a model's seeds on ``fold`` is written."""
    return run_dir(out, label, fold, 0).parent / ENSEMBLE / MODEL_FILE


def ensemble_label(label: str, seeds: Sequence[int]) -> str:
    """Return the table label of a model's ensemble of ``seeds``."""
    return f'{label}, ensemble of {len(seeds)} seeds'


def packed_from(ensemble: Path, members: Sequence[Path]) -> bool:
    """Tell whether ``ensemble`` is a finished ensemble of exactly ``members``."""
    try:
        header = read_header(ensemble)
    except (CheckpointError, FileNotFoundError):
        return False
    return (header.get('ensemble') or {}).get('members') == [str(p) for p in members]


def ensemble_plan(models: Sequence[ModelPlan], folds: Sequence[Fold], seeds: Sequence[int],
                  out: Path, say: Callable[[str], None] = lambda m: print(m, file=sys.stderr)
                  ) -> list[str]:
    """
    Pack every hybrid's seeds of each fold into its ensemble; return the models packed.

    A finished ensemble of the same members is kept (a second call resumes); one of
    other members (a call with more seeds) is packed again. Models that are not hybrids
    have none.
    """
    packed = []
    for m in models:
        if not is_hybrid(load_model(run_dir(out, m.label, folds[0], seeds[0]) / MODEL_FILE)[0]):
            continue
        for f in folds:
            target = ensemble_path(out, m.label, f)
            members = [run_dir(out, m.label, f, s) / MODEL_FILE for s in seeds]
            if not packed_from(target, members):
                target.parent.mkdir(parents=True, exist_ok=True)
                serve_ensemble(members, f.path, target)
            say(f'ensemble of {len(seeds)} seeds: {m.label}/fold{f.index}')
        packed.append(m.label)
    return packed


def read_study(out: Path) -> tuple[list[Fold], dict]:
    """
    Return the folds of the finished study in ``out`` and its results (results.json).

    The fold views are read where ``make_folds`` wrote them under ``out``, so a study
    moved as a whole still reads.
    """
    path = Path(out) / RESULTS_FILE
    try:
        result = json.loads(path.read_text())
        folds = [Fold(int(f['index']), fold_dir(out, int(f['index'])),
                      *(tuple(f[s]) for s in ('train', 'val', 'test')))
                 for f in result['folds']]
    except FileNotFoundError:
        raise ValueError(f'{out} holds no finished study ({RESULTS_FILE} missing)') from None
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f'{path} is not the results of a study '
                         f'({type(exc).__name__}: {exc})') from None
    return folds, result


def study_models(result: dict) -> list[str]:
    """Return the labels of the models a study trained (its rows other than physics)."""
    return [row['label'] for row in result['rows'] if 'per_seed_metrics' in row]


def train_plan(models: Sequence[ModelPlan], folds: Sequence[Fold], seeds: Sequence[int],
               out: Path, jobs: int = 2, threads: int = 2,
               say: Callable[[str], None] = lambda m: print(m, file=sys.stderr)) -> list[dict]:
    """
    Train every (model, fold, seed), ``jobs`` at a time; return the trainings' summaries.

    Each seed trains one model whatever the config's ``training.members``: a study's seeds
    are the members of the ensemble it packs (``ensemble_plan``).
    """
    per_job = max(1, threads // max(jobs, 1))
    labels = {m.label for m in models}
    unknown = [m.start_from for m in models if m.start_from and m.start_from not in labels]
    if unknown:
        raise ValueError(f'start_from {unknown[0]!r} is not a model of the plan')

    def job(m: ModelPlan, f: Fold, s: int) -> tuple:
        start = [] if m.start_from is None else [
            f'training.init_from={run_dir(out, m.start_from, f, s) / MODEL_FILE}']
        return (f'{m.label}/fold{f.index}/seed{s}', m.config,
                m.overrides_for(f) + start + [f'dataset={f.path.resolve()}',
                                              f'training.seed={s}',
                                              f'training.threads={per_job}',
                                              'training.members=1'],
                run_dir(out, m.label, f, s))

    # The models others start from train in the first wave, those others in the second.
    waves = [[job(m, f, s) for f in folds for m in models for s in seeds
              if (m.start_from is None) == first] for first in (True, False)]
    total, results = sum(map(len, waves)), []
    with ThreadPoolExecutor(max(jobs, 1)) as pool:
        for wave in waves:
            for fut in as_completed([pool.submit(train_job, *args) for args in wave]):
                res = fut.result()
                results.append(res)
                say(f"trained {len(results)}/{total}: {res['label']} {res['status']}")
    return results


def evaluate_plan(models: Sequence[ModelPlan], folds: Sequence[Fold], seeds: Sequence[int],
                  out: Path, window: int | None = None, horizon: int | None = None,
                  stride: int | None = None, ensembles: Sequence[str] = ()) -> dict:
    """
    Forecast every fold's test runs with its models; pool the folds; return the results.

    The result holds the table rows (models, each followed by its ensemble when
    ``ensembles`` names it, then one per distinct physics), the mean position error at
    every horizon step per model and seed (for the figure), the protocol and the folds.
    """
    spec = read_dataset(folds[0].path).vessel
    window, horizon, stride = evaluation_protocol(spec, window, horizon, stride)
    preds: dict[tuple[str, int], list] = {}
    physics: dict[tuple[str, int], list] = {}   # (label, seed) -> per fold (fp, name, pred)
    targets, n_forecasts = [], 0
    for fold in folds:
        runs = load_runs(fold.path, 'test', spec)
        windows = forecast_windows(runs, window, horizon, stride, 'true')
        targets.append(windows.z_target)
        n_forecasts += len(windows)
        for m in models:
            paths = {s: run_dir(out, m.label, fold, s) / MODEL_FILE for s in seeds}
            if m.label in ensembles:
                paths[ENSEMBLE] = ensemble_path(out, m.label, fold)
            for s, path in paths.items():
                model, _ = load_model(path)
                preds.setdefault((m.label, s), []).append(predict(model, windows))
                if is_hybrid(model):
                    fp, name = physics_identity(model.physical)
                    physics.setdefault((m.label, s), []).append(
                        (fp, name, lambda w=windows, p=model.physical: predict(PhysicsOnly(p),
                                                                              w)))
    true = np.concatenate(targets)
    # One scale of each state for every model's state error: that of the held-out runs.
    scale = true.reshape(-1, true.shape[-1]).std(axis=0)
    rows, curves, physics_rows = [], {}, {}
    for m in models:
        metrics = []
        for s in seeds:
            pred = np.concatenate(preds[(m.label, s)])
            metrics.append(forecast_metrics(pred, true, spec, state_std=scale))
            curves.setdefault(m.label, []).append(_position_curve(pred, true, spec))
        row = seed_row(m.label, metrics) if len(seeds) > 1 else {
            'label': m.label, 'metrics': metrics[0]}
        row['per_seed_metrics'] = metrics
        if (m.label, seeds[0]) in physics:
            own = [_physics_pooled(physics[(m.label, s)], m.label, true, spec, physics_rows,
                                   curves, scale) for s in seeds]
            row['physics'] = sorted({p['label'] for p in own})
            row['harms_vs_physics'] = [harms(mm['profile'], p['metrics']['profile'])
                                       for mm, p in zip(metrics, own, strict=True)]
        rows.append(row)
        if m.label in ensembles:
            pred = np.concatenate(preds[(m.label, ENSEMBLE)])
            label = ensemble_label(m.label, seeds)
            own = _physics_pooled(physics[(m.label, ENSEMBLE)], m.label, true, spec,
                                  physics_rows, curves, scale)
            metrics = forecast_metrics(pred, true, spec, state_std=scale)
            curves[label] = [_position_curve(pred, true, spec)]
            rows.append({'label': label, 'metrics': metrics, 'ensemble_of': m.label,
                         'physics': [own['label']],
                         'harms_vs_physics': [harms(metrics['profile'],
                                                    own['metrics']['profile'])]})
    rows += list(physics_rows.values())
    return {'protocol': {'window': window, 'horizon': horizon, 'stride': stride,
                         'target': 'true', 'n_forecasts': n_forecasts,
                         'seeds': list(seeds), 'folds': len(folds)},
            'folds': [f.describe() for f in folds], 'rows': rows,
            'position_error_curves': curves}


def out_of_fold_forecasts(out: Path, label: str, spec, relative_threshold, window: int,
                          horizon: int, stride: int, seeds: Sequence[int] | None = None,
                          say: Callable[[str], None] = lambda m: None) -> list[HeldOut]:
    """
    Forecast every fold's test runs with that fold's hybrids of ``label``; return them.

    Each (fold, seed) model of the study in ``out`` is served at ``relative_threshold``
    (``HybridModel.served_at``) and forecasts its fold's test runs (one forecast every
    ``stride`` samples, ``window`` + ``horizon`` samples) against the measured states;
    ``seeds`` None takes every seed of the study. Refuse a label the study did not
    train, a model that is not a hybrid, a seed the study has not, fewer than 2 folds,
    a study of another vessel or rate than ``spec`` (the vessel the bands are for).
    """
    folds, result = read_study(out)
    labels, study_seeds = study_models(result), result['protocol']['seeds']
    if label not in labels:
        raise ValueError(f'{out} trained no model {label!r}; it trained {labels}')
    if len(folds) < 2:
        raise ValueError(f"{out} is a study of {len(folds)} fold (the dataset's own "
                         f'split): out-of-fold forecasts need at least 2 folds')
    seeds = list(study_seeds if seeds is None else seeds)
    unknown = sorted(set(seeds) - set(study_seeds))
    if unknown:
        raise ValueError(f'{out} trained seeds {study_seeds}, not {unknown}')
    read_dataset(folds[0].path).vessel.check_compatible(
        spec, f'the model given bands by study {out}')
    held_out = []
    for fold in folds:
        windows = forecast_windows(load_runs(fold.path, 'test', spec), window, horizon, stride)
        preds = []
        for s in seeds:
            model, _ = load_model(run_dir(out, label, fold, s) / MODEL_FILE)
            if not is_hybrid(model):
                raise ValueError(f'{label!r} of {out} is a {type(model).__name__}, not a '
                                 f'hybrid: only a hybrid is served at a threshold')
            with model.served_at(relative_threshold):
                preds.append(predict(model, windows))
            say(f'fold {fold.index} seed {s}: {len(windows)} forecasts of '
                f'{len(fold.test)} runs')
        held_out.append(HeldOut(fold.index, fold.test, np.concatenate(preds),
                                np.concatenate([windows.z_target] * len(seeds))))
    return held_out


def _position_curve(pred: np.ndarray, true: np.ndarray, spec) -> list[float]:
    errors = StepErrors.of(pred, true, spec)
    return (errors.position / errors.count).tolist()


def _physics_pooled(per_fold: list, owner: str, true: np.ndarray, spec,
                    physics_rows: dict, curves: dict, scale: np.ndarray) -> dict:
    """Return the pooled row of one seed's physics (per fold), made once per physics."""
    key = tuple(fp for fp, _, _ in per_fold)
    if key not in physics_rows:
        name = per_fold[0][1]
        label = physics_label(name, key[0], owner,
                              {row['label'] for row in physics_rows.values()})
        pred = np.concatenate([forecast() for _, _, forecast in per_fold])
        physics_rows[key] = {'label': label,
                             'metrics': forecast_metrics(pred, true, spec, state_std=scale),
                             'fingerprints': list(key)}
        curves[label] = [_position_curve(pred, true, spec)]
    return physics_rows[key]


def write_results(out: Path, result: dict, spec) -> None:
    """Write results.json, table.md and position_error_over_horizon.png into ``out``."""
    out = Path(out)
    (out / RESULTS_FILE).write_text(json.dumps(result, indent=2))
    (out / 'table.md').write_text(report.markdown_table(result['rows'], spec))
    report.plot_position_curves(out / 'position_error_over_horizon.png', spec,
                                result['position_error_curves'])


def harm_lines(rows: list[dict]) -> list[str]:
    """Return one Markdown line per hybrid: in how many seeds it is worse than its physics."""
    lines = []
    for row in rows:
        if 'harms_vs_physics' not in row:
            continue
        worse = [h for h in row['harms_vs_physics'] if h]
        if row.get('ensemble_of'):
            verdict = ('not worse than its physics at any reported step' if not worse else
                       f'worse than its physics ({"; ".join(worse[0][:3])} ...)')
        else:
            verdict = ('not worse than its physics at any reported step in any seed'
                       if not worse else
                       f'worse than its physics in {len(worse)} of '
                       f'{len(row["harms_vs_physics"])} seeds ({"; ".join(worse[0][:3])} ...)')
        lines.append(f'- {row["label"]} ({", ".join(row["physics"])}): {verdict}')
    return lines
