#!/usr/bin/env python3
r"""
Replay a held-out snuboat bag over DDS into the running predictor; compare with offline.

Builds the boat's message package (snumsg_pkg) from its .msg files in a scratch colcon
workspace, starts the installed predictor with the snuboat vessel file and a trained
checkpoint, publishes the bag's /sensor and /ctrl_fb_boat messages with the boat's own
types at their recorded pace, and collects /vessel/forecast. Each published forecast is
then recomputed offline from the same messages (the same input window code, the same
compiled engine and bound) and the two are compared. While the bag still plays, it asks
the predictor's what-if service for forecasts of candidate plans in the boat's own
controls (n_port, n_stbd, delta_port, delta_stbd), and sends a plan with a wrong unit,
one with a wrong control name and one with a missing control, which must be refused.
With ``--load-plans N``, a planner's request as well (``offline/benchmarks/what_if.py``:
N plans of ``--load-steps`` steps about the middle of each control's range, every step
answered) is sent again and again for ``--load-seconds`` by a what-if client in C
(package what_if_c, as the service soak's), one request in flight, each timed from its
sending to its whole answer received (``what_if_load``). Prints one JSON document.

usage (repo root, after `make setup` and docs/results/real/snuboat/run.sh):
  tools/with_env.sh python docs/results/real/snuboat/replay.py \\
      --model /tmp/real/snuboat_runs/hybrid/model.safetensors \\
      --bag ../shared/real/snuboat/bags/FREE_RUNNING_8_0813_223706
"""

import argparse
import json
import os
from pathlib import Path
import subprocess
import sys
import tempfile
import time

import numpy as np

REPO = Path(__file__).resolve().parents[4]
PACKAGE_XML = """<?xml version="1.0"?>
<package format="3">
  <name>snumsg_pkg</name>
  <version>0.0.0</version>
  <description>snuboat message types, built from the boat's .msg files</description>
  <maintainer email="maintainers@hybrid-ship.dev">hybrid-ship maintainers</maintainer>
  <license>unknown</license>
  <buildtool_depend>ament_cmake</buildtool_depend>
  <buildtool_depend>rosidl_default_generators</buildtool_depend>
  <depend>builtin_interfaces</depend>
  <exec_depend>rosidl_default_runtime</exec_depend>
  <member_of_group>rosidl_interface_packages</member_of_group>
  <export><build_type>ament_cmake</build_type></export>
</package>
"""
CMAKE = """cmake_minimum_required(VERSION 3.8)
project(snumsg_pkg)
find_package(ament_cmake REQUIRED)
find_package(rosidl_default_generators REQUIRED)
find_package(builtin_interfaces REQUIRED)
file(GLOB MSGS RELATIVE ${CMAKE_CURRENT_SOURCE_DIR} msg/*.msg)
rosidl_generate_interfaces(${PROJECT_NAME} ${MSGS} DEPENDENCIES builtin_interfaces)
ament_export_dependencies(rosidl_default_runtime)
ament_package()
"""
TOPICS = ('/sensor', '/ctrl_fb_boat')
THRESHOLD = 0.15   # the relative threshold the replayed predictor serves by default
# How much later (s) than this script's send time the node may stamp a sample on arrival.
ARRIVAL_SLACK = 0.05


def build_messages(msg_dir: Path, workspace: Path) -> Path:
    """Build snumsg_pkg from the boat's .msg files with colcon; return its install prefix."""
    pkg = workspace / 'src' / 'snumsg_pkg'
    (pkg / 'msg').mkdir(parents=True, exist_ok=True)
    for f in msg_dir.glob('*.msg'):
        (pkg / 'msg' / f.name).write_text(f.read_text())
    (pkg / 'package.xml').write_text(PACKAGE_XML)
    (pkg / 'CMakeLists.txt').write_text(CMAKE)
    env = dict(os.environ, AMENT_PREFIX_PATH=os.environ.get('VIRTUAL_ENV', sys.prefix))
    done = subprocess.run(['colcon', 'build', '--event-handlers', 'console_direct-'],
                          cwd=workspace, env=env, capture_output=True, text=True)
    if done.returncode:
        sys.exit(f'replay: error: building snumsg_pkg failed: {done.stderr[-500:]}')
    return workspace / 'install'


