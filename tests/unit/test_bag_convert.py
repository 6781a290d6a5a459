"""
End-to-end conversion of real bag files.

Exact round trip, counted drops and gaps, a foreign vessel mapped without code, clear
errors, and the command line (manifest, split, parallel bags).
"""

import math
from pathlib import Path
import subprocess
import sys

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from vessel_datasets import bag_to_dataset, synthetic
from vessel_datasets import format as fmt
from vessel_datasets.bag_source import find_bags
from vessel_datasets.quantities import local_projection
from vessel_datasets.readers.bags import bag_to_runs, convert_bag
from vessel_datasets.sources import sha256
from vessel_datasets.topic_map import parse_topic_map, topic_map_for
from vessel_description import load_vessel
from vessel_physics import frames

SHIP = load_vessel('patrol_boat')

REPO = Path(__file__).resolve().parents[2]
STORE = get_typestore(Stores.ROS2_JAZZY)
S = 1_000_000_000


def assert_matches(table, traj, step=1, atol=1e-9):
    """Compare a run table to the trajectory sampled every ``step`` samples."""
    for column, values in traj.columns.items():
        ref = values[::step][:len(table)]
        if column in ('x', 'y'):
            ref = ref - ref[0]
        np.testing.assert_allclose(table[column].to_numpy(), ref, atol=atol, rtol=0,
                                   err_msg=column)


def test_round_trip_is_exact(tmp_path):
    traj = synthetic.demo_trajectory(600)
    runs = bag_to_runs(synthetic.write_bag(tmp_path / 'bag', traj), topic_map_for(SHIP))
    (table,) = runs.values()
    assert list(table.columns) == list(SHIP.dataset_columns)
    assert table['t'].tolist() == list(map(float, range(600)))
    assert_matches(table, traj, atol=1e-12)


def write_damaged_bag(path):
    """
    Write 200 s of data with flaws of known number.

    Odometry: 2 NaN, 3 duplicate and 1 out-of-order message; wind: 10 messages missing.
    """
    traj = synthetic.demo_trajectory(200)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {t: w.add_connection(t, m, typestore=STORE)
                 for t, m in synthetic.SIM_TOPICS.items()}
        odoms = {}
        for topic, ns, msg in synthetic.sim_messages(traj, STORE):
            i = (ns - traj.t_ns[0]) // S
            if topic == '/vessel/wind' and 100 <= i < 110:
                continue
            if topic == '/vessel/odom':
                odoms[i] = STORE.serialize_cdr(msg, synthetic.SIM_TOPICS[topic])
                if i in (50, 150):
                    msg.twist.twist.linear.x = math.nan
            raw = STORE.serialize_cdr(msg, synthetic.SIM_TOPICS[topic])
            w.write(conns[topic], ns + 1000, raw)
            if topic == '/vessel/odom' and i in (60, 61, 62):
                w.write(conns[topic], ns + 2000, raw)  # sent twice
            if topic == '/vessel/odom' and i == 70:
                w.write(conns[topic], ns + 3000, odoms[10])  # a stale message arrives late
    return path


def test_drops_and_gaps_are_counted_exactly(tmp_path):
    (bag,) = find_bags([write_damaged_bag(tmp_path / 'damaged')])
    result = convert_bag(bag, topic_map_for(SHIP))
    assert result.error is None
    topics = result.report['sources']
    assert topics['/vessel/odom']['received'] == 204
    assert topics['/vessel/odom']['kept'] == 198
    assert topics['/vessel/odom']['dropped'] == {'nan': 2, 'duplicate': 3, 'out_of_order': 1}
    assert topics['/vessel/wind']['dropped'] == {'nan': 0, 'duplicate': 0, 'out_of_order': 0}
    assert topics['/vessel/wind']['received'] == 190
    (gap,) = result.report['gaps']
    assert gap['sources'] == ['/vessel/wind'] and gap['duration_s'] == 11.0
    assert [r['samples'] for r in result.report['runs']] == [100, 90]
    assert [len(t) for t in result.runs.values()] == [100, 90]


