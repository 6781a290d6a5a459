"""
Convert tabular logs (CSV, whitespace-separated .dat, ...) into a training dataset.

Reads text tables, several, or folders of them (one run per file, or per value of a
run column). The vessel file (--vessel) names the vessel's states, actuators and sample
rate; its recordings.columns map (--column-map overrides it) says how to read the
files and which column gives each quantity in which unit, frame and sign (the keys are
documented in vessel_datasets/table_source.py). Quantities are converted to the model's
units and frames (NED/FRD, SI), NaN samples and spikes beyond the vessel's declared
ranges are dropped and counted, runs are split at time gaps and resampled to the
vessel's rate (states linearly, actuators held).

Before anything is written, map checks compare each run's velocities with its
differentiated position and its rates with its differentiated angles; a failing check
(a unit, frame or sign the map got wrong) refuses the conversion unless
--accept-checks. The manifest records the files with their SHA-256, the column map,
the split and every check.

Exit status: 0 when a dataset was written (or --dry-run passed), 1 when nothing usable
remained, 2 on a usage error or failed checks.
"""

from pathlib import Path
import shutil
import sys

from vessel_datasets import format as fmt
from vessel_datasets import map_checks
from vessel_datasets import table_source as tables
from vessel_datasets.cli import converter_parser, reading_progress, resolve_options
from vessel_description import VesselError, load_vessel

EXIT_OK, EXIT_NOTHING, EXIT_USAGE = 0, 1, 2
# --help shows these after the docstring (in it, pep257 would take them for a section).
EXAMPLES = """\
examples:
  table_to_dataset.py raw_data/ --vessel kvlcc2_hsva --out data/kvlcc2
      --holdout HSVA_CPMC_KVLCC2_Z_35_05 --val HSVA_CPMC_KVLCC2_Z_15_05
  table_to_dataset.py trial.csv --vessel my_vessel.yaml --out data/trial --dry-run
      --column-map trial_map.yaml   (a column map other than the vessel file's)
"""


def parse_args(argv):
    """Parse the command line; gap, run-length and split defaults are the bag converter's."""
    parser, _ = converter_parser(
        __doc__ + '\n' + EXAMPLES, 'tables', 'FILE_OR_DIR',
        'table file, or a folder of them (.csv .dat .txt .tsv .log)')
    parser.add_argument('--column-map', metavar='YAML',
                        help="how to read the tables, replacing the vessel file's "
                             'recordings.columns')
    parser.add_argument('--glob', metavar='PATTERN',
                        help='files to take from folders (default: the suffixes above)')
    parser.add_argument('--holdout', nargs='+', default=[], metavar='RUN',
                        help='runs for the test split, whole (a run id or file stem); the '
                             'others share the remaining fractions')
    parser.add_argument('--val', nargs='+', default=[], metavar='RUN',
                        help='runs for the validation split, whole')
    parser.add_argument('--dry-run', action='store_true',
                        help='convert and check, write nothing')
    args = parser.parse_args(argv)
    opts = resolve_options(parser, args)
    args.max_gap_s, args.min_run_s, args.seed = opts.max_gap_s, opts.min_run_s, opts.seed
    return args, opts.split


def main(argv=None) -> int:
    """Convert, check, write, report; return the exit status."""
    args, fractions = parse_args(argv)
    out = Path(args.out)
    try:
        vessel = load_vessel(args.vessel)
        cmap = tables.column_map_for(vessel, args.column_map)
        paths = tables.find_tables(args.tables, args.glob)
    except (VesselError, tables.ColumnMapError, tables.TableError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    if args.max_gap_s * vessel.rate_hz < 1.0:
        print(f'error: max gap {args.max_gap_s} s is shorter than the sample period '
              f'{vessel.dt} s of the vessel', file=sys.stderr)
        return EXIT_USAGE
    if not args.dry_run and ((out / fmt.MANIFEST).exists() or (out / fmt.RUNS_DIR).exists()):
        if not args.overwrite:
            print(f'error: {out} already holds a dataset; use --overwrite to replace it',
                  file=sys.stderr)
            return EXIT_USAGE

    opts = tables.TableOptions(max_gap_s=args.max_gap_s, min_run_s=args.min_run_s)
    try:
        with reading_progress(args.quiet, total=len(paths), unit='file') as bar:
            results = tables.convert_tables(paths, cmap, opts,
                                            on_result=lambda r: _announce(r, bar))
    except tables.TableError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    if not any(r.runs for r in results):
        print('error: nothing usable remained; no dataset written', file=sys.stderr)
        return EXIT_NOTHING
    try:
        split = tables.assign_split(results, args.holdout, args.val, args.seed, fractions)
    except ValueError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE

    per_run = tables.check_results(results, cmap, args.refuse_spikes)
    go_on, checks = map_checks.gate(per_run, map_checks.COLUMN_LABELS, args.accept_checks,
                                    args.refuse_spikes, sys.stderr)
    if not go_on:
        return EXIT_USAGE
    if args.dry_run:
        print('dry run: checks done, nothing written', file=sys.stderr)
        return EXIT_OK
    if args.overwrite:
        shutil.rmtree(out / fmt.RUNS_DIR, ignore_errors=True)
        (out / fmt.MANIFEST).unlink(missing_ok=True)
    manifest = tables.write(out, results, cmap, opts, seed=args.seed, fractions=fractions,
                     split=split, checks=checks, argv=sys.argv if argv is None else argv)
    _summary(manifest)
    return EXIT_OK


def _announce(result: tables.TableResult, bar) -> None:
    """Print one finished file's report line (or its error) above the progress bar."""
    bar.update(1)
    rep = result.report
    if result.error:
        bar.write(f'error: {result.error}', file=sys.stderr)
        return
    samples = sum(r['samples'] for r in rep['runs'])
    spikes = sum(s['dropped'] for s in rep['spikes'].values())
    nan = sum(rep['nan'].values())
    bar.write(f'{Path(rep["path"]).name}: {rep["rows"]} rows -> {len(result.runs)} run(s), '
              f'{samples} samples; {len(rep["gaps"])} gap(s), {rep["time_restarts"]} time '
              f'restart(s), {len(rep["short_runs"])} short run(s) dropped; dropped: '
              f'{nan} NaN values in {rep["nan_rows"]} rows, {rep["duplicate_times"]} '
              f'repeated times, {spikes} spikes', file=sys.stderr)


def _summary(manifest) -> None:
    """Print the runs per split and the manifest path."""
    dataset = fmt.read_dataset(manifest.parent)
    for name in fmt.SPLITS:
        ids = dataset.run_ids(name)
        print(f'{name}: {len(ids)} run(s) {", ".join(ids)}', file=sys.stderr)
    print(manifest)


if __name__ == '__main__':
    sys.exit(main())
