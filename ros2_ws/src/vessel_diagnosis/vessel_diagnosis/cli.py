"""
Diagnose where and why a nominal physics model departs from recordings.

Locates the mismatch (residual maps against speed, turn rate, apparent wind, sea state
and heading; departing time windows), names the missing physics (sparse regression over
a library of named candidate terms, block-bootstrap inclusion probabilities, 95 %
intervals, aliases that cannot be told apart), writes an augmented physics (nominal plus
the terms found) and shows one-step and 900-step errors before and after on held-out
recordings. docs/diagnosis.md explains the method and the output.

Writes REPORT_DIR/report.md with PNG figures, REPORT_DIR/findings.json (every number)
and, when something was found, augmented_physics.yaml, augmented_vessel.yaml and
augmented_simulation.yaml. Progress goes to stderr, a one-line summary to stdout.

Before anything is fitted, the recordings must fit the vessel file's scale (Froude
number, turning rate, limits; --skip-scale-check overrides), and only candidates the
vessel can have are tried (no wind without a wind sensor, no current in a basin, no roll
terms without roll states). The augmented physics is written only when it forecasts the
held-out recordings better.

Exit status: 0 diagnosed (findings, or nothing significant missing), 1 unusable input
(recordings, physics, settings, a vessel file of another scale), 2 usage error,
3 recordings too short or too little excited to diagnose (the report says why).

For a vessel whose physics is the MMG standard model (its vessel file names an MMG
parameter file, or --physics does), the diagnosis is the MMG family's: equation error on
measured accelerations over a library of MMG coefficients and effects
(vessel_diagnosis.mmg_family, settings config/mmg_diagnosis.yaml, --config to override);
it writes report.md, findings.json and, when it improves held-out forecasts,
augmented_mmg.yaml.
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

from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel
from vessel_diagnosis import mmg_family
from vessel_diagnosis.findings import SCHEMA, STATUS
from vessel_diagnosis.library import LibraryError, load_library
from vessel_diagnosis.pipeline import InsufficientDataError, diagnose
from vessel_diagnosis.recordings import DIAGNOSED_VESSEL, RecordingsError
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
                        help='nominal physics file (vessel_physics.augmented format), a '
                             'plain vessel parameter file (then every simulator term) or an '
                             "MMG parameter file (default: the dataset's vessel file names it)")
    parser.add_argument('--out', required=True, metavar='REPORT_DIR',
                        help='directory for report.md, findings.json, figures, physics')
    parser.add_argument('--config', metavar='YAML',
                        help=f'settings overriding {config_dir() / "diagnosis.yaml"}')
    parser.add_argument('--library', metavar='YAML',
                        help=f'candidate library (default {config_dir() / "library.yaml"})')
    parser.add_argument('--topic-map', metavar='YAML',
                        help="topic map for recordings (default: the simulator's topics)")
    parser.add_argument('--vessel', metavar='NAME_OR_FILE',
                        help='vessel file the recordings come from (default: the one the '
                             'datasets carry; for bags the one their topic map is for)')
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
            'summary': f'Cannot diagnose: {reason}.', 'findings': [], 'metrics': None}
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
        if mmg_family.uses_mmg(args.recordings, args.physics):
            return _diagnose_mmg(args, out, say)
        if args.physics is None:
            raise RecordingsError('--physics is required unless the recordings are a dataset '
                                  'whose vessel file names an MMG parameter file')
        settings = load_settings(args.config)
        library = load_library(args.library)
        topic_map = topic_map_for(DIAGNOSED_VESSEL, args.topic_map) if args.topic_map \
            else None
        vessel = load_vessel(args.vessel) if args.vessel else None
        result = diagnose(args.recordings, args.physics, out, settings, library, topic_map, say,
                          vessel, not args.skip_scale_check)
    except InsufficientDataError as exc:
        _insufficient(out, str(exc))
        print(f'{PROG}: cannot diagnose: {exc}', file=sys.stderr)
        return EXIT_INSUFFICIENT
    except (RecordingsError, ConfigError, SettingsError, LibraryError, TopicMapError,
            VesselError, ScaleError) as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return EXIT_INPUT
    except OSError as exc:
        print(f'{PROG}: error: {exc.filename or out}: {exc.strerror}', file=sys.stderr)
        return EXIT_INPUT
    print(f'{result["status"]}: {result["summary"]} ({out / "report.md"})')
    if result['status'] == 'insufficient_excitation':
        print(f'{PROG}: cannot diagnose: {result["summary"]}', file=sys.stderr)
        return EXIT_INSUFFICIENT
    return EXIT_OK


def _diagnose_mmg(args, out: Path, say) -> int:
    """Run the MMG family's diagnosis on one dataset; return the exit code."""
    if len(args.recordings) != 1:
        raise RecordingsError('the MMG diagnosis reads one dataset directory; convert the '
                              'recordings into one (offline/bag_to_dataset.py)')
    result = mmg_family.diagnose_mmg(args.recordings[0], out,
                                     mmg_family.load_mmg_settings(args.config), args.physics,
                                     say, not args.skip_scale_check)
    written = 'augmented_mmg.yaml written' if result['augmented_written'] else \
        'no augmented file (no held-out improvement)'
    print(f'found {result["verdict"]}; {written} ({out / "report.md"})')
    return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
