"""
Bag-to-dataset conversion throughput against a bare rosbags pass, in the same run.

A synthetic recording of the simulator's three topics (default: 96 hours at 1 Hz,
1,036,800 messages, the paper-sized fleet recording) is written once; then the same
messages are read and deserialized by a bare rosbags loop (the floor any converter
built on rosbags pays) and converted by ``vessel_datasets.pipeline`` all the way to a
written dataset. Goals: converter >= 0.7 x the bare pass; 96 h of data in <= 60 s.
"""

from __future__ import annotations

from pathlib import Path
import tempfile
import time

from rosbags.highlevel import AnyReader

from vessel_datasets import synthetic
from vessel_datasets.pipeline import Options, assign_split, convert_all, write
from vessel_datasets.readers.bags import BagRecordings
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel

GOAL_RATIO = 0.7
GOAL_96H_S = 60.0
HOURS_96_MESSAGES = 96 * 3600 * len(synthetic.SIM_TOPICS)  # at 1 Hz per topic
BRIEF_96H_MESSAGES = 1_400_000  # the brief's rounder figure, projected as well


# A run that takes seconds to minutes, for CI (`bench.py --quick convert`): it shows the
# suite still runs end to end; its figures say nothing of the full run's.
QUICK = ('--hours', '0.5')


def add_arguments(parser) -> None:
    """Command-line options of this suite."""
    parser.add_argument('--hours', type=float, default=96.0,
                        help='length of the generated recording (default 96 h)')
    parser.add_argument('--rate', type=float, default=1.0, metavar='HZ',
                        help='publishing rate of each topic (default 1 Hz)')
    parser.add_argument('--bag', type=Path, metavar='DIR',
                        help='use (or create, then keep) this bag instead of a temporary one')
    parser.add_argument('--repeat', type=int, default=1,
                        help='time each pass this many times and keep the best')


def run(args) -> dict:
    """Generate or reuse the bag, time both passes, return the figures and goals."""
    with tempfile.TemporaryDirectory(prefix='bench_convert_') as tmp:
        bag = args.bag or Path(tmp) / 'bag'
        generate_s = None
        if not (bag / 'metadata.yaml').is_file():
            n = int(round(args.hours * 3600 * args.rate))
            start = time.perf_counter()
            synthetic.write_bag(bag, synthetic.demo_trajectory(n, rate_hz=args.rate))
            generate_s = time.perf_counter() - start
        bare = min((bare_pass(bag) for _ in range(args.repeat)), key=lambda r: r[1])
        conv = min((converter_pass(bag, Path(tmp) / f'dataset{i}')
                    for i in range(args.repeat)), key=lambda r: r[1])
        size = sum(f.stat().st_size for f in bag.glob('*.mcap'))
    messages, bare_s = bare
    conv_messages, conv_s, runs, samples = conv
    bare_rate, conv_rate = messages / bare_s, conv_messages / conv_s
    ratio = conv_rate / bare_rate
    hours_96_s = HOURS_96_MESSAGES / conv_rate
    return {
        'suite': 'convert',
        'bag': {'messages': messages, 'bytes': size, 'hours': messages / 3 / 3600 / args.rate,
                'generated_in_s': generate_s},
        'bare_rosbags_pass': {'seconds': bare_s, 'messages_per_s': bare_rate},
        'converter': {'seconds': conv_s, 'messages_per_s': conv_rate, 'runs': runs,
                      'samples': samples, 'includes': 'read, clean, resample, frames, '
                                                      'write parquet + manifest'},
        'ratio_to_bare': ratio,
        'projected_s': {'96h_1Hz_1036800_msgs': hours_96_s,
                        '1400000_msgs': BRIEF_96H_MESSAGES / conv_rate,
                        'measured_directly': abs(messages - HOURS_96_MESSAGES) < 3},
        'goals': {'ratio_min': GOAL_RATIO, 'ratio_met': ratio >= GOAL_RATIO,
                  '96h_max_s': GOAL_96H_S,
                  '96h_met': max(hours_96_s, BRIEF_96H_MESSAGES / conv_rate) <= GOAL_96H_S},
    }


def bare_pass(bag: Path) -> tuple[int, float]:
    """Read and deserialize every message with rosbags, nothing else."""
    start = time.perf_counter()
    n = 0
    with AnyReader([bag]) as reader:
        deserialize = reader.deserialize
        for conn, _, raw in reader.messages():
            deserialize(raw, conn.msgtype)
            n += 1
    return n, time.perf_counter() - start


def converter_pass(bag: Path, out: Path) -> tuple[int, float, int, int]:
    """Convert the bag to a dataset on disk, as offline/bag_to_dataset.py does."""
    topic_map, opts = topic_map_for(load_vessel(synthetic.SIM_VESSEL)), Options.from_yaml()
    start = time.perf_counter()
    reader = BagRecordings()
    results = convert_all([bag], reader, topic_map, opts)
    write(out, results, reader, topic_map, opts,
          assign_split(results, (), (), opts.seed, opts.split))
    elapsed = time.perf_counter() - start
    report = results[0].report
    return (report['read'][0], elapsed, len(results[0].runs),
            sum(r['samples'] for r in report['runs']))
