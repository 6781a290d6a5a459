"""
The predictor for the paper's second vehicle: a quadrotor at 100 Hz, forecasts in space.

A Crazyflie 2.1 Brushless hybrid (MinQ + Lin physics) is trained in seconds on 6-DOF
flights (tests/unit/tracks.spatial_flight), then the installed predictor is started with
the shipped vehicle file and fed over DDS at 100 Hz on the topics that file names
(odometry with the pose and the FLU twist, rotor speeds as joint velocities). Its
forecasts must carry the eight states, 100 steps and the track's height, equal their
offline recomputation from the same messages (hybrid_predictor.re_forecast), and its
what-if service must answer plans in the rotors' speeds and refuse one in rpm.
"""

from pathlib import Path
import time

import numpy as np
import pandas as pd
import pytest

from .conftest import answer_of, spin_until

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
STATES = ('u', 'v', 'w', 'p', 'q', 'r', 'phi', 'theta')


def flight_table(truth) -> pd.DataFrame:
    table = {'t': truth['t'], **{s: truth[s] for s in STATES}, 'psi': truth['psi'],
             'x': truth['x'], 'y': truth['y'], 'z': truth['z']}
    table.update({f'm{i + 1}': truth['motors'][i] for i in range(4)})
    return pd.DataFrame(table)


@pytest.fixture(scope='module')
def quad_model(tmp_path_factory):
    """Return the checkpoint of a smoke-trained MinQ+Lin hybrid of the Crazyflie."""
    from hybrid_models.training import train
    from hybrid_models.training.config import load_config
    from tests.unit.tracks import spatial_flight
    from vessel_datasets.format import write_dataset
    from vessel_description import load_vessel

    root = tmp_path_factory.mktemp('quad')
    runs = {f'flight{k}': flight_table(spatial_flight(seconds=8.0, seed=k)) for k in range(4)}
    write_dataset(root / 'ds', runs, vessel=load_vessel('crazyflie_brushless'),
                  provenance={'tool': 'test'},
                  split={'train': ['flight0', 'flight1'], 'val': ['flight2'],
                         'test': ['flight3']})
    cfg = load_config(REPO / 'ros2_ws/src/hybrid_models/config/smoke.yaml',
                      [f'dataset={root / "ds"}', 'model.physical.kind=minq+lin',
                       'training.window=null', 'training.validation={}', 'evaluation={}',
                       'training.progress=false',
                       'training.phases=[{kind: teacher, max_epochs: 1, patience: 1, '
                       'lr: 0.005}, {kind: multistep, max_epochs: 1, patience: 1, '
                       'lr: 0.003}]'])
    train(cfg, root / 'run')
    return root / 'run' / 'model.safetensors'


