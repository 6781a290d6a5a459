"""
Convert autopilot logs (ArduPilot DataFlash .bin, PX4 ULog .ulg) into a training dataset.

Reads log files, several, or folders of them (one recording per file). The vessel file
(--vessel) names the vessel's states, actuators and sample rate; its recordings.logs
map (--log-map overrides it; the syntax of a topic map, docs/bags.md) names the log's
messages as topics and their fields -- GPS Lat/Lng, ATT Yaw, XKF1 VN/VE, RCOU C1 for
ArduPilot; vehicle_local_position x/y/vx/vy/heading for PX4 -- with scales, delays and
alternatives. Logs are parsed by pymavlink's DataFlash reader and by pyulog; samples
are timed by the log's microseconds since boot. The rest is the one recording pipeline:
delays, velocities from the track where the map gives none, spikes, runs, resampling,
frames, map checks, split and the manifest.
"""

import sys

from vessel_datasets.cli import EXIT_USAGE, converter_parser, resolve_options, run
from vessel_datasets.readers.dataflash import DataFlashRecordings
from vessel_datasets.readers.ulog import ULogRecordings
from vessel_datasets.sources import find_files
from vessel_datasets.topic_map import TopicMapError, topic_map_for
from vessel_description import VesselError, load_vessel

# --help shows these after the docstring (in it, pep257 would take them for a section).
EXAMPLES = """\
examples:
  log_to_dataset.py 00000042.BIN --vessel my_rover.yaml --out data/rover
  log_to_dataset.py logs/ --vessel my_boat.yaml --out data/boat --log-map boat_px4.yaml
"""
READERS = {'.bin': DataFlashRecordings(), '.ulg': ULogRecordings()}


class AutopilotLogs:
    """DataFlash and ULog files side by side: each read by the reader of its suffix."""

    tool = 'log_to_dataset'
    section = 'logs'

    def find(self, paths):
        """Return the .bin and .ulg files at the paths."""
        return find_files(paths, tuple(READERS), 'autopilot logs')

    def read(self, recording, topic_map, opts, report, progress):
        """Read one log with the reader of its format."""
        reader = READERS[recording.path.suffix.lower()]
        report['log_format'] = reader.config()['log_format']
        return reader.read(recording, topic_map, opts, report, progress)

    def config(self):
        """Return nothing more: each recording's report names its format."""
        return {}


def parse_args(argv):
    """Parse the command line; gap, run-length and split defaults are config/convert.yaml's."""
    parser, _ = converter_parser(__doc__ + '\n' + EXAMPLES, 'LOG',
                                 'DataFlash .bin or ULog .ulg file, or a folder of them')
    parser.add_argument('--log-map', metavar='YAML',
                        help="which message/field gives each quantity, replacing the vessel "
                             "file's recordings.logs")
    args = parser.parse_args(argv)
    return args, resolve_options(parser, args)


def main(argv=None) -> int:
    """Convert, check, write, report; return the exit status."""
    args, opts = parse_args(argv)
    try:
        topic_map = topic_map_for(load_vessel(args.vessel), args.log_map, section='logs')
    except (VesselError, TopicMapError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return EXIT_USAGE
    return run(args, opts, AutopilotLogs(), topic_map, 'msg', argv)


if __name__ == '__main__':
    sys.exit(main())
