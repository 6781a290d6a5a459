r"""
Train the same hybrid on different physics; compare the relative threshold each needs.

    python offline/compare_physics.py --dataset DIR --out RESULTS \\
        --physics nominal=DIR/nominal_physics.yaml augmented=DIAG/augmented_physics.yaml

The question it answers: does better physics (e.g. the augmented physics that
``offline/diagnose.py`` writes) let the LSTM's share shrink? For each physics file it
trains the hybrid of ``--config`` (default the 2P hybrid) with that physics as its
physical part (``model.physical.kind=physics``), resumable, ``--jobs`` at a time. Then on
the test runs it sweeps the relative threshold at inference (0 = physics alone) and
reports, per physics, the smallest threshold whose per-state RMSE is within
``--tolerance`` (5 %) of (a) the FIRST physics' unconstrained hybrid, i.e. the same
accuracy for every physics, and (b) its own unconstrained hybrid.

Writes into --out: report.md, results.json (every number), table.md and
threshold_comparison.png. Progress on stderr. Exit codes: 0 done, 1 a training or an
input failed, 2 bad arguments.
"""

import argparse
import json
from pathlib import Path
import sys
import time

import torch

from hybrid_models.checkpoint import CheckpointError, load_model
from hybrid_models.data import dataset_hash, evaluation_protocol
from hybrid_models.studies.compare_physics import (
    evaluate_all,
    format_threshold,
    needed_thresholds,
    train_all,
    write_report,
)
from hybrid_models.training.config import config_dir
from hybrid_models.training.train import MODEL_FILE
from vessel_description import Vessel
from vessel_physics.errors import ConfigError
from vessel_physics.physics_file import load_physics

DEFAULT_CONFIG = 'hybrid_2p.yaml'  # in the package's config/
DEFAULT_THRESHOLDS = [0.005, 0.01, 0.02, 0.03, 0.05, 0.075, 0.1, 0.15, 0.2, 0.3, 0.5]


def labelled_physics(text: str) -> tuple[str, Path]:
    """Parse LABEL=FILE for argparse."""
    label, sep, path = text.partition('=')
    if not sep or not label or not path:
        raise argparse.ArgumentTypeError(f'expected LABEL=FILE, got {text!r}')
    return label, Path(path).resolve()


def _shown(path: Path) -> str:
    """Return a physics file as results.json records it: inside the cwd, relative to it."""
    # The repository's own files then name no path of this machine.
    cwd = Path.cwd().resolve()
    return str(path.relative_to(cwd)) if path.is_relative_to(cwd) else str(path)


def parse_args(argv):
    """Return the parsed command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--dataset', required=True, type=Path, help='dataset directory')
    parser.add_argument('--physics', nargs='+', required=True, type=labelled_physics,
                        metavar='LABEL=FILE',
                        help='physics files to compare; the first is the reference')
    parser.add_argument('--out', required=True, type=Path, help='results directory')
    parser.add_argument('--config', type=Path, default=config_dir() / DEFAULT_CONFIG,
                        help='training config (default: the 2P hybrid)')
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='config override for every training (repeatable)')
    parser.add_argument('--thresholds', type=float, nargs='+', default=DEFAULT_THRESHOLDS,
                        help='relative thresholds to sweep (0 = physics only is always added)')
    parser.add_argument('--tolerance', type=float, default=0.05,
                        help='"same accuracy": every state RMSE within this share (0.05)')
    parser.add_argument('--jobs', type=int, default=2, help='trainings at a time')
    parser.add_argument('--threads', type=int, default=2, help='cores to use in total')
    parser.add_argument('--time-limit-minutes', type=float,
                        help="cap each training (default: the config's)")
    parser.add_argument('--window', type=int,
                        help="initialization window (samples; default: the vessel's)")
    parser.add_argument('--horizon', type=int,
                        help="forecast length (samples; default: the vessel's horizon)")
    parser.add_argument('--stride', type=int,
                        help='samples between forecast starts (default: horizon/7.5)')
    args = parser.parse_args(argv)
    labels = [label for label, _ in args.physics]
    if len(set(labels)) != len(labels) or len(labels) < 2:
        parser.error(f'give at least two physics with distinct labels, got {labels}')
    if any(not 0 < t for t in args.thresholds) or args.tolerance < 0:
        parser.error('thresholds must be > 0 and the tolerance >= 0')
    return args


def main(argv=None) -> int:
    """Train, evaluate, report; return the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = parse_args(argv)
    for label, path in args.physics:
        try:
            load_physics(path)
        except ConfigError as exc:
            print(f'compare_physics: error: {label}: {exc}', file=sys.stderr)
            return 1
    args.out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(args.threads)
    start = time.monotonic()
    trainings = train_all(args)
    failed = [t for t in trainings if t['status'] not in ('ok', 'kept')]
    if failed:
        print(f"compare_physics: error: {failed[0]['label']}: {failed[0]['status']}",
              file=sys.stderr)
        return 1
    try:
        _, cfg = load_model(args.out / 'runs' / args.physics[0][0] / MODEL_FILE)
    except CheckpointError as exc:
        print(f'compare_physics: error: {exc}', file=sys.stderr)
        return 1
    spec = Vessel.from_dict(cfg['vehicle'])
    args.window, args.horizon, args.stride = evaluation_protocol(spec, args.window,
                                                                 args.horizon, args.stride)
    evaluated = evaluate_all(args, spec)
    result = {'dataset': {'path': str(args.dataset), 'sha256': dataset_hash(args.dataset)},
              'physics': {label: _shown(path) for label, path in args.physics},
              'reference': args.physics[0][0], 'tolerance': args.tolerance,
              'protocol': {'window': args.window, 'horizon': args.horizon,
                           'stride': args.stride, 'target': 'true'},
              'trainings': trainings, 'evaluation': evaluated,
              'needed_thresholds': needed_thresholds(evaluated, args.physics[0][0],
                                                     args.tolerance),
              'argv': argv, 'minutes': round((time.monotonic() - start) / 60, 1)}
    (args.out / 'results.json').write_text(json.dumps(result, indent=2))
    write_report(args, spec, result)
    for label, need in result['needed_thresholds'].items():
        print(f'{label}: threshold for the {args.physics[0][0]} accuracy '
              f'{format_threshold(need["for_reference_accuracy"])}, within '
              f'{100 * args.tolerance:g} % of its own '
              f'{format_threshold(need["for_own_unconstrained_accuracy"])}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
