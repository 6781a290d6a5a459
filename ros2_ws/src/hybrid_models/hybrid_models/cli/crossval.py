r"""
Compare models over seeds and over folds of whole recordings, each held out once.

    python offline/crossval.py --dataset DIR --out RESULTS --seeds 5 --folds 5 \\
        --model hybrid=docs/results/real/configs/hybrid_mmg.yaml \\
        --model lstm=docs/results/real/configs/lstm.yaml
    ros2 run hybrid_models crossval ...          # the same program, installed

Without --folds the dataset's own split is used (one fold). With --folds K the
recordings are dealt into K test groups of about equal samples (a seeded shuffle, the
longest recordings first; runs cut from one recording stay together; --fold-balance
recordings deals equal counts instead), and of the other recordings --val-fraction
validate and the rest train, so every recording is forecast by models that never saw
it. Every model is trained with every seed on every fold (resumable: a finished
training is kept, a killed one continues), --jobs at a time. Test forecasts of all
folds are pooled; a row is the mean ± standard deviation over the seeds. With two or
more seeds, each hybrid's seeds of a fold are also served as one ensemble (the mean of
their corrections, its threshold and bands chosen on the fold's validation runs; what
`training.members` trains), compared in a row of its own. Every distinct physics of
the hybrids gets a row, and each hybrid seed and ensemble is checked against its own
physics at every reported horizon step.

Writes into --out: report.md, table.md, results.json (every number, per seed and per
fold), position_error_over_horizon.png, folds/ (the fold views) and runs/ (the
trainings). Exit codes: 0 done, 1 a training or an input failed, 2 bad arguments.
"""

import argparse
from collections.abc import Callable
import math
from pathlib import Path
import sys
import time

import torch

from hybrid_models.checkpoint import CheckpointError
from hybrid_models.data import evaluation_protocol
from hybrid_models.studies.crossval import (
    ModelPlan,
    ensemble_plan,
    evaluate_plan,
    harm_lines,
    make_folds,
    train_plan,
    write_results,
)
from vessel_datasets.format import DatasetError, read_dataset

PROG = 'crossval'
# A fold with this many training recordings can spare a second one to validate.
MIN_TRAIN_FOR_TWO_VAL = 4


def labelled(text: str) -> tuple[str, str]:
    """Parse LABEL=VALUE for argparse."""
    label, sep, value = text.partition('=')
    if not sep or not label or not value:
        raise argparse.ArgumentTypeError(f'expected LABEL=VALUE, got {text!r}')
    return label, value


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser (the workflow program adds its own options)."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, type=Path, help='dataset directory')
    parser.add_argument('--out', required=True, type=Path, help='results directory')
    add_plan_options(parser)
    parser.add_argument('--model', action='append', required=True, type=labelled,
                        metavar='LABEL=CONFIG', help='a model to compare (repeatable)')
    return parser


def add_plan_options(parser: argparse.ArgumentParser) -> None:
    """Add the options every cross-validated comparison takes."""
    parser.add_argument('--seeds', type=int, default=5,
                        help='trainings per model and fold, seeds 0..N-1 (default 5)')
    parser.add_argument('--folds', type=int,
                        help="hold each recording out once in K folds (default: the "
                             "dataset's own split)")
    parser.add_argument('--fold-by', metavar='REGEX',
                        help="one fold per distinct match of REGEX in the recordings' "
                             "names, e.g. one per kind of manoeuvre (instead of --folds)")
    parser.add_argument('--fold-balance', choices=('samples', 'recordings'),
                        default='samples',
                        help='deal each fold about as many samples as whole recordings '
                             'allow (default), or as many recordings')
    parser.add_argument('--val-fraction', type=float, default=0.1,
                        help="share of a fold's other recordings that validate (0.1; "
                             'with few recordings give one that lets two validate)')
    parser.add_argument('--fold-seed', type=int, default=0,
                        help='seed of the shuffle that deals recordings into folds (0)')
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='config override for every training (repeatable)')
    parser.add_argument('--no-ensemble', dest='ensemble', action='store_false',
                        help="skip each hybrid's ensemble of its seeds (by default, with 2 "
                             "or more seeds, each fold's seeds are also served as one "
                             "ensemble, chosen on the fold's validation runs, and compared "
                             "as a row of its own)")
    parser.add_argument('--jobs', type=int, default=2, help='trainings at a time (2)')
    parser.add_argument('--threads', type=int, default=2, help='cores to use in total (2)')
    for name, what in (('window', 'initialization window'), ('horizon', 'forecast length'),
                       ('stride', 'samples between forecast starts')):
        parser.add_argument(f'--{name}', type=int,
                            help=f"{what} of test forecasts (samples; default: the vessel's)")