def bag_messages(bag: Path, msg_dir: Path):
    """Return [(log_ns, topic, rosbags message)] of the replayed topics, in log order."""
    from vessel_datasets.bag_source import BagReader, MessageDefinitions, find_bags

    [found] = find_bags([bag])
    out = []
    with BagReader(found, MessageDefinitions([msg_dir], package='snumsg_pkg')) as reader:
        store = reader.typestore
        for topic, log_ns, raw in reader.messages(TOPICS):
            out.append((log_ns, topic, store.deserialize_cdr(raw,
                                                             reader.topics[topic].msgtype)))
    return sorted(out, key=lambda m: m[0])


def what_if_requests(vessel, horizon: int, shafts: dict, control_plan) -> list:
    """
    Return [(name, Predict request)]: eight candidate plans, then three malformed ones.

    The candidates hold the shafts at ``shafts`` (rad/s, the latest measured) and sweep
    both rudders over the boat's range; the malformed plans give a shaft speed in rpm,
    name a control the boat does not have, and leave out the starboard rudder.
    """
    from hybrid_predictor_interfaces.srv import Predict

    names = list(vessel.actuator_names)
    rudder = vessel.actuator('delta_port')
    plans = []
    for delta in np.linspace(rudder.low, rudder.high, 8):
        row = dict(shafts, delta_port=delta, delta_stbd=delta)
        plans.append(control_plan(vessel, np.tile([row[a] for a in names], (horizon, 1)),
                                  plan_id=f'rudder {delta:+.2f}'))
    wrong_unit = control_plan(vessel, np.zeros((horizon, len(names))), plan_id='rpm')
    wrong_unit.control_units[0] = 'rpm'
    wrong_name = control_plan(vessel, np.zeros((horizon, len(names))), plan_id='name')
    wrong_name.control_names[0] = 'n_centre'
    missing = control_plan(vessel, np.zeros((horizon, len(names) - 1)), names[:-1],
                           plan_id='missing')
    return [('eight candidate plans', Predict.Request(plans=plans)),
            ('a shaft speed in rpm', Predict.Request(plans=[wrong_unit])),
            ('a control the boat does not have', Predict.Request(plans=[wrong_name])),
            ('a control left out', Predict.Request(plans=[missing]))]


def served_threshold(text: str) -> float | None:
    """Return --threshold: a number, or None for the checkpoint's own ("own")."""
    return None if text == 'own' else float(text)


def load_figures(merged, shape) -> dict:
    """Return what the planner's requests (``--load-plans``) measured, in ms and kB."""
    from benchmarks.soak import percentile_ms  # offline/ is on the path with --load-plans

    return {'plans': shape.plans, 'steps': shape.steps, 'sent': merged.sent,
            'success': merged.success, 'busy': merged.busy, 'failures': merged.failures,
            'request_kb': merged.request_kb, 'answer_kb': merged.success_answer_kb,
            'p50_ms': percentile_ms(merged.success_latencies, 50),
            'p99_ms': percentile_ms(merged.success_latencies, 99)}


