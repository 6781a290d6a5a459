"""
Convert tabular logs (CSV, whitespace-separated .dat, ..., Parquet) into a training dataset.

Reads tables, several, or folders of them (one recording per file; a run column
splits a file into runs). The vessel file (--vessel) names the vessel's states,
actuators and sample rate; its recordings.columns map (--column-map overrides it) says
how to read the files and which column gives each quantity in which unit, frame, sign
and delay (the keys are documented in vessel_datasets/column_map.py); without velocity
columns the body velocities come from the position track and the heading. Quantities
are converted to the model's units and frames (NED/FRD, SI), NaN samples and spikes
beyond the vessel's declared ranges are dropped and counted, runs are split at time
gaps and resampled to the vessel's rate (states linearly, actuators held).

Before anything is written, map checks compare each run's velocities with its
differentiated position, its heading with its track, its rates with its differentiated
angles and estimate lags; coarse columns are named and judged at a scale their
resolution allows. A failing check (a unit, frame, sign or delay the map got wrong)
refuses the conversion unless --accept-checks. The manifest records the files with
their SHA-256, the column map, the split and every check.
"""

import sys

from vessel_datasets.cli import EXIT_USAGE, converter_parser, resolve_options, run
from vessel_datasets.column_map import ColumnMapError, column_map_for
from vessel_datasets.readers.tables import SUFFIXES, TableRecordings
from vessel_description import VesselError, load_vessel

# --help shows these after the docstring (in it, pep257 would take them for a section).
EXAMPLES = """\
examples:
  table_to_dataset.py raw_data/ --vessel kvlcc2_hsva --out data/kvlcc2
      --holdout HSVA_CPMC_KVLCC2_Z_35_05 --val HSVA_CPMC_KVLCC2_Z_15_05
  table_to_dataset.py trial.csv --vessel my_vessel.yaml --out data/trial --dry-run
      --column-map trial_map.yaml   (a column map other than the vessel file's)
"""


def parse_args(argv):
    """Parse the command line; gap, run-length and split defaults are config/convert.yaml's."""
    parser, _ = converter_parser(
        __doc__ + '\n' + EXAMPLES, 'FILE_OR_DIR',
        'table file, or a folder of them (' + '; '.join(
            f'{fmt}: {" ".join(suffixes)}' for fmt, suffixes in SUFFIXES.items()) + ')')
    parser.add_argument('--column-map', metavar='YAML',
                        help="how to read the tables, replacing the vessel file's "
                             'recordings.columns')
    parser.add_argument('--glob', metavar='PATTERN',
                        help='files to take from folders (default: the suffixes above)')
    args = parser.parse_args(argv)
    return args, resolve_options(parser, args)


def main(argv=None) -> int:
    """Convert, check, write, report; return the exit status."""
    args, opts = parse_args(argv)
    try:
        cmap = column_map_for(load_vessel(args.vessel), args.column_map)
    except (VesselError, ColumnMapError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    return run(args, opts, TableRecordings(cmap, args.glob), cmap.topic_map, 'file', argv)


if __name__ == '__main__':
    sys.exit(main())
