"""
Autopilot logs: an ArduPilot DataFlash .bin and a PX4 ULog .ulg made here, converted.

Both are written byte by byte as their formats are documented (ArduPilot's DataFlash:
FMT records, then messages; PX4's ULog: header, formats, subscriptions, data) from an
exact track of a rover-like boat, and read back through pymavlink and pyulog by the
log_to_dataset program: the run must be the truth, the map checks must pass, and a
missing message or field must be named in one line. A vehicle standing still (the
real ArduSub log of docs/results/real/autopilot_import.md) converts with every check
skipped as too still: no lag is found in its noise, no regression divides by nothing.
"""

import json
import math
import struct

import numpy as np
import pytest
import yaml

from vessel_datasets import log_to_dataset
from vessel_datasets.format import read_dataset
from vessel_datasets.quantities import local_projection

from .dataflash import fmt_record, record
from .tracks import trajectory

LAT0, LON0 = 59.9, 10.7
RATE_HZ = 5.0
VESSEL = {
    'name': 'rover_boat', 'rate_hz': RATE_HZ, 'window_s': 2.0, 'horizon_s': 10.0,
    'states': ['u', 'v', 'r'],
    'limits': {'u': [-1.0, 3.0], 'v': [-1.0, 1.0], 'r': [-1.0, 1.0]},
    'actuators': {'throttle': {'kind': 'other', 'unit': '1', 'range': [-1.0, 1.0]},
                  'steering': {'kind': 'other', 'unit': '1', 'range': [-1.0, 1.0]}},
    'particulars': {'length_m': 1.2},
}
# ArduRover: GPS for the track, ATT for the heading (deg), XKF1 for the EKF's earth-frame
# velocity, IMU for the yaw rate (rad/s, FRD), RCOU for the servo outputs (PWM).
DATAFLASH_MAP = {
    'earth_velocity': {'north': {'topic': 'XKF1', 'field': 'VN'},
                       'east': {'topic': 'XKF1', 'field': 'VE'}},
    'body_velocity': {'frame': 'frd', 'yaw_rate': {'topic': 'IMU', 'field': 'GyrZ'}},
    'attitude': {'frame': 'ned_frd',
                 'heading': {'topic': 'ATT', 'field': 'Yaw', 'scale': math.pi / 180}},
    'position': {'lat': {'topic': 'GPS', 'field': 'Lat'},
                 'lon': {'topic': 'GPS', 'field': 'Lng'}},
    'speed_over_ground': {'speed': {'topic': 'GPS', 'field': 'Spd'}},
    'actuators': {'throttle': {'topic': 'RCOU', 'field': 'C3', 'scale': 1 / 500,
                               'offset': -3.0},
                  'steering': {'topic': 'RCOU', 'field': 'C1', 'scale': 1 / 500,
                               'offset': -3.0}},
}
# PX4: vehicle_local_position (NED m, m/s, heading rad), actuator_outputs (normalised).
ULOG_MAP = {
    'earth_velocity': {'north': {'topic': 'vehicle_local_position', 'field': 'vx'},
                       'east': {'topic': 'vehicle_local_position', 'field': 'vy'}},
    'attitude': {'frame': 'ned_frd',
                 'heading': {'topic': 'vehicle_local_position', 'field': 'heading'}},
    'position': {'frame': 'ned', 'x': {'topic': 'vehicle_local_position', 'field': 'x'},
                 'y': {'topic': 'vehicle_local_position', 'field': 'y'}},
    'actuators': {'throttle': {'topic': 'actuator_outputs', 'field': 'output[1]'},
                  'steering': {'topic': 'actuator_outputs', 'field': 'output[0]'}},
}


def track():
    truth = trajectory(duration_s=60.0, rate_hz=50.0, speed=1.0)
    truth['throttle'] = 0.3 + 0.2 * np.sin(truth['t'] / 7.0)
    truth['steering'] = np.clip(truth['delta'] / 0.6, -1, 1)
    north, east = truth['x'] - truth['x'][0], truth['y'] - truth['y'][0]
    truth['lon'], truth['lat'] = local_projection(LAT0, LON0).transform(
        east, north, direction='INVERSE')
    return truth


