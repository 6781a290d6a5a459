"""
Convert rosbag2 recordings (MCAP, also damaged ones) into a training dataset.

Reads rosbag2 directories (MCAP or sqlite3), bare .mcap/.db3 files, several, or
folders of them; needs no ROS installation. The vessel file (--vessel) says which
states and actuators the vessel has, its sample rate and which topic and field gives
each quantity (its recordings.topics map; --topic-map overrides it). Fields are
converted from the ROS frames (ENU/FLU) to the model's (NED/FRD), resampled to the
vessel's rate and split into runs wherever a topic has a gap. NaN, duplicate and out-of-order
samples are dropped and counted; what damaged files lost is reported line by line.
Writes docs/conventions.md's dataset format; the manifest records the source files
with their SHA-256, the topic map, rate, gaps, split and drop counts.

Exit status: 0 when a dataset was written (warnings go to stderr), 1 when nothing
usable remained, 2 on a usage error.
"""

from pathlib import Path
import shutil
import sys

from vessel_datasets import format as fmt
from vessel_datasets import map_checks
from vessel_datasets.bag_source import BagError, MessageDefinitionError, MessageDefinitions
from vessel_datasets.cli import converter_parser, reading_progress, resolve_options
from vessel_datasets.convert import BagResult, convert_bags, write
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel

EXIT_OK, EXIT_NOTHING, EXIT_USAGE = 0, 1, 2
# --help shows these after the docstring (in it, pep257 would take them for a section).
EXAMPLES = """\
examples:
  bag_to_dataset.py rosbag2_2024_05_01/ --vessel patrol_boat --out data/trial1
  bag_to_dataset.py recordings/ --vessel my_vessel.yaml --out data/fleet --jobs 2
  bag_to_dataset.py humble_bags/ --vessel my_vessel.yaml --out data/boat --msg-dir msgs/
      (--msg-dir: .msg files of custom types that Humble sqlite3 bags carry no definition of)
"""


def parse_args(argv):
    """Parse the command line; defaults come from the package's config/convert.yaml."""
    parser, defaults = converter_parser(__doc__ + '\n' + EXAMPLES, 'bags', 'BAG',
                                        'rosbag2 directory, .mcap file, or a folder of them')
    parser.add_argument('--topic-map', metavar='YAML',
                        help='which topic/field gives each quantity, replacing the vessel '
                             "file's recordings.topics")
    parser.add_argument('--time-source', choices=('header', 'log'),
                        help=f'header stamps or log (receive) times '
                             f'(default {defaults.time_source})')
    parser.add_argument('--msg-dir', action='append', default=[], dest='msg_dirs',
                        metavar='DIR',
                        help='folder of .msg files (searched recursively) for the message '
                             'types a bag does not define (sqlite3 bags recorded before ROS 2 '
                             'Iron define none); <pkg>/msg/Name.msg defines pkg/msg/Name; '
                             'may be repeated')
    parser.add_argument('--msg-package', metavar='NAME',
                        help='package of the .msg files in --msg-dir that are not in a '
                             '<pkg>/msg/ folder')
    parser.add_argument('--jobs', type=int, default=1, metavar='N',
                        help='convert N bags at a time in separate processes (default 1)')
    args = parser.parse_args(argv)
    if args.msg_package and not args.msg_dirs:
        parser.error('--msg-package names the package of the .msg files of --msg-dir; '
                     'give --msg-dir too')
    return args, resolve_options(parser, args, time_source=args.time_source)


def main(argv=None) -> int:
    """Convert, write, report; return the exit status."""
    args, opts = parse_args(argv)
    out = Path(args.out)
    try:
        topic_map = topic_map_for(load_vessel(args.vessel), args.topic_map)
        opts.check(topic_map.vessel.rate_hz)
    except (VesselError, TopicMapError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    try:
        definitions = MessageDefinitions(args.msg_dirs, args.msg_package)
    except MessageDefinitionError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    if (out / fmt.MANIFEST).exists() or (out / fmt.RUNS_DIR).exists():
        if not args.overwrite:
            print(f'error: {out} already holds a dataset; use --overwrite to replace it',
                  file=sys.stderr)
            return EXIT_USAGE
        shutil.rmtree(out / fmt.RUNS_DIR, ignore_errors=True)
        (out / fmt.MANIFEST).unlink(missing_ok=True)

    try:
        with reading_progress(args.quiet, unit='msg', unit_scale=True) as bar:
            results = convert_bags(args.bags, topic_map, opts, jobs=args.jobs,
                                   progress=bar.update,
                                   on_result=lambda r: _announce(r, bar),
                                   definitions=definitions)
    except BagError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_NOTHING

    if not any(r.runs for r in results):
        print('error: nothing usable remained; no dataset written', file=sys.stderr)
        return EXIT_NOTHING
    if not map_checks.check_bag_results(results, topic_map.vessel, args.accept_checks,
                                        args.refuse_spikes, sys.stderr):
        return EXIT_USAGE
    manifest = write(out, results, topic_map, opts, argv=sys.argv if argv is None else argv,
                     definitions=definitions)
    _summary(results, manifest)
    return EXIT_OK


def _announce(result: BagResult, bar) -> None:
    """Print one finished bag's notes, losses and problems above the progress bar."""
    for line in result.report.get('notes', []):
        bar.write(f'note: {line}', file=sys.stderr)
    for line in result.report.get('losses', []):
        bar.write(f'lost: {line}', file=sys.stderr)
    if result.error:
        bar.write(f'error: {result.error}', file=sys.stderr)


def _summary(results, manifest) -> None:
    """Print what was converted: runs, gaps and drops per bag, then the dataset path."""
    for r in results:
        rep = r.report
        if r.error:
            print(f'{r.name}: skipped', file=sys.stderr)
            continue
        dropped = {k: sum(t['dropped'][k] for t in rep['topics'].values())
                   for k in ('nan', 'duplicate', 'out_of_order')}
        samples = sum(x['samples'] for x in rep['runs'])
        print(f'{r.name}: {rep["messages_read"]} messages -> {len(r.runs)} run(s), '
              f'{samples} samples; {len(rep["gaps"])} gap(s), {len(rep["short_runs"])} short '
              f'run(s) dropped; dropped samples: {dropped["nan"]} NaN, '
              f'{dropped["duplicate"]} duplicate, {dropped["out_of_order"]} out of order',
              file=sys.stderr)
        for gap in rep['gaps']:
            print(f'  gap on {gap["topic"]}: {gap["start"]} to {gap["end"]} '
                  f'({gap["duration_s"]:.1f} s)', file=sys.stderr)
    print(manifest)


if __name__ == '__main__':
    sys.exit(main())
