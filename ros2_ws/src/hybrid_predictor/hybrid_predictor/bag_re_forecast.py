r"""
Re-forecast a recorded bag offline and compare with the forecasts recorded in it.

Reads a rosbag2 recording (``vessel_datasets.bag_source``, the project's one bag reader:
MCAP or sqlite3, damaged files recovered) holding the predictor's input topics (the
vessel file's topic map), its ControlPlan topic and its Forecast topic, as
``offline/demo.py --record DIR`` or ``vessel_recorder record`` write them. Every
recorded forecast is recomputed from the recorded inputs with the same checkpoint, the
window the node assembles and the plan it followed (``hybrid_predictor.re_forecast``);
one JSON document on stdout gives the largest difference live - offline per state.

  offline/re_forecast.py --bag out/demo_bag [--model model.safetensors] [--vessel NAME]

Exit status: 0 when every compared forecast equals its re-forecast to float32
precision, 1 when one does not or none could be compared, 2 on bad input.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
import sys

from vessel_ros_bridge.names import DEFAULT_NAMESPACE as NAMESPACE


def parse_args(argv):
    """Parse the command line."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--bag', required=True, type=Path, help='rosbag2 directory or file')
    parser.add_argument('--model', type=Path, default=None,
                        help="checkpoint the predictor served (default: the predictor's "
                             'embedded model)')
    parser.add_argument('--vessel', default='',
                        help="the predictor's vessel parameter, if it was set: a vessel file "
                             '(name or path) whose topic map it read (default: as the '
                             "predictor, the model's vessel)")
    parser.add_argument('--namespace', default=NAMESPACE,
                        help=f'namespace of the forecast and plan topics (default {NAMESPACE})')
    parser.add_argument('--relative-threshold', type=float, default=None,
                        help="the predictor's relative_threshold if it was set (default: the "
                             "checkpoint's own)")
    return parser.parse_args(argv)


def read_bag(path: Path, re_forecast, forecast_topic: str, plan_topic: str) -> list:
    """Feed a bag's inputs and plans to ``re_forecast``; return its Forecast messages."""
    from vessel_datasets.bag_source import BagReader, find_bags

    bags = find_bags([path])
    if len(bags) != 1:
        raise ValueError(f'{path}: expected one recording, found {len(bags)}')
    forecasts = []
    with BagReader(bags[0]) as reader:
        missing = [t for t in re_forecast.topics if t not in reader.topics]
        if missing:
            raise ValueError(f"{path}: the predictor's input topics {missing} are not "
                             f'recorded (recorded: {sorted(reader.topics)})')
        wanted = [*re_forecast.topics, forecast_topic, plan_topic]
        for topic, _, raw in reader.messages(wanted):
            msg = reader.typestore.deserialize_cdr(raw, reader.topics[topic].msgtype)
            if topic == forecast_topic:
                forecasts.append(msg)
            elif topic == plan_topic:
                re_forecast.add_plan(msg)
            else:
                re_forecast.add_input(topic, msg)
        for line in reader.losses:
            print(f're_forecast: {line}', file=sys.stderr)
    return forecasts


def main(argv=None) -> int:
    """Re-forecast a bag; print JSON; return the exit status."""
    args = parse_args(argv)
    from hybrid_models.checkpoint_format import CheckpointError
    from hybrid_models.engine import Forecaster
    from hybrid_predictor.node import default_model_path
    from hybrid_predictor.re_forecast import ReForecast, compare, predictor_defaults
    from hybrid_predictor.vessel_source import served_vessel
    from vessel_datasets.topic_map import TopicMapError, topic_map_for
    from vessel_description import VesselError
    from vessel_ros_bridge.messages import seconds_from_stamp

    try:
        model = args.model or default_model_path(args.vessel)
        engine = Forecaster.from_checkpoint(model, args.relative_threshold)
        topic_map = topic_map_for(served_vessel(args.vessel, engine.spec, str(model))[0])
        re_forecast = ReForecast(engine, topic_map, predictor_defaults())
        namespace = '/' + args.namespace.strip('/')
        forecasts = read_bag(args.bag, re_forecast, f'{namespace}/forecast',
                             f'{namespace}/control_plan')
    except (CheckpointError, FileNotFoundError, TopicMapError, VesselError, ValueError,
            OSError) as exc:
        print(f're_forecast: error: {exc}', file=sys.stderr)
        return 2
    if not forecasts:
        print(f're_forecast: error: {args.bag} holds no {namespace}/forecast messages to '
              f'compare with (record the forecast topic too)', file=sys.stderr)
        return 2
    print(f're_forecast: recomputing {len(forecasts)} forecasts', file=sys.stderr)
    summary = {'bag': str(args.bag), 'model_id': engine.model_id,
               'forecasts_recorded': len(forecasts),
               **compare(re_forecast, forecasts, since=min(seconds_from_stamp(f.header.stamp)
                                                            for f in forecasts))}
    print(json.dumps(summary, indent=2))
    return 0 if summary['compared'] and summary['equal'] else 1


if __name__ == '__main__':
    sys.exit(main())