# ----------------------------------------------------------------- DataFlash writer
DF_TYPES = {  # name -> (id, format, columns, rows every n samples of the 50 Hz track)
    'GPS': (130, 'QBLLf', ('TimeUS', 'I', 'Lat', 'Lng', 'Spd'), 10),
    'ATT': (131, 'Qf', ('TimeUS', 'Yaw'), 5),
    'XKF1': (132, 'QBff', ('TimeUS', 'C', 'VN', 'VE'), 5),
    'IMU': (133, 'Qf', ('TimeUS', 'GyrZ'), 1),
    'RCOU': (134, 'QHH', ('TimeUS', 'C1', 'C3'), 5),
}


def write_dataflash(path, truth, drop=()):
    out = bytearray()
    for name, (msg_id, fmt, columns, _) in DF_TYPES.items():
        if name not in drop:
            out += fmt_record(msg_id, name, fmt, columns)
    speed = np.hypot(truth['north_dot'], truth['east_dot'])
    for i, t in enumerate(truth['t']):
        us = int(round(t * 1e6)) + 5_000_000  # the autopilot booted 5 s before
        rows = {
            'GPS': (us, 0, int(round(truth['lat'][i] * 1e7)), int(round(truth['lon'][i] * 1e7)),
                    speed[i]),
            'ATT': (us, math.degrees(truth['psi'][i]) % 360),
            'XKF1': (us, 0, truth['north_dot'][i], truth['east_dot'][i]),
            'IMU': (us, truth['r'][i]),
            'RCOU': (us, int(round(1500 + 500 * truth['steering'][i])),
                     int(round(1500 + 500 * truth['throttle'][i]))),
        }
        for name, (msg_id, fmt, _, every) in DF_TYPES.items():
            if name not in drop and i % every == 0:
                out += record(msg_id, fmt, rows[name])
    path.write_bytes(bytes(out))
    return path


# ----------------------------------------------------------------- ULog writer
def _ulog_message(kind, payload):
    return struct.pack('<HB', len(payload), ord(kind)) + payload


def write_ulog(path, truth):
    formats = {'vehicle_local_position': 'uint64_t timestamp;float x;float y;float vx;'
                                         'float vy;float heading;',
               'actuator_outputs': 'uint64_t timestamp;float[4] output;'}
    out = bytearray(b'ULog\x01\x12\x35\x01' + struct.pack('<Q', 0))
    out += _ulog_message('B', bytes(40))  # flag bits: nothing incompatible
    for name, fields in formats.items():
        out += _ulog_message('F', f'{name}:{fields}'.encode())
    for msg_id, name in enumerate(formats):
        out += _ulog_message('A', struct.pack('<BH', 0, msg_id) + name.encode())
    north, east = truth['x'] - truth['x'][0], truth['y'] - truth['y'][0]
    for i, t in enumerate(truth['t']):
        us = int(round(t * 1e6)) + 5_000_000
        if i % 5 == 0:
            heading = math.atan2(math.sin(truth['psi'][i]), math.cos(truth['psi'][i]))
            out += _ulog_message('D', struct.pack('<HQfffff', 0, us, north[i], east[i],
                                                  truth['north_dot'][i],
                                                  truth['east_dot'][i], heading))
            out += _ulog_message('D', struct.pack('<HQffff', 1, us, truth['steering'][i],
                                                  truth['throttle'][i], 0.0, 0.0))
    path.write_bytes(bytes(out))
    return path


# ----------------------------------------------------------------- conversions
def vessel_file(tmp_path, log_map):
    path = tmp_path / 'rover_boat.yaml'
    path.write_text(yaml.safe_dump({**VESSEL, 'recordings': {'logs': log_map}}))
    return path


def convert(tmp_path, log, log_map, *extra):
    out = tmp_path / 'dataset'
    status = log_to_dataset.main([str(log), '--vessel', str(vessel_file(tmp_path, log_map)),
                                  '--out', str(out), '--quiet', '--split', '1,0,0',
                                  '--overwrite', *extra])
    return status, out


