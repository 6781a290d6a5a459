"""
Diagnose where and why a nominal physics model departs from recordings, for any vessel.

Locates the mismatch (residual maps against speed, turn rate, apparent wind, sea state
and heading, a 6-DOF vehicle's heave speed and tilt; departing time windows), names the
missing physics (sparse regression over a library of named candidate terms of the
physics' family, block-bootstrap inclusion probabilities, 95 % intervals that widen where
the runs disagree, aliases that cannot be told apart), writes an augmented physics
(nominal plus the terms found) and shows one-step and forecast errors before and after on
held-out recordings.
docs/diagnosis.md explains the method and the output.

The nominal physics may be of any family (vessel_physics: the patrol boat's 4-DOF
terms, the MMG standard model, the Fossen matrix model, the multirotor's rigid body);
without --physics it is the one the vessel file names. Each family brings its candidate
library (vessel_physics/FAMILY/diagnosis_candidates.yaml) and its settings
(config/families/FAMILY.yaml over config/diagnosis.yaml; --config overrides).

Writes REPORT_DIR/report.md with PNG figures, REPORT_DIR/findings.json (every number;
``augmented_physics`` names the files written) and, when something was found and it
forecasts the held-out recordings better, augmented_physics.yaml,
augmented_parameters.yaml and augmented_simulation.yaml. Progress goes to stderr, a
one-line summary to stdout.

Before anything is fitted, the recordings must fit the vessel file's scale (Froude
number, turning rate, limits; a 6-DOF vehicle's limits only; --skip-scale-check
overrides), and only candidates the
vessel can have are tried (no wind without a wind sensor, no current in a basin, no roll
terms without roll states).

Exit status: 0 diagnosed (findings, or nothing significant missing), 1 unusable input
(recordings -- a NaN in a run included --, physics, settings, a vessel file of another
scale), 2 usage error, 3 recordings too short or too little excited to diagnose (the
report says why).
For instance:
  diagnose.py --recordings data/ship --physics nominal_vessel.yaml --out out/diagnosis
  diagnose.py --recordings trial1/ trial2/ --physics my.yaml --out out/trial
  diagnose.py --recordings datasets/kvlcc2 --out out/kvlcc2     # physics: the vessel file's
"""

import argparse
import json
from pathlib import Path
import sys
import time

from vessel_datasets.format import DatasetError
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel
from vessel_diagnosis.findings import SCHEMA, STATUS
from vessel_diagnosis.library import LibraryError, load_library
from vessel_diagnosis.pipeline import InsufficientDataError, diagnose, nominal_physics
from vessel_diagnosis.recordings import RecordingsError, recordings_vessel
from vessel_diagnosis.scale import ScaleError
from vessel_diagnosis.settings import SettingsError, config_dir, load_settings
from vessel_physics.errors import ConfigError

EXIT_OK, EXIT_INPUT, EXIT_USAGE, EXIT_INSUFFICIENT = 0, 1, 2, 3
PROG = 'diagnose.py'


def build_parser() -> argparse.ArgumentParser:
    """Return the command-line parser."""
    parser = argparse.ArgumentParser(prog=PROG, description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--recordings', nargs='+', required=True, metavar='BAGS_OR_DATASET',
                        help='dataset directories and/or rosbag2 recordings (MCAP)')
    parser.add_argument('--physics', metavar='NOMINAL.yaml',
                        help='nominal physics file, or a parameter file of a family (then its '
                             "whole model); default: the one the recordings' vessel file "
                             'names')
    parser.add_argument('--out', required=True, metavar='REPORT_DIR',
                        help='directory for report.md, findings.json, figures, physics')
    parser.add_argument('--config', metavar='YAML',
                        help=f'settings overriding {config_dir() / "diagnosis.yaml"} and the '
                             f"family's {config_dir() / 'families'}/FAMILY.yaml")
    parser.add_argument('--library', metavar='YAML',
                        help=f"candidate library (default the family's, "
                             f'{config_dir() / "library"}/FAMILY.yaml)')
    parser.add_argument('--topic-map', metavar='YAML',
                        help="topic map for bags (default: the vessel file's)")
    parser.add_argument('--vessel', metavar='NAME_OR_FILE',
                        help='vessel file the recordings come from (default: the one the '
                             'datasets carry; bags need it)')
    parser.add_argument('--skip-scale-check', action='store_true',
                        help="diagnose even when the recordings' speeds and turns do not "
                             "fit the vessel file's length and limits")
    parser.add_argument('--quiet', action='store_true', help='no progress on stderr')
    return parser


def _insufficient(out: Path, reason: str) -> None:
    """Write a report that says why nothing could be diagnosed."""
    out.mkdir(parents=True, exist_ok=True)
    status = 'insufficient_excitation'
    data = {'schema': SCHEMA, 'status': status, 'status_meaning': STATUS[status],
            'summary': f'Cannot diagnose: {reason}.', 'findings': [], 'kept_out': [],
            'metrics': None, 'augmented_physics': None}
    (out / 'findings.json').write_text(json.dumps(data, indent=2))
    (out / 'report.md').write_text(f'# Simulation-to-reality diagnosis\n\n**Cannot diagnose: '
                                   f'{reason}.**\n\nStatus: `{status}`.\n')


def main(argv=None) -> int:
    """Parse arguments, diagnose, report; return the exit code."""
    args = build_parser().parse_args(argv)
    start = time.perf_counter()

    def say(message: str) -> None:
        if not args.quiet:
            print(f'[{time.perf_counter() - start:6.1f} s] {message}', file=sys.stderr,
                  flush=True)

    out = Path(args.out)
    try:
        vessel = recordings_vessel(args.recordings,
                                   load_vessel(args.vessel) if args.vessel else None)
        nominal = nominal_physics(args.physics, vessel)
        settings = load_settings(args.config, family=nominal.family.name)
        library = load_library(args.library, nominal.family)
        topic_map = topic_map_for(vessel, args.topic_map) if args.topic_map else None
        say(f'vessel {vessel.name}, physics: the {nominal.family.title}')
        result = diagnose(args.recordings, nominal, out, settings, library, topic_map, say,
                          vessel, not args.skip_scale_check)
    except InsufficientDataError as exc:
        _insufficient(out, str(exc))
        print(f'{PROG}: cannot diagnose: {exc}', file=sys.stderr)
        return EXIT_INSUFFICIENT
    except (RecordingsError, ConfigError, SettingsError, LibraryError, TopicMapError,
            VesselError, ScaleError, DatasetError) as exc:
        print(f'{PROG}: error: {" ".join(str(exc).split())}', file=sys.stderr)
        return EXIT_INPUT
    except OSError as exc:
        print(f'{PROG}: error: {exc.filename or out}: {exc.strerror}', file=sys.stderr)
        return EXIT_INPUT
    print(f'{result["status"]}: {result["summary"]} ({out / "report.md"})')
    if result['status'] == 'insufficient_excitation':
        print(f'{PROG}: cannot diagnose: {result["summary"]}', file=sys.stderr)
        return EXIT_INSUFFICIENT
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
