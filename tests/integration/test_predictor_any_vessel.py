"""
The predictor for a vessel that is not ours: its own topics, vectors and checkpoint.

A 3-DOF skiff (one propeller, one rudder, no wind, 10 Hz; tests/unit/test_any_vessel.py)
is trained in seconds, then the installed predictor is started with its vessel file and
checkpoint, fed over DDS on the skiff's topics, and must publish forecasts with the
skiff's state and control names, in the odometry's frames, and answer what-if plans
in the skiff's own controls. A checkpoint of another vessel is refused in one line.
"""

from pathlib import Path
import time

import numpy as np
import pytest
import yaml

from .conftest import spin_until

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def skiff_model(tmp_path_factory):
    """Return (vessel file, checkpoint) of a smoke-trained skiff hybrid."""
    from hybrid_models.training import train
    from hybrid_models.training.config import load_config
    from tests.unit.test_any_vessel import RATE_HZ, VESSEL, simulate, write_bag
    from vessel_datasets import bag_to_dataset

    root = tmp_path_factory.mktemp('skiff')
    vessel_file = root / 'skiff.yaml'
    vessel_file.write_text(yaml.safe_dump(VESSEL, sort_keys=False))
    bags = [write_bag(root / f'bag{i}', simulate(i, int(120 * RATE_HZ)), 1000.0 + 300.0 * i)
            for i in range(5)]
    assert bag_to_dataset.main([*map(str, bags), '--vessel', str(vessel_file), '--out',
                                str(root / 'ds'), '--quiet']) == 0
    cfg = load_config(REPO / 'ros2_ws/src/hybrid_models/config/smoke.yaml',
                      [f'dataset={root / "ds"}', 'training.window=null',
                       'training.validation={}', 'evaluation={}', 'training.progress=false'])
    train(cfg, root / 'run')
    return vessel_file, root / 'run' / 'model.safetensors'


def publish_skiff(node, seconds: float, rate_hz: float = 10.0):
    """Publish the skiff's odometry and joints, stamped with the wall clock, for a while."""
    from nav_msgs.msg import Odometry
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState

    from vessel_ros_bridge import messages as m

    odom_pub = node.create_publisher(Odometry, '/skiff/odom', 50)
    joint_pub = node.create_publisher(JointState, '/skiff/joints', 50)
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        for k in range(int(seconds * rate_hz)):
            stamp = m.stamp_from_seconds(time.time())
            odom = Odometry()
            odom.header.stamp, odom.header.frame_id = stamp, 'odom'
            odom.pose.pose.position.x = 0.8 * k / rate_hz
            odom.pose.pose.orientation.w = 1.0
            odom.twist.twist.linear.x = 0.8
            odom.twist.twist.angular.z = -0.05  # FLU: turning to starboard
            odom_pub.publish(odom)
            joints = JointState(name=['prop', 'rudder'], position=[0.0, 0.1],
                                velocity=[25.0, 0.0])
            joints.header.stamp = stamp
            joint_pub.publish(joints)
            executor.spin_once(timeout_sec=1.0 / rate_hz)
    finally:
        executor.remove_node(node)
        executor.shutdown()


def test_predictor_serves_a_foreign_vessel_on_its_own_topics(skiff_model, launcher,
                                                             ros_node):
    from hybrid_predictor_interfaces.msg import ControlPlan, Forecast
    from hybrid_predictor_interfaces.srv import Predict

    vessel_file, checkpoint = skiff_model
    forecasts = []
    ros_node.create_subscription(Forecast, '/vessel/forecast', forecasts.append, 10)
    predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                    '-p', f'model_path:={checkpoint}',
                                    '-p', f'vessel:={vessel_file}')
    assert spin_until(ros_node, lambda: 'compiled in' in predictor.output(), 60), \
        predictor.output()
    publish_skiff(ros_node, seconds=5.0)
    assert spin_until(ros_node, lambda: forecasts, 10), predictor.output()
    msg = forecasts[-1]
    assert msg.vessel == 'skiff'
    assert list(msg.state_names) == ['u', 'v', 'r'] and list(msg.state_units) == [
        'm/s', 'm/s', 'rad/s']
    assert list(msg.control_names) == ['n', 'delta']
    assert msg.horizon == 100 and msg.step_period == pytest.approx(0.1)
    hybrid = np.reshape(msg.hybrid, (100, 3))
    assert np.isfinite(hybrid).all()
    assert hybrid[0, 0] == pytest.approx(0.8, abs=0.5)  # starts near the measured surge
    # The forecast speaks the odometry's convention (REP-103): FLU rates, ENU heading.
    odom_r = -0.05
    assert msg.child_frame_id == 'base_link'
    assert np.sign(hybrid[0, 2]) == np.sign(odom_r) and abs(hybrid[0, 2] - odom_r) < 0.03
    np.testing.assert_allclose(np.diff(msg.heading), hybrid[1:, 2] * msg.step_period,
                               rtol=0.05, atol=1e-4)
    # Calibrated bands with every forecast, around it, in its frame, never narrowing.
    assert list(msg.band_levels) == [0.5, 0.9], msg.band_note
    lower = np.reshape(msg.band_lower, (2, 100, 3))
    upper = np.reshape(msg.band_upper, (2, 100, 3))
    radius = np.reshape(msg.band_position_radius, (2, 100))
    width = upper - lower
    assert np.all(width >= 0) and np.all(width[1] >= width[0] - 1e-12)
    assert np.all(np.diff(width, axis=1) >= -1e-9) and np.all(np.diff(radius, axis=1) >= -1e-9)
    # What-if in the skiff's own controls (n, delta); the patrol boat's are refused.
    client = ros_node.create_client(Predict, '/vessel/predictor/predict')
    assert client.wait_for_service(timeout_sec=10)

    def ask(*plans):
        future = client.call_async(Predict.Request(plans=list(plans)))
        assert spin_until(ros_node, future.done, 10)
        return future.result()

    def skiff_plan(rudder, names=('n', 'delta'), units=('rad/s', 'rad')):
        return ControlPlan(control_names=list(names), control_units=list(units),
                           values=[25.0, rudder] * 100)

    publish_skiff(ros_node, seconds=1.0)     # keep the window fresh
    answer = ask(skiff_plan(-0.3), skiff_plan(0.3))
    assert answer.success, answer.message
    assert [list(f.control_names) for f in answer.forecasts] == [['n', 'delta']] * 2
    assert answer.forecasts[0].hybrid != answer.forecasts[1].hybrid
    assert all(list(f.band_levels) == [0.5, 0.9] for f in answer.forecasts)   # what-ifs too
    refused = ask(ControlPlan(control_names=['n', 'delta_port', 'delta_stbd'],
                              control_units=['rad/s', 'rad', 'rad'], values=[25.0, 0, 0] * 100))
    assert not refused.success and "not among the controls of vessel 'skiff'" in \
        refused.message and '\n' not in refused.message
    wrong_unit = ask(skiff_plan(0.0, units=('rpm', 'rad')))
    assert not wrong_unit.success and "n in 'rpm'" in wrong_unit.message


def test_a_checkpoint_of_another_vessel_is_refused_at_start(skiff_model, launcher, ros_node):
    vessel_file, _ = skiff_model
    predictor = launcher.start_node('hybrid_predictor', 'predictor', '--ros-args',
                                    '-p', f'vessel:={vessel_file}')
    assert predictor.popen.wait(60) == 2
    lines = [line for line in predictor.output().splitlines() if 'error' in line.lower()]
    assert lines and "made for vessel 'patrol_boat'" in lines[-1], predictor.output()