def folds_of(dataset, args) -> list:
    """
    Write and return the folds the plan options (``add_plan_options``) ask for.

    A validating run needs one forecast's window and horizon, the test forecasts' own.
    """
    window, horizon, _ = evaluation_protocol(dataset.vessel, args.window, args.horizon, 1)
    folds = make_folds(dataset, args.out, args.folds, args.fold_seed, args.val_fraction,
                       args.fold_by, window + horizon, args.fold_balance)
    # Epochs and the served threshold are chosen on the validation runs, and do no harm
    # can weigh a difference against its spread only across two runs or more: on one,
    # noise decided (KVLCC2 five folds, docs/results/real/kvlcc2/README.md).
    # Folds deal whole recordings (a recording may hold several runs): count those.
    recording_of = {run: rec for rec, runs in dataset.recordings().items() for run in runs}

    def recordings(runs) -> int:
        return len({recording_of[run] for run in runs})

    single = [f for f in folds if recordings(f.val) == 1
              and recordings(f.train) >= MIN_TRAIN_FOR_TWO_VAL]
    if single and (args.folds is not None or args.fold_by is not None):
        # The smallest fold's share gives two to every fold.
        others = min(recordings(f.train + f.val) for f in single)
        print(f'warning: fold(s) {", ".join(str(f.index) for f in single)} validate on one '
              'recording, so epochs and thresholds are chosen on that run alone; '
              f'--val-fraction {math.ceil(200 / others) / 100:g} lets two validate',
              file=sys.stderr)
    return folds


def stopwatch() -> Callable[[str], None]:
    """Return a function that prints a message on stderr after the minutes since now."""
    start = time.monotonic()

    def say(message: str) -> None:
        print(f'[{(time.monotonic() - start) / 60:5.1f} min] {message}', file=sys.stderr,
              flush=True)
    return say


def run_plan(args, models: list[ModelPlan], folds, say) -> dict | None:
    """Train and evaluate a plan; return the results, None when a training failed."""
    seeds = list(range(args.seeds))
    trainings = train_plan(models, folds, seeds, args.out, args.jobs, args.threads, say)
    failed = [t for t in trainings if t['status'] not in ('ok', 'kept')]
    if failed:
        print(f"{PROG}: error: {failed[0]['label']}: {failed[0]['status']}", file=sys.stderr)
        return None
    ensembles = (ensemble_plan(models, folds, seeds, args.out, say)
                 if args.ensemble and len(seeds) > 1 else [])
    say('forecasting the held-out runs')
    result = evaluate_plan(models, folds, seeds, args.out, args.window, args.horizon,
                           args.stride, ensembles)
    result['trainings'] = trainings
    return result


def write_study(out: Path, result: dict, spec, title: str, intro: list[str],
                sections: list[str] = ()) -> str:
    """Write results.json, table.md, the figure and report.md into ``out``; return the table."""
    write_results(out, result, spec)
    table = (out / 'table.md').read_text()
    (out / 'report.md').write_text(report_text(title, result, table, intro, sections))
    return table


def report_text(title: str, result: dict, table: str, intro: list[str],
                sections: list[str] = ()) -> str:
    """Return report.md: what was compared how, the table, the do-no-harm check, sections."""
    p = result['protocol']
    folds = ("the dataset's own split" if p['folds'] == 1 else
             f"{p['folds']} folds, every recording in one of them held out once")
    lines = [f'# {title}', '', *intro,
             f"Test forecasts: {p['n_forecasts']} of {p['horizon']} steps (one every "
             f"{p['stride']} samples after a {p['window']}-sample window), pooled over "
             f"{folds}; {len(p['seeds'])} seeds per model (mean ± sd over seeds).", '',
             table, '## Do no harm on the held-out runs', ''] + harm_lines(result['rows'])
    if sections:
        lines += ['', *sections]
    return '\n'.join(lines + ['', 'Every number: results.json; figure: '
                              'position_error_over_horizon.png.', ''])


def main(argv=None) -> int:
    """Parse arguments, train, evaluate, report; return the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    labels = [label for label, _ in args.model]
    if len(set(labels)) != len(labels) or args.seeds < 1:
        parser.error(f'give distinct model labels and --seeds >= 1 (labels {labels})')
    say = stopwatch()
    torch.set_num_threads(args.threads)
    try:
        dataset = read_dataset(args.dataset)
        spec = dataset.vessel
        folds = folds_of(dataset, args)
        models = [ModelPlan(label, Path(config).resolve(), args.set)
                  for label, config in args.model]
        result = run_plan(args, models, folds, say)
    except (DatasetError, CheckpointError, ValueError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 1
    if result is None:
        return 1
    print(write_study(args.out, result, spec, f'Cross-validated comparison on {spec.name}',
                      [f'Dataset `{args.dataset}`; models: ' + ', '.join(
                          f'{label} (`{config}`)' for label, config in args.model) + '.', '']))
    return 0


if __name__ == '__main__':
    sys.exit(main())
