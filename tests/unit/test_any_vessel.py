"""
A vessel that is not ours, end to end: 3-DOF, one propeller, one rudder, no wind, 10 Hz.

The tests record its own small simulator as rosbag2 bags with standard message types,
describe it with a vessel file only (no code), convert, train a smoke model, evaluate,
and check every refusal: another rate, a checkpoint of another vessel, a physical model
without hull parameters. Reversing thrust keeps its sign.
"""

import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
import yaml

from hybrid_models.checkpoint import load_model
from hybrid_models.cli import evaluate
from hybrid_models.physical import build_physical
from hybrid_models.training import train
from hybrid_models.training.config import load_config
from vessel_datasets import bag_to_dataset
from vessel_datasets.format import read_dataset
from vessel_description import load_vessel, parse_vessel
from vessel_physics import frames
from vessel_physics.patrol.forces import unit_thrust
from vessel_physics.physics_file import load_physics

REPO = Path(__file__).resolve().parents[2]
RATE_HZ, RUN_S = 10.0, 180.0
VESSEL = {
    'name': 'skiff', 'rate_hz': RATE_HZ, 'window_s': 2.0, 'horizon_s': 10.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-2.0, 4.0], 'v': [-1.0, 1.0], 'r': [-1.0, 1.0]},
    'actuators': {'n': {'kind': 'propeller', 'range': [-30.0, 60.0]},
                  'delta': {'kind': 'rudder', 'range': [-0.6, 0.6]}},
    'particulars': {'length_m': 2.0},
    'recordings': {'topics': {
        'body_velocity': {'frame': 'flu',
                          'surge': {'topic': '/skiff/odom', 'field': 'twist.twist.linear.x',
                                    'type': 'nav_msgs/msg/Odometry'},
                          'sway': {'topic': '/skiff/odom', 'field': 'twist.twist.linear.y'},
                          'yaw_rate': {'topic': '/skiff/odom',
                                       'field': 'twist.twist.angular.z'}},
        'attitude': {'frame': 'enu_flu',
                     'quaternion': {'topic': '/skiff/odom', 'field': 'pose.pose.orientation'}},
        'position': {'frame': 'enu',
                     'point': {'topic': '/skiff/odom', 'field': 'pose.pose.position'}},
        'actuators': {'n': {'topic': '/skiff/joints', 'field': 'velocity[prop]',
                            'type': 'sensor_msgs/msg/JointState'},
                      'delta': {'topic': '/skiff/joints', 'field': 'position[rudder]'}},
    }},
}


