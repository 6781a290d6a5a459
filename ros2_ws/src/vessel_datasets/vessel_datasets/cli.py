"""
The command line every recording converter shares: options, progress, gate, write.

``bag_to_dataset``, ``table_to_dataset`` and ``log_to_dataset`` (modules of this package,
also offline/*.py) each add their inputs and reader options to ``converter_parser``,
build their reader and map, and hand over to ``run``, so a flag means the same in all
of them, its default is written once (config/convert.yaml), and every format is
converted, reported, checked and written the same way.
"""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
import shutil
import sys

from tqdm import tqdm

from . import format as fmt
from . import pipeline
from .pipeline import Options, Result
from .sources import Reader, RecordingError
from .topic_map import TopicMap

EXIT_OK, EXIT_NOTHING, EXIT_USAGE = 0, 1, 2
GAPS_LISTED = 5   # gaps of a recording listed one per line; the rest in one line
EXIT_STATUS = """\
exit status: 0 when a dataset was written (or --dry-run passed), 1 when nothing usable
remained, 2 on a usage error or failed map checks.
"""


def converter_parser(description: str, metavar: str,
                     inputs_help: str) -> tuple[argparse.ArgumentParser, Options]:
    """Return a converter's parser (its inputs, then the shared options) and the defaults."""
    defaults = Options.from_yaml()
    parser = argparse.ArgumentParser(description=description + '\n' + EXIT_STATUS,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('inputs', nargs='+', metavar=metavar, help=inputs_help)
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
                        help='fractions of recordings per split (default '
                             + ','.join(f'{f:g}' for f in defaults.split) + ')')
    parser.add_argument('--holdout', nargs='+', default=[], metavar='RUN',
                        help='runs for the test split, whole (a run id or a recording '
                             'name); the others share the remaining fractions')
    parser.add_argument('--val', nargs='+', default=[], metavar='RUN',
                        help='runs for the validation split, whole')
    parser.add_argument('--accept-checks', action='store_true',
                        help='write the dataset even when map checks fail (they are still '
                             'printed and recorded; vessel_datasets/map_checks.py)')
    parser.add_argument('--refuse-spikes', action='store_true',
                        help='fail the spike check instead of dropping spikes')
    parser.add_argument('--jobs', type=int, default=1, metavar='N',
                        help='convert N recordings at a time in separate processes '
                             '(default 1)')
    parser.add_argument('--dry-run', action='store_true',
                        help='convert and check, write nothing')
    parser.add_argument('--overwrite', action='store_true',
                        help='replace an existing dataset in --out')
    parser.add_argument('--quiet', action='store_true', help='no progress bar')
    return parser, defaults


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


def run(args: argparse.Namespace, opts: Options, reader: Reader, topic_map: TopicMap,
        unit: str, argv: Sequence[str] | None) -> int:
    """Convert, check, write and report as the shared options say; return the exit status."""
    out = Path(args.out)
    try:
        opts.check(topic_map.vessel.rate_hz)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    if not args.dry_run and ((out / fmt.MANIFEST).exists() or (out / fmt.RUNS_DIR).exists()):
        if not args.overwrite:
            print(f'error: {out} already holds a dataset; use --overwrite to replace it',
                  file=sys.stderr)
            return EXIT_USAGE
    try:
        with reading_progress(args.quiet, unit=unit, unit_scale=True) as bar:
            results = pipeline.convert_all(args.inputs, reader, topic_map, opts,
                                           jobs=args.jobs, progress=bar.update,
                                           on_result=lambda r: _announce(r, bar, unit))
    except RecordingError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_NOTHING
    if not any(r.runs for r in results):
        print('error: nothing usable remained; no dataset written', file=sys.stderr)
        return EXIT_NOTHING
    try:
        split = pipeline.assign_split(results, args.holdout, args.val, opts.seed, opts.split)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    go_on, checks = pipeline.check(results, topic_map, args.accept_checks,
                                   args.refuse_spikes, sys.stderr)
    if not go_on:
        return EXIT_USAGE
    if args.dry_run:
        print('dry run: checks done, nothing written', file=sys.stderr)
        return EXIT_OK
    if args.overwrite:
        shutil.rmtree(out / fmt.RUNS_DIR, ignore_errors=True)
        (out / fmt.MANIFEST).unlink(missing_ok=True)
    manifest = pipeline.write(out, results, reader, topic_map, opts, split, checks,
                              argv=sys.argv if argv is None else argv)
    for name in fmt.SPLITS:
        print(f'{name}: {len(split[name])} run(s)', file=sys.stderr)
    print(manifest)
    return EXIT_OK


def _announce(result: Result, bar, unit: str) -> None:
    """Print one finished recording's report: notes, losses, its runs or its error."""
    rep = result.report
    for line in rep.get('notes', []):
        bar.write(f'note: {line}', file=sys.stderr)
    for line in rep.get('losses', []):
        bar.write(f'lost: {line}', file=sys.stderr)
    if rep.get('alternatives'):
        chosen = sorted({source.split(' ', 1)[0] + (' (' + source.split('(', 1)[1]
                                                    if '(' in source else '')
                         for source in rep['alternatives'].values()})
        bar.write(f'{result.name}: alternatives taken: {", ".join(chosen)}', file=sys.stderr)
    if result.error:
        bar.write(f'error: {result.error}', file=sys.stderr)
        bar.write(f'{result.name}: skipped', file=sys.stderr)
        return
    dropped: dict[str, int] = {}
    for source in rep.get('sources', {}).values():
        for reason, n in source.get('dropped', {}).items():
            dropped[reason] = dropped.get(reason, 0) + n
    dropped['NaN values'] = dropped.pop('nan', 0) + sum(rep.get('nan', {}).values())
    dropped['repeated times'] = dropped.pop('duplicate', 0) + rep.get('duplicate_times', 0)
    dropped['spikes'] = sum(s['dropped'] for s in rep.get('spikes', {}).values())
    count, what = rep.get('read', (0, unit))
    samples = sum(r['samples'] for r in rep['runs'])
    bar.write(f'{result.name}: {count} {what} -> {len(result.runs)} run(s), {samples} samples; '
              f'{len(rep["gaps"])} gap(s), {len(rep["short_runs"])} short run(s) dropped; '
              f'dropped: ' + ', '.join(f'{n} {reason.replace("_", " ")}'
                                       for reason, n in dropped.items()), file=sys.stderr)
    gaps = rep['gaps']
    for gap in gaps[:GAPS_LISTED]:
        sources = gap['sources'] if gap['sources'] == 'all' else ', '.join(gap['sources'])
        bar.write(f'  gap on {sources}: {gap["start"]} to {gap["end"]} '
                  f'({gap["duration_s"]:.1f} s)', file=sys.stderr)
    if len(gaps) > GAPS_LISTED:   # the manifest keeps every one
        rest = [g['duration_s'] for g in gaps[GAPS_LISTED:]]
        bar.write(f'  ... and {len(rest)} more gaps of {min(rest):.1f}-{max(rest):.1f} s, the '
                  f'last ending at {gaps[-1]["end"]}', file=sys.stderr)
