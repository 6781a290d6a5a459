r"""
Diagnose, augment the physics, retrain the hybrid on it and compare: the whole workflow.

    python offline/workflow.py --dataset DIR --hybrid HYBRID.yaml --lstm LSTM.yaml \\
        --seeds 5 --folds 5 --out RESULTS [--physics NOMINAL.yaml]
    ros2 run vessel_diagnosis workflow ...        # the same program, installed

For every fold of whole recordings (--folds K: each recording held out once; without
it, the dataset's own split), the diagnosis identifies what the nominal physics lacks on
the fold's training runs and keeps the augmented physics only if it forecasts the
fold's validation runs better. The hybrid of --hybrid (its physical part replaced by
the nominal physics, then by that fold's augmented physics; any family's physics file)
and the LSTM baseline of --lstm are trained with every seed on every fold, and all are
compared on the held-out runs: nominal physics alone, augmented physics alone, the
hybrid on each, the LSTM. Each hybrid seed is checked against its own physics at every
reported horizon step (do no harm). The hybrid on the augmented physics starts from
the recurrent layers of the one on the nominal physics of its fold and seed (its
correction starts at zero all the same; --cold-start: from scratch).

Writes into --out: report.md (the table, what each fold's diagnosis found, the check
and, with two seeds or more, the two hybrids compared seed by seed), table.md,
results.json, position_error_over_horizon.png, folds/ (views and each fold's
diagnosis report) and runs/ (the trainings; a second call keeps finished ones). Exit
codes: 0 done, 1 bad input or a failed training, 2 bad arguments.
"""

import argparse
from pathlib import Path
import sys

import torch

from hybrid_models.checkpoint import CheckpointError
from hybrid_models.cli.crossval import (
    add_plan_options,
    folds_of,
    run_plan,
    stopwatch,
    write_study,
)
from vessel_datasets.format import DatasetError, read_dataset
from vessel_diagnosis import cli as diagnose_cli
from vessel_diagnosis.workflow import diagnose_fold, nominal_physics, plan, seed_by_seed

PROG = 'workflow'


def parse_args(argv):
    """Return the parsed command line."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, type=Path, help='dataset directory')
    parser.add_argument('--out', required=True, type=Path, help='results directory')
    parser.add_argument('--hybrid', required=True, type=Path,
                        help='training config of the hybrid (its physics is replaced)')
    parser.add_argument('--lstm', type=Path, help='training config of the LSTM baseline')
    parser.add_argument('--physics', help="nominal physics file (default: the one the "
                                          "dataset's vessel file names)")
    parser.add_argument('--cold-start', action='store_true',
                        help='train the hybrid on the augmented physics from scratch '
                             '(default: from the recurrent layers of the hybrid on the '
                             'nominal physics of its fold and seed)')
    add_plan_options(parser)
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error('--seeds must be at least 1')
    return args


def main(argv=None) -> int:
    """Diagnose each fold, train, compare, report; return the exit code."""
    args = parse_args(argv)
    say = stopwatch()
    torch.set_num_threads(args.threads)
    try:
        dataset = read_dataset(args.dataset)
        nominal = nominal_physics(dataset, args.physics)
        folds = folds_of(dataset, args)
        diagnoses = {}
        for fold in folds:
            say(f'diagnosing fold {fold.index} ({len(fold.train)} training runs, judged on '
                f"{len(fold.val)} validation run{'' if len(fold.val) == 1 else 's'})")
            diagnoses[fold.index] = diagnose_fold(dataset, fold, args.physics,
                                                  args.out / 'folds' / f'fold{fold.index}',
                                                  diagnose_cli.main)
            if diagnoses[fold.index]['exit'] not in (diagnose_cli.EXIT_OK,
                                                     diagnose_cli.EXIT_INSUFFICIENT):
                raise ValueError(f'the diagnosis of fold {fold.index} failed (exit '
                                 f"{diagnoses[fold.index]['exit']}); see "
                                 f"{diagnoses[fold.index]['report']}")
            say(f"fold {fold.index}: {diagnoses[fold.index]['summary']}")
        augmented = {k: d['augmented'] or nominal for k, d in diagnoses.items()}
        models = plan(args.hybrid.resolve(), args.lstm and args.lstm.resolve(), nominal,
                      augmented, args.set, warm_start=not args.cold_start)
        result = run_plan(args, models, folds, say)
    except (DatasetError, CheckpointError, ValueError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    if result is None:
        return 1
    result['diagnoses'] = diagnoses
    result['nominal_physics'] = nominal
    result['paired'], paired_section = seed_by_seed(result['rows'])
    # The report sits in --out: the folds' own reports are named relative to it.
    found = [f"- fold {k}: {(d['summary'] or 'no summary').replace(f'{args.out}/', '')}"
             + ('' if d['augmented'] else ' (no augmented physics: the hybrid on augmented '
                                          'physics is the one on nominal physics)')
             for k, d in diagnoses.items()]
    intro = [f'Dataset `{args.dataset}`; nominal physics `{nominal}`; hybrid config '
             f'`{args.hybrid}`' + (f', LSTM config `{args.lstm}`' if args.lstm else '') + '.',
             '', 'What the diagnosis found on each fold (identified on its training runs, '
             'judged on its validation runs):', '', *found, '']
    print(write_study(args.out, result, dataset.vessel,
                      f'Diagnose, augment, retrain: {dataset.vessel.name}', intro,
                      paired_section))
    return 0


if __name__ == '__main__':
    sys.exit(main())