def test_time_source_log_uses_receive_times(tmp_path):
    traj = synthetic.demo_trajectory(50)
    bag = synthetic.write_bag(tmp_path / 'bag', traj, log_delay_ns=S // 4)
    (table,) = bag_to_runs(bag, topic_map_for(SHIP), time_source='log').values()
    assert len(table) == 49  # the grid starts at the first whole second after 0.25 s


def test_missing_topic_lists_what_the_bag_contains(tmp_path):
    bag = synthetic.write_bag(tmp_path / 'bag', synthetic.demo_trajectory(30))
    data = topic_map_for(SHIP).to_dict()
    data['wind']['velocity']['topic'] = '/weather/wind'
    (found,) = find_bags([bag])
    result = convert_bag(found, parse_topic_map(data, SHIP))
    assert result.error == (
        f'{bag}: the topic map needs /weather/wind (wind.velocity), which the bag lacks; '
        'it has: /vessel/actuators (sensor_msgs/msg/JointState, 30 msgs), /vessel/odom '
        '(nav_msgs/msg/Odometry, 30 msgs), /vessel/wind (geometry_msgs/msg/Vector3Stamped, '
        '30 msgs)')


def test_missing_field_lists_the_numeric_fields(tmp_path):
    bag = synthetic.write_bag(tmp_path / 'bag', synthetic.demo_trajectory(30))
    data = topic_map_for(SHIP).to_dict()
    data['body_velocity']['surge']['field'] = 'twist.linear.x'
    (found,) = find_bags([bag])
    result = convert_bag(found, parse_topic_map(data, SHIP))
    assert result.error.startswith(
        f"{bag}: the topic map reads 'twist.linear.x' (body_velocity.surge) from /vessel/odom "
        "(nav_msgs/msg/Odometry): no field 'linear' in geometry_msgs/msg/TwistWithCovariance;"
        ' its numeric fields are: header.stamp.sec, ')
    assert 'twist.twist.linear.x' in result.error and '\n' not in result.error


# A vessel with its own names, types and units: twist and IMU, GNSS, joint states in
# degrees and rpm, and a custom wind message in knots whose definition only the bag has.
FOREIGN_MAP = """
body_velocity:
  frame: flu
  surge: {topic: /nav/twist, field: twist.linear.x, type: geometry_msgs/msg/TwistStamped}
  sway: {topic: /nav/twist, field: twist.linear.y}
  roll_rate: {topic: /imu/data, field: angular_velocity.x}
  yaw_rate: {topic: /imu/data, field: angular_velocity.z}
attitude:
  frame: enu_flu
  quaternion: {topic: /imu/data, field: orientation, type: sensor_msgs/msg/Imu}
position:
  latlon: {topic: /gps/fix, field: '', type: sensor_msgs/msg/NavSatFix}
actuators:
  n: {topic: /propulsion/joints, field: 'velocity[shaft]', scale: 0.10471975511965977}
  delta_port: {topic: /propulsion/joints, field: 'position[azimuth_ps]',
                scale: -0.017453292519943295}
  delta_stbd: {topic: /propulsion/joints, field: 'position[azimuth_sb]',
                scale: -0.017453292519943295}
wind:
  frame: frd
  speed: {topic: /weather/wind, field: speed_knots, scale: 0.5144444444444445}
  from_angle: {topic: /weather/wind, field: angle_deg, scale: 0.017453292519943295}
stamps: {/weather/wind: log}
"""
WIND_MSG = 'std_msgs/Header header\nfloat32 speed_knots\nfloat32 angle_deg\n'
KNOT = 0.5144444444444445
LAT0, LON0 = 59.9, 10.7


def local_to_latlon(north, east):
    """Inverse of the converter's projection (pyproj, centred on the first fix)."""
    lon, lat = local_projection(LAT0, LON0).transform(east, north, direction='INVERSE')
    return np.asarray(lat), np.asarray(lon)


def write_foreign_bag(path, traj):
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(get_types_from_msg(WIND_MSG, 'weather_msgs/msg/WindReading'))
    T = store.types
    c = traj.columns
    vx, vy, wx, wz = frames.twist_frd_to_flu(c['u'], c['v'], c['p'], c['r'])
    q = frames.orientation_ned_to_enu(c['phi'], c['psi'])
    lat, lon = local_to_latlon(c['x'] - c['x'][0], c['y'] - c['y'][0])
    wind_from = np.arctan2(c['wind_dir_sin'], c['wind_dir_cos'])
    types = {'/nav/twist': 'geometry_msgs/msg/TwistStamped', '/imu/data': 'sensor_msgs/msg/Imu',
             '/gps/fix': 'sensor_msgs/msg/NavSatFix',
             '/propulsion/joints': 'sensor_msgs/msg/JointState',
             '/weather/wind': 'weather_msgs/msg/WindReading'}
    every = {'/imu/data': 1, '/nav/twist': 2, '/propulsion/joints': 5, '/gps/fix': 10,
             '/weather/wind': 10}  # 10, 5, 2, 1, 1 Hz on a 10 Hz trajectory
    V3 = T['geometry_msgs/msg/Vector3']

    def message(topic, i, header):
        if topic == '/imu/data':
            return T['sensor_msgs/msg/Imu'](
                header=header, orientation=T['geometry_msgs/msg/Quaternion'](
                    x=q[0][i], y=q[1][i], z=q[2][i], w=q[3][i]),
                orientation_covariance=np.zeros(9),
                angular_velocity=V3(x=wx[i], y=0.0, z=wz[i]),
                angular_velocity_covariance=np.zeros(9),
                linear_acceleration=V3(x=0.0, y=0.0, z=9.81),
                linear_acceleration_covariance=np.zeros(9))
        elif topic == '/nav/twist':
            return T['geometry_msgs/msg/TwistStamped'](
                header=header, twist=T['geometry_msgs/msg/Twist'](
                    linear=V3(x=vx[i], y=vy[i], z=0.0), angular=V3(x=0.0, y=0.0, z=0.0)))
        elif topic == '/propulsion/joints':
            return T['sensor_msgs/msg/JointState'](
                header=header, name=['azimuth_ps', 'shaft', 'azimuth_sb'],
                position=np.array([-np.degrees(c['delta_port'][i]), 0.0,
                                   -np.degrees(c['delta_stbd'][i])]),
                velocity=np.array([0.0, c['n'][i] * 60 / (2 * math.pi), 0.0]),
                effort=np.zeros(0))
        elif topic == '/gps/fix':
            return T['sensor_msgs/msg/NavSatFix'](
                header=header, status=T['sensor_msgs/msg/NavSatStatus'](status=0,
                                                                        service=1),
                latitude=lat[i], longitude=lon[i], altitude=0.0,
                position_covariance=np.zeros(9), position_covariance_type=0)
        elif topic == '/weather/wind':
            return T['weather_msgs/msg/WindReading'](
                header=header, speed_knots=c['wind_speed'][i] / KNOT,
                angle_deg=math.degrees(wind_from[i]))
        raise KeyError(topic)

    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {t: w.add_connection(t, m, typestore=store) for t, m in types.items()}
        for i, ns in enumerate(traj.t_ns.tolist()):
            header = T['std_msgs/msg/Header'](
                stamp=T['builtin_interfaces/msg/Time'](sec=ns // S, nanosec=ns % S),
                frame_id='base_link')
            for topic in types:
                if i % every[topic] == 0:
                    msg = message(topic, i, header)
                    w.write(conns[topic], ns, store.serialize_cdr(msg, types[topic]))
    return path


def test_foreign_vessel_converts_with_a_topic_map_only(tmp_path):
    traj = synthetic.demo_trajectory(1200, rate_hz=10.0)
    bag = write_foreign_bag(tmp_path / 'foreign', traj)
    (tmp_path / 'map.yaml').write_text(FOREIGN_MAP)
    runs = bag_to_runs(bag, topic_map_for(SHIP, tmp_path / 'map.yaml'))
    (table,) = runs.values()
    assert len(table) == 120  # 1 Hz over 0..119 s
    exact = {k: v for k, v in traj.columns.items() if not k.startswith('wind')}
    # Positions went through degrees of latitude/longitude and back: 1e-9 m apart.
    assert_matches(table, synthetic.Trajectory(traj.t_ns, exact), step=10, atol=1e-8)
    wind = {k: v for k, v in traj.columns.items() if k.startswith('wind')}
    # The custom message carries float32: single precision is all it can give back.
    assert_matches(table, synthetic.Trajectory(traj.t_ns, wind), step=10, atol=1e-5)


def run_cli(*argv):
    return bag_to_dataset.main([str(a) for a in argv] + ['--vessel', 'patrol_boat'])


def test_cli_writes_dataset_manifest_and_split(tmp_path, capsys):
    bags = [synthetic.write_bag(tmp_path / f'bag{i}', synthetic.demo_trajectory(100 + i,
                                                                               seed=i))
            for i in range(2)]
    out = tmp_path / 'dataset'
    assert run_cli(*bags, '--out', out, '--jobs', 2, '--seed', 3, '--split', '0.5,0,0.5',
                   '--quiet') == 0
    dataset = fmt.read_dataset(out)
    assert dataset.run_ids() == ['bag0', 'bag1']
    assert sorted(dataset.run_ids('train') + dataset.run_ids('test')) == dataset.run_ids()
    manifest = dataset.manifest
    assert manifest['split']['seed'] == 3 and manifest['split']['fractions'] == [0.5, 0, 0.5]
    sources = manifest['provenance']['sources']
    assert [s['sha256'] for s in sources] == [sha256(next(b.glob('*.mcap'))) for b in bags]
    conversion = manifest['conversion']
    assert conversion['rate_hz'] == 1.0
    assert manifest['provenance']['config']['time_source'] == 'header'
    # One manifest entry per bag, whichever worker process converted it.
    assert [b['name'] for b in conversion['recordings']] == ['bag0', 'bag1']
    assert conversion['dropped_samples'] == {'nan': 0, 'duplicate': 0, 'out_of_order': 0}
    assert manifest['provenance']['config']['map']['wind']['frame'] == 'flu'
    assert manifest['provenance']['config']['map_section'] == 'topics'
    assert len(dataset.load('bag1')) == 101
    assert str(out / 'manifest.json') in capsys.readouterr().out

    # An existing dataset is not overwritten unless asked.
    assert run_cli(bags[0], '--out', out, '--quiet') == 2
    assert run_cli(bags[0], '--out', out, '--quiet', '--overwrite') == 0
    assert fmt.read_dataset(out).run_ids() == ['bag0']


def test_two_workers_write_the_same_dataset_as_one(tmp_path):
    # More bags than workers, so a worker converts several; a damaged bag and a bad one
    # carry drops, gaps and an error through the pool as well.
    bags = [synthetic.write_bag(tmp_path / f'bag{i}', synthetic.demo_trajectory(60 + i,
                                                                              seed=i))
            for i in range(3)]
    bags.insert(1, write_damaged_bag(tmp_path / 'damaged'))
    (tmp_path / 'junk.mcap').write_bytes(b'\x00' * 100)
    bags.append(tmp_path / 'junk.mcap')
    manifests = []
    for jobs in (1, 2):
        out = tmp_path / f'dataset{jobs}'
        assert run_cli(*bags, '--out', out, '--jobs', jobs, '--quiet') == 0
        manifest = fmt.read_dataset(out).manifest
        del manifest['provenance']['argv']  # the only difference: --jobs and --out
        manifests.append(manifest)
    assert manifests[0] == manifests[1]
    assert [b['name'] for b in manifests[0]['conversion']['recordings']] == [
        'bag0', 'damaged', 'bag1', 'bag2', 'junk']
    for run in manifests[0]['runs']:
        assert (tmp_path / 'dataset1' / run['file']).read_bytes() == (
            tmp_path / 'dataset2' / run['file']).read_bytes()


def test_cli_exit_codes_for_bad_input(tmp_path, capsys):
    good = synthetic.write_bag(tmp_path / 'good', synthetic.demo_trajectory(30))
    junk = tmp_path / 'junk.mcap'
    junk.write_bytes(b'\x00' * 100)
    assert run_cli(junk, '--out', tmp_path / 'd1', '--quiet') == 1
    err = capsys.readouterr().err
    assert 'not an MCAP file' in err and 'nothing usable remained' in err
    assert not (tmp_path / 'd1' / 'manifest.json').exists()
    # Usable data beside a bad bag: the dataset is written, the bad bag reported.
    assert run_cli(junk, good, '--out', tmp_path / 'd2', '--quiet') == 0
    assert 'junk.mcap' in capsys.readouterr().err
    (tmp_path / 'map.yaml').write_text('body_velocity: 3\n')
    assert run_cli(good, '--out', tmp_path / 'd3', '--topic-map', tmp_path / 'map.yaml') == 2
    assert 'topic map' in capsys.readouterr().err
    with pytest.raises(SystemExit):
        run_cli(good, '--out', tmp_path / 'd4', '--split', '0.5,0.5')


def test_cli_help_runs_as_a_script():
    done = subprocess.run([sys.executable, str(REPO / 'offline' / 'bag_to_dataset.py'),
                           '--help'], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and '--topic-map' in done.stdout