def simulate(seed: int, n: int) -> dict[str, np.ndarray]:
    """Return a skiff run in model frames: a propeller that also reverses, a rudder."""
    rng = np.random.default_rng(seed)
    dt = 1.0 / RATE_HZ
    hold = int(8 * RATE_HZ)
    shaft = np.repeat(rng.uniform(-20.0, 50.0, n // hold + 1), hold)[:n]
    rudder = np.repeat(rng.uniform(-0.5, 0.5, n // hold + 1), hold)[:n]
    u = v = r = psi = x = y = 0.0
    out = {k: np.empty(n) for k in ('u', 'v', 'r', 'psi', 'x', 'y')}
    for k in range(n):
        for key, value in zip(('u', 'v', 'r', 'psi', 'x', 'y'), (u, v, r, psi, x, y),
                              strict=True):
            out[key][k] = value
        thrust = 1e-3 * shaft[k] * abs(shaft[k])
        u += dt * (thrust - 0.4 * u * abs(u))
        v += dt * (-1.2 * v - 0.3 * u * r)
        r += dt * (-r + 0.8 * u * rudder[k]) / 1.5
        psi += dt * r
        x += dt * (u * math.cos(psi) - v * math.sin(psi))
        y += dt * (u * math.sin(psi) + v * math.cos(psi))
    return {**out, 'n': shaft, 'delta': rudder}


def write_bag(path: Path, run: dict[str, np.ndarray], start_s: float) -> Path:
    """Record a run as a foreign vessel's driver would: Odometry (ENU/FLU), JointState."""
    store = get_typestore(Stores.ROS2_JAZZY)
    T = store.types
    east, north, _ = frames.position_ned_to_enu(run['x'], run['y'])
    qx, qy, qz, qw = frames.orientation_ned_to_enu(np.zeros_like(run['psi']), run['psi'])
    vx, vy, _, wz = frames.twist_frd_to_flu(run['u'], run['v'], 0.0 * run['u'], run['r'])
    vector, zero = T['geometry_msgs/msg/Vector3'], np.zeros(36)
    with Writer(path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP) as w:
        odom = w.add_connection('/skiff/odom', 'nav_msgs/msg/Odometry', typestore=store)
        joints = w.add_connection('/skiff/joints', 'sensor_msgs/msg/JointState',
                                  typestore=store)
        for k in range(len(run['u'])):
            ns = int(round((start_s + k / RATE_HZ) * 1e9))
            header = T['std_msgs/msg/Header'](
                stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
                frame_id='odom')
            msg = T['nav_msgs/msg/Odometry'](
                header=header, child_frame_id='base_link',
                pose=T['geometry_msgs/msg/PoseWithCovariance'](
                    pose=T['geometry_msgs/msg/Pose'](
                        position=T['geometry_msgs/msg/Point'](x=float(east[k]),
                                                              y=float(north[k]), z=0.0),
                        orientation=T['geometry_msgs/msg/Quaternion'](
                            x=float(qx[k]), y=float(qy[k]), z=float(qz[k]), w=float(qw[k]))),
                    covariance=zero),
                twist=T['geometry_msgs/msg/TwistWithCovariance'](
                    twist=T['geometry_msgs/msg/Twist'](
                        linear=vector(x=float(vx[k]), y=float(vy[k]), z=0.0),
                        angular=vector(x=0.0, y=0.0, z=float(wz[k]))),
                    covariance=zero))
            w.write(odom, ns, store.serialize_cdr(msg, 'nav_msgs/msg/Odometry'))
            state = T['sensor_msgs/msg/JointState'](
                header=header, name=['prop', 'rudder'],
                position=np.array([0.0, run['delta'][k]]),
                velocity=np.array([run['n'][k], 0.0]), effort=np.zeros(0))
            w.write(joints, ns, store.serialize_cdr(state, 'sensor_msgs/msg/JointState'))
    return path


@pytest.fixture(scope='module')
def skiff(tmp_path_factory):
    """Eight 3-minute bags, the vessel file, and the converted dataset."""
    root = tmp_path_factory.mktemp('skiff')
    n = int(RUN_S * RATE_HZ)
    runs = {i: simulate(i, n) for i in range(8)}
    bags = [write_bag(root / f'bag{i}', run, 1000.0 + 400.0 * i) for i, run in runs.items()]
    vessel_file = root / 'skiff.yaml'
    vessel_file.write_text(yaml.safe_dump(VESSEL, sort_keys=False))
    dataset = root / 'dataset'
    assert bag_to_dataset.main([*map(str, bags), '--vessel', str(vessel_file), '--out',
                                str(dataset), '--quiet']) == 0
    return {'root': root, 'bags': bags, 'vessel': vessel_file, 'dataset': dataset,
            'runs': runs}


def test_a_vessel_file_alone_turns_its_bags_into_a_dataset(skiff):
    ds = read_dataset(skiff['dataset'])
    vessel = ds.vessel
    assert vessel.name == 'skiff' and ds.rate_hz == RATE_HZ
    table = ds.load(ds.run_ids()[0])
    assert list(table.columns) == ['t', 'u', 'v', 'r', 'psi', 'x', 'y', 'n', 'delta']
    assert len(table) >= RUN_S * RATE_HZ - 1
    truth = skiff['runs'][int(ds.run_ids()[0][3])]
    np.testing.assert_allclose(table['n'], truth['n'][:len(table)], atol=1e-9)
    assert table['n'].min() < 0  # reversing survives conversion, sign intact
    np.testing.assert_allclose(table['r'], truth['r'][:len(table)], atol=1e-6)


def test_train_and_evaluate_a_3dof_vessel(skiff, tmp_path, capsys):
    cfg = load_config(REPO / 'ros2_ws/src/hybrid_models/config/smoke.yaml',
                      [f'dataset={skiff["dataset"]}', 'model.physical.kind=hyd',
                       'training.window=null', 'training.validation={}',
                       'evaluation={}', 'training.progress=false'])
    summary = train(cfg, tmp_path / 'run')
    assert summary['vehicle']['name'] == 'skiff'
    assert summary['training']['training']['window'] == 20  # the vessel's 2 s at 10 Hz
    model, ckpt = load_model(tmp_path / 'run' / 'model.safetensors')
    assert model.spec.state_names == ('u', 'v', 'r')
    assert model.spec.control_names == ('n', 'delta')
    assert evaluate.main([str(tmp_path / 'run'), '--dataset', str(skiff['dataset']),
                          '--out', str(tmp_path / 'eval'), '--physics-only']) == 0
    table = (tmp_path / 'eval' / 'table.md').read_text()
    assert '| r [rad/s] |' in table and 'phi' not in table
    # A dataset at another rate is refused by the model trained at 10 Hz, in one line.
    faster = skiff['root'] / 'skiff20.yaml'
    faster.write_text(yaml.safe_dump({**VESSEL, 'rate_hz': 20.0}, sort_keys=False))
    assert bag_to_dataset.main([*map(str, skiff['bags'][:3]), '--vessel', str(faster),
                                '--out', str(tmp_path / 'ds20'), '--quiet']) == 0
    capsys.readouterr()
    assert evaluate.main([str(tmp_path / 'run'), '--dataset', str(tmp_path / 'ds20'),
                          '--out', str(tmp_path / 'eval20')]) == 2
    err = capsys.readouterr().err.strip()
    assert 'rate_hz 10.0 vs 20.0' in err and len(err.splitlines()) == 1


def test_a_checkpoint_of_another_vessel_is_refused(skiff, tmp_path, capsys):
    default = REPO / 'ros2_ws/src/hybrid_predictor/models/default/model.safetensors'
    assert evaluate.main([str(default), '--dataset', str(skiff['dataset']),
                          '--out', str(tmp_path / 'eval')]) == 2
    err = capsys.readouterr().err.strip()
    assert "made for vessel 'patrol_boat'" in err and len(err.splitlines()) == 1


def test_a_window_longer_than_every_run_is_refused_before_training(skiff, tmp_path):
    cfg = load_config(REPO / 'ros2_ws/src/hybrid_models/config/smoke.yaml',
                      [f'dataset={skiff["dataset"]}', 'evaluation.horizon=5000'])
    with pytest.raises(ValueError, match='no test run is long enough'):
        train(cfg, tmp_path / 'run')
    assert not (tmp_path / 'run').exists()  # refused before anything was written


def test_physics_without_hull_parameters_is_refused():
    skiff = parse_vessel(VESSEL)
    with pytest.raises(ValueError, match="needs physics, and vessel 'skiff' names none"):
        build_physical({'kind': 'min'}, skiff)
    with pytest.raises(ValueError, match='use a regression physics'):
        build_physical({'kind': 'pro', 'params': 'nominal_vessel'}, skiff)
    assert build_physical({'kind': 'hyd'}, skiff).features.names[-1] == 'r|r|'
    assert build_physical({'kind': 'pro'}, load_vessel('patrol_boat')) is not None


def test_reversing_thrust_pulls_astern():
    params = load_physics('nominal_vessel').params
    ahead = unit_thrust(np.array(2.0), 0.0, np.array(5.0), np.array(0.0), params)
    astern = unit_thrust(np.array(2.0), 0.0, np.array(-5.0), np.array(0.0), params)
    assert ahead > 0 and astern < 0