def assert_truth(out, truth, atol):
    (run,) = read_dataset(out).load_split('train').values()
    manifest = json.loads((out / 'manifest.json').read_text())
    start = manifest['runs'][0]['source']['start_ns'] / 1e9 - 5.0
    t = run['t'].to_numpy() + start
    inner = slice(1, -1)  # a yaw rate differentiated from the heading is one-sided there
    for column in ('u', 'v', 'r', 'throttle', 'steering'):
        np.testing.assert_allclose(run[column][inner],
                                   np.interp(t, truth['t'], truth[column])[inner],
                                   atol=atol, err_msg=column)
    return manifest


def test_an_ardupilot_dataflash_log_converts_with_its_map(tmp_path, capsys):
    truth = track()
    log = write_dataflash(tmp_path / '00000042.BIN', truth)
    status, out = convert(tmp_path, log, DATAFLASH_MAP)
    err = capsys.readouterr().err
    assert status == 0, err
    assert 'check speed over ground vs the track: slope 1.00' in err
    # Float32 fields and PWM steps of 1/500 are all the log can give back.
    manifest = assert_truth(out, truth, atol=3e-3)
    (recording,) = manifest['conversion']['recordings']
    assert recording['log_format'] == 'ardupilot-dataflash'
    assert manifest['checks']['ok']


def test_a_px4_ulog_converts_with_its_map(tmp_path, capsys):
    truth = track()
    log = write_ulog(tmp_path / 'log_7.ulg', truth)
    status, out = convert(tmp_path, log, ULOG_MAP)
    assert status == 0, capsys.readouterr().err
    manifest = assert_truth(out, truth, atol=1e-3)
    (recording,) = manifest['conversion']['recordings']
    assert recording['log_format'] == 'px4-ulog' and 'r' in manifest['conversion']['derived']


@pytest.mark.parametrize('drop, edit, message', [
    (('XKF1',), None, 'the log map needs XKF1 (earth_velocity.north, earth_velocity.east), '
                      'which the log lacks; it has: '),
    ((), ('ATT', 'Yaw', 'Heading'), "the log map reads 'Heading' (attitude.heading) from ATT, "
                                    'which has no such field; its fields are: '),
])
def test_a_missing_message_or_field_is_one_line(tmp_path, capsys, drop, edit, message):
    log = write_dataflash(tmp_path / 'short.bin', track(), drop=drop)
    log_map = yaml.safe_load(yaml.safe_dump(DATAFLASH_MAP))
    if edit:
        log_map['attitude']['heading']['field'] = edit[2]
    status, _ = convert(tmp_path, log, log_map)
    err = capsys.readouterr().err
    assert status == 1 and message in err
    assert next(line for line in err.splitlines() if message in line).count('\n') == 0


def still(duration_s=30.0, rate_hz=50.0, seed=0):
    """Return a vehicle at rest: sensor noise of a few mm/s and mrad/s, neutral outputs."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * rate_hz)) / rate_hz
    n = len(t)
    return {'t': t, 'lat': np.full(n, LAT0), 'lon': np.full(n, LON0),
            'psi': 3.73 + 2e-4 * rng.standard_normal(n),
            'north_dot': 4e-3 * rng.standard_normal(n),
            'east_dot': 4e-3 * rng.standard_normal(n),
            'r': 7e-4 * rng.standard_normal(n),
            'throttle': np.zeros(n), 'steering': np.zeros(n)}


def test_a_vehicle_standing_still_converts_with_its_checks_skipped(tmp_path, capsys):
    log = write_dataflash(tmp_path / 'still.BIN', still())
    status, out = convert(tmp_path, log, DATAFLASH_MAP)
    err = capsys.readouterr().err
    assert status == 0, err
    checks = [line for line in err.splitlines() if ': check ' in line]
    assert checks and all('skipped' in line or 'spikes: none' in line for line in checks), err
    assert 'all runs: check timing of position, heading, yaw_rate vs velocity: skipped: ' \
           'no lag is measurable' in err
    (run,) = read_dataset(out).load_split('train').values()
    assert len(run) > 100 and np.abs(run['u']).max() < 0.05
    assert json.loads((out / 'manifest.json').read_text())['checks']['ok']