def test_the_predictor_forecasts_a_quadrotor_in_space_equal_to_its_offline_recomputation(
        quad_model, launcher, ros_node):
    from diagnostic_msgs.msg import DiagnosticArray
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from hybrid_models.engine import Forecaster
    from hybrid_predictor.re_forecast import ReForecast, compare, predictor_defaults
    from hybrid_predictor.replay import RunReplay
    from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
    from hybrid_predictor_interfaces.srv import Predict
    from tests.unit.tracks import spatial_flight
    from vessel_datasets.topic_map import topic_map_for
    from vessel_description import load_vessel

    forecasts, diagnostics = [], []
    ros_node.create_subscription(Forecast, '/vessel/forecast', forecasts.append, 100)
    ros_node.create_subscription(DiagnosticArray, '/diagnostics', diagnostics.append, 10)
    predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                    '-p', f'model_path:={quad_model}',
                                    '-p', 'vessel:=crazyflie_brushless',
                                    '-p', 'forecast_period:=0.0')   # one per state
    assert spin_until(ros_node, lambda: 'compiled in' in predictor.output(), 90), \
        predictor.output()

    vehicle = load_vessel('crazyflie_brushless')
    topic_map = topic_map_for(vehicle)
    replay = RunReplay(ros_node, topic_map, {'/vessel/odom': Odometry,
                                             '/vessel/actuators': JointState})
    flight = flight_table(spatial_flight(seconds=3.0, seed=9))
    executor = SingleThreadedExecutor(context=ros_node.context)
    executor.add_node(ros_node)
    try:
        replay.play(flight, time.time(), lambda s: executor.spin_once(timeout_sec=s))
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline and len(forecasts) < 10:
            executor.spin_once(timeout_sec=0.05)
    finally:
        executor.remove_node(ros_node)
        executor.shutdown()
    # 2.5 s of states after the 0.5 s window, one forecast per state message as far as the
    # node keeps up (its schedule skips, never queues; how fast it keeps up at 100 Hz is
    # the forecast benchmark's to measure, not a verdict here).
    assert len(forecasts) >= 10, (len(forecasts), predictor.output()[-2000:])

    # What-if in the rotors' own speeds (rad/s), asked while the window is fresh; a plan
    # in rpm is refused in one line.
    client = ros_node.create_client(Predict, '/vessel/predictor/predict')
    assert client.wait_for_service(timeout_sec=10)
    hover = float(np.mean(flight[['m1', 'm2', 'm3', 'm4']].to_numpy()[-1]))

    def plan(speeds, units='rad/s'):
        return ControlPlan(control_names=['m1', 'm2', 'm3', 'm4'], control_units=[units] * 4,
                           values=list(speeds) * 100, step_period=0.01)

    answer = answer_of(ros_node, client, Predict.Request(plans=[
        plan([hover] * 4), plan([hover * 1.1, hover * 0.9, hover * 1.1, hover * 0.9])]))
    assert answer.success, answer.message
    assert [len(f.z) for f in answer.forecasts] == [100, 100]
    assert answer.forecasts[0].hybrid != answer.forecasts[1].hybrid
    refused = answer_of(ros_node, client, Predict.Request(plans=[plan([15000.0] * 4, 'rpm')]))
    assert not refused.success and 'rpm' in refused.message and '\n' not in refused.message

    msg = forecasts[-1]
    assert msg.vessel == 'crazyflie_brushless' and list(msg.state_names) == list(STATES)
    assert list(msg.control_names) == ['m1', 'm2', 'm3', 'm4']
    assert msg.horizon == 100 and msg.step_period == pytest.approx(0.01)
    assert len(msg.x) == len(msg.y) == len(msg.z) == 100
    assert np.isfinite(msg.hybrid).all() and np.isfinite(msg.z).all()
    # Live = offline: every forecast recomputed from the messages as they were sent, but
    # for those the node had to make before a state's rotor speeds arrived (under load;
    # counted on /diagnostics): so does the demo.
    seen = len(diagnostics)
    assert spin_until(ros_node, lambda: len(diagnostics) > seen, 10)
    status = {kv.key: kv.value for s in diagnostics[-1].status
              if s.name.endswith(': forecast') for kv in s.values}
    late = int(status['forecasts_before_sample_complete'])
    # The node serves the checkpoint's own threshold (a schedule here, which the message
    # reports by its loosest entry): so does the offline engine.
    kept = ReForecast(Forecaster.from_checkpoint(quad_model), topic_map, predictor_defaults())
    for t, topic, values in replay.sent:
        kept.add_sample(topic, t, values)
    summary = compare(kept, forecasts)
    assert summary['compared'] == len(forecasts), summary
    assert summary['unequal_count'] <= late, (summary, late)
    assert summary['compared'] - late >= 10, (summary, late)


@pytest.mark.slow   # two node processes timed at 100 Hz: about 35 s
def test_the_rate_benchmark_times_the_predictor_and_its_floor(quad_model):
    # offline/bench.py forecast's 100 Hz figures: the predictor, one forecast per state,
    # and the floor of the same replay and receiver, a stand-in that answers at once.
    from offline.benchmarks.node_rate import measure

    floor = measure(quad_model, 'crazyflie_brushless', 60, stand_in=True)
    assert floor['stand_in'] and floor['states_timed'] == 61, floor
    assert floor['share_received'] == 1.0 and 0 < floor['p50_ms'] <= floor['p99_ms'], floor
    served = measure(quad_model, 'crazyflie_brushless', 60)
    counts = served['predictor_counts']
    assert 0 < served['forecasts_received'] <= counts['forecasts_published'], served
    assert counts['forecasts_published'] + counts['forecasts_withheld'] <= 61, served
    assert set(served['predictor_latency_ms']) == {'p50', 'p99'}, served
    assert not served['predictor_warnings'] or all(
        'withheld' in w for w in served['predictor_warnings']), served
