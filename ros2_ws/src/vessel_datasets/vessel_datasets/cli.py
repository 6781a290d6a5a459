"""
Command-line options every recording converter shares (bags and tables alike).

The ``bag_to_dataset`` and ``table_to_dataset`` programs (modules of this package, also
offline/*.py) build their parsers with ``converter_parser`` (their inputs, then these
options) and turn the flags into ``convert.Options`` with ``resolve_options``, so a flag
means the same in both and its default is written once (config/convert.yaml).
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator
from contextlib import contextmanager
import sys

from tqdm import tqdm

from . import format as fmt
from .convert import Options


def converter_parser(description: str, inputs: str, metavar: str,
                     inputs_help: str) -> tuple[argparse.ArgumentParser, Options]:
    """Return a converter's parser (its inputs, then the shared options) and the defaults."""
    defaults = Options.from_yaml()
    parser = argparse.ArgumentParser(description=description,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(inputs, nargs='+', metavar=metavar, help=inputs_help)
    add_dataset_options(parser, defaults)
    return parser, defaults


def add_dataset_options(parser: argparse.ArgumentParser, defaults: Options) -> None:
    """Add --out, --vessel, gaps, run length, split, checks and output flags."""
    parser.add_argument('--out', required=True, metavar='DATASET',
                        help='dataset directory to write')
    parser.add_argument('--vessel', required=True, metavar='FILE',
                        help='vessel description (YAML), or the name of a shipped one '
                             "(e.g. patrol_boat, the simulator's)")
    parser.add_argument('--max-gap', type=float, dest='max_gap_s', metavar='S',
                        help=f'split runs where an input is silent longer than this '
                             f'(default {defaults.max_gap_s} s)')
    parser.add_argument('--min-run', type=float, dest='min_run_s', metavar='S',
                        help=f'drop runs shorter than this (default {defaults.min_run_s} s)')
    parser.add_argument('--seed', type=int, help=f'split seed (default {defaults.seed})')
    parser.add_argument('--split', metavar='TRAIN,VAL,TEST',
                        help='fractions of runs per split (default '
                             + ','.join(f'{f:g}' for f in defaults.split) + ')')
    parser.add_argument('--accept-checks', action='store_true',
                        help='write the dataset even when map checks fail (they are still '
                             'printed and recorded; vessel_datasets/map_checks.py)')
    parser.add_argument('--refuse-spikes', action='store_true',
                        help='fail the spike check instead of dropping spikes')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing dataset in --out')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')


def resolve_options(parser: argparse.ArgumentParser, args: argparse.Namespace,
                    **extra) -> Options:
    """Return the flags over the defaults as Options; a bad value is a usage error."""
    split = None
    if args.split:
        try:
            split = tuple(float(x) for x in args.split.split(','))
        except ValueError:
            parser.error(f'--split wants three numbers like 0.6,0.1,0.3, got {args.split!r}')
    try:
        opts = Options.from_yaml(max_gap_s=args.max_gap_s, min_run_s=args.min_run_s,
                                 seed=args.seed, split=split, **extra)
        fmt.split_runs([], opts.seed, opts.split)  # validates the fractions
    except (ValueError, fmt.DatasetError) as exc:
        parser.error(str(exc))
    if not (opts.max_gap_s > 0 and opts.min_run_s >= 0):
        parser.error('--max-gap must be positive and --min-run not negative')
    return opts


@contextmanager
def reading_progress(quiet: bool, **bar_options) -> Iterator[tqdm]:
    """Yield the 'reading' progress bar on stderr (a terminal only), closed however it ends."""
    bar = tqdm(desc='reading', file=sys.stderr, disable=True if quiet else None,
               mininterval=0.5, **bar_options)
    try:
        yield bar
    finally:
        bar.close()
