"""
The whole improvement workflow: diagnose, augment the physics, retrain the hybrid, compare.

Per fold of whole recordings (``hybrid_models.studies.crossval``), the diagnosis sees the
fold's training runs and judges its augmented physics on the fold's validation runs
(never on the fold's test runs, which no step of the workflow sees before the final
comparison). Then the hybrid of one config is trained on the nominal physics and on that
fold's augmented physics, beside an LSTM baseline, each with every seed, and all are
compared on the held-out runs with the physics alone: nominal physics, augmented
physics, the hybrid on each, the LSTM, and the do-no-harm check of each hybrid against
its own physics; with two seeds or more, the two hybrids seed by seed (an order, or a
tie).
"""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

from hybrid_models.studies.crossval import Fold, ModelPlan
from hybrid_models.studies.paired import paired_rows, paired_table
from vessel_datasets.format import Dataset, resplit

NOMINAL, AUGMENTED, LSTM = 'hybrid on nominal physics', 'hybrid on augmented physics', 'lstm'


def augmented_physics_file(report_dir: Path) -> Path | None:
    """Return the augmented physics file a diagnosis wrote into ``report_dir``, if any."""
    findings = json.loads((Path(report_dir) / 'findings.json').read_text())
    written = findings.get('augmented_physics')    # every family: the files written, or None
    return Path(report_dir) / written['physics'] if written else None


def diagnose_fold(dataset: Dataset, fold: Fold, physics: str | None, out: Path,
                  diagnose_main) -> dict:
    """
    Diagnose one fold: identify on its training runs, judge on its validation runs.

    ``diagnose_main`` is the diagnose program's ``main`` (argv -> exit code). Returns
    {'report', 'exit', 'augmented' (a path, or None when nothing improved), 'summary'}.
    """
    view = resplit(dataset, out / 'view', {'train': fold.train, 'test': fold.val},
                   f'fold {fold.index} for the diagnosis: its validation runs held out')
    report = out / 'diagnosis'
    argv = ['--recordings', str(view.root), '--out', str(report), '--quiet']
    if physics is not None:
        argv += ['--physics', str(physics)]
    said = io.StringIO()
    with contextlib.redirect_stdout(said):
        code = diagnose_main(argv)
    augmented = augmented_physics_file(report) if (report / 'findings.json').is_file() \
        else None
    return {'report': str(report / 'report.md'), 'exit': code,
            'augmented': None if augmented is None else str(augmented),
            'summary': said.getvalue().strip()}


def plan(hybrid_config: Path, lstm_config: Path | None, nominal: str,
         augmented: dict[int, str], common: list[str] = (),
         warm_start: bool = True) -> list[ModelPlan]:
    """
    Return the models the workflow compares: the hybrid on each physics, the LSTM.

    ``augmented`` maps a fold's index to its augmented physics file (the nominal one
    where the diagnosis wrote none); ``common`` overrides every model's config.
    ``warm_start``: the hybrid on the augmented physics starts from the recurrent layers
    of the hybrid on the nominal physics of its fold and seed (its correction still
    starts at zero): on the KVLCC2 folds the correction then learns what the better
    physics leaves (docs/results/real/kvlcc2/README.md, issue #23).
    """
    def physics(path: str) -> list[str]:
        return [*common, 'model.physical.kind=physics', f'model.physical.physics={path}']

    models = [ModelPlan(NOMINAL, hybrid_config, physics(nominal)),
              ModelPlan(AUGMENTED, hybrid_config, lambda f: physics(augmented[f.index]),
                        start_from=NOMINAL if warm_start else None)]
    if lstm_config is not None:
        models.append(ModelPlan(LSTM, lstm_config, list(common)))
    return models


def nominal_physics(dataset: Dataset, given: str | None) -> str:
    """Return the nominal physics: the one given, else the one the vessel file names."""
    physics = given or dataset.vessel.physics
    if physics is None:
        raise ValueError(f'vessel {dataset.vessel.name!r} names no physics file (key '
                         f'physics: in its vessel file); give --physics NOMINAL.yaml')
    return str(physics)


def seed_by_seed(rows: list[dict]) -> tuple[dict | None, list[str]]:
    """
    Compare the hybrid on augmented and on nominal physics seed by seed.

    ``rows`` are a study's result rows. Returns the comparison
    (``hybrid_models.studies.paired``) and the report's section on it; (None, []) when
    either hybrid has fewer than two seeds, which cannot tell an order from a tie.
    """
    by_label = {row['label']: row for row in rows}
    if any(len(by_label.get(label, {}).get('per_seed_metrics') or []) < 2
           for label in (AUGMENTED, NOMINAL)):
        return None, []
    paired = paired_rows(by_label[AUGMENTED], by_label[NOMINAL])
    return paired, [f'## Seed by seed: {AUGMENTED} (first) against {NOMINAL}', '',
                    'Seed k of one is paired with seed k of the other (same folds, '
                    'validation runs and seed). A difference whose p-values exceed 0.05 '
                    'is a tie between the two, not an order.', '', *paired_table(paired)]
