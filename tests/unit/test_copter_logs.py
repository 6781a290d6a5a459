"""
ArduCopter DataFlash logs: a 2014-style log made here, and the two real ones of 2014.

The made log carries a 6-DOF flight as ArduCopter 3.2/3.3 wrote it (TimeMS boot time in
milliseconds, ATT in degrees, IMU gyro in rad/s, EKF1 NED velocity and position, RCOU
PWM) and must import exactly with every check passing. The real logs
(../shared/real/ardupilot_copter, docs/results/real/autopilot_import.md) are judged on
the moving craft: their rates against their attitude pass in every flight; their
velocities against their positions fail, for the reasons the document gives.
"""

import math
from pathlib import Path

import numpy as np
import pytest

from vessel_datasets.format import read_dataset
from vessel_datasets.log_to_dataset import main as log_to_dataset
from vessel_datasets.map_checks import aggregate, check_run, context_for
from vessel_datasets.pipeline import Options, convert
from vessel_datasets.readers.dataflash import DataFlashRecordings
from vessel_datasets.topic_map import topic_map_for
from vessel_description import load_vessel
from vessel_physics.integrator import body_to_ned

from .dataflash import fmt_record, record
from .tracks import spatial_flight

ROOT = Path(__file__).resolve().parents[2]
VEHICLE = ROOT / 'docs' / 'results' / 'real' / 'autopilot' / 'arducopter_quad.yaml'
REAL = ROOT.parent / 'shared' / 'real' / 'ardupilot_copter'
PWM_MIN, PWM_SPAN = 991.0, 1025.0   # the vehicle file's RC3_MIN and RC3_MAX - RC3_MIN
TYPES = {   # name -> (id, format, columns), as ArduCopter 3.3-dev logged them
    'ATT': (131, 'Ifff', ('TimeMS', 'Roll', 'Pitch', 'Yaw')),
    'IMU': (132, 'Ifff', ('TimeMS', 'GyrX', 'GyrY', 'GyrZ')),
    'EKF1': (133, 'Iffffff', ('TimeMS', 'VN', 'VE', 'VD', 'PN', 'PE', 'PD')),
    'RCOU': (134, 'IHHHH', ('TimeMS', 'Ch1', 'Ch2', 'Ch3', 'Ch4')),
}
EVERY = {'ATT': 10, 'IMU': 2, 'EKF1': 10, 'RCOU': 10}   # rows every n of the 100 Hz flight


def write_copter_log(path, truth):
    out = bytearray(b''.join(fmt_record(i, name, fmt, cols)
                             for name, (i, fmt, cols) in TYPES.items()))
    velocity = body_to_ned(truth['u'], truth['v'], truth['w'], truth['phi'],
                           truth['theta'], truth['psi'])
    throttle = [(np.clip(m / 2500.0, 0, 1) * PWM_SPAN + PWM_MIN) for m in truth['motors']]
    for k, t in enumerate(truth['t']):
        ms = int(round(t * 1000)) + 20_000   # booted 20 s before the flight
        rows = {
            'ATT': (ms, math.degrees(truth['phi'][k]), math.degrees(truth['theta'][k]),
                    math.degrees(truth['psi'][k]) % 360.0),
            'IMU': (ms, truth['p'][k], truth['q'][k], truth['r'][k]),
            'EKF1': (ms, *(float(c[k]) for c in velocity), truth['x'][k], truth['y'][k],
                     truth['z'][k]),
            'RCOU': (ms, *(int(round(th[k])) for th in throttle)),
        }
        for name, (msg_id, fmt, _) in TYPES.items():
            if k % EVERY[name] == 0:
                out += record(msg_id, fmt, rows[name])
    path.write_bytes(bytes(out))
    return path


def test_a_2014_copter_log_imports_its_flight_with_every_check_passing(tmp_path, capsys):
    truth = spatial_flight(seconds=60.0, seed=3)
    log = write_copter_log(tmp_path / 'flight.bin', truth)
    code = log_to_dataset([str(log), '--vessel', str(VEHICLE), '--out', str(tmp_path / 'ds'),
                           '--split', '1,0,0', '--quiet'])
    said = capsys.readouterr().err
    assert code == 0, said
    assert 'failed' not in said and 'skipped: the vehicle' not in said
    ds = read_dataset(tmp_path / 'ds')
    (run,) = ds.load_split('train').values()
    (entry,) = ds.manifest['runs']
    # Truth rows of the run's samples: its first sample's boot time, less the 20 s.
    first = entry['source']['start_ns'] / 1e9 - 20.0
    idx = np.round((first + run['t'].to_numpy()) * 100).astype(int)
    for state in ('phi', 'theta', 'p', 'q', 'r'):
        np.testing.assert_allclose(run[state], truth[state][idx], atol=2e-3, err_msg=state)
    for state in ('u', 'v', 'w'):
        np.testing.assert_allclose(run[state], truth[state][idx], atol=5e-3, err_msg=state)
    np.testing.assert_allclose(run['motor2'], np.clip(truth['motors'][1][idx] / 2500, 0, 1),
                               atol=2e-3)


def test_a_log_whose_messages_have_no_boot_time_is_refused_in_one_line(tmp_path, capsys):
    path = tmp_path / 'timeless.bin'
    path.write_bytes(fmt_record(131, 'ATT', 'fff', ('Roll', 'Pitch', 'Yaw'))
                     + record(131, 'fff', (0.0, 0.0, 0.0)))
    code = log_to_dataset([str(path), '--vessel', str(VEHICLE), '--out', str(tmp_path / 'x'),
                           '--quiet'])
    said = capsys.readouterr().err
    assert code != 0 and "none of the fields ['TimeUS', 'TimeMS'] to time it" in said


def judged(log):
    vehicle = load_vessel(VEHICLE)
    topic_map = topic_map_for(vehicle, section='logs')
    reader = DataFlashRecordings()
    result = convert(reader.find([log])[0], reader, topic_map, Options())
    assert result.error is None, result.error
    ctx = context_for(topic_map, interval_s=0.1)
    per_run = {rid: check_run(run, topic_map, ctx, result.context[rid]['spikes'])
               for rid, run in result.runs.items()}
    return per_run, {c.name: c for c in aggregate(per_run, ctx)}


RATES = ('roll_rate vs d(roll)/dt', 'pitch_rate vs d(pitch)/dt', 'yaw_rate vs d(heading)/dt')


@pytest.mark.skipif(not REAL.is_dir(), reason=f'{REAL} is absent (third-party logs)')
@pytest.mark.parametrize('log, flights, velocity', [
    # GPS glitches (ERR subsystem 11) move the EKF's position up to 3.3 m in 0.1 s.
    ('Loiter_RTL.bin', 2, (0.30, 0.50)),
    # No GPS fix: the EKF diverges, its velocities beyond the vehicle's limits.
    ('pxf_7-9-2014_25.BIN', 4, (-0.05, 0.05)),
])
def test_the_real_copter_logs_rates_follow_their_attitude_in_flight(log, flights, velocity):
    per_run, pooled = judged(REAL / log)
    assert len(per_run) == flights
    for name in RATES:   # judged, not skipped: the craft turns and rolls
        assert pooled[name].ok and pooled[name].figure is not None, pooled[name].line()
        assert 0.9 <= pooled[name].figure <= 1.1
    # The velocities against the positions: the failure the document reports.
    slope = pooled['velocity vs d(position)/dt']
    assert not slope.ok and velocity[0] <= slope.figure <= velocity[1], slope.line()