def main() -> int:
    """Replay, collect, recompute, compare; print JSON."""
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--model', required=True, type=Path, help='snuboat checkpoint')
    parser.add_argument('--bag', required=True, type=Path, help='a held-out snuboat bag')
    parser.add_argument('--msg-dir', type=Path, default=REPO.parent / 'shared' / 'real' /
                        'snuboat' / 'msg', help="the boat's .msg folder")
    parser.add_argument('--seconds', type=float, default=40.0, help='how much to replay')
    parser.add_argument('--threshold', type=served_threshold, default=THRESHOLD,
                        help='the relative threshold served (default 0.15); "own": the '
                             "checkpoint's own, with its bands (a threshold of another "
                             'serves none)')
    parser.add_argument('--load-plans', type=int, default=0,
                        help="plans in a planner's request timed end to end (0: none)")
    parser.add_argument('--load-steps', type=int, default=100,
                        help="steps of each of its plans: the predictor's horizon (100)")
    parser.add_argument('--load-seconds', type=float, default=15.0,
                        help='how long such requests are sent, from the first forecast '
                             '(15)')
    args = parser.parse_args()
    if 'SNUBOAT_REPLAY_WORK' not in os.environ:
        # The built package's libraries must be on the loader path before the process
        # starts: build, then run this script again in that environment.
        work = Path(tempfile.mkdtemp(prefix='snuboat_replay_'))
        prefix = build_messages(args.msg_dir, work) / 'snumsg_pkg'
        site = next(prefix.glob('lib/python*/site-packages'))
        env = dict(os.environ, SNUBOAT_REPLAY_WORK=str(work), PYTHONUNBUFFERED='1',
                   AMENT_PREFIX_PATH=f'{prefix}:' + os.environ.get('AMENT_PREFIX_PATH', ''),
                   PYTHONPATH=f'{site}:' + os.environ.get('PYTHONPATH', ''),
                   LD_LIBRARY_PATH=f'{prefix / "lib"}:' + os.environ.get('LD_LIBRARY_PATH', ''))
        os.execve(sys.executable, [sys.executable, *sys.argv], env)
    work = Path(os.environ['SNUBOAT_REPLAY_WORK'])
    env = dict(os.environ)

    from builtin_interfaces.msg import Time
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from snumsg_pkg.msg import Control, Sensor
    from vessel_bringup.processes import Children, rclpy_options

    from hybrid_models.engine import Forecaster
    from hybrid_predictor.plan_message import control_plan
    from hybrid_predictor.re_forecast import ReForecast, ReForecastError, predictor_defaults
    from hybrid_predictor_interfaces.msg import Forecast
    from hybrid_predictor_interfaces.srv import Predict
    from vessel_datasets.topic_map import ACTUATOR_PREFIX, topic_map_for
    from vessel_datasets.topic_messages import channel_reader
    from vessel_description import load_vessel
    from vessel_ros_bridge.messages import seconds_from_stamp

    messages = bag_messages(args.bag, args.msg_dir)
    vessel = load_vessel('snuboat')
    load_params = {'horizon': args.load_steps, 'max_plans': args.load_plans} \
        if args.load_plans else {}
    # The predictor is stopped however this block ends (an error, Ctrl-C, SIGTERM).
    with Children(work) as children:
        predictor = children.node('hybrid_predictor', 'predictor', params={
            'model_path': str(args.model), 'vessel': 'snuboat',
            **({} if args.threshold is None else {'relative_threshold': args.threshold}),
            **load_params}, env=env)
        load = None
        if args.load_plans:
            sys.path.insert(0, str(REPO / 'offline'))
            from benchmarks.soak import ProcessLoads, RequestShape
            from benchmarks.what_if import candidate_plans

            shape = RequestShape(args.load_plans, 0.0, 0.0, args.load_steps)
            load = ProcessLoads(children, work, 1, 1, 1, shape, 0.2, 'c', Predict.Request(
                plans=candidate_plans(vessel, args.load_plans, args.load_steps)))
        rclpy.init(**rclpy_options())
        node = rclpy.create_node('snuboat_replay')
        forecasts = []
        node.create_subscription(Forecast, '/vessel/forecast', forecasts.append, 100)
        client = node.create_client(Predict, '/vessel/predictor/predict')
        pubs = {'/sensor': node.create_publisher(Sensor, '/sensor', 100),
                '/ctrl_fb_boat': node.create_publisher(Control, '/ctrl_fb_boat', 100)}
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        deadline = time.monotonic() + 60
        while 'compiled in' not in (work / 'predictor.log').read_text():
            if time.monotonic() > deadline or predictor.poll() is not None:
                sys.exit('replay: error: the predictor did not start: '
                         + (work / 'predictor.log').read_text()[-1000:])
            executor.spin_once(timeout_sec=0.2)

        if load is not None:
            load.wait_ready()
        topic_map = topic_map_for(vessel)
        readers = {t: channel_reader(topic_map, t) for t in TOPICS}
        sent = []  # (wall time s, topic, channel values) as the predictor timed them
        t0_bag, t0_wall = messages[0][0], time.monotonic()
        asks, answers, pending = None, {}, None

        def serve_asks() -> None:
            # One what-if request in flight: keep the answer of a finished one, send the next.
            nonlocal pending
            if pending is not None and pending[1].done():
                answers[pending[0]] = pending[1].result()
                pending = None
            if pending is None and asks:
                name, request = asks.pop(0)
                pending = (name, client.call_async(request))

        for log_ns, topic, msg in messages:
            if (log_ns - t0_bag) * 1e-9 > args.seconds:
                break
            if asks is None and forecasts:
                if load is not None:
                    load.begin(args.load_seconds)
                # The predictor forecasts, so its window is full: ask while the bag plays.
                latest = {k: v for _, t, values in sent if t == '/ctrl_fb_boat'
                          for k, v in values.items()}
                asks = what_if_requests(vessel, forecasts[0].horizon,
                                        {k: latest[ACTUATOR_PREFIX + k]
                                         for k in ('n_port', 'n_stbd')}, control_plan)
            serve_asks()
            while time.monotonic() - t0_wall < (log_ns - t0_bag) * 1e-9:
                executor.spin_once(timeout_sec=0.002)
            tick = Time(sec=int(msg.tick.sec), nanosec=int(msg.tick.nanosec))
            if topic == '/sensor':
                out = Sensor(tick=tick, status=msg.status, pose=[float(x) for x in msg.pose],
                             vel=[float(x) for x in msg.vel])
            else:
                out = Control(tick=tick, ctrl=[float(x) for x in msg.ctrl])
            pubs[topic].publish(out)
            try:
                sent.append((time.time(), topic, readers[topic](msg)))
            except ValueError:
                pass
        end = time.monotonic() + 3
        while time.monotonic() < end or ((asks or pending) and time.monotonic() < end + 30):
            executor.spin_once(timeout_sec=0.05)
            serve_asks()
        if load is not None:
            load.settle(args.load_seconds)
    what_if = {name: {'success': a.success, 'message': a.message,
                      'forecasts': len(a.forecasts),
                      'control_names': list(a.forecasts[0].control_names)
                      if a.forecasts else None,
                      'finite': bool(all(np.isfinite(f.hybrid).all() for f in a.forecasts))}
               for name, a in answers.items()}

    # Recomputed by the predictor's own re-forecast (hybrid_predictor.re_forecast) from the
    # samples as they were sent: these types carry no header, so the node stamped each on
    # arrival, a few milliseconds after the time kept here (ARRIVAL_SLACK).
    kept = ReForecast(Forecaster.from_checkpoint(args.model, args.threshold), topic_map,
                      predictor_defaults())
    for t, topic, values in sent:
        kept.add_sample(topic, t, values)
    compared, not_compared = [], {}
    for fc in forecasts:
        try:
            compared.append(kept.difference(fc, ARRIVAL_SLACK))
        except ReForecastError as exc:
            not_compared[f'{seconds_from_stamp(fc.header.stamp):.3f}'] = str(exc)
    diffs = np.array([[d.relative[n] for n in vessel.state_names] for d in compared])
    print(json.dumps({
        'bag': args.bag.name, 'replayed_s': args.seconds,
        'messages_published': len([s for s in sent]), 'forecasts_published': len(forecasts),
        'forecasts_compared': int(len(diffs)),
        'why_not_compared': dict(list(not_compared.items())[:5]),
        'forecasts_within_1e-3': None if not len(diffs) else
        int((diffs.max(axis=1) < 1e-3).sum()),
        'state_names': list(forecasts[0].state_names) if forecasts else None,
        'control_names': list(forecasts[0].control_names) if forecasts else None,
        'max_relative_difference_online_vs_offline': None if not len(diffs) else
        dict(zip(vessel.state_names, diffs.max(axis=0).round(6).tolist(), strict=True)),
        'median_relative_difference': None if not len(diffs) else
        dict(zip(vessel.state_names, np.median(diffs, axis=0).round(6).tolist(),
                 strict=True)),
        'what_if': what_if,
        'what_if_load': None if load is None else load_figures(load.figures(), shape),
    }, indent=2))
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
