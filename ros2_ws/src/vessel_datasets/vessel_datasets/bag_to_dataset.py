"""
Convert rosbag2 recordings (MCAP, also damaged ones) into a training dataset.

Reads rosbag2 directories (MCAP or sqlite3), bare .mcap/.db3 files, several, or
folders of them; needs no ROS installation. The vessel file (--vessel) says which
states and actuators the vessel has, its sample rate and which topic and field gives
each quantity (its recordings.topics map; --topic-map overrides it), with delays and
alternative topics. Fields are converted from the ROS frames (ENU/FLU) to the model's
(NED/FRD), resampled to the vessel's rate and split into runs wherever a topic has a
gap. NaN, duplicate and out-of-order samples and spikes are dropped and counted; what
damaged files lost is reported line by line. Map checks compare the velocities with
the differentiated position, the rates with the differentiated angles and estimate
lags before anything is written. Writes docs/conventions.md's dataset format; the
manifest records the source files with their SHA-256, the topic map, rate, gaps,
split, drop counts and checks.
"""

import sys

from vessel_datasets.bag_source import MessageDefinitionError, MessageDefinitions
from vessel_datasets.cli import EXIT_USAGE, converter_parser, resolve_options, run
from vessel_datasets.readers.bags import BagRecordings
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel

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
    parser, defaults = converter_parser(__doc__ + '\n' + EXAMPLES, 'BAG',
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
    args = parser.parse_args(argv)
    if args.msg_package and not args.msg_dirs:
        parser.error('--msg-package names the package of the .msg files of --msg-dir; '
                     'give --msg-dir too')
    return args, resolve_options(parser, args, time_source=args.time_source)


def main(argv=None) -> int:
    """Convert, check, write, report; return the exit status."""
    args, opts = parse_args(argv)
    try:
        topic_map = topic_map_for(load_vessel(args.vessel), args.topic_map)
        reader = BagRecordings(MessageDefinitions(args.msg_dirs, args.msg_package))
    except (VesselError, TopicMapError, MessageDefinitionError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    return run(args, opts, reader, topic_map, 'msg', argv)


if __name__ == '__main__':
    sys.exit(main())
